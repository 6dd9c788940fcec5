#pragma once
// Hand-built PNG chunks for tests that forge PNG headers (sizes a real encoder would not write).
#include <cstdint>
#include <string>

namespace specula::test {

// CRC-32 of PNG chunks (PNG specification, annex D: polynomial 0xEDB88320, reflected).
inline std::uint32_t png_crc(const std::string& bytes) {
    std::uint32_t c = 0xFFFFFFFFu;
    for (const char ch : bytes) {
        c ^= static_cast<unsigned char>(ch);
        for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
    }
    return c ^ 0xFFFFFFFFu;
}

inline std::string be32(std::uint32_t v) {
    return {static_cast<char>(v >> 24), static_cast<char>(v >> 16), static_cast<char>(v >> 8), static_cast<char>(v)};
}

// One chunk: length, type, data, CRC of type and data.
inline std::string png_chunk(const std::string& type, const std::string& data) {
    return be32(static_cast<std::uint32_t>(data.size())) + type + data + be32(png_crc(type + data));
}

// A PNG whose header (IHDR, PNG specification 11.2.2) claims w x h 8-bit RGB pixels, with a
// few bytes of data: a reader that trusts the header allocates w x h x 3 values.
inline std::string png_claiming(std::uint32_t w, std::uint32_t h) {
    const std::string ihdr = be32(w) + be32(h) + std::string("\x08\x02\x00\x00\x00", 5);
    return std::string("\x89PNG\r\n\x1a\n", 8) + png_chunk("IHDR", ihdr) +
           png_chunk("IDAT", std::string("\x78\x9c\x63\x00\x00\x00\x01\x00\x01", 9)) + png_chunk("IEND", "");
}

} // namespace specula::test
