// Private to the volume loaders (volume_io.cpp, metaimage_io.cpp, nifti_io.cpp): the message,
// text, file and byte-source helpers they share. Not installed, not part of the public API.
#pragma once

#include <fvr/core/io/volume_io.h>
#include <fvr/core/text.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <streambuf>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include <zlib.h>

namespace fvr::core::detail {

namespace fs = std::filesystem;

// Messages (volume_io_text.cpp)

/** Throws LoadError "<file>: <field>: <detail>". */
[[noreturn]] void fail(const fs::path& file, std::string_view field, const std::string& detail);
std::string quoteValue(std::string_view s);

template <class T>
std::string str(const T& v) {
    std::ostringstream os;
    os << v;
    return os.str();
}

std::string dimsText(const std::vector<std::int64_t>& d);
const char* typeName(ElementType t);

// Text helpers (volume_io_text.cpp)

std::vector<std::string_view> splitWords(std::string_view s);

/** Exactly `count` whitespace-separated numbers (parseNumber each), or nullopt; floating-point
 *  values must also be finite (spacing, origin and direction cosines). */
template <class T>
std::optional<std::vector<T>> parseNumbers(std::string_view s, std::size_t count) {
    const auto words = splitWords(s);
    if (words.size() != count) return std::nullopt;
    std::vector<T> v(count);
    for (std::size_t i = 0; i < count; ++i) {
        const std::optional<T> x = parseNumber<T>(words[i]);
        if (!x) return std::nullopt;
        if constexpr (std::is_floating_point_v<T>)
            if (!std::isfinite(*x)) return std::nullopt;
        v[i] = *x;
    }
    return v;
}

std::optional<bool> parseBool(std::string_view s);
bool endsWith(std::string_view s, std::string_view suffix);
std::string volumeName(const fs::path& path);

// Files (volume_io_bytes.cpp)

std::uint64_t regularFileSize(const fs::path& file, const fs::path& reportAs,
                              std::string_view field);
bool readHeaderLine(std::streambuf& sb, std::string& line, std::size_t maxLen, bool& tooLong);

// ------------------------------------------------------------------------------------------------
// Byte sources: plain file region, gzip/plain through zlib's gz* functions, zlib/gzip inflate of
// a file region (MetaImage CompressedData).

class ByteSource {
public:
    virtual ~ByteSource() = default;
    /** Reads up to n bytes; fewer only at the end of the data or on an error. */
    virtual std::size_t read(unsigned char* dst, std::size_t n) = 0;
    /** A description of the read error, empty when the data simply ended. */
    virtual std::string error() const { return {}; }
};

class FileSource final : public ByteSource {
public:
    FileSource(const fs::path& file, std::uint64_t offset) : m_in(file, std::ios::binary) {
        if (m_in) m_in.seekg(std::streamoff(offset), std::ios::beg);
        m_ok = bool(m_in);
    }
    bool ok() const { return m_ok; }
    std::size_t read(unsigned char* dst, std::size_t n) override {
        if (!m_ok) return 0;
        m_in.read(reinterpret_cast<char*>(dst), std::streamsize(n));
        return std::size_t(m_in.gcount());
    }
    std::string error() const override { return m_ok ? std::string() : "cannot open or seek"; }

private:
    std::ifstream m_in;
    bool m_ok = false;
};

class GzSource final : public ByteSource {
public:
    explicit GzSource(const fs::path& file)
        : m_gz(gzopen(file.c_str(), "rb")), m_path(file.string()) {
        if (m_gz) gzbuffer(m_gz, 1 << 18);
    }
    ~GzSource() override {
        if (m_gz) gzclose(m_gz);
    }
    GzSource(const GzSource&) = delete;
    GzSource& operator=(const GzSource&) = delete;
    bool ok() const { return m_gz != nullptr; }
    std::size_t read(unsigned char* dst, std::size_t n) override {
        std::size_t total = 0;
        while (m_gz && total < n && !m_failed) {
            const unsigned want = unsigned(std::min<std::size_t>(n - total, 1u << 30));
            const int got = gzread(m_gz, dst + total, want);
            if (got <= 0) {
                int err = Z_OK;
                const char* msg = gzerror(m_gz, &err);
                if (got < 0 || (err != Z_OK && err != Z_STREAM_END)) {
                    m_failed = true;
                    m_error = msg ? msg : "read error";
                    // zlib prefixes the message with the path, which our messages already name.
                    const std::string prefix = m_path + ": ";
                    if (m_error.compare(0, prefix.size(), prefix) == 0)
                        m_error.erase(0, prefix.size());
                }
                break;
            }
            total += std::size_t(got);
        }
        return total;
    }
    std::string error() const override { return m_error; }

private:
    gzFile m_gz = nullptr;
    std::string m_path;
    bool m_failed = false;
    std::string m_error;
};

class InflateSource final : public ByteSource {
public:
    InflateSource(const fs::path& file, std::uint64_t offset, std::uint64_t compressedBytes)
        : m_in(file, std::ios::binary), m_remaining(compressedBytes), m_buf(1 << 18) {
        if (m_in) m_in.seekg(std::streamoff(offset), std::ios::beg);
        // 15 + 32: zlib or gzip header, detected automatically (as MetaIO writes zlib streams).
        m_ok = bool(m_in) && inflateInit2(&m_zs, 15 + 32) == Z_OK;
        if (!m_ok) m_error = "cannot open or seek";
    }
    ~InflateSource() override {
        if (m_ok) inflateEnd(&m_zs);
    }
    InflateSource(const InflateSource&) = delete;
    InflateSource& operator=(const InflateSource&) = delete;
    std::size_t read(unsigned char* dst, std::size_t n) override {
        std::size_t total = 0;
        while (m_ok && !m_done && total < n) {
            if (m_zs.avail_in == 0) {
                if (m_remaining == 0) {
                    m_error = "compressed data ended early";
                    m_done = true;
                    break;
                }
                const std::size_t want =
                    std::size_t(std::min<std::uint64_t>(m_buf.size(), m_remaining));
                m_in.read(reinterpret_cast<char*>(m_buf.data()), std::streamsize(want));
                const std::size_t got = std::size_t(m_in.gcount());
                if (got == 0) {
                    m_error = "compressed data ended early";
                    m_done = true;
                    break;
                }
                m_remaining -= got;
                m_zs.next_in = m_buf.data();
                m_zs.avail_in = unsigned(got);
            }
            const unsigned chunk = unsigned(std::min<std::size_t>(n - total, 1u << 30));
            m_zs.next_out = dst + total;
            m_zs.avail_out = chunk;
            const int rc = inflate(&m_zs, Z_NO_FLUSH);
            total += chunk - m_zs.avail_out;
            if (rc == Z_STREAM_END) {
                m_done = true;
            } else if (rc != Z_OK && rc != Z_BUF_ERROR) {
                m_error = std::string("corrupt compressed data (") +
                          (m_zs.msg ? m_zs.msg : "zlib error") + ")";
                m_done = true;
            }
        }
        return total;
    }
    std::string error() const override { return m_error; }

private:
    std::ifstream m_in;
    std::uint64_t m_remaining;
    std::vector<unsigned char> m_buf;
    z_stream m_zs{};
    bool m_ok = false;
    bool m_done = false;
    std::string m_error;
};

// ------------------------------------------------------------------------------------------------
// Element conversion (volume_io_bytes.cpp)

struct Scaling {
    bool apply = false;
    double slope = 1.0;
    double inter = 0.0;
};

template <class T>
inline T byteSwapped(T v) {
    if constexpr (sizeof(T) == 1) {
        return v;
    } else {
        using U =
            std::conditional_t<sizeof(T) == 2, std::uint16_t,
                               std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint64_t>>;
        U u;
        std::memcpy(&u, &v, sizeof u);
        if constexpr (sizeof(T) == 2)
            u = __builtin_bswap16(u);
        else if constexpr (sizeof(T) == 4)
            u = __builtin_bswap32(u);
        else
            u = __builtin_bswap64(u);
        std::memcpy(&v, &u, sizeof v);
        return v;
    }
}

std::uint64_t readElements(ByteSource& src, ElementType t, bool bigEndian, const Scaling& sc,
                           std::size_t count, float* dst);
std::vector<float> allocateVoxels(const Dims3& dims, const fs::path& file);
std::uint64_t maxInflatedBytes(std::uint64_t compressedBytes);
Volume emptyVolume(const Dims3& dims, const Vec3& spacing, const Vec3& origin,
                   const glm::dmat3& direction, std::string name, const fs::path& file);

} // namespace fvr::core::detail
