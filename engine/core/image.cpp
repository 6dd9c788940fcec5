#include "core/image.h"
#include "core/image_input.h"

#include "core/error.h"
#include "core/file_util.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <new>
#include <optional>

namespace specula {

namespace fs = std::filesystem;

float srgb_to_linear(float v) noexcept {
    return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

float linear_to_srgb(float v) noexcept {
    return v <= 0.0031308f ? v * 12.92f : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

namespace {

std::uint32_t little_endian_u32(const std::uint8_t* b) {
    return static_cast<std::uint32_t>(b[0]) | static_cast<std::uint32_t>(b[1]) << 8 |
           static_cast<std::uint32_t>(b[2]) << 16 | static_cast<std::uint32_t>(b[3]) << 24;
}

std::string dimension_refusal(std::int64_t width, std::int64_t height, int max_dimension) {
    return "image is " + std::to_string(width) + " x " + std::to_string(height) +
           ", above the largest accepted width or height (" + std::to_string(max_dimension) + ")";
}

constexpr std::uint8_t kExrMagic[4] = {0x76, 0x2F, 0x31, 0x01};

// The value size OpenEXR reads for its fixed-size attribute types, whatever size the file
// declares (0: a type whose reader uses the declared size: string, stringvector, opaque).
std::size_t exr_fixed_size(const std::string& type) {
    static const std::pair<const char*, std::size_t> kSizes[] = {
        {"box2i", 16}, {"box2f", 16}, {"v2i", 8},  {"v2f", 8},          {"v2d", 16},     {"v3i", 12},
        {"v3f", 12},   {"v3d", 24},   {"int", 4},  {"float", 4},        {"double", 8},   {"compression", 1},
        {"lineOrder", 1}, {"envmap", 1}, {"deepImageState", 1}, {"m33f", 36}, {"m33d", 72}, {"m44f", 64},
        {"m44d", 128}, {"chromaticities", 32}, {"keycode", 28}, {"timecode", 8}, {"rational", 8}, {"tiledesc", 9}};
    for (const auto& [name, size] : kSizes)
        if (type == name) return size;
    return 0;
}

// Reads up to n bytes at an offset into dst; returns how many it read (fewer at the end).
using ReadAt = std::function<std::size_t(std::uint64_t offset, std::uint8_t* dst, std::size_t n)>;

// A channel list (chlist) as OpenEXR reads it: entries of a NUL-terminated name and 16 bytes
// (pixel type, linear flag, 3 reserved, x and y sampling) up to an empty name, which must be
// the last of the `size` bytes the attribute declares.
template <class Refuse>
void check_exr_channel_list(const ReadAt& read_at, std::uint64_t at, std::size_t size, const std::string& name,
                            const Refuse& refuse) {
    if (size == 0) refuse("the channel list '" + name + "' is empty (not even its terminating NUL)");
    std::vector<std::uint8_t> value(size);
    if (read_at(at, value.data(), size) != size) refuse("the file ends inside attribute '" + name + "'");
    std::size_t p = 0;
    while (p < size && value[p] != 0) {
        const auto end = std::find(value.begin() + static_cast<std::ptrdiff_t>(p), value.end(), std::uint8_t{0});
        p = static_cast<std::size_t>(end - value.begin()) + 1 + 16; // the name, its NUL, the 16 bytes
    }
    if (p + 1 != size)
        refuse("the channel list '" + name + "' does not end where its declared size (" + std::to_string(size) + " bytes) ends");
}

// OpenEXR's header (the OpenEXR file layout): after the 4-byte magic number and the 4-byte
// version field come attributes, each a name and a type name (NUL-terminated, at most 31
// bytes, 255 with the long-names flag 0x400), a 4-byte little-endian size and that many bytes
// of value; an empty name ends the header. A multi-part file (flag 0x1000) holds one header
// per part and an empty header after the last. OpenEXR allocates an attribute's declared
// size before it reads the value: a 485-byte file whose string attribute claimed 1.85 GB
// made it allocate 1.85 GB (found by fuzz_image_decode, tests/core/hostile_test.cpp keeps
// it). So the header is walked here first: every attribute must fit in the bytes the file
// holds (`total`), and the data window within max_dimension, before OpenEXR sees the file.
// OpenEXR reads a fixed-size type's value (box2i: 16 bytes) and a channel list (entries up to
// an empty name) by their content, not by the declared size: a size that disagrees would put
// its reading and this walk at different places in the file (a fuzz input whose channel list
// ran one byte past its size hid a data window 10,682,372 pixels wide from the walk, and
// OpenEXR allocated and cleared a buffer for it for a minute). Such sizes are refused.
void check_exr_header(const ReadAt& read_at, std::uint64_t total, const fs::path& file, const std::string& field,
                      int max_dimension) {
    auto refuse = [&](const std::string& why) {
        throw InputError(file, field, "malformed OpenEXR header: " + why);
    };
    std::uint8_t version[8];
    if (read_at(0, version, sizeof version) < sizeof version) refuse("the file ends inside the version field");
    const std::uint32_t flags = little_endian_u32(version + 4);
    if ((flags & 0xFFu) != 2) refuse("version " + std::to_string(flags & 0xFFu) + " (only version 2 exists)");
    const std::size_t max_name = (flags & 0x400u) != 0 ? 255 : 31;
    const bool multipart = (flags & 0x1000u) != 0;
    std::uint64_t pos = sizeof version;
    auto read_name = [&](const char* what) {
        std::uint8_t buf[256];
        const std::size_t got = read_at(pos, buf, max_name + 1);
        const std::uint8_t* end = std::find(buf, buf + got, std::uint8_t{0});
        if (end == buf + got)
            refuse(std::string("the attribute ") + what + " at byte " + std::to_string(pos) + " is unterminated or longer than " +
                   std::to_string(max_name) + " bytes");
        std::string s(reinterpret_cast<const char*>(buf), reinterpret_cast<const char*>(end));
        pos += s.size() + 1;
        return s;
    };
    for (;;) { // one header per part
        int attributes = 0;
        for (std::string name = read_name("name"); !name.empty(); name = read_name("name"), ++attributes) {
            const std::string type = read_name("type name");
            std::uint8_t size_bytes[4];
            if (read_at(pos, size_bytes, 4) < 4) refuse("the file ends inside the size of attribute '" + name + "'");
            pos += 4;
            const auto size = static_cast<std::int32_t>(little_endian_u32(size_bytes));
            if (size < 0 || static_cast<std::uint64_t>(size) > total - pos)
                refuse("attribute '" + name + "' (" + type + ") claims " + std::to_string(size) + " bytes, but the file holds " +
                       std::to_string(total - pos) + " after it");
            const std::size_t fixed = exr_fixed_size(type);
            if (fixed != 0 && static_cast<std::size_t>(size) != fixed)
                refuse("attribute '" + name + "' (" + type + ") declares " + std::to_string(size) + " bytes; a " + type +
                       " holds " + std::to_string(fixed));
            if (type == "chlist") check_exr_channel_list(read_at, pos, static_cast<std::size_t>(size), name, refuse);
            if (name == "dataWindow" && type == "box2i") {
                std::uint8_t box[16];
                if (read_at(pos, box, sizeof box) == sizeof box) {
                    auto corner = [&](int i) { return static_cast<std::int64_t>(static_cast<std::int32_t>(little_endian_u32(box + 4 * i))); };
                    const std::int64_t width = corner(2) - corner(0) + 1, height = corner(3) - corner(1) + 1;
                    if (width > max_dimension || height > max_dimension)
                        throw InputError(file, field, dimension_refusal(width, height, max_dimension));
                }
            }
            pos += static_cast<std::uint64_t>(size);
        }
        if (!multipart || attributes == 0) return;
    }
}

constexpr std::uint8_t kPngMagic[8] = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};

// PNG's chunks (PNG specification, section 5.3): a 4-byte big-endian length (at most 2^31 - 1),
// a 4-byte type, the data, a 4-byte CRC; IEND ends the file. libpng and OpenImageIO allocate
// for what a chunk claims: a 246-byte file whose tEXt chunk claimed 1,870,069,780 bytes took
// 2 GB of memory (found by fuzz_image_decode). So every chunk up to IEND must fit in the bytes
// the file holds before a decoder sees it.
void check_png_chunks(const ReadAt& read_at, std::uint64_t total, const fs::path& file, const std::string& field) {
    std::uint64_t pos = sizeof kPngMagic;
    std::uint8_t head[8];
    while (read_at(pos, head, sizeof head) == sizeof head) {
        const std::uint32_t length = static_cast<std::uint32_t>(head[0]) << 24 | static_cast<std::uint32_t>(head[1]) << 16 |
                                     static_cast<std::uint32_t>(head[2]) << 8 | head[3];
        std::string type;
        for (int i = 4; i < 8; ++i) type += std::isprint(head[i]) != 0 ? static_cast<char>(head[i]) : '?';
        const std::uint64_t left = total - pos - sizeof head;
        if (length > 0x7FFFFFFFu || std::uint64_t{length} + 4 > left)
            throw InputError(file, field, "malformed PNG: chunk '" + type + "' at byte " + std::to_string(pos) + " claims " +
                                              std::to_string(length) + " bytes, but the file holds " + std::to_string(left) +
                                              " after it (truncated or corrupt)");
        if (type == "IEND") return;
        pos += sizeof head + length + 4;
    }
}

} // namespace

std::unique_ptr<OIIO::ImageInput> open_image_file(const fs::path& path, const std::string& field, int max_dimension) {
    std::error_code ec;
    const fs::file_status status = fs::status(path, ec);
    if (!fs::exists(status)) throw InputError(path, field, "file not found");
    // Opening a FIFO or a device could block or never end.
    if (!fs::is_regular_file(status)) throw InputError(path, field, "not a regular file");
    {
        std::ifstream file(path, std::ios::binary);
        const std::uint64_t total = fs::file_size(path, ec);
        std::uint8_t magic[8] = {};
        const ReadAt read_at = [&](std::uint64_t offset, std::uint8_t* dst, std::size_t n) -> std::size_t {
            file.clear();
            file.seekg(static_cast<std::streamoff>(offset));
            file.read(reinterpret_cast<char*>(dst), static_cast<std::streamsize>(n));
            return static_cast<std::size_t>(std::max<std::streamsize>(file.gcount(), 0));
        };
        if (file && !ec && read_at(0, magic, sizeof magic) == sizeof magic) {
            if (std::memcmp(magic, kExrMagic, sizeof kExrMagic) == 0) check_exr_header(read_at, total, path, field, max_dimension);
            if (std::memcmp(magic, kPngMagic, sizeof kPngMagic) == 0) check_png_chunks(read_at, total, path, field);
        }
    }
    // Alpha is ignored by contract: ask for unassociated alpha so OIIO does not
    // premultiply the colour channels by it (a PNG pixel with alpha 0 would read black).
    OIIO::ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);
    auto in = OIIO::ImageInput::open(path.string(), &config);
    if (!in) {
        std::string why = OIIO::geterror();
        throw InputError(path, field, "cannot read image" + (why.empty() ? std::string() : " (" + why + ")"));
    }
    return in;
}

namespace {

ImageFileInfo info_from_spec(const OIIO::ImageSpec& spec) {
    ImageFileInfo info;
    info.width = spec.width;
    info.height = spec.height;
    info.channels = spec.nchannels;
    const auto base = spec.format.basetype;
    info.is_float = base == OIIO::TypeDesc::FLOAT || base == OIIO::TypeDesc::HALF || base == OIIO::TypeDesc::DOUBLE;
    info.bits_per_channel = static_cast<int>(spec.format.size() * 8);
    return info;
}

// After a read_image that returned true: OpenImageIO still records an error when the decoder
// ran out of data or met corrupt data and filled in what it could not read (libjpeg's
// "Premature end of JPEG file": the missing rows come out grey). Such pixels are made up, not
// measured, so the file is refused.
void check_complete(OIIO::ImageInput& in, const fs::path& path, const std::string& field) {
    if (!in.has_error()) return;
    throw InputError(path, field,
                     "the image decoded only in part (" + in.geterror() + "): the file is truncated or corrupt");
}

} // namespace

ImageFileInfo read_image_info(const fs::path& path, const std::string& field) {
    auto in = open_image_file(path, field);
    ImageFileInfo info = info_from_spec(in->spec());
    in->close();
    return info;
}

Image read_image(const fs::path& path, ColorSpace integer_encoding, const std::string& field, ImageFileInfo* info_out,
                 int max_dimension) {
    auto in = open_image_file(path, field, max_dimension);
    const OIIO::ImageSpec& spec = in->spec();
    const ImageFileInfo info = info_from_spec(spec);
    if (info.width <= 0 || info.height <= 0 || info.channels <= 0 || spec.depth > 1)
        throw InputError(path, field, "image has no pixels");
    // Refused from the header, before a pixel is decoded or allocated.
    if (info.width > max_dimension || info.height > max_dimension)
        throw InputError(path, field, dimension_refusal(info.width, info.height, max_dimension));
    Image image;
    try {
        image = Image(info.width, info.height, info.channels);
    } catch (const std::bad_alloc&) {
        throw InputError(path, field, "image too large to decode (out of memory)");
    }
    // read_image converts integer data to float in [0, 1] without any colour transform.
    if (!in->read_image(0, 0, 0, info.channels, OIIO::TypeDesc::FLOAT, image.pixels.data())) {
        std::string why = in->geterror();
        throw InputError(path, field, "cannot decode image" + (why.empty() ? std::string() : " (" + why + ")"));
    }
    check_complete(*in, path, field);
    in->close();
    if (!info.is_float && integer_encoding == ColorSpace::Srgb) {
        for (float& v : image.pixels) v = srgb_to_linear(v);
    }
    if (info_out) *info_out = info;
    return image;
}

void write_image(const fs::path& path, const Image& image, ColorSpace integer_encoding, int bits) {
    if (image.empty()) throw InputError(path, "", "refusing to write an empty image");
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    const bool is_float = ext == ".exr" || ext == ".hdr";
    if (!is_float && bits != 8 && bits != 16) throw InputError(path, "", "integer images are 8 or 16 bits");

    write_atomically(path, [&](const fs::path& tmp) {
        auto out = OIIO::ImageOutput::create(path.string());
        if (!out) throw InputError(path, "", "no image writer for extension '" + ext + "'");
        OIIO::TypeDesc type = is_float ? OIIO::TypeDesc::FLOAT : (bits == 16 ? OIIO::TypeDesc::UINT16 : OIIO::TypeDesc::UINT8);
        OIIO::ImageSpec spec(image.width, image.height, image.channels, type);
        if (ext == ".exr") spec.attribute("compression", "zip");
        spec.attribute("oiio:UnassociatedAlpha", 1); // our colour is never premultiplied by alpha
        std::vector<float> encoded;
        const float* data = image.pixels.data();
        if (!is_float) {
            encoded.resize(image.pixels.size());
            for (std::size_t i = 0; i < encoded.size(); ++i) {
                float v = image.pixels[i];
                v = std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f;
                encoded[i] = integer_encoding == ColorSpace::Srgb ? linear_to_srgb(v) : v;
            }
            data = encoded.data();
        }
        if (!out->open(tmp.string(), spec) || !out->write_image(OIIO::TypeDesc::FLOAT, data) || !out->close())
            throw InputError(path, "", "cannot write image (" + out->geterror() + ")");
    });
}

// ---------------------------------------------------------------------------------------------
// The in-memory codec: OpenImageIO reads and writes through an IOProxy over a byte vector.

namespace {

// OIIO picks the format from the file name's extension; the name is never opened.
const char* codec_name(ImageCodec codec) {
    switch (codec) {
    case ImageCodec::Png: return "memory.png";
    case ImageCodec::Jpeg: return "memory.jpg";
    case ImageCodec::Exr: return "memory.exr";
    }
    return "memory.png";
}

// The format from the first bytes (the signatures of the PNG specification section 5.2,
// JPEG's SOI marker FF D8 FF, and OpenEXR's magic number 20000630 little-endian).
std::optional<ImageCodec> sniff_codec(std::span<const std::uint8_t> bytes) {
    static constexpr std::uint8_t kJpeg[3] = {0xFF, 0xD8, 0xFF};
    auto starts = [&](const std::uint8_t* sig, std::size_t n) {
        return bytes.size() >= n && std::memcmp(bytes.data(), sig, n) == 0;
    };
    if (starts(kPngMagic, sizeof kPngMagic)) return ImageCodec::Png;
    if (starts(kJpeg, sizeof kJpeg)) return ImageCodec::Jpeg;
    if (starts(kExrMagic, sizeof kExrMagic)) return ImageCodec::Exr;
    return std::nullopt;
}

// OpenImageIO 2.4's IOMemReader copies from `offset` without checking that it is not
// negative (`size + size_t(offset)` wraps around): an OpenEXR file whose chunk offset table
// holds -1 made it read before the buffer (found by fuzz_image_decode; AddressSanitizer:
// heap-buffer-overflow in IOMemReader::pread). This reader refuses positions outside the bytes.
class BoundedMemReader final : public OIIO::Filesystem::IOMemReader {
public:
    using IOMemReader::IOMemReader;
    bool seek(std::int64_t offset) override {
        if (offset < 0 || offset > static_cast<std::int64_t>(size())) return false;
        m_pos = offset;
        return true;
    }
    std::size_t read(void* buf, std::size_t n) override {
        const std::size_t got = pread(buf, n, m_pos);
        m_pos += static_cast<std::int64_t>(got);
        return got;
    }
    std::size_t pread(void* buf, std::size_t n, std::int64_t offset) override {
        if (offset < 0 || offset >= static_cast<std::int64_t>(size())) return 0;
        return IOMemReader::pread(buf, std::min<std::size_t>(n, size() - static_cast<std::size_t>(offset)), offset);
    }
};

// An ImageInput over bytes that must outlive it (the proxy keeps a pointer).
struct MemoryInput {
    BoundedMemReader proxy;
    std::unique_ptr<OIIO::ImageInput> in;

