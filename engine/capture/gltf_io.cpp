// glTF 2.0 I/O (Khronos glTF 2.0 specification: 3.6 "Buffers and Buffer Views", 3.6.2
// accessors, 3.8 images, 4.4 "GLB File Format"), guarded as gltf_io.h describes.
#include "capture/gltf_io.h"

#include "core/error.h"
#include "core/file_util.h"
#include "core/json_guard.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>
#include <new>
#include <optional>
#include <set>
#include <string_view>

namespace specula {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr std::uint32_t kGlbMagic = 0x46546C67u;  // "glTF"
constexpr std::uint32_t kChunkJson = 0x4E4F534Au; // "JSON"
constexpr std::uint32_t kChunkBin = 0x004E4942u;  // "BIN\0"

std::string index_field(const std::string& array, std::size_t i) { return array + "[" + std::to_string(i) + "]"; }

// ---------------------------------------------------------------------------------------------
// Files: only regular files are read, and opening never blocks.

// What a stat result is, for messages.
std::string file_kind(mode_t mode) {
    if (S_ISDIR(mode)) return "a folder";
    if (S_ISFIFO(mode)) return "a FIFO";
    if (S_ISCHR(mode) || S_ISBLK(mode)) return "a device";
    if (S_ISSOCK(mode)) return "a socket";
    return "not a regular file";
}

// Reads a whole regular file. The file is opened with O_NONBLOCK, so a FIFO swapped in after
// the caller's stat cannot block the open, and fstat on the open descriptor refuses anything
// but a regular file before a byte is read. Returns false with `why` on failure.
bool read_regular_file(const fs::path& path, std::vector<std::uint8_t>& out, std::string& why) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
        why = std::string("cannot open: ") + std::strerror(errno);
        return false;
    }
    struct Closer {
        int fd;
        ~Closer() { ::close(fd); }
    } closer{fd};
    struct stat st {};
    if (::fstat(fd, &st) != 0) {
        why = std::string("cannot stat: ") + std::strerror(errno);
        return false;
    }
    if (!S_ISREG(st.st_mode)) {
        why = file_kind(st.st_mode) + ", not a regular file";
        return false;
    }
    if (static_cast<std::uint64_t>(st.st_size) > kMaxGltfFileBytes) {
        why = std::to_string(st.st_size) + " bytes, above the 4 GiB a glTF file may hold";
        return false;
    }
    out.resize(static_cast<std::size_t>(st.st_size));
    std::size_t done = 0;
    while (done < out.size()) {
        const ssize_t got = ::read(fd, out.data() + done, out.size() - done);
        if (got < 0 && errno == EINTR) continue;
        if (got < 0) {
            why = std::string("cannot read: ") + std::strerror(errno);
            return false;
        }
        if (got == 0) break; // shrank while reading
        done += static_cast<std::size_t>(got);
    }
    out.resize(done);
    return true;
}

// Whether `child` lies inside folder `parent` (both canonical).
bool is_within(const fs::path& child, const fs::path& parent) {
    auto c = child.begin();
    for (auto p = parent.begin(); p != parent.end(); ++p, ++c)
        if (c == child.end() || *c != *p) return false;
    return c != child.end();
}

// tinygltf's file callbacks (tiny_gltf.h FsCallbacks): a URI is opened only when the checks
// below resolved it to this canonical path. tinygltf also looks a URI up relative to the
// working directory when it is not in the file's folder; that lookup finds nothing here.
struct FsGuard {
    std::set<std::string> allowed;
};

std::optional<std::string> allowed_path(const std::string& path, void* user) {
    std::error_code ec;
    const fs::path resolved = fs::canonical(path, ec);
    if (ec) return std::nullopt;
    const auto& allowed = static_cast<const FsGuard*>(user)->allowed;
    if (allowed.count(resolved.string()) == 0) return std::nullopt;
    return resolved.string();
}

bool guard_file_exists(const std::string& path, void* user) { return allowed_path(path, user).has_value(); }

std::string guard_expand_path(const std::string& path, void*) { return path; } // no ~ or $VAR expansion

