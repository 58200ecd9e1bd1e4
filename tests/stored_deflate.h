#pragma once
// gzip and zlib streams of "stored" (uncompressed) deflate blocks, so that tests can write
// compressed volume files (valid streams: zlib checks their trailers) without linking zlib, and
// make a small file declare a large one.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>

namespace fvr::test {

inline std::uint32_t crc32(const std::string& data) {
    std::uint32_t crc = 0xffffffffu;
    for (const unsigned char c : data) {
        crc ^= c;
        for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
    }
    return ~crc;
}

inline std::uint32_t adler32(const std::string& data) {
    std::uint32_t a = 1, b = 0;
    for (const unsigned char c : data) {
        a = (a + c) % 65521u;
        b = (b + a) % 65521u;
    }
    return (b << 16) | a;
}

/** `v` in `bytes` bytes, least significant first (or most significant first). */
inline void appendUnsigned(std::string& out, std::uint32_t v, int bytes, bool bigEndian) {
    for (int i = 0; i < bytes; ++i) {
        const int shift = 8 * (bigEndian ? bytes - 1 - i : i);
        out += char((v >> shift) & 0xffu);
    }
}

/** `data` as deflate blocks of type "stored": as large as the data. */
inline std::string deflateStored(const std::string& data) {
    std::string out;
    std::size_t pos = 0;
    do {
        const std::size_t n = std::min<std::size_t>(65535, data.size() - pos);
        out += char(pos + n == data.size() ? 1 : 0);
        appendUnsigned(out, std::uint32_t(n), 2, false);
        appendUnsigned(out, std::uint32_t(~n & 0xffffu), 2, false);
        out.append(data, pos, n);
        pos += n;
    } while (pos < data.size());
    return out;
}

inline std::string gzipStored(const std::string& data) {
    std::string out("\x1f\x8b\x08\x00\x00\x00\x00\x00\x00\xff", 10);
    out += deflateStored(data);
    appendUnsigned(out, crc32(data), 4, false);
    appendUnsigned(out, std::uint32_t(data.size()), 4, false);
    return out;
}

inline std::string zlibStored(const std::string& data) {
    std::string out("\x78\x01", 2);
    out += deflateStored(data);
    appendUnsigned(out, adler32(data), 4, true);
    return out;
}

} // namespace fvr::test