    MemoryInput(std::span<const std::uint8_t> bytes, const fs::path& file, const std::string& field,
                int max_dimension = kMaxDecodedImageDimension)
        : proxy(bytes.data(), bytes.size()) {
        const std::optional<ImageCodec> codec = sniff_codec(bytes);
        if (!codec) throw InputError(file, field, "not a PNG, JPEG or OpenEXR image");
        const ReadAt read_at = [&](std::uint64_t offset, std::uint8_t* dst, std::size_t n) -> std::size_t {
            if (offset >= bytes.size() || n == 0) return 0;
            const std::size_t count = std::min<std::size_t>(n, bytes.size() - offset);
            std::memcpy(dst, bytes.data() + offset, count);
            return count;
        };
        if (*codec == ImageCodec::Exr) check_exr_header(read_at, bytes.size(), file, field, max_dimension);
        if (*codec == ImageCodec::Png) check_png_chunks(read_at, bytes.size(), file, field);
        OIIO::ImageSpec config;
        config.attribute("oiio:UnassociatedAlpha", 1); // as open_input: colour never premultiplied by alpha
        // With a config, OIIO's readers take the proxy from it (an argument alone is dropped).
        void* proxy_ptr = &proxy;
        config.attribute("oiio:ioproxy", OIIO::TypeDesc::PTR, &proxy_ptr);
        in = OIIO::ImageInput::open(codec_name(*codec), &config, &proxy);
        if (!in) {
            const std::string why = OIIO::geterror();
            throw InputError(file, field, "cannot read image" + (why.empty() ? std::string() : " (" + why + ")"));
        }
    }
};

} // namespace

std::vector<std::uint8_t> encode_image(const Image& image, ImageCodec codec, ColorSpace integer_encoding, int bits) {
    if (image.width <= 0 || image.height <= 0 || image.channels <= 0 ||
        image.pixels.size() != static_cast<std::size_t>(image.width) * image.height * image.channels)
        throw Error("encode_image: empty or inconsistent image");
    const bool is_float = codec == ImageCodec::Exr;
    if (!is_float && bits != 8 && !(bits == 16 && codec == ImageCodec::Png))
        throw Error("encode_image: PNG is 8 or 16 bits, JPEG 8 bits");

    std::vector<std::uint8_t> bytes;
    OIIO::Filesystem::IOVecOutput proxy(bytes);
    auto out = OIIO::ImageOutput::create(codec_name(codec));
    if (!out) throw Error(std::string("encode_image: no encoder for ") + codec_name(codec) + ": " + OIIO::geterror());
    const OIIO::TypeDesc type = is_float ? OIIO::TypeDesc::FLOAT : bits == 16 ? OIIO::TypeDesc::UINT16 : OIIO::TypeDesc::UINT8;
    OIIO::ImageSpec spec(image.width, image.height, image.channels, type);
    void* proxy_ptr = &proxy;
    spec.attribute("oiio:ioproxy", OIIO::TypeDesc::PTR, &proxy_ptr);
    if (codec == ImageCodec::Exr) spec.attribute("compression", "zip");
    if (!is_float && integer_encoding == ColorSpace::Srgb) spec.attribute("oiio:ColorSpace", "sRGB");
    if (image.channels == 2 || image.channels == 4) spec.attribute("oiio:UnassociatedAlpha", 1);

    // Integer data is quantized here (round to nearest), not by OIIO, so the codes are
    // exactly lround(encode(v) * max) whatever OIIO's own conversion does.
    std::vector<std::uint8_t> q8;
    std::vector<std::uint16_t> q16;
    const void* data = image.pixels.data();
    if (!is_float) {
        const float max_code = bits == 16 ? 65535.0f : 255.0f;
        auto code = [&](float v) {
            v = std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f;
            return std::lround((integer_encoding == ColorSpace::Srgb ? linear_to_srgb(v) : v) * max_code);
        };
        if (bits == 16) {
            q16.resize(image.pixels.size());
            for (std::size_t i = 0; i < q16.size(); ++i) q16[i] = static_cast<std::uint16_t>(code(image.pixels[i]));
            data = q16.data();
        } else {
            q8.resize(image.pixels.size());
            for (std::size_t i = 0; i < q8.size(); ++i) q8[i] = static_cast<std::uint8_t>(code(image.pixels[i]));
            data = q8.data();
        }
    }
    if (!out->open(codec_name(codec), spec) || !out->write_image(type, data) || !out->close())
        throw Error(std::string("encode_image: encoding ") + codec_name(codec) + " failed: " + out->geterror());
    return bytes;
}

ImageFileInfo read_image_info(std::span<const std::uint8_t> bytes, const fs::path& file, const std::string& field) {
    MemoryInput input(bytes, file, field);
    return info_from_spec(input.in->spec());
}

Image decode_image(std::span<const std::uint8_t> bytes, ColorSpace integer_encoding, const fs::path& file,
                   const std::string& field, int max_dimension) {
    MemoryInput input(bytes, file, field, max_dimension);
    const OIIO::ImageSpec& spec = input.in->spec();
    const ImageFileInfo info = info_from_spec(spec);
    if (info.width <= 0 || info.height <= 0 || info.channels <= 0 || spec.depth > 1)
        throw InputError(file, field, "image has no pixels");
    // Refused from the header, before a pixel is decoded or allocated.
    if (info.width > max_dimension || info.height > max_dimension)
        throw InputError(file, field, dimension_refusal(info.width, info.height, max_dimension));
    Image image;
    try {
        image = Image(info.width, info.height, info.channels);
    } catch (const std::bad_alloc&) {
        throw InputError(file, field, "image too large to decode");
    }
    if (!input.in->read_image(0, 0, 0, info.channels, OIIO::TypeDesc::FLOAT, image.pixels.data())) {
        const std::string why = input.in->geterror();
        throw InputError(file, field, "cannot decode image" + (why.empty() ? std::string() : " (" + why + ")"));
    }
    check_complete(*input.in, file, field);
    input.in->close();
    if (!info.is_float && integer_encoding == ColorSpace::Srgb)
        for (float& v : image.pixels) v = srgb_to_linear(v);
    return image;
}

} // namespace specula