bool guard_read_file(std::vector<unsigned char>* out, std::string* err, const std::string& path, void* user) {
    const std::optional<std::string> resolved = allowed_path(path, user);
    std::string why = "not a URI the loader checked";
    if (resolved && read_regular_file(*resolved, *out, why)) return true;
    if (err) *err += path + ": " + why + "\n";
    return false;
}

bool guard_write_file(std::string* err, const std::string& path, const std::vector<unsigned char>&, void*) {
    if (err) *err += path + ": the loader writes nothing\n";
    return false;
}

// The bytes of images given by URI, kept when asked (tinygltf calls this with the encoded
// file or data URI); nothing is decoded here.
struct ImageStash {
    bool keep = false;
    std::vector<std::vector<std::uint8_t>> bytes;
};

bool stash_image(tinygltf::Image* image, const int index, std::string*, std::string*, int, int,
                 const unsigned char* data, int size, void* user) {
    auto* stash = static_cast<ImageStash*>(user);
    if (!stash->keep || image->bufferView >= 0 || index < 0 || size <= 0) return true;
    if (stash->bytes.size() <= static_cast<std::size_t>(index)) stash->bytes.resize(static_cast<std::size_t>(index) + 1);
    stash->bytes[static_cast<std::size_t>(index)].assign(data, data + size);
    return true;
}

// ---------------------------------------------------------------------------------------------
// Checks on the parsed document, before tinygltf reads it (and opens its URIs).

// A URI's path as tinygltf 2.7 decodes it before opening a file (so the check sees the file
// tinygltf would open): '%' followed by two characters gives the byte they spell in hex,
// a character that is not a hex digit counting as 0 (so "%zz" is a NUL), and '+' a space.
std::string decode_uri(const std::string& uri) {
    auto hex = [](char c) -> unsigned {
        if (c >= '0' && c <= '9') return static_cast<unsigned>(c - '0');
        if (c >= 'a' && c <= 'f') return static_cast<unsigned>(c - 'a' + 10);
        if (c >= 'A' && c <= 'F') return static_cast<unsigned>(c - 'A' + 10);
        return 0;
    };
    std::string out;
    for (std::size_t i = 0; i < uri.size(); ++i) {
        if (uri[i] == '+') {
            out += ' ';
        } else if (uri[i] == '%' && i + 2 < uri.size()) {
            out += static_cast<char>((hex(uri[i + 1]) << 4) | hex(uri[i + 2]));
            i += 2;
        } else {
            out += uri[i];
        }
    }
    return out;
}

class DocumentChecker {
public:
    DocumentChecker(const fs::path& file, const json& doc, FsGuard& guard, std::vector<std::string>& warnings)
        : m_file(file), m_doc(doc), m_guard(guard), m_warnings(warnings) {
        std::error_code ec;
        m_folder = fs::canonical(fs::absolute(file, ec).parent_path(), ec);
        if (ec) fail("", "cannot resolve the file's folder: " + ec.message());
    }

    void run() {
        required_extensions();
        const json& buffers = array("buffers");
        std::vector<std::uint64_t> buffer_bytes;
        for (std::size_t i = 0; i < buffers.size(); ++i) {
            const std::string f = index_field("buffers", i);
            const json& b = object(buffers[i], f);
            const std::uint64_t bytes = unsigned_value(b, "byteLength", f, std::nullopt);
            if (bytes > kMaxGltfFileBytes) fail(f + ".byteLength", std::to_string(bytes) + " bytes, above 4 GiB");
            buffer_bytes.push_back(bytes);
            if (b.contains("uri")) uri(b["uri"], f + ".uri", bytes);
        }
        const json& views = array("bufferViews");
        for (std::size_t i = 0; i < views.size(); ++i) {
            const std::string f = index_field("bufferViews", i);
            const json& v = object(views[i], f);
            const std::uint64_t buffer = unsigned_value(v, "buffer", f, std::nullopt);
            if (buffer >= buffer_bytes.size()) fail(f + ".buffer", "buffer " + std::to_string(buffer) + " does not exist");
            const std::uint64_t offset = unsigned_value(v, "byteOffset", f, 0);
            const std::uint64_t length = unsigned_value(v, "byteLength", f, std::nullopt);
            const std::uint64_t size = buffer_bytes[buffer];
            if (offset > size || length > size - offset)
                fail(f + ".byteLength", "byteOffset " + std::to_string(offset) + " + byteLength " + std::to_string(length) +
                                            " runs past buffers[" + std::to_string(buffer) + "] (" +
                                            std::to_string(size) + " bytes)");
        }
        const json& images = array("images");
        for (std::size_t i = 0; i < images.size(); ++i) {
            const std::string f = index_field("images", i);
            const json& image = object(images[i], f);
            if (image.contains("bufferView")) {
                const std::uint64_t view = unsigned_value(image, "bufferView", f, std::nullopt);
                if (view >= views.size()) fail(f + ".bufferView", "bufferView " + std::to_string(view) + " does not exist");
            } else if (image.contains("uri")) {
                uri(image["uri"], f + ".uri", std::nullopt);
            }
        }
    }

private:
    [[noreturn]] void fail(const std::string& field, const std::string& message) const {
        throw InputError(m_file, field, message);
    }

