#pragma once
// Hand-written glTF files for tests: a JSON document plus one binary buffer,
// embedded as a base64 data URI (.gltf) so node hierarchies, index types,
// sparse accessors and broken files can be built exactly.
#include "core/file_util.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

namespace specula::test {

inline std::string base64(const std::vector<unsigned char>& data) {
    static const char* kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    std::size_t i = 0;
    for (; i + 2 < data.size(); i += 3) {
        const unsigned v = (unsigned(data[i]) << 16) | (unsigned(data[i + 1]) << 8) | data[i + 2];
        out += {kAlphabet[(v >> 18) & 63], kAlphabet[(v >> 12) & 63], kAlphabet[(v >> 6) & 63], kAlphabet[v & 63]};
    }
    if (i + 1 == data.size()) {
        const unsigned v = unsigned(data[i]) << 16;
        out += {kAlphabet[(v >> 18) & 63], kAlphabet[(v >> 12) & 63], '=', '='};
    } else if (i + 2 == data.size()) {
        const unsigned v = (unsigned(data[i]) << 16) | (unsigned(data[i + 1]) << 8);
        out += {kAlphabet[(v >> 18) & 63], kAlphabet[(v >> 12) & 63], kAlphabet[(v >> 6) & 63], '='};
    }
    return out;
}

class GltfBuilder {
public:
    GltfBuilder() {
        m_doc = {{"asset", {{"version", "2.0"}}},
                 {"accessors", nlohmann::json::array()},
                 {"bufferViews", nlohmann::json::array()},
                 {"meshes", nlohmann::json::array()},
                 {"nodes", nlohmann::json::array()}};
    }

    /// Appends raw values to the buffer (4-byte aligned) as a new bufferView; returns its index.
    template <class T>
    int view(const std::vector<T>& values) {
        while (m_bin.size() % 4 != 0) m_bin.push_back(0);
        const std::size_t offset = m_bin.size();
        m_bin.resize(offset + values.size() * sizeof(T));
        if (!values.empty()) std::memcpy(m_bin.data() + offset, values.data(), values.size() * sizeof(T));
        m_doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", values.size() * sizeof(T)}});
        return static_cast<int>(m_doc["bufferViews"].size() - 1);
    }

    /// Adds an accessor over a new bufferView holding `values`.
    template <class T>
    int accessor(const std::vector<T>& values, int component_type, const std::string& type, std::size_t count) {
        const int v = view(values);
        m_doc["accessors"].push_back({{"bufferView", v}, {"componentType", component_type}, {"count", count}, {"type", type}});
        return static_cast<int>(m_doc["accessors"].size() - 1);
    }

    int positions(const std::vector<float>& xyz) { return accessor(xyz, 5126, "VEC3", xyz.size() / 3); }
    int normals(const std::vector<float>& xyz) { return accessor(xyz, 5126, "VEC3", xyz.size() / 3); }
    int texcoords(const std::vector<float>& uv) { return accessor(uv, 5126, "VEC2", uv.size() / 2); }
    int indices_u8(const std::vector<std::uint8_t>& i) { return accessor(i, 5121, "SCALAR", i.size()); }
    int indices_u16(const std::vector<std::uint16_t>& i) { return accessor(i, 5123, "SCALAR", i.size()); }
    int indices_u32(const std::vector<std::uint32_t>& i) { return accessor(i, 5125, "SCALAR", i.size()); }

    /// Adds a mesh with the given primitives (JSON objects); returns its index.
    int mesh(const nlohmann::json& primitives) {
        m_doc["meshes"].push_back({{"primitives", primitives}});
        return static_cast<int>(m_doc["meshes"].size() - 1);
    }
    int node(const nlohmann::json& node) {
        m_doc["nodes"].push_back(node);
        return static_cast<int>(m_doc["nodes"].size() - 1);
    }

    nlohmann::json& doc() { return m_doc; }

    /// The .gltf text, with the buffer embedded as a data URI.
    std::string text() const {
        nlohmann::json doc = m_doc;
        doc["buffers"] = {{{"byteLength", m_bin.size()},
                           {"uri", "data:application/octet-stream;base64," + base64(m_bin)}}};
        return doc.dump(1);
    }

    /// Writes a .gltf with the buffer embedded as a data URI.
    void write(const std::filesystem::path& path) const { write_text_file(path, text()); }

    /// Writes a .gltf whose buffer is the external file `uri` (taken as it is: tests give
    /// hostile ones), and the buffer's bytes to `bin_file` unless it is empty.
    void write_external(const std::filesystem::path& path, const std::string& uri,
                        const std::filesystem::path& bin_file = {}) const {
        nlohmann::json doc = m_doc;
        doc["buffers"] = {{{"byteLength", m_bin.size()}, {"uri", uri}}};
        write_text_file(path, doc.dump(1));
        if (!bin_file.empty()) write_text_file(bin_file, std::string(m_bin.begin(), m_bin.end()));
    }

    /// The buffer's bytes.
    const std::vector<unsigned char>& bin() const { return m_bin; }

private:
    nlohmann::json m_doc;
    std::vector<unsigned char> m_bin;
};

} // namespace specula::test
