#include "core/json_guard.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <unordered_set>
#include <vector>

namespace specula {

using nlohmann::json;

std::optional<std::string> json_too_deep(std::string_view text, int max_depth) {
    struct Level {
        bool object;
        std::size_t index = 0; // arrays: the element being read
        std::string key;       // objects: the last key
    };
    std::vector<Level> levels;
    std::string last_string;
    for (std::size_t i = 0; i < text.size(); ++i) {
        const char ch = text[i];
        if (ch == '"') { // skip the string, keeping its start (a key's name, for the path)
            const std::size_t start = i + 1;
            for (++i; i < text.size() && text[i] != '"'; ++i)
                if (text[i] == '\\') ++i;
            last_string.assign(text.substr(start, std::min<std::size_t>(std::min(i, text.size()) - start, 64)));
        } else if (ch == ':') {
            if (!levels.empty() && levels.back().object) levels.back().key = last_string;
        } else if (ch == ',') {
            if (!levels.empty() && !levels.back().object) ++levels.back().index;
        } else if (ch == '{' || ch == '[') {
            if (levels.size() >= static_cast<std::size_t>(max_depth)) {
                std::string path;
                for (std::size_t k = 0; k < levels.size() && k < 6; ++k)
                    path += levels[k].object ? (path.empty() ? "" : ".") + levels[k].key
                                             : "[" + std::to_string(levels[k].index) + "]";
                return path.empty() ? std::string("json") : path;
            }
            levels.push_back({ch == '{'});
        } else if (ch == '}' || ch == ']') {
            if (!levels.empty()) levels.pop_back();
        }
    }
    return std::nullopt;
}

namespace {

// The SAX pass: stops at the first duplicate key, keeping the path of the field.
class KeyChecker : public nlohmann::json_sax<json> {
public:
    JsonKeyReport report;

    bool null() override { return value(); }
    bool boolean(bool) override { return value(); }
    bool number_integer(number_integer_t) override { return value(); }
    bool number_unsigned(number_unsigned_t) override { return value(); }
    bool number_float(number_float_t, const string_t&) override { return value(); }
    bool string(string_t&) override { return value(); }
    bool binary(binary_t&) override { return value(); }
    bool start_object(std::size_t) override { return open(true); }
    bool start_array(std::size_t) override { return open(false); }
    bool end_object() override { return close(); }
    bool end_array() override { return close(); }
    bool key(string_t& k) override {
        Level& top = m_levels.back();
        top.key = k;
        if (!top.keys.insert(k).second) {
            report.duplicate_field = child_path();
            return false;
        }
        return true;
    }
    bool parse_error(std::size_t byte, const std::string&, const nlohmann::detail::exception& e) override {
        report.error = e.what();
        report.error_byte = byte;
        return false;
    }

private:
    struct Level {
        bool object;
        std::string path;
        std::size_t index = 0;
        std::string key;
        std::unordered_set<std::string> keys;
    };
    std::string child_path() const {
        if (m_levels.empty()) return {};
        const Level& top = m_levels.back();
        if (top.object) return top.path.empty() ? top.key : top.path + "." + top.key;
        return top.path + "[" + std::to_string(top.index) + "]";
    }
    bool value() {
        if (!m_levels.empty() && !m_levels.back().object) ++m_levels.back().index;
        return true;
    }
    bool open(bool object) {
        Level level{object, child_path()};
        m_levels.push_back(std::move(level));
        return true;
    }
    bool close() {
        if (!m_levels.empty()) m_levels.pop_back();
        return value();
    }
    std::vector<Level> m_levels;
};

} // namespace

JsonKeyReport check_json_keys(std::string_view text) {
    KeyChecker keys;
    json::sax_parse(text.begin(), text.end(), &keys);
    return keys.report;
}

} // namespace specula