    const json& array(const char* key) const {
        static const json kEmpty = json::array();
        if (!m_doc.contains(key)) return kEmpty;
        if (!m_doc[key].is_array()) fail(key, "not an array");
        return m_doc[key];
    }
    const json& object(const json& j, const std::string& field) const {
        if (!j.is_object()) fail(field, "not an object");
        return j;
    }
    std::uint64_t unsigned_value(const json& obj, const char* key, const std::string& field,
                                 std::optional<std::uint64_t> fallback) const {
        if (!obj.contains(key)) {
            if (!fallback) fail(field + "." + key, "missing");
            return *fallback;
        }
        if (!obj[key].is_number_unsigned()) fail(field + "." + key, "not a non-negative integer");
        return obj[key].get<std::uint64_t>();
    }

    // extensionsRequired: a reader that cannot honour one must not load the file (glTF 2.0
    // section 3.12, extensions).
    void required_extensions() const {
        if (!m_doc.contains("extensionsRequired")) return;
        const json& list = m_doc["extensionsRequired"];
        if (!list.is_array()) fail("extensionsRequired", "not an array of strings");
        for (std::size_t i = 0; i < list.size(); ++i) {
            const std::string f = index_field("extensionsRequired", i);
            if (!list[i].is_string()) fail(f, "not a string");
            const std::string name = list[i].get<std::string>();
            if (std::none_of(std::begin(kHonouredGltfExtensions), std::end(kHonouredGltfExtensions),
                             [&](const char* known) { return name == known; }))
                fail(f, "the file requires the extension \"" + name +
                            "\", which Specula cannot honour (it honours SPECULA_lafortune and KHR_mesh_quantization; "
                            "decompress Draco or meshopt geometry first)");
        }
    }

    // A buffer's or image's URI: data: URIs are decoded in memory by tinygltf; anything else
    // must name a regular file inside the glTF file's folder. `bytes`: a buffer's byteLength
    // (the file must hold exactly that, as tinygltf requires); images have none, and a missing
    // image file is only a warning (a mesh does not need its textures).
    void uri(const json& value, const std::string& field, std::optional<std::uint64_t> bytes) {
        if (!value.is_string()) fail(field, "not a string");
        const std::string text = value.get<std::string>();
        if (text.find('\0') != std::string::npos) fail(field, "contains a NUL character");
        if (tinygltf::IsDataURI(text)) return;
        if (text.rfind("data:", 0) == 0)
            fail(field, "a data: URI of a media type glTF does not embed (application/octet-stream, "
                        "application/gltf-buffer, image/png, image/jpeg)");
        if (text.find("://") != std::string::npos) fail(field, "only relative file URIs and data: URIs are supported");
        const std::string decoded = decode_uri(text);
        if (decoded.find('\0') != std::string::npos) fail(field, "contains a NUL character (percent-encoded)");
        if (decoded.empty()) fail(field, "empty");
        const fs::path relative(decoded);
        if (relative.has_root_path()) fail(field, "an absolute path: a URI must name a file inside the glTF file's folder");
        const fs::path normal = relative.lexically_normal();
        if (normal.empty() || *normal.begin() == "..")
            fail(field, "\"" + text + "\" leaves the glTF file's folder");
        const fs::path full = m_folder / normal;
        struct stat st {};
        if (::lstat(full.c_str(), &st) != 0) {
            if (bytes) fail(field, "file not found: " + full.string());
            m_warnings.push_back(m_file.string() + ": " + field + ": file not found (" + full.string() + "); ignored");
            return;
        }
        std::error_code ec;
        const fs::path resolved = fs::canonical(full, ec);
        if (ec) fail(field, "cannot resolve " + full.string() + ": " + ec.message());
        if (!is_within(resolved, m_folder))
            fail(field, "a symbolic link that leads outside the glTF file's folder (to " + resolved.string() + ")");
        if (::stat(resolved.c_str(), &st) != 0) fail(field, "cannot stat " + resolved.string());
        if (!S_ISREG(st.st_mode))
            fail(field, full.string() + " is " + file_kind(st.st_mode) +
                            ", not a regular file (reading it could block or never end)");
        if (bytes && static_cast<std::uint64_t>(st.st_size) != *bytes)
            fail(field, "the file holds " + std::to_string(st.st_size) + " bytes but byteLength is " +
                            std::to_string(*bytes));
        m_guard.allowed.insert(resolved.string());
    }

