#pragma once
// Checks on JSON text before it is parsed into a document, shared by every reader of JSON
// input from anywhere (capture.json, glTF): nesting depth (nlohmann's parser and tinygltf's
// converter recurse, so 100,000 levels overflow the stack) and duplicate keys (RFC 8259
// section 4: names within an object SHOULD be unique; where they are not, readers disagree:
// nlohmann and tinygltf keep the last value, others the first, so two programs would read
// different files).
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

namespace specula {

/// The JSON field where the nesting first exceeds `max_depth` (outside strings), or nothing.
/// The field is the path of its first six levels, e.g. "asset.extras[0][0][0][0]"; "json"
/// when the text itself starts too deep.
[[nodiscard]] std::optional<std::string> json_too_deep(std::string_view text, int max_depth);

/// What one SAX pass over the text found: the first duplicate key (its field path, e.g.
/// "frames[3].light.position"), or the first syntax error (with the byte where the parser
/// stopped). Both empty: the text parses and every object's keys are unique.
struct JsonKeyReport {
    std::string duplicate_field;
    std::string error;
    std::size_t error_byte = 0;
};

/// Runs the SAX pass. Call json_too_deep first: the pass itself keeps one level per nesting.
[[nodiscard]] JsonKeyReport check_json_keys(std::string_view text);

} // namespace specula
