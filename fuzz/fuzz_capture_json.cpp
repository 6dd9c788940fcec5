// libFuzzer target: capture.json's text through parse_capture_text (nesting and duplicate keys
// on the text, then the parser and every field check). A refusal is an InputError; anything
// else that escapes (another exception, a crash, a sanitizer report, a hang) is a finding.
#include "capture/capture.h"
#include "core/error.h"

#include <cstddef>
#include <cstdint>
#include <string_view>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    try {
        const specula::CaptureDesc desc = specula::parse_capture_text(text, "fuzz/capture.json");
        // What a loaded description feeds next: the memory estimate and the JSON written back.
        (void)specula::decoded_image_bytes(desc, 2);
        (void)specula::capture_desc_to_json(desc).dump();
    } catch (const specula::InputError&) {
    }
    return 0;
}