    const fs::path& m_file;
    const json& m_doc;
    FsGuard& m_guard;
    std::vector<std::string>& m_warnings;
    fs::path m_folder;
};

std::uint32_t get_u32(const std::vector<std::uint8_t>& bytes, std::size_t at) {
    std::uint32_t v = 0;
    std::memcpy(&v, bytes.data() + at, 4); // GLB is little-endian, as is every platform we build on
    return v;
}

std::string one_line(std::string text) {
    while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
    std::replace(text.begin(), text.end(), '\n', ';');
    return text;
}

} // namespace

// ---------------------------------------------------------------------------------------------

GltfFile GltfFile::load(const fs::path& path, const std::string& field, const GltfLoadOptions& options) {
    GltfFile file;
    file.m_path = path;
    const auto not_gltf = [&](const std::string& why) {
        return InputError(path, field, "not a readable glTF 2.0 file (" + why + ")");
    };
    try {
        if (path.native().find('\0') != std::string::npos) throw InputError(path, field, "the path contains a NUL character");
        struct stat st {};
        if (::stat(path.c_str(), &st) != 0) throw InputError(path, field, "file not found");
        if (!S_ISREG(st.st_mode))
            throw InputError(path, field, file_kind(st.st_mode) + ", not a regular file (reading it could block)");
        std::vector<std::uint8_t> bytes;
        std::string why;
        if (!read_regular_file(path, bytes, why)) throw InputError(path, field, why);

        // The JSON text: the whole file, or a .glb's first chunk (glTF 2.0 chapter 4: a
        // 12-byte header, then chunks of length, type and data; the JSON chunk comes first).
        // tinygltf parses the container again; this only finds the text to check.
        const bool binary = bytes.size() >= 4 && get_u32(bytes, 0) == kGlbMagic;
        std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
        if (binary) {
            if (bytes.size() < 20) throw not_gltf("truncated GLB header");
            if (get_u32(bytes, 4) != 2) throw not_gltf("GLB version is not 2");
            const std::uint64_t length = get_u32(bytes, 8), json_length = get_u32(bytes, 12);
            if (length < 20 || length > bytes.size()) throw not_gltf("the GLB header's length does not match the file");
            if (get_u32(bytes, 16) != kChunkJson) throw not_gltf("the first GLB chunk is not JSON");
            if (json_length > length - 20) throw not_gltf("the JSON chunk runs past the end of the file");
            text = text.substr(20, static_cast<std::size_t>(json_length));
        }
        // Before any parser builds the document (core/json_guard.h).
        if (const std::optional<std::string> deep = json_too_deep(text, kMaxGltfJsonDepth))
            throw InputError(path, *deep, "JSON nested deeper than " + std::to_string(kMaxGltfJsonDepth) +
                                              " levels (refused before parsing)");
        const JsonKeyReport keys = check_json_keys(text);
        if (!keys.duplicate_field.empty())
            throw InputError(path, keys.duplicate_field, "duplicate JSON key (readers disagree on which value counts)");
        if (!keys.error.empty())
            throw not_gltf("malformed JSON at byte " + std::to_string(keys.error_byte) + ": " + keys.error);
        file.m_json = json::parse(text.begin(), text.end());
        if (!file.m_json.is_object()) throw not_gltf("the JSON is not an object");

        FsGuard guard;
        DocumentChecker(path, file.m_json, guard, file.m_warnings).run();

        tinygltf::TinyGLTF loader;
        ImageStash stash{options.keep_image_bytes, {}};
        loader.SetImageLoader(&stash_image, &stash);
        loader.SetFsCallbacks({&guard_file_exists, &guard_expand_path, &guard_read_file, &guard_write_file, &guard});
        std::error_code ec;
        const std::string base_dir = fs::canonical(fs::absolute(path).parent_path(), ec).string();
        std::string err, warn;
        bool ok = false;
        try {
            ok = binary ? loader.LoadBinaryFromMemory(&file.m_model, &err, &warn, bytes.data(),
                                                      static_cast<unsigned int>(bytes.size()), base_dir)
                        : loader.LoadASCIIFromString(&file.m_model, &err, &warn, text.data(),
                                                     static_cast<unsigned int>(text.size()), base_dir);
        } catch (const std::exception& e) {
            err = e.what();
            ok = false;
        }
        if (!ok) throw not_gltf(err.empty() ? "tinygltf refused it" : one_line(err));
        file.m_image_bytes = std::move(stash.bytes);
    } catch (const std::bad_alloc&) { // sizes come from the file: a hostile one must not escape as bad_alloc
        throw InputError(path, field, "out of memory while reading the file (implausible sizes in it?)");
    } catch (const json::exception& e) { // defensive: the SAX pass above has parsed the same text
        throw not_gltf(e.what());
    }
    return file;
}

