// libFuzzer target: image bytes (PNG, JPEG, OpenEXR, told apart by their signatures) through
// core's in-memory codec: read_image_info, then decode_image. decode_image refuses a width or
// height above its limit from the header; here the limit is 2048 (not the default 16384) so a
// legal-size image (16384^2 x 4 floats = 4.3 GB) does not exceed the run's -rss_limit_mb=2048.
// A refusal is an InputError; anything else that escapes is a finding.
#include "core/error.h"
#include "core/image.h"

#include <cstddef>
#include <cstdint>
#include <span>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::span<const std::uint8_t> bytes(data, size);
    try {
        (void)specula::read_image_info(bytes, "fuzz.img", "image");
        (void)specula::decode_image(bytes, specula::ColorSpace::Srgb, "fuzz.img", "image", 2048);
    } catch (const specula::InputError&) {
    }
    return 0;
}
