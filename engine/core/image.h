#pragma once
// Images in memory are linear float, interleaved, row 0 at the top (the capture
// format's pixel convention). All image files go through OpenImageIO; the sRGB
// transfer function is applied here, exactly, not by OIIO's colour management.
#include <cstdint>
#include <filesystem>
#include <span>
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

/// Reads the header only. Throws InputError(path, field, ...) when the file is missing, not a
/// regular file, or unreadable.
[[nodiscard]] ImageFileInfo read_image_info(const std::filesystem::path& path, const std::string& field = {});

/// Largest width or height decode_image and read_image accept unless told otherwise: 16384, the
/// maxImageDimension2D of the devices Specula targets (and far above any texture it writes),
/// so a file that claims 30000 x 30000 is refused from its header instead of decoded (10 GB).
inline constexpr int kMaxDecodedImageDimension = 16384;

/// Reads an image and decodes it to linear float. Integer files are decoded
/// with `integer_encoding`; float files are taken as linear. Non-finite values are kept
/// (callers flag them). Throws InputError naming the file and `field`: a path that is not a
/// regular file (a FIFO would block), a width or height above `max_dimension` (from the
/// header, before anything is decoded), and a file the decoder read only in part (truncated
/// or corrupt: OpenImageIO reports an error although it filled the pixels, e.g. a JPEG cut in
/// half decodes with its missing half grey).
[[nodiscard]] Image read_image(const std::filesystem::path& path, ColorSpace integer_encoding,
                               const std::string& field = {}, ImageFileInfo* info = nullptr,
                               int max_dimension = kMaxDecodedImageDimension);

/// Writes an image, atomically. The format follows the extension (.png, .jpg,
/// .exr, .hdr, .tif). For integer formats, values are clamped to [0, 1],
/// encoded with `integer_encoding` and rounded; `bits` is 8 or 16 (PNG, TIFF).
/// EXR is written as 32-bit float.
void write_image(const std::filesystem::path& path, const Image& image, ColorSpace integer_encoding, int bits = 8);

/// The formats of the in-memory codec: what glTF embeds (PNG, JPEG: glTF 2.0 section 3.8.3)
/// and Specula's float images (OpenEXR).
enum class ImageCodec { Png, Jpeg, Exr };

/// Encodes an image in memory (the bytes a file of that format would hold). Integer formats
/// (PNG 8 or 16 bits, JPEG 8 bits): values are clamped to [0, 1], encoded with
/// `integer_encoding` and rounded to nearest (std::lround); non-finite values become 0. EXR
/// is 32-bit float, values as they are. Throws Error when the encoder fails.
[[nodiscard]] std::vector<std::uint8_t> encode_image(const Image& image, ImageCodec codec, ColorSpace integer_encoding,
                                                     int bits = 8);

/// The header of an image held in memory (its format from its first bytes: PNG, JPEG or
/// OpenEXR). Throws InputError(file, field, ...) when the bytes are none of these or unreadable.
[[nodiscard]] ImageFileInfo read_image_info(std::span<const std::uint8_t> bytes, const std::filesystem::path& file,
                                            const std::string& field);

/// Decodes an image held in memory to linear float, as read_image does for a file (alpha is
/// kept unassociated: colour is never premultiplied). Its size is read from the header first:
/// a width or height above `max_dimension` is refused before any pixel is decoded or any
/// pixel memory allocated. Bytes the decoder read only in part (truncated or corrupt) are
/// refused. Throws InputError(file, field, ...) naming the file the bytes came from.
[[nodiscard]] Image decode_image(std::span<const std::uint8_t> bytes, ColorSpace integer_encoding,
                                 const std::filesystem::path& file, const std::string& field,
                                 int max_dimension = kMaxDecodedImageDimension);

} // namespace specula