void GltfFile::fail(const std::string& field, const std::string& message) const {
    throw InputError(m_path, field, message);
}

const tinygltf::Accessor& GltfFile::accessor(int index, const std::string& field) const {
    if (index < 0 || static_cast<std::size_t>(index) >= m_model.accessors.size())
        fail(field, "accessor index " + std::to_string(index) + " out of range");
    const tinygltf::Accessor& acc = m_model.accessors[static_cast<std::size_t>(index)];
    if (acc.count > kMaxGltfAccessorCount)
        fail(field, "accessor count " + std::to_string(acc.count) + " is above the maximum " +
                        std::to_string(kMaxGltfAccessorCount));
    return acc;
}

GltfFile::Span GltfFile::span(int view_index, std::size_t byte_offset, int component_type, int components,
                              std::size_t count, const std::string& field) const {
    if (view_index < 0 || static_cast<std::size_t>(view_index) >= m_model.bufferViews.size())
        fail(field, "bufferView index " + std::to_string(view_index) + " out of range");
    const tinygltf::BufferView& view = m_model.bufferViews[static_cast<std::size_t>(view_index)];
    if (view.buffer < 0 || static_cast<std::size_t>(view.buffer) >= m_model.buffers.size())
        fail(field, "buffer index " + std::to_string(view.buffer) + " out of range");
    const std::vector<unsigned char>& buffer = m_model.buffers[static_cast<std::size_t>(view.buffer)].data;
    const int csize = tinygltf::GetComponentSizeInBytes(static_cast<std::uint32_t>(component_type));
    if (csize <= 0) fail(field, "unknown componentType " + std::to_string(component_type));
    const std::size_t elem = static_cast<std::size_t>(csize) * static_cast<std::size_t>(components);
    const std::size_t stride = view.byteStride == 0 ? elem : view.byteStride;
    if (stride < elem) fail(field, "byteStride smaller than an element");
    if (view.byteOffset > buffer.size() || view.byteLength > buffer.size() - view.byteOffset)
        fail(field, "bufferView " + std::to_string(view_index) + " exceeds its buffer");
    Span s{buffer.data() + view.byteOffset, stride};
    if (count == 0) return s;
    // byte_offset + stride * (count - 1) + elem <= byteLength, without overflow.
    if (byte_offset > view.byteLength) fail(field, "byteOffset exceeds the bufferView");
    const std::size_t room = view.byteLength - byte_offset;
    if (elem > room || (count - 1) > (room - elem) / stride)
        fail(field, std::to_string(count) + " elements exceed the bufferView");
    s.data += byte_offset;
    return s;
}

