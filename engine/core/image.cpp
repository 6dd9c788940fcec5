#include "core/image.h"

#include "core/error.h"
#include "core/file_util.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <cstring>
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

std::unique_ptr<OIIO::ImageInput> open_input(const fs::path& path, const std::string& field) {
    std::error_code ec;
    const fs::file_status status = fs::status(path, ec);
    if (!fs::exists(status)) throw InputError(path, field, "file not found");
    // Opening a FIFO or a device could block or never end.
    if (!fs::is_regular_file(status)) throw InputError(path, field, "not a regular file");
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

std::string dimension_refusal(int width, int height, int max_dimension) {
    return "image is " + std::to_string(width) + " x " + std::to_string(height) +
           ", above the largest accepted width or height (" + std::to_string(max_dimension) + ")";
}

} // namespace

ImageFileInfo read_image_info(const fs::path& path, const std::string& field) {
    auto in = open_input(path, field);
    ImageFileInfo info = info_from_spec(in->spec());
    in->close();
    return info;
}

Image read_image(const fs::path& path, ColorSpace integer_encoding, const std::string& field, ImageFileInfo* info_out,
                 int max_dimension) {
    auto in = open_input(path, field);
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
    static constexpr std::uint8_t kPng[8] = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
    static constexpr std::uint8_t kJpeg[3] = {0xFF, 0xD8, 0xFF};
    static constexpr std::uint8_t kExr[4] = {0x76, 0x2F, 0x31, 0x01};
    auto starts = [&](const std::uint8_t* sig, std::size_t n) {
        return bytes.size() >= n && std::memcmp(bytes.data(), sig, n) == 0;
    };
    if (starts(kPng, sizeof kPng)) return ImageCodec::Png;
    if (starts(kJpeg, sizeof kJpeg)) return ImageCodec::Jpeg;
    if (starts(kExr, sizeof kExr)) return ImageCodec::Exr;
    return std::nullopt;
}

// An ImageInput over bytes that must outlive it (the proxy keeps a pointer).
struct MemoryInput {
    OIIO::Filesystem::IOMemReader proxy;
    std::unique_ptr<OIIO::ImageInput> in;

    MemoryInput(std::span<const std::uint8_t> bytes, const fs::path& file, const std::string& field)
        : proxy(bytes.data(), bytes.size()) {
        const std::optional<ImageCodec> codec = sniff_codec(bytes);
        if (!codec) throw InputError(file, field, "not a PNG, JPEG or OpenEXR image");
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
    MemoryInput input(bytes, file, field);
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
