#include "core/image.h"

#include "core/error.h"
#include "core/file_util.h"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>

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
    if (!fs::exists(path, ec)) throw InputError(path, field, "file not found");
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

} // namespace

ImageFileInfo read_image_info(const fs::path& path, const std::string& field) {
    auto in = open_input(path, field);
    ImageFileInfo info = info_from_spec(in->spec());
    in->close();
    return info;
}

Image read_image(const fs::path& path, ColorSpace integer_encoding, const std::string& field, ImageFileInfo* info_out) {
    auto in = open_input(path, field);
    const OIIO::ImageSpec& spec = in->spec();
    const ImageFileInfo info = info_from_spec(spec);
    if (info.width <= 0 || info.height <= 0 || info.channels <= 0)
        throw InputError(path, field, "image has no pixels");
    Image image(info.width, info.height, info.channels);
    // read_image converts integer data to float in [0, 1] without any colour transform.
    if (!in->read_image(0, 0, 0, info.channels, OIIO::TypeDesc::FLOAT, image.pixels.data())) {
        std::string why = in->geterror();
        throw InputError(path, field, "cannot decode image" + (why.empty() ? std::string() : " (" + why + ")"));
    }
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

} // namespace specula