double GltfFile::component(const unsigned char* elem, int c, int type, bool normalized, const std::string& field) const {
    // glTF 2.0 section 3.11 "Animations" (normalized integers): unsigned v / max, signed max(v / max, -1).
    auto get = [&](auto tag) {
        using T = decltype(tag);
        T v;
        std::memcpy(&v, elem + static_cast<std::size_t>(c) * sizeof(T), sizeof(T));
        double d = static_cast<double>(v);
        if (normalized) d = std::max(d / static_cast<double>(std::numeric_limits<T>::max()), -1.0);
        return d;
    };
    switch (type) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: {
        float v;
        std::memcpy(&v, elem + static_cast<std::size_t>(c) * sizeof(float), sizeof v);
        return static_cast<double>(v);
    }
    case TINYGLTF_COMPONENT_TYPE_BYTE: return get(std::int8_t{});
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return get(std::uint8_t{});
    case TINYGLTF_COMPONENT_TYPE_SHORT: return get(std::int16_t{});
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return get(std::uint16_t{});
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return get(std::uint32_t{});
    default: fail(field, "unsupported componentType " + std::to_string(type));
    }
}

std::vector<double> GltfFile::read_floats(int index, int components, const std::string& field) const {
    const tinygltf::Accessor& acc = accessor(index, field);
    if (tinygltf::GetNumComponentsInType(static_cast<std::uint32_t>(acc.type)) != components)
        fail(field, "expected " + std::to_string(components) + " components per element");
    // The data range is validated before allocating: the count comes from the file.
    Span s;
    if (acc.bufferView >= 0) s = span(acc.bufferView, acc.byteOffset, acc.componentType, components, acc.count, field);
    std::vector<double> out(acc.count * static_cast<std::size_t>(components), 0.0);
    if (acc.bufferView >= 0) {
        for (std::size_t i = 0; i < acc.count; ++i)
            for (int c = 0; c < components; ++c)
                out[i * components + c] = component(s.data + i * s.stride, c, acc.componentType, acc.normalized, field);
    }
    if (acc.sparse.isSparse) { // glTF 2.0 section 3.6.2.3
        const std::string sf = field + ".sparse";
        if (acc.sparse.count < 0 || static_cast<std::size_t>(acc.sparse.count) > acc.count)
            fail(sf, "sparse count out of range");
        const auto n = static_cast<std::size_t>(acc.sparse.count);
        const std::vector<std::uint32_t> idx = read_index_span(
            acc.sparse.indices.bufferView, acc.sparse.indices.byteOffset, acc.sparse.indices.componentType, n,
            sf + ".indices");
        if (acc.sparse.values.byteOffset < 0) fail(sf + ".values", "negative byteOffset");
        const Span v = span(acc.sparse.values.bufferView, static_cast<std::size_t>(acc.sparse.values.byteOffset),
                            acc.componentType, components, n, sf + ".values");
        for (std::size_t k = 0; k < n; ++k) {
            if (idx[k] >= acc.count) fail(sf + ".indices", "index " + std::to_string(idx[k]) + " out of range");
            for (int c = 0; c < components; ++c)
                out[idx[k] * components + c] =
                    component(v.data + k * v.stride, c, acc.componentType, acc.normalized, sf + ".values");
        }
    }
    return out;
}

std::vector<float> GltfFile::read_float32(int index, int components, const std::string& field) const {
    const tinygltf::Accessor& acc = accessor(index, field);
    if (acc.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT) fail(field, "componentType must be FLOAT (5126)");
    const std::vector<double> wide = read_floats(index, components, field);
    // float -> double -> float is the identity on every float, denormals and -0 included.
    std::vector<float> out(wide.size());
    for (std::size_t i = 0; i < wide.size(); ++i) out[i] = static_cast<float>(wide[i]);
    return out;
}

std::vector<std::uint32_t> GltfFile::read_indices(int index, const std::string& field) const {
    const tinygltf::Accessor& acc = accessor(index, field);
    if (acc.type != TINYGLTF_TYPE_SCALAR) fail(field, "indices must be scalars");
    if (acc.sparse.isSparse) fail(field, "sparse index accessors are not supported");
    if (acc.bufferView < 0) fail(field, "index accessor has no bufferView");
    return read_index_span(acc.bufferView, acc.byteOffset, acc.componentType, acc.count, field);
}

