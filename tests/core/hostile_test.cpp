// Core's guards against hostile input and faults (issue 21): the JSON text checks, the memory
// available, why a write failed, and image files that are not what they claim.
#include "core/error.h"
#include "core/file_util.h"
#include "core/image.h"
#include "core/json_guard.h"
#include "core/memory.h"
#include "expect_error.h"
#include "test_dirs.h"

#include <gtest/gtest.h>

#include <sys/resource.h>
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <future>
#include <span>
#include <vector>

namespace specula {
namespace {

TEST(JsonGuard, DepthIsFoundOnTheTextWithItsPath) {
    EXPECT_FALSE(json_too_deep(R"({"a": [[1]]})", 3).has_value());
    const auto deep = json_too_deep(R"({"frames": [{"light": {"position": [[0]]}}]})", 4);
    ASSERT_TRUE(deep.has_value());
    EXPECT_EQ(*deep, "frames[0].light.position");
    EXPECT_EQ(json_too_deep(std::string(300, '['), 256).value_or(""), "[0][0][0][0][0][0]");
    // Brackets inside strings do not count.
    EXPECT_FALSE(json_too_deep(R"({"s": "[[[[[[[[["})", 2).has_value());
    // An unterminated string or a trailing backslash ends the scan safely.
    EXPECT_FALSE(json_too_deep("{\"s\": \"abc\\", 2).has_value());
}

TEST(JsonGuard, DuplicateKeysAreNamedByTheirPath) {
    EXPECT_TRUE(check_json_keys(R"({"a": 1, "b": {"a": 2}, "c": [{"a": 1}, {"a": 2}]})").duplicate_field.empty());
    EXPECT_EQ(check_json_keys(R"({"w": 1, "w": 2})").duplicate_field, "w");
    EXPECT_EQ(check_json_keys(R"({"frames": [{"a": 1}, {"light": {"type": "point", "type": "spot"}}]})").duplicate_field,
              "frames[1].light.type");
    const JsonKeyReport bad = check_json_keys("{\"a\": 1,,}");
    EXPECT_TRUE(bad.duplicate_field.empty());
    EXPECT_FALSE(bad.error.empty());
    EXPECT_EQ(bad.error_byte, 9u);
}

TEST(Memory, AvailableIsPositiveAndNamed) {
    const MemoryAvailable m = available_memory();
    EXPECT_GT(m.bytes, 0u);
    EXPECT_FALSE(m.limit.empty());
}

TEST(Memory, BytesAreFormattedWithThreeDigits) {
    EXPECT_EQ(format_bytes(12), "12 bytes");
    EXPECT_EQ(format_bytes(20480), "20.5 KB");
    EXPECT_EQ(format_bytes(512000000), "512 MB");
    EXPECT_EQ(format_bytes(32715571200ull), "32.7 GB");
    EXPECT_EQ(format_bytes(std::uint64_t{1} << 28), "268 MB");
}

// A full disk used to say "cannot write file" and nothing more. The file size limit
// (RLIMIT_FSIZE, with SIGXFSZ ignored so the write fails with EFBIG instead of killing the
// process) stands in for a full disk: the message must carry the system's reason.
TEST(FileUtil, AFailedWriteSaysWhy) {
    test::TempDir dir("hostile");
    const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
    rlimit old{};
    ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old), 0);
    rlimit small = old;
    small.rlim_cur = 64;
    ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &small), 0);
    std::string message;
    try {
        write_text_file(dir / "big.txt", std::string(4096, 'x'));
    } catch (const InputError& e) {
        message = e.what();
    }
    ::setrlimit(RLIMIT_FSIZE, &old);
    std::signal(SIGXFSZ, old_handler);
    EXPECT_NE(message.find(std::strerror(EFBIG)), std::string::npos) << message;
    EXPECT_NE(message.find("big.txt"), std::string::npos) << message;
    EXPECT_FALSE(std::filesystem::exists(dir / "big.txt")); // nothing half-written is left
    // A folder that cannot be created says why too.
    write_text_file(dir / "file", "x");
    try {
        write_text_file(dir / "file" / "sub" / "a.txt", "x");
        ADD_FAILURE() << "no error";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("cannot create directory: "), std::string::npos) << e.what();
    }
}

TEST(ImageGuard, ATruncatedJpegIsRefusedNotFilledWithGrey) {
    test::TempDir dir("hostile");
    Image img(64, 48, 3);
    for (std::size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = static_cast<float>(i % 97) / 96.0f;
    write_image(dir / "whole.jpg", img, ColorSpace::Srgb);
    const std::string bytes = read_text_file(dir / "whole.jpg");
    write_text_file(dir / "half.jpg", bytes.substr(0, bytes.size() / 2));
    EXPECT_NO_THROW((void)read_image(dir / "whole.jpg", ColorSpace::Srgb, "f"));
    try {
        (void)read_image(dir / "half.jpg", ColorSpace::Srgb, "f");
        ADD_FAILURE() << "a JPEG cut in half was accepted";
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), "f");
        EXPECT_NE(e.message().find("decoded only in part"), std::string::npos) << e.what();
    }
    // The same through the in-memory codec.
    const std::vector<std::uint8_t> jpeg = encode_image(img, ImageCodec::Jpeg, ColorSpace::Srgb);
    const std::span<const std::uint8_t> half(jpeg.data(), jpeg.size() / 2);
    EXPECT_NO_THROW((void)decode_image(jpeg, ColorSpace::Srgb, "m.jpg", "images[0]"));
    EXPECT_THROW((void)decode_image(half, ColorSpace::Srgb, "m.jpg", "images[0]"), InputError);
}

TEST(ImageGuard, FilesReadOnlyWhenRegularAndWithinTheSizeLimit) {
    test::TempDir dir("hostile");
    write_image(dir / "wide.png", Image(40, 2, 3, 0.5f), ColorSpace::Srgb);
    EXPECT_NO_THROW((void)read_image(dir / "wide.png", ColorSpace::Srgb, "f"));
    try {
        (void)read_image(dir / "wide.png", ColorSpace::Srgb, "f", nullptr, 32);
        ADD_FAILURE() << "40 x 2 accepted with a limit of 32";
    } catch (const InputError& e) {
        EXPECT_NE(e.message().find("image is 40 x 2, above the largest accepted width or height (32)"), std::string::npos)
            << e.what();
    }
    // A FIFO is refused without opening it (opening would block until a writer comes).
    ASSERT_EQ(::mkfifo((dir / "pipe.png").c_str(), 0600), 0);
    auto result = std::async(std::launch::async, [&] {
        EXPECT_THROW((void)read_image_info(dir / "pipe.png", "f"), InputError);
        EXPECT_THROW((void)read_image(dir / "pipe.png", ColorSpace::Srgb, "f"), InputError);
    });
    ASSERT_EQ(result.wait_for(std::chrono::seconds(20)), std::future_status::ready) << "blocked on a FIFO";
    result.get();
}

// An OpenEXR file whose header claims more than the file holds. fuzz_image_decode found a
// 485-byte file whose string attribute `capDate` claimed 1,852,727,656 bytes ("hann" read
// as a size): OpenEXR allocated that much before reading it. The header is now walked first.
std::vector<std::uint8_t> exr_with_attribute(std::span<const std::uint8_t> exr, const std::string& name,
                                             const std::string& type, std::uint32_t claimed_size,
                                             const std::string& value = {}) {
    std::string attribute = name + '\0' + type + '\0';
    for (int i = 0; i < 4; ++i) attribute += static_cast<char>(claimed_size >> (8 * i));
    attribute += value;
    std::vector<std::uint8_t> out(exr.size() + attribute.size());
    const auto after_version = std::copy(exr.begin(), exr.begin() + 8, out.begin()); // magic and version
    std::copy(exr.begin() + 8, exr.end(), std::copy(attribute.begin(), attribute.end(), after_version));
    return out;
}

// Refused by every reader: in memory, from a file, and the file's header alone.
void expect_refused(std::span<const std::uint8_t> bytes, const std::filesystem::path& dir, const std::string& expected) {
    const InputError in_memory =
        test::expect_input_error([&] { (void)decode_image(bytes, ColorSpace::Linear, "m.exr", "images[0]"); });
    EXPECT_EQ(in_memory.field(), "images[0]");
    EXPECT_NE(in_memory.message().find(expected), std::string::npos) << in_memory.what();
    write_text_file(dir / "f.exr", std::string(bytes.begin(), bytes.end()));
    for (const InputError& e : {test::expect_input_error([&] { (void)read_image(dir / "f.exr", ColorSpace::Linear, "f"); }),
                                test::expect_input_error([&] { (void)read_image_info(dir / "f.exr", "f"); })}) {
        EXPECT_EQ(e.field(), "f");
        EXPECT_NE(e.message().find(expected), std::string::npos) << e.what();
    }
}

TEST(ImageGuard, OpenExrHeadersAreCheckedAgainstTheBytesTheFileHolds) {
    test::TempDir dir("hostile");
    const Image img(3, 3, 3, 0.25f);
    const std::vector<std::uint8_t> exr = encode_image(img, ImageCodec::Exr, ColorSpace::Linear);
    // A well-formed extra attribute is walked past: the header reads (the pixels would not,
    // their offsets in the file having moved).
    const std::string date = "2026:12:02 04:29:02";
    const std::vector<std::uint8_t> dated =
        exr_with_attribute(exr, "capDate", "string", static_cast<std::uint32_t>(date.size()), date);
    const ImageFileInfo info = read_image_info(dated, "m.exr", "images[0]");
    EXPECT_EQ(info.width, 3);
    EXPECT_EQ(info.height, 3);
    EXPECT_EQ(decode_image(exr, ColorSpace::Linear, "m.exr", "images[0]").pixels, img.pixels);

    // The fuzz finding's claim: refused from the header, naming the attribute.
    expect_refused(exr_with_attribute(exr, "capDate", "string", 1'852'727'656u), dir.path(),
                   "malformed OpenEXR header: attribute 'capDate' (string) claims 1852727656 bytes, but the file holds");
    // A negative size, a name without its terminating NUL, and a header cut short.
    expect_refused(exr_with_attribute(exr, "capDate", "string", 0xFFFFFFF0u), dir.path(), "claims -16 bytes");
    expect_refused(exr_with_attribute(exr, std::string(40, 'n'), "string", 4), dir.path(),
                   "the attribute name at byte 8 is unterminated or longer than 31 bytes");
    expect_refused(std::span(exr).first(30), dir.path(), "malformed OpenEXR header");

    // A data window beyond the limit is refused from the header, before OpenEXR reads it.
    std::vector<std::uint8_t> wide = exr;
    const std::string key = "dataWindow";
    const auto at = std::search(wide.begin(), wide.end(), key.begin(), key.end());
    ASSERT_NE(at, wide.end());
    const std::size_t xmax = static_cast<std::size_t>(at - wide.begin()) + key.size() + 1 + 6 + 4 + 8;
    const std::uint32_t huge = 99'999;
    for (int i = 0; i < 4; ++i) wide[xmax + i] = static_cast<std::uint8_t>(huge >> (8 * i));
    expect_refused(wide, dir.path(), "image is 100000 x 3, above the largest accepted width or height (16384)");

    // Sizes that disagree with what OpenEXR reads: OpenEXR reads a box2i's 16 bytes and a
    // channel list up to its empty name whatever the size says, so its reading and the walk
    // would part (the third finding: a channel list one byte longer than its size hid a data
    // window 10,682,372 pixels wide, which OpenEXR spent a minute allocating for).
    auto with_size = [&](const std::string& attribute, auto new_size) {
        std::vector<std::uint8_t> bytes = exr;
        const auto found = std::search(bytes.begin(), bytes.end(), attribute.begin(), attribute.end());
        EXPECT_NE(found, bytes.end()) << attribute;
        const std::size_t at = static_cast<std::size_t>(found - bytes.begin()) + attribute.size() + 1; // after the NUL
        std::int32_t size = 0;
        std::memcpy(&size, bytes.data() + at, 4);
        size = new_size(size);
        std::memcpy(bytes.data() + at, &size, 4);
        return bytes;
    };
    const std::string window = std::string("dataWindow") + '\0' + "box2i", channels = std::string("channels") + '\0' + "chlist";
    expect_refused(with_size(window, [](std::int32_t s) { return s - 4; }), dir.path(),
                   "attribute 'dataWindow' (box2i) declares 12 bytes; a box2i holds 16");
    expect_refused(with_size(channels, [](std::int32_t s) { return s - 1; }), dir.path(),
                   "the channel list 'channels' does not end where its declared size");
    // The fourth finding, in the walk itself: a channel list of size 0 (UBSan: memcpy to null).
    expect_refused(with_size(channels, [](std::int32_t) { return 0; }), dir.path(), "the channel list 'channels' is empty");
}

// The fifth finding of fuzz_image_decode: a 246-byte PNG whose tEXt chunk claimed 1,870,069,780
// bytes took 2 GB of memory in libpng and OpenImageIO. PNG chunks are walked first now.
TEST(ImageGuard, PngChunksMustFitInTheFile) {
    const std::vector<std::uint8_t> png = encode_image(Image(4, 3, 3, 0.5f), ImageCodec::Png, ColorSpace::Srgb);
    std::vector<std::uint8_t> claiming(png.begin(), png.begin() + 33); // the signature and IHDR
    for (const char b : std::string("\x6F\x77\x1B\x14tEXtab")) claiming.push_back(static_cast<std::uint8_t>(b));
    claiming.insert(claiming.end(), png.begin() + 33, png.end());
    const test::TempDir dir("hostile");
    EXPECT_NO_THROW((void)decode_image(png, ColorSpace::Srgb, "m.png", "images[0]"));
    for (const auto& [bytes, expected] :
         {std::pair{claiming, std::string("malformed PNG: chunk 'tEXt' at byte 33 claims 1870076692 bytes")},
          std::pair{std::vector<std::uint8_t>(png.begin(), png.end() - 20), std::string("(truncated or corrupt)")}}) {
        const InputError e = test::expect_input_error([&] { (void)decode_image(bytes, ColorSpace::Srgb, "m.png", "images[0]"); });
        EXPECT_NE(e.message().find(expected), std::string::npos) << e.what();
        write_text_file(dir / "f.png", std::string(bytes.begin(), bytes.end()));
        const InputError f = test::expect_input_error([&] { (void)read_image_info(dir / "f.png", "f"); });
        EXPECT_NE(f.message().find(expected), std::string::npos) << f.what();
    }
}

// The second finding of fuzz_image_decode: an OpenEXR file whose chunk offset table holds -1
// made OpenImageIO's in-memory reader copy from before its buffer (a heap-buffer-overflow that
// only the sanitizer build shows: tools/run-sanitized-tests.sh runs this test). Refused now.
TEST(ImageGuard, AnOpenExrChunkOffsetBeforeTheFileIsRefused) {
    const std::vector<std::uint8_t> exr = encode_image(Image(3, 3, 3, 0.5f), ImageCodec::Exr, ColorSpace::Linear);
    // The offset table follows the header: attributes (name, type, 4-byte size, value) up to an
    // empty name. A 3-row zip-compressed image is one chunk, so the table is one 8-byte offset.
    std::size_t pos = 8;
    while (exr.at(pos) != 0) {
        pos = static_cast<std::size_t>(std::find(exr.begin() + static_cast<std::ptrdiff_t>(pos), exr.end(), 0) - exr.begin()) + 1;
        pos = static_cast<std::size_t>(std::find(exr.begin() + static_cast<std::ptrdiff_t>(pos), exr.end(), 0) - exr.begin()) + 1;
        const std::uint32_t size = exr.at(pos) | exr.at(pos + 1) << 8 | exr.at(pos + 2) << 16 | static_cast<std::uint32_t>(exr.at(pos + 3)) << 24;
        pos += 4 + size;
    }
    std::vector<std::uint8_t> broken = exr;
    ASSERT_LE(pos + 1 + 8, broken.size());
    std::fill(broken.begin() + static_cast<std::ptrdiff_t>(pos + 1), broken.begin() + static_cast<std::ptrdiff_t>(pos + 9), 0xFF);
    EXPECT_NO_THROW((void)decode_image(exr, ColorSpace::Linear, "m.exr", "images[0]"));
    const InputError e = test::expect_input_error([&] { (void)decode_image(broken, ColorSpace::Linear, "m.exr", "images[0]"); });
    EXPECT_EQ(e.field(), "images[0]");
}

} // namespace
} // namespace specula
