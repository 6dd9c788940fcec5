#pragma once
// Images in memory are linear float, interleaved, row 0 at the top (the capture
// format's pixel convention). All image files go through OpenImageIO; the sRGB
// transfer function is applied here, exactly, not by OIIO's colour management.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace specula {

enum class ColorSpace { Srgb, Linear };

struct Image {
    int width = 0;
    int height = 0;
    int channels = 0;
    std::vector<float> pixels; // size = width * height * channels

    Image() = default;
    Image(int w, int h, int c, float fill = 0.0f)
        : width(w), height(h), channels(c), pixels(static_cast<std::size_t>(w) * h * c, fill) {}

    [[nodiscard]] bool empty() const noexcept { return pixels.empty(); }
    [[nodiscard]] std::size_t index(int x, int y, int c = 0) const noexcept {
        return (static_cast<std::size_t>(y) * width + x) * channels + c;
    }
    [[nodiscard]] float& at(int x, int y, int c = 0) noexcept { return pixels[index(x, y, c)]; }
    [[nodiscard]] float at(int x, int y, int c = 0) const noexcept { return pixels[index(x, y, c)]; }
};

/// What the file holds, read from its header alone.
struct ImageFileInfo {
    int width = 0;
    int height = 0;
    int channels = 0;
    bool is_float = false;    // float formats are always linear and have no saturation
    int bits_per_channel = 8; // 8, 16 or 32
};

/// sRGB transfer functions (IEC 61966-2-1), for values in [0, 1].
[[nodiscard]] float srgb_to_linear(float v) noexcept;
[[nodiscard]] float linear_to_srgb(float v) noexcept;

/// Reads the header only. Throws InputError(path, field, ...) when the file is missing or unreadable.
[[nodiscard]] ImageFileInfo read_image_info(const std::filesystem::path& path, const std::string& field = {});

/// Reads an image and decodes it to linear float. Integer files are decoded
/// with `integer_encoding`; float files are taken as linear. Non-finite values are kept
/// (callers flag them). Throws InputError naming the file and `field`.
[[nodiscard]] Image read_image(const std::filesystem::path& path, ColorSpace integer_encoding,
                               const std::string& field = {}, ImageFileInfo* info = nullptr);

/// Writes an image, atomically. The format follows the extension (.png, .jpg,
/// .exr, .hdr, .tif). For integer formats, values are clamped to [0, 1],
/// encoded with `integer_encoding` and rounded; `bits` is 8 or 16 (PNG, TIFF).
/// EXR is written as 32-bit float.
void write_image(const std::filesystem::path& path, const Image& image, ColorSpace integer_encoding, int bits = 8);

} // namespace specula