std::vector<std::uint32_t> GltfFile::read_index_span(int view, std::size_t byte_offset, int component_type,
                                                     std::size_t count, const std::string& field) const {
    if (component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
        component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
        fail(field, "indices must be unsigned byte, short or int");
    if (count > kMaxGltfAccessorCount) fail(field, "count " + std::to_string(count) + " is above the maximum");
    const Span s = span(view, byte_offset, component_type, 1, count, field);
    std::vector<std::uint32_t> out(count);
    for (std::size_t i = 0; i < count; ++i) {
        const unsigned char* p = s.data + i * s.stride;
        switch (component_type) {
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: out[i] = *p; break;
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
            std::uint16_t v;
            std::memcpy(&v, p, sizeof v);
            out[i] = v;
            break;
        }
        default: std::memcpy(&out[i], p, sizeof(std::uint32_t));
        }
    }
    return out;
}

std::span<const std::uint8_t> GltfFile::view_bytes(int index, const std::string& field) const {
    if (index < 0 || static_cast<std::size_t>(index) >= m_model.bufferViews.size())
        fail(field, "bufferView index " + std::to_string(index) + " out of range");
    const tinygltf::BufferView& view = m_model.bufferViews[static_cast<std::size_t>(index)];
    if (view.buffer < 0 || static_cast<std::size_t>(view.buffer) >= m_model.buffers.size())
        fail(field, "buffer index " + std::to_string(view.buffer) + " out of range");
    const std::vector<unsigned char>& buffer = m_model.buffers[static_cast<std::size_t>(view.buffer)].data;
    if (view.byteOffset > buffer.size() || view.byteLength > buffer.size() - view.byteOffset)
        fail(field, "bufferView " + std::to_string(index) + " exceeds its buffer");
    return {buffer.data() + view.byteOffset, view.byteLength};
}

Image GltfFile::decode_image(int index, ColorSpace integer_encoding, const std::string& field) const {
    if (index < 0 || static_cast<std::size_t>(index) >= m_model.images.size())
        fail(field, "image index " + std::to_string(index) + " out of range");
    const tinygltf::Image& image = m_model.images[static_cast<std::size_t>(index)];
    std::span<const std::uint8_t> bytes;
    std::string where = field;
    if (image.bufferView >= 0) {
        where = field + ".bufferView";
        bytes = view_bytes(image.bufferView, where);
    } else {
        where = field + ".uri";
        const auto i = static_cast<std::size_t>(index);
        if (i >= m_image_bytes.size() || m_image_bytes[i].empty())
            fail(image.uri.empty() ? field : where, image.uri.empty() ? "neither bufferView nor uri"
                                                                      : "the image could not be read (file not found?)");
        bytes = m_image_bytes[i];
    }
    return specula::decode_image(bytes, integer_encoding, m_path, where);
}

// ---------------------------------------------------------------------------------------------
// Writing.

std::size_t GlbWriter::add_view(const void* data, std::size_t bytes, int target) {
    while (m_bin.size() % 4 != 0) m_bin.push_back(0);
    const std::size_t offset = m_bin.size();
    m_bin.resize(offset + bytes);
    if (bytes > 0) std::memcpy(m_bin.data() + offset, data, bytes);
    json view = {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes}};
    if (target != 0) view["target"] = target;
    m_views.push_back(std::move(view));
    return m_views.size() - 1;
}

std::size_t GlbWriter::add_accessor(json accessor) {
    m_accessors.push_back(std::move(accessor));
    return m_accessors.size() - 1;
}

json GlbWriter::add_mesh(const Mesh& mesh, const fs::path& file, std::span<const glm::vec4> tangents) {
    constexpr int kArrayBuffer = 34962, kElementArrayBuffer = 34963; // bufferView.target, glTF 2.0 section 3.6.1.1
    const std::size_t n = mesh.positions.size();
    if (n == 0 || mesh.triangles.empty()) throw InputError(file, "mesh", "refusing to write an empty mesh");
    for (const glm::uvec3& t : mesh.triangles)
        if (t.x >= n || t.y >= n || t.z >= n) throw InputError(file, "mesh.triangles", "triangle index out of range");
    auto finite = [](auto v) {
        for (int c = 0; c < v.length(); ++c)
            if (!std::isfinite(v[c])) return false;
        return true;
    };
    for (const glm::vec3& p : mesh.positions)
        if (!finite(p)) throw InputError(file, "mesh.positions", "non-finite vertex position");
    const bool has_uv = mesh.has_texcoords();
    if (has_uv)
        for (const glm::vec2& uv : mesh.texcoords)
            if (!finite(uv)) throw InputError(file, "mesh.texcoords", "non-finite texture coordinate");
    const std::vector<glm::vec3> normals = gltf_unit_normals(mesh);

    glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
    for (const glm::vec3& p : mesh.positions) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    auto vec3_json = [](const glm::vec3& v) {
        return json::array({static_cast<double>(v.x), static_cast<double>(v.y), static_cast<double>(v.z)});
    };
    json attributes;
    attributes["POSITION"] = add_accessor({{"bufferView", add_view(mesh.positions.data(), n * sizeof(glm::vec3), kArrayBuffer)},
                                           {"componentType", TINYGLTF_COMPONENT_TYPE_FLOAT}, {"count", n}, {"type", "VEC3"},
                                           {"min", vec3_json(lo)}, {"max", vec3_json(hi)}});
    attributes["NORMAL"] = add_accessor({{"bufferView", add_view(normals.data(), n * sizeof(glm::vec3), kArrayBuffer)},
                                         {"componentType", TINYGLTF_COMPONENT_TYPE_FLOAT}, {"count", n}, {"type", "VEC3"}});
    if (has_uv)
        attributes["TEXCOORD_0"] =
            add_accessor({{"bufferView", add_view(mesh.texcoords.data(), n * sizeof(glm::vec2), kArrayBuffer)},
                          {"componentType", TINYGLTF_COMPONENT_TYPE_FLOAT}, {"count", n}, {"type", "VEC2"}});
    if (!tangents.empty()) {
        if (tangents.size() != n) throw InputError(file, "mesh.tangents", "not one per vertex");
        attributes["TANGENT"] = add_accessor({{"bufferView", add_view(tangents.data(), n * sizeof(glm::vec4), kArrayBuffer)},
                                              {"componentType", TINYGLTF_COMPONENT_TYPE_FLOAT}, {"count", n}, {"type", "VEC4"}});
    }
    std::vector<std::uint32_t> idx;
    idx.reserve(mesh.triangles.size() * 3);
    for (const glm::uvec3& t : mesh.triangles) idx.insert(idx.end(), {t.x, t.y, t.z});
    const std::size_t indices =
        add_accessor({{"bufferView", add_view(idx.data(), idx.size() * sizeof(std::uint32_t), kElementArrayBuffer)},
                      {"componentType", TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT}, {"count", idx.size()}, {"type", "SCALAR"}});
    return {{"attributes", attributes}, {"indices", indices}, {"mode", TINYGLTF_MODE_TRIANGLES}};
}

void GlbWriter::write(const fs::path& path, json doc) {
    while (m_bin.size() % 4 != 0) m_bin.push_back(0);
    doc["buffers"] = json::array({{{"byteLength", m_bin.size()}}});
    doc["bufferViews"] = m_views;
    doc["accessors"] = m_accessors;

    std::string text = doc.dump();
    while (text.size() % 4 != 0) text.push_back(' ');
    const std::uint64_t total = 12 + 8 + text.size() + 8 + m_bin.size();
    if (total > kMaxGltfFileBytes) throw InputError(path, "", "too large for a .glb (4 GiB)");
    std::string out;
    out.reserve(static_cast<std::size_t>(total));
    auto put32 = [&](std::uint64_t v) {
        const auto u = static_cast<std::uint32_t>(v);
        char b[4];
        std::memcpy(b, &u, 4); // GLB is little-endian, as is every platform we build on
        out.append(b, 4);
    };
    put32(kGlbMagic);
    put32(2);
    put32(total);
    put32(text.size());
    put32(kChunkJson);
    out += text;
    put32(m_bin.size());
    put32(kChunkBin);
    out.append(reinterpret_cast<const char*>(m_bin.data()), m_bin.size());
    write_text_file(path, out);
}

} // namespace specula
