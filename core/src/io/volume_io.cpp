// Volume loaders: MetaImage, NIfTI-1 and headerless raw.
//
// Every loader works in the same order: parse and validate the header, work out exactly which
// bytes of which files hold the voxels and check those files are long enough, and only then
// allocate the volume and read it in bulk (1 MiB chunks converted to float). Nothing about the
// input is trusted before it has been checked, so garbage files end in a LoadError, not a crash
// or a huge allocation.
#include <fvr/core/io/volume_io.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <new>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <system_error>
#include <type_traits>
#include <vector>

#include <zlib.h>

#include <fvr/core/errors.h>
#include <fvr/core/memory_budget.h>

namespace fvr::core {

namespace fs = std::filesystem;

namespace {

// ------------------------------------------------------------------------------------------------
// Messages

[[noreturn]] void fail(const fs::path& file, std::string_view field, const std::string& detail) {
    std::string msg = file.string();
    msg += ": ";
    msg += field;
    msg += ": ";
    msg += detail;
    throw LoadError(msg);
}

/** A header value quoted for a message: at most 80 characters, control bytes shown as '?'. */
std::string quoteValue(std::string_view s) {
    std::string out = "'";
    const std::size_t n = std::min<std::size_t>(s.size(), 80);
    for (std::size_t i = 0; i < n; ++i) {
        const auto c = static_cast<unsigned char>(s[i]);
        out += (c >= 0x20 && c < 0x7f) ? char(c) : '?';
    }
    if (s.size() > n) out += "...";
    out += "'";
    return out;
}

template <class T>
std::string str(const T& v) {
    std::ostringstream os;
    os << v;
    return os.str();
}

std::string dimsText(const std::vector<std::int64_t>& d) {
    std::string s;
    for (std::size_t i = 0; i < d.size(); ++i) s += (i ? " x " : "") + std::to_string(d[i]);
    return s;
}

const char* typeName(ElementType t) {
    switch (t) {
    case ElementType::Int8: return "int8";
    case ElementType::UInt8: return "uint8";
    case ElementType::Int16: return "int16";
    case ElementType::UInt16: return "uint16";
    case ElementType::Int32: return "int32";
    case ElementType::UInt32: return "uint32";
    case ElementType::Int64: return "int64";
    case ElementType::UInt64: return "uint64";
    case ElementType::Float32: return "float32";
    case ElementType::Float64: return "float64";
    }
    return "unknown";
}

// ------------------------------------------------------------------------------------------------
// Text helpers (locale independent: std::from_chars, never strtod/atof)

std::string_view trim(std::string_view s) {
    const auto ws = [](char c) {
        return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v';
    };
    while (!s.empty() && ws(s.front())) s.remove_prefix(1);
    while (!s.empty() && ws(s.back())) s.remove_suffix(1);
    return s;
}

std::string lower(std::string_view s) {
    std::string out(s);
    for (char& c : out) c = char(std::tolower(static_cast<unsigned char>(c)));
    return out;
}

std::vector<std::string_view> splitWords(std::string_view s) {
    std::vector<std::string_view> words;
    std::size_t i = 0;
    while (i < s.size()) {
        while (i < s.size() && std::isspace(static_cast<unsigned char>(s[i]))) ++i;
        std::size_t j = i;
        while (j < s.size() && !std::isspace(static_cast<unsigned char>(s[j]))) ++j;
        if (j > i) words.push_back(s.substr(i, j - i));
        i = j;
    }
    return words;
}

bool parseInt(std::string_view s, std::int64_t& out) {
    s = trim(s);
    if (!s.empty() && s.front() == '+') s.remove_prefix(1);
    if (s.empty()) return false;
    const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
    return ec == std::errc() && ptr == s.data() + s.size();
}

bool parseDouble(std::string_view s, double& out) {
    s = trim(s);
    if (!s.empty() && s.front() == '+') s.remove_prefix(1);
    if (s.empty()) return false;
    const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
    return ec == std::errc() && ptr == s.data() + s.size();
}

std::optional<std::vector<std::int64_t>> parseInts(std::string_view s, std::size_t count) {
    const auto words = splitWords(s);
    if (words.size() != count) return std::nullopt;
    std::vector<std::int64_t> v(count);
    for (std::size_t i = 0; i < count; ++i)
        if (!parseInt(words[i], v[i])) return std::nullopt;
    return v;
}

std::optional<std::vector<double>> parseDoubles(std::string_view s, std::size_t count) {
    const auto words = splitWords(s);
    if (words.size() != count) return std::nullopt;
    std::vector<double> v(count);
    for (std::size_t i = 0; i < count; ++i)
        if (!parseDouble(words[i], v[i]) || !std::isfinite(v[i])) return std::nullopt;
    return v;
}

std::optional<bool> parseBool(std::string_view s) {
    const std::string l = lower(trim(s));
    if (l == "true" || l == "1" || l == "yes") return true;
    if (l == "false" || l == "0" || l == "no") return false;
    return std::nullopt;
}

bool endsWith(std::string_view s, std::string_view suffix) {
    return s.size() >= suffix.size() && s.substr(s.size() - suffix.size()) == suffix;
}

/** The volume name: the file name without .gz and the format extension. */
std::string volumeName(const fs::path& path) {
    std::string name = path.filename().string();
    const std::string l = lower(name);
    for (const char* ext : {".nii.gz", ".nii", ".mhd", ".mha"}) {
        if (endsWith(l, ext)) return name.substr(0, name.size() - std::strlen(ext));
    }
    return path.stem().string();
}

// ------------------------------------------------------------------------------------------------
// Files

/** Size of a regular file; errors are reported against `reportAs` (the header) and `field`. */
std::uint64_t regularFileSize(const fs::path& file, const fs::path& reportAs,
                              std::string_view field) {
    std::error_code ec;
    const auto st = fs::status(file, ec);
    if (ec || !fs::exists(st)) {
        if (file == reportAs) fail(reportAs, field, "cannot open file: no such file");
        fail(reportAs, field, "cannot open data file '" + file.string() + "': no such file");
    }
    if (!fs::is_regular_file(st))
        fail(reportAs, field, "'" + file.string() + "' is not a regular file");
    const auto size = fs::file_size(file, ec);
    if (ec)
        fail(reportAs, field, "cannot read the size of '" + file.string() + "': " + ec.message());
    return size;
}

/** Reads one header line (without the newline) of at most maxLen bytes from a binary stream.
 *  Returns false at the end of the stream when nothing was read. Sets tooLong and stops early
 *  when the line exceeds maxLen, so that a binary file read as a header costs nothing. */
bool readHeaderLine(std::streambuf& sb, std::string& line, std::size_t maxLen, bool& tooLong) {
    line.clear();
    tooLong = false;
    bool any = false;
    for (;;) {
        const int c = sb.sbumpc();
        if (c == std::char_traits<char>::eof()) return any;
        any = true;
        if (c == '\n') return true;
        if (line.size() >= maxLen) {
            tooLong = true;
            return true;
        }
        line.push_back(char(c));
    }
}

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
// Element conversion

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

/** double -> float with values beyond the float range mapped to +-infinity (a plain cast of
 *  such a value is undefined behaviour). NaN stays NaN. */
inline float toFloat(double v) {
    constexpr double kMax = double(std::numeric_limits<float>::max());
    if (v > kMax) return std::numeric_limits<float>::infinity();
    if (v < -kMax) return -std::numeric_limits<float>::infinity();
    return static_cast<float>(v);
}

template <class T, bool Swap, bool Scale>
void convertLoop(const unsigned char* src, std::size_t n, const Scaling& sc, float* dst) {
    for (std::size_t i = 0; i < n; ++i) {
        T v;
        std::memcpy(&v, src + i * sizeof(T), sizeof(T));
        if constexpr (Swap) v = byteSwapped(v);
        if constexpr (Scale)
            dst[i] = toFloat(static_cast<double>(v) * sc.slope + sc.inter);
        else if constexpr (std::is_same_v<T, double>)
            dst[i] = toFloat(v);
        else
            dst[i] = static_cast<float>(v);
    }
}

template <class T>
void convertTyped(const unsigned char* src, std::size_t n, bool swap, const Scaling& sc,
                  float* dst) {
    if (swap) {
        if (sc.apply)
            convertLoop<T, true, true>(src, n, sc, dst);
        else
            convertLoop<T, true, false>(src, n, sc, dst);
    } else {
        if (sc.apply)
            convertLoop<T, false, true>(src, n, sc, dst);
        else
            convertLoop<T, false, false>(src, n, sc, dst);
    }
}

void convertElements(const unsigned char* src, std::size_t n, ElementType t, bool swap,
                     const Scaling& sc, float* dst) {
    switch (t) {
    case ElementType::Int8: return convertTyped<std::int8_t>(src, n, swap, sc, dst);
    case ElementType::UInt8: return convertTyped<std::uint8_t>(src, n, swap, sc, dst);
    case ElementType::Int16: return convertTyped<std::int16_t>(src, n, swap, sc, dst);
    case ElementType::UInt16: return convertTyped<std::uint16_t>(src, n, swap, sc, dst);
    case ElementType::Int32: return convertTyped<std::int32_t>(src, n, swap, sc, dst);
    case ElementType::UInt32: return convertTyped<std::uint32_t>(src, n, swap, sc, dst);
    case ElementType::Int64: return convertTyped<std::int64_t>(src, n, swap, sc, dst);
    case ElementType::UInt64: return convertTyped<std::uint64_t>(src, n, swap, sc, dst);
    case ElementType::Float32: return convertTyped<float>(src, n, swap, sc, dst);
    case ElementType::Float64: return convertTyped<double>(src, n, swap, sc, dst);
    }
}

/** Reads `count` elements from `src` into dst as float. Returns the number of bytes read, which
 *  is count * elementSize(t) unless the data ended early. */
std::uint64_t readElements(ByteSource& src, ElementType t, bool bigEndian, const Scaling& sc,
                           std::size_t count, float* dst) {
    const std::size_t es = elementSize(t);
    const bool swap = bigEndian != (std::endian::native == std::endian::big);
    if (t == ElementType::Float32 && !swap && !sc.apply) {
        // Already in the output format: read straight into the volume.
        return src.read(reinterpret_cast<unsigned char*>(dst), count * sizeof(float));
    }
    constexpr std::size_t kChunkBytes = std::size_t(1) << 20; // a multiple of every element size
    std::vector<unsigned char> buf(std::min(kChunkBytes, count * es));
    std::uint64_t bytes = 0;
    std::size_t done = 0;
    while (done < count) {
        const std::size_t want = std::min(count - done, kChunkBytes / es);
        const std::size_t got = src.read(buf.data(), want * es);
        bytes += got;
        convertElements(buf.data(), got / es, t, swap, sc, dst + done);
        done += got / es;
        if (got < want * es) break;
    }
    return bytes;
}

/** Room for the float voxels of `dims`, after checking that this process may take it (a header's
 *  dimensions are not trusted with the machine's memory). */
std::vector<float> allocateVoxels(const Dims3& dims, const fs::path& file) {
    const std::int64_t count = dims[0] * dims[1] * dims[2];
    checkMemoryFor(std::uint64_t(count) * sizeof(float), file.string(),
                   "voxels: the header declares " + std::to_string(dims[0]) + " x " +
                       std::to_string(dims[1]) + " x " + std::to_string(dims[2]) +
                       " voxels, which as float");
    try {
        return std::vector<float>(std::size_t(count));
    } catch (const std::bad_alloc&) {
        fail(file, "voxels",
             "cannot allocate " + std::to_string(count) + " floats (" + std::to_string(count * 4) +
                 " bytes)");
    }
}

/** Upper bound on what `compressedBytes` of deflate data can expand to (deflate's maximum
 *  ratio is about 1032:1), so that a tiny compressed file cannot make us allocate gigabytes. */
std::uint64_t maxInflatedBytes(std::uint64_t compressedBytes) {
    return compressedBytes * 1040 + 65536;
}

// ------------------------------------------------------------------------------------------------
// MetaImage

constexpr std::size_t kMaxHeaderLine = 64 * 1024;
constexpr std::uint64_t kMaxHeaderBytes = 1 << 20;

struct DataPart {
    fs::path file;
    std::uint64_t offset = 0; ///< where the (compressed) data starts
    std::uint64_t bytes = 0; ///< uncompressed data bytes
    bool compressed = false;
    std::uint64_t compressedBytes = 0; ///< bytes of compressed data available from offset
};

/** Formats a MetaImage slice-file pattern holding one printf integer conversion (%d, %i, %u,
 *  optionally with a zero flag and width, e.g. %03d). The pattern is interpreted here instead of
 *  being handed to printf, so that a malicious header cannot use other conversions. */
std::optional<std::string> formatPattern(std::string_view pattern, std::int64_t value) {
    std::string out;
    bool used = false;
    for (std::size_t i = 0; i < pattern.size(); ++i) {
        if (pattern[i] != '%') {
            out += pattern[i];
            continue;
        }
        if (i + 1 < pattern.size() && pattern[i + 1] == '%') {
            out += '%';
            ++i;
            continue;
        }
        if (used) return std::nullopt;
        used = true;
        std::size_t j = i + 1;
        bool zero = false;
        if (j < pattern.size() && pattern[j] == '0') {
            zero = true;
            ++j;
        }
        int width = 0;
        while (j < pattern.size() && std::isdigit(static_cast<unsigned char>(pattern[j]))) {
            width = width * 10 + (pattern[j] - '0');
            if (width > 32) return std::nullopt;
            ++j;
        }
        if (j >= pattern.size() || (pattern[j] != 'd' && pattern[j] != 'i' && pattern[j] != 'u'))
            return std::nullopt;
        std::string digits = std::to_string(value < 0 ? -value : value);
        std::string sign = value < 0 ? "-" : "";
        std::string number;
        const std::size_t len = sign.size() + digits.size();
        if (std::size_t(width) > len) {
            if (zero)
                number = sign + std::string(width - len, '0') + digits;
            else
                number = std::string(width - len, ' ') + sign + digits;
        } else {
            number = sign + digits;
        }
        out += number;
        i = j;
    }
    if (!used) return std::nullopt;
    return out;
}

} // namespace

// ------------------------------------------------------------------------------------------------
// Public API

std::size_t elementSize(ElementType t) {
    switch (t) {
    case ElementType::Int8:
    case ElementType::UInt8: return 1;
    case ElementType::Int16:
    case ElementType::UInt16: return 2;
    case ElementType::Int32:
    case ElementType::UInt32:
    case ElementType::Float32: return 4;
    case ElementType::Int64:
    case ElementType::UInt64:
    case ElementType::Float64: return 8;
    }
    throw SettingsError("element type: expected one of int8..float64, found enum value " +
                        std::to_string(int(t)));
}

ElementType parseElementType(const std::string& name) {
    struct Entry {
        const char* name;
        ElementType type;
    };
    // MetaIO sizes: MET_LONG/MET_ULONG are 4 bytes, MET_LONG_LONG/MET_ULONG_LONG 8 bytes.
    static constexpr Entry kNames[] = {
        {"int8", ElementType::Int8},           {"uint8", ElementType::UInt8},
        {"int16", ElementType::Int16},         {"uint16", ElementType::UInt16},
        {"int32", ElementType::Int32},         {"uint32", ElementType::UInt32},
        {"int64", ElementType::Int64},         {"uint64", ElementType::UInt64},
        {"float32", ElementType::Float32},     {"float64", ElementType::Float64},
        {"float", ElementType::Float32},       {"double", ElementType::Float64},
        {"met_char", ElementType::Int8},       {"met_uchar", ElementType::UInt8},
        {"met_short", ElementType::Int16},     {"met_ushort", ElementType::UInt16},
        {"met_int", ElementType::Int32},       {"met_uint", ElementType::UInt32},
        {"met_long", ElementType::Int32},      {"met_ulong", ElementType::UInt32},
        {"met_long_long", ElementType::Int64}, {"met_ulong_long", ElementType::UInt64},
        {"met_float", ElementType::Float32},   {"met_double", ElementType::Float64},
    };
    const std::string l = lower(trim(name));
    for (const Entry& e : kNames)
        if (l == e.name) return e.type;
    throw SettingsError(
        "element type: expected int8, uint8, int16, uint16, int32, uint32, int64, uint64, "
        "float32, float64 or MET_CHAR, MET_UCHAR, MET_SHORT, MET_USHORT, MET_INT, MET_UINT, "
        "MET_LONG, MET_ULONG, MET_LONG_LONG, MET_ULONG_LONG, MET_FLOAT, MET_DOUBLE, found " +
        quoteValue(name));
}

/** A volume with its geometry and room for its voxels (allocated after every check passed). */
static Volume emptyVolume(const Dims3& dims, const Vec3& spacing, const Vec3& origin,
                          const std::array<Vec3, 3>& direction, std::string name,
                          const fs::path& file) {
    Volume vol;
    vol.dims = dims;
    vol.spacing = spacing;
    vol.origin = origin;
    vol.direction = direction;
    vol.name = std::move(name);
    vol.voxels = allocateVoxels(dims, file);
    return vol;
}

bool isVolumeFileName(const fs::path& path) {
    const std::string l = lower(path.filename().string());
    return endsWith(l, ".mhd") || endsWith(l, ".mha") || endsWith(l, ".nii") ||
           endsWith(l, ".nii.gz");
}

Volume loadVolume(const fs::path& path) {
    const std::string l = lower(path.filename().string());
    if (endsWith(l, ".mhd") || endsWith(l, ".mha")) return loadMetaImage(path);
    if (endsWith(l, ".nii") || endsWith(l, ".nii.gz")) return loadNifti(path);
    fail(path, "format",
         "unknown volume format: expected .mhd, .mha, .nii or .nii.gz, found " +
             quoteValue(path.extension().string()));
}

namespace {

/** The MetaImage header: "Key = Value" lines up to and including ElementDataFile. */
struct MetaHeader {
    std::map<std::string, std::string, std::less<>> fields;
    std::uint64_t fileSize = 0; ///< size of the header file
    std::uint64_t localOffset = 0; ///< the first byte after the ElementDataFile line

    const std::string* get(std::string_view key) const {
        const auto it = fields.find(key);
        return it == fields.end() ? nullptr : &it->second;
    }
    /** The first of `keys` present, with its value; {nullptr, nullptr} when none is. */
    std::pair<const char*, const std::string*> firstOf(
        std::initializer_list<const char*> keys) const {
        for (const char* k : keys)
            if (const std::string* v = get(k)) return {k, v};
        return {nullptr, nullptr};
    }
};

/** Reads the header lines (keys case-sensitive); leaves `sb` just after ElementDataFile. */
MetaHeader readMetaHeader(const fs::path& path, std::streambuf& sb, std::uint64_t fileSize) {
    MetaHeader header;
    header.fileSize = fileSize;
    std::string line;
    bool tooLong = false;
    bool sawDataFile = false;
    std::uint64_t consumed = 0;
    while (readHeaderLine(sb, line, kMaxHeaderLine, tooLong)) {
        consumed += line.size() + 1;
        if (tooLong || consumed > kMaxHeaderBytes)
            fail(path, "header",
                 "expected 'Key = Value' text lines ending with ElementDataFile within the first "
                 "1 MiB, found a line or header longer than that (not a MetaImage file?)");
        const std::string_view t = trim(line);
        if (t.empty()) continue;
        const std::size_t eq = t.find('=');
        if ((eq == std::string_view::npos || trim(t.substr(0, eq)).empty()) &&
            header.fields.empty())
            throw LoadError(path.string() +
                            ": not a MetaImage file (its header is 'Key = Value' lines such as "
                            "'NDims = 3'; the first line is " +
                            quoteValue(t) + ")");
        if (eq == std::string_view::npos || trim(t.substr(0, eq)).empty())
            fail(path, "header", "expected 'Key = Value' lines, found " + quoteValue(t));
        const std::string key(trim(t.substr(0, eq)));
        header.fields[key] = std::string(trim(t.substr(eq + 1)));
        if (key == "ElementDataFile") {
            sawDataFile = true;
            break;
        }
    }
    if (!sawDataFile)
        fail(path, "ElementDataFile", "expected the key (the last header line), found none");
    const auto localPos = sb.pubseekoff(0, std::ios::cur, std::ios::in);
    header.localOffset = localPos < 0 ? 0 : std::uint64_t(std::streamoff(localPos));
    return header;
}

/** The grid of a MetaImage: NDims, DimSize, spacing, origin and axis directions. */
struct MetaGeometry {
    std::size_t ndims = 0;
    std::vector<std::int64_t> dimSize; ///< the NDims sizes as written
    Dims3 dims{1, 1, 1};
    std::int64_t voxelCount = 0;
    Vec3 spacing{1.0, 1.0, 1.0};
    Vec3 origin{0.0, 0.0, 0.0};
    std::array<Vec3, 3> direction = Volume{}.direction;
    bool directionStated = false; ///< TransformMatrix, Rotation or Orientation present
};

/** NDims and DimSize, checked against the per-axis and total voxel limits. */
void readMetaDims(const fs::path& path, const MetaHeader& header, MetaGeometry& g) {
    const std::string* ndimsText = header.get("NDims");
    if (!ndimsText) fail(path, "NDims", "expected 1, 2 or 3, found no NDims key");
    std::int64_t nd = 0;
    if (!parseInt(*ndimsText, nd) || nd < 1 || nd > 3)
        fail(path, "NDims", "expected 1, 2 or 3, found " + quoteValue(*ndimsText));
    g.ndims = std::size_t(nd);

    const std::string* dimText = header.get("DimSize");
    if (!dimText)
        fail(path, "DimSize",
             "expected " + std::to_string(g.ndims) + " sizes, found no DimSize key");
    const auto dimSize = parseInts(*dimText, g.ndims);
    if (!dimSize)
        fail(path, "DimSize",
             "expected " + std::to_string(g.ndims) + " integers (NDims = " +
                 std::to_string(g.ndims) + "), found " + quoteValue(*dimText));
    for (const std::int64_t d : *dimSize) {
        if (d < 1 || d > kMaxDimPerAxis)
            fail(path, "DimSize",
                 "expected 1.." + std::to_string(kMaxDimPerAxis) + " voxels per axis, found " +
                     quoteValue(*dimText));
    }
    g.dimSize = *dimSize;
    for (std::size_t a = 0; a < g.ndims; ++a) g.dims[a] = g.dimSize[a];
    g.voxelCount = g.dims[0] * g.dims[1] * g.dims[2];
    if (g.voxelCount > kMaxVoxels)
        fail(path, "DimSize",
             "expected at most " + std::to_string(kMaxVoxels) + " voxels in total, found " +
                 dimsText(g.dimSize) + " = " + std::to_string(g.voxelCount));
}

/** ElementSpacing (fallback ElementSize) and Offset / Origin / Position. */
void readMetaSpacingOrigin(const fs::path& path, const MetaHeader& header, MetaGeometry& g) {
    const std::size_t ndims = g.ndims;
    if (const auto [key, text] = header.firstOf({"ElementSpacing", "ElementSize"}); text) {
        const auto sp = parseDoubles(*text, ndims);
        bool ok = bool(sp);
        if (ok)
            for (const double s : *sp) ok = ok && s > 0.0;
        if (!ok)
            fail(path, key,
                 "expected " + std::to_string(ndims) + " finite numbers > 0 (mm), found " +
                     quoteValue(*text));
        for (std::size_t a = 0; a < ndims; ++a) g.spacing[a] = (*sp)[a];
    }
    if (const auto [key, text] = header.firstOf({"Offset", "Origin", "Position"}); text) {
        const auto o = parseDoubles(*text, ndims);
        if (!o)
            fail(path, key,
                 "expected " + std::to_string(ndims) + " finite numbers, found " +
                     quoteValue(*text));
        for (std::size_t a = 0; a < ndims; ++a) g.origin[a] = (*o)[a];
    }
}

/** TransformMatrix / Rotation / Orientation: the first NDims numbers are index axis 0's
 *  direction, and so on (as ITK's MetaImageIO reads them). */
void readMetaDirection(const fs::path& path, const MetaHeader& header, MetaGeometry& g) {
    const std::size_t ndims = g.ndims;
    const auto [key, text] = header.firstOf({"TransformMatrix", "Rotation", "Orientation"});
    if (!text) return;
    g.directionStated = true;
    const auto m = parseDoubles(*text, ndims * ndims);
    if (!m)
        fail(path, key,
             "expected " + std::to_string(ndims * ndims) + " finite numbers, found " +
                 quoteValue(*text));
    for (std::size_t a = 0; a < ndims; ++a) {
        Vec3 axis{0, 0, 0};
        for (std::size_t c = 0; c < ndims; ++c) axis[c] = (*m)[a * ndims + c];
        const auto unit = normalized(axis);
        if (!unit) fail(path, key, "expected non-zero axis vectors, found " + quoteValue(*text));
        g.direction[a] = *unit;
    }
    if (ndims == 2)
        g.direction[2] = normalized(cross(g.direction[0], g.direction[1])).value_or(Vec3{0, 0, 1});
}

/** How the voxel bytes are stored: element type, byte order, compression, HeaderSize. */
struct MetaEncoding {
    ElementType type{};
    std::string typeText; ///< the ElementType value as written
    std::uint64_t es = 0; ///< bytes per element
    bool bigEndian = false;
    bool compressed = false;
    std::uint64_t compressedDataSize = 0; ///< 0: not given
    std::int64_t headerSize = 0; ///< -1: the data ends the file

    /** "int16 (MET_SHORT, 2 bytes)" */
    std::string typeDesc() const {
        return std::string(typeName(type)) + " (" + typeText + ", " + std::to_string(es) +
               " bytes)";
    }
};

/** ElementType and ElementNumberOfChannels (scalar volumes only). */
void readMetaElementType(const fs::path& path, const MetaHeader& header, MetaEncoding& e) {
    const std::string* typeText = header.get("ElementType");
    if (!typeText)
        fail(path, "ElementType", "expected MET_UCHAR, MET_SHORT, ..., found no ElementType key");
    try {
        e.type = parseElementType(*typeText);
    } catch (const SettingsError&) {
        fail(path, "ElementType",
             "expected MET_CHAR, MET_UCHAR, MET_SHORT, MET_USHORT, MET_INT, MET_UINT, MET_LONG, "
             "MET_ULONG, MET_LONG_LONG, MET_ULONG_LONG, MET_FLOAT or MET_DOUBLE, found " +
                 quoteValue(*typeText));
    }
    e.typeText = *typeText;
    e.es = elementSize(e.type);
    if (const std::string* v = header.get("ElementNumberOfChannels")) {
        std::int64_t ch = 0;
        if (!parseInt(*v, ch) || ch != 1)
            fail(path, "ElementNumberOfChannels",
                 "expected 1 (scalar volumes only), found " + quoteValue(*v));
    }
}

/** Byte order, BinaryData, CompressedData, CompressedDataSize and HeaderSize. */
void readMetaStorage(const fs::path& path, const MetaHeader& header, MetaEncoding& e) {
    if (const auto [key, text] = header.firstOf({"ElementByteOrderMSB", "BinaryDataByteOrderMSB"});
        text) {
        const auto b = parseBool(*text);
        if (!b) fail(path, key, "expected True or False, found " + quoteValue(*text));
        e.bigEndian = *b;
    }
    if (const std::string* v = header.get("BinaryData")) {
        const auto b = parseBool(*v);
        if (!b || !*b)
            fail(path, "BinaryData",
                 "expected True (ASCII MetaImage data is not supported), found " + quoteValue(*v));
    }
    if (const std::string* v = header.get("CompressedData")) {
        const auto b = parseBool(*v);
        if (!b) fail(path, "CompressedData", "expected True or False, found " + quoteValue(*v));
        e.compressed = *b;
    }
    if (const std::string* v = header.get("CompressedDataSize"); v && e.compressed) {
        std::int64_t c = 0;
        if (!parseInt(*v, c) || c < 1)
            fail(path, "CompressedDataSize", "expected a byte count > 0, found " + quoteValue(*v));
        e.compressedDataSize = std::uint64_t(c);
    }
    if (const std::string* v = header.get("HeaderSize")) {
        if (!parseInt(*v, e.headerSize) || e.headerSize < -1)
            fail(path, "HeaderSize",
                 "expected -1 (data at the end of the file) or a byte count >= 0, found " +
                     quoteValue(*v));
    }
    if (e.compressed && e.headerSize == -1)
        fail(path, "HeaderSize", "expected a byte count >= 0 with CompressedData = True, found -1");
}

/** Works out which bytes of which files hold the voxels (ElementDataFile as LOCAL, LIST, a
 *  pattern or one file name) and checks that every file is long enough. */
struct MetaDataLocator {
    const fs::path& path;
    const MetaHeader& header;
    const MetaGeometry& geo;
    const MetaEncoding& enc;
    std::vector<DataPart> parts;

    std::uint64_t totalBytes() const { return std::uint64_t(geo.voxelCount) * enc.es; }

    /** One external data file (or one of a LIST/pattern) holding `bytes` data bytes. */
    void external(const fs::path& name, std::uint64_t bytes, const std::string& what) {
        const fs::path file = name.is_absolute() ? name : path.parent_path() / name;
        const std::uint64_t size = regularFileSize(file, path, "ElementDataFile");
        DataPart p;
        p.file = file;
        p.bytes = bytes;
        if (enc.compressed) {
            p.compressed = true;
            p.offset = std::uint64_t(enc.headerSize);
            if (size < p.offset)
                fail(path, "ElementDataFile",
                     "'" + file.string() +
                         "': expected at least HeaderSize = " + std::to_string(p.offset) +
                         " bytes, found " + std::to_string(size) + " bytes");
            p.compressedBytes = size - p.offset;
        } else if (enc.headerSize == -1) {
            if (size < bytes)
                fail(path, "ElementDataFile",
                     "'" + file.string() + "': expected at least " + std::to_string(bytes) +
                         " bytes (" + what + ", HeaderSize = -1), found " + std::to_string(size) +
                         " bytes");
            p.offset = size - bytes;
        } else {
            p.offset = std::uint64_t(enc.headerSize);
            if (size != p.offset + bytes)
                fail(path, "ElementDataFile",
                     "'" + file.string() + "': expected " + std::to_string(p.offset + bytes) +
                         " bytes (" + what + " = " + std::to_string(bytes) +
                         " data bytes + HeaderSize " + std::to_string(p.offset) + "), found " +
                         std::to_string(size) + " bytes");
        }
        parts.push_back(p);
    }

    /** LOCAL, compressed: from HeaderSize (or the end of the header) to CompressedDataSize or
     *  the end of the file. */
    void localCompressed(DataPart& p) const {
        const std::uint64_t fileSize = header.fileSize;
        p.compressed = true;
        p.offset = enc.headerSize > 0 ? std::uint64_t(enc.headerSize) : header.localOffset;
        if (fileSize < p.offset)
            fail(path, "HeaderSize",
                 "expected at most the file size " + std::to_string(fileSize) + ", found " +
                     std::to_string(p.offset));
        p.compressedBytes = fileSize - p.offset;
        if (enc.compressedDataSize > 0) {
            if (enc.compressedDataSize > p.compressedBytes)
                fail(path, "CompressedDataSize",
                     "expected at most the " + std::to_string(p.compressedBytes) +
                         " bytes after the header, found " +
                         std::to_string(enc.compressedDataSize));
            p.compressedBytes = enc.compressedDataSize;
        }
    }

    /** LOCAL, uncompressed: at the end of the file (HeaderSize = -1) or after the header. */
    void localPlain(DataPart& p) const {
        const std::uint64_t fileSize = header.fileSize;
        const std::uint64_t total = totalBytes();
        if (enc.headerSize == -1) {
            if (fileSize < total)
                fail(path, "ElementDataFile",
                     "LOCAL: expected at least " + std::to_string(total) + " bytes (" +
                         dimsText(geo.dimSize) + " x " + enc.typeDesc() +
                         ", HeaderSize = -1), found " + std::to_string(fileSize) + " bytes");
            p.offset = fileSize - total;
            return;
        }
        p.offset = enc.headerSize > 0 ? std::uint64_t(enc.headerSize) : header.localOffset;
        if (fileSize < p.offset || fileSize - p.offset < total)
            fail(path, "ElementDataFile",
                 "LOCAL: expected " + std::to_string(total) + " data bytes (" +
                     dimsText(geo.dimSize) + " x " + enc.typeDesc() + ") after byte " +
                     std::to_string(p.offset) + ", found " +
                     std::to_string(fileSize > p.offset ? fileSize - p.offset : 0) + " bytes");
    }

    void local() {
        DataPart p;
        p.file = path;
        p.bytes = totalBytes();
        if (enc.compressed)
            localCompressed(p);
        else
            localPlain(p);
        parts.push_back(p);
    }

    /** "LIST [nD]": file names one per line after the header (read from `sb`), each an nD block
     *  (default NDims-1). */
    void list(const std::vector<std::string_view>& words, const std::string& dataFile,
              std::streambuf& sb) {
        std::int64_t fileDim = std::int64_t(geo.ndims) - 1;
        if (words.size() > 1) {
            std::int64_t d = 0;
            const std::string_view w = words[1];
            const auto [ptr, ec] = std::from_chars(w.data(), w.data() + w.size(), d);
            if (ec != std::errc() ||
                (ptr != w.data() + w.size() &&
                 lower(std::string_view(ptr, w.data() + w.size() - ptr)) != "d"))
                fail(path, "ElementDataFile",
                     "expected 'LIST' or 'LIST <n>D', found " + quoteValue(dataFile));
            if (d >= 1 && d <= std::int64_t(geo.ndims)) fileDim = d;
        }
        std::int64_t perFile = 1;
        for (std::int64_t a = 0; a < fileDim; ++a) perFile *= geo.dimSize[std::size_t(a)];
        const std::int64_t nFiles = geo.voxelCount / perFile;
        std::int64_t found = 0;
        std::string line;
        bool tooLong = false;
        while (found < nFiles) {
            if (!readHeaderLine(sb, line, kMaxHeaderLine, tooLong) || tooLong) break;
            const std::string_view name = trim(line);
            if (name.empty()) continue;
            external(fs::path(std::string(name)), std::uint64_t(perFile) * enc.es,
                     "LIST file " + std::to_string(found + 1) + " of " + std::to_string(nFiles) +
                         ": " + std::to_string(perFile) + " x " + enc.typeDesc());
            ++found;
        }
        if (found < nFiles)
            fail(path, "ElementDataFile",
                 "LIST: expected " + std::to_string(nFiles) +
                     " file names after the header (one per " + std::to_string(fileDim) +
                     "D block of " + dimsText(geo.dimSize) + "), found " + std::to_string(found));
    }

    void pattern(const std::vector<std::string_view>& words, const std::string& dataFile);
};

/** "pattern [start [end [step]]]": one file per slice of the last axis. */
void MetaDataLocator::pattern(const std::vector<std::string_view>& words,
                              const std::string& dataFile) {
    std::int64_t nums[3] = {1, 0, 1};
    std::size_t nNums = 0;
    for (std::size_t k = words.size(); k > 1 && nNums < 3; --k) {
        std::int64_t v = 0;
        if (!parseInt(words[k - 1], v)) break;
        ++nNums;
    }
    if (words.size() - nNums < 1)
        fail(path, "ElementDataFile",
             "expected 'pattern start end step', found " + quoteValue(dataFile));
    // Pattern words may contain spaces: rejoin everything before the numbers.
    const std::size_t nameWords = words.size() - nNums;
    const char* begin = words[0].data();
    const char* end = words[nameWords - 1].data() + words[nameWords - 1].size();
    const std::string_view pattern(begin, std::size_t(end - begin));
    std::int64_t parsed[3] = {0, 0, 0};
    for (std::size_t k = 0; k < nNums; ++k) parseInt(words[nameWords + k], parsed[k]);
    const std::int64_t nLast = geo.dimSize.back();
    if (nNums >= 1) nums[0] = parsed[0];
    nums[1] = nNums >= 2 ? parsed[1] : nums[0] + nLast - 1;
    if (nNums >= 3) nums[2] = parsed[2];
    const std::int64_t start = nums[0], stop = nums[1], step = nums[2];
    if (step == 0 || (stop - start != 0 && ((stop - start) > 0) != (step > 0)) ||
        std::abs(start) > (std::int64_t(1) << 40) || std::abs(stop) > (std::int64_t(1) << 40))
        fail(path, "ElementDataFile",
             "expected 'pattern start end step' with a step going from start to end, found " +
                 quoteValue(dataFile));
    const std::int64_t count = (stop - start) / step + 1;
    if (count != nLast)
        fail(path, "ElementDataFile",
             "expected " + std::to_string(nLast) + " files (one per slice, DimSize[" +
                 std::to_string(geo.ndims - 1) + "] = " + std::to_string(nLast) +
                 "), found a pattern giving " + std::to_string(count) + " (" +
                 quoteValue(dataFile) + ")");
    if (!formatPattern(pattern, 0))
        fail(path, "ElementDataFile",
             "expected a file pattern with one %d conversion (e.g. slice%03d.raw), found " +
                 quoteValue(pattern));
    const std::int64_t perFile = geo.voxelCount / nLast;
    for (std::int64_t k = 0; k < count; ++k) {
        const std::int64_t number = start + k * step;
        external(fs::path(*formatPattern(pattern, number)), std::uint64_t(perFile) * enc.es,
                 "slice file " + std::to_string(k + 1) + " of " + std::to_string(count) + ": " +
                     std::to_string(perFile) + " x " + enc.typeDesc());
    }
}

/** The data parts named by ElementDataFile, each checked against its file's size and, when
 *  compressed, against what its compressed bytes can hold. `sb` is just after the header. */
std::vector<DataPart> locateMetaData(const fs::path& path, const MetaHeader& header,
                                     const MetaGeometry& geo, const MetaEncoding& enc,
                                     std::streambuf& sb) {
    MetaDataLocator locate{path, header, geo, enc, {}};
    const std::string& dataFile = *header.get("ElementDataFile");
    const auto words = splitWords(dataFile);
    if (dataFile.empty())
        fail(path, "ElementDataFile",
             "expected LOCAL, a file name, LIST or a pattern, found an empty value");
    else if (lower(dataFile) == "local")
        locate.local();
    else if (words[0] == "LIST")
        locate.list(words, dataFile, sb);
    else if (dataFile.find('%') != std::string::npos)
        locate.pattern(words, dataFile);
    else
        locate.external(fs::path(dataFile), locate.totalBytes(),
                        dimsText(geo.dimSize) + " x " + enc.typeDesc());

    for (const DataPart& p : locate.parts) {
        if (p.compressed && p.bytes > maxInflatedBytes(p.compressedBytes))
            fail(path, "CompressedData",
                 "'" + p.file.string() + "': expected " + std::to_string(p.bytes) +
                     " bytes after decompression, found only " + std::to_string(p.compressedBytes) +
                     " compressed bytes, which cannot hold that much");
    }
    return std::move(locate.parts);
}

/** Reads every part in turn into `dst` (room for all of them). */
void readMetaData(const fs::path& path, const std::vector<DataPart>& parts, const MetaEncoding& enc,
                  float* dst) {
    for (const DataPart& p : parts) {
        std::unique_ptr<ByteSource> src;
        if (p.compressed)
            src = std::make_unique<InflateSource>(p.file, p.offset, p.compressedBytes);
        else
            src = std::make_unique<FileSource>(p.file, p.offset);
        const std::size_t count = std::size_t(p.bytes / enc.es);
        const std::uint64_t got =
            readElements(*src, enc.type, enc.bigEndian, Scaling{}, count, dst);
        if (got != p.bytes) {
            const std::string err = src->error();
            fail(path, "ElementDataFile",
                 "'" + p.file.string() + "': expected " + std::to_string(p.bytes) +
                     (p.compressed ? " bytes after decompression"
                                   : " data bytes from byte " + std::to_string(p.offset)) +
                     ", found " + std::to_string(got) + " bytes" +
                     (err.empty() ? std::string() : " (" + err + ")"));
        }
        dst += count;
    }
}

} // namespace

Volume loadMetaImage(const fs::path& path) {
    const std::uint64_t headerFileSize = regularFileSize(path, path, "header");
    std::ifstream in(path, std::ios::binary);
    if (!in) fail(path, "header", "cannot open file");
    const MetaHeader header = readMetaHeader(path, *in.rdbuf(), headerFileSize);
    if (const std::string* v = header.get("ObjectType"); v && *v != "Image")
        fail(path, "ObjectType", "expected Image, found " + quoteValue(*v));

    MetaGeometry geo;
    readMetaDims(path, header, geo);
    readMetaSpacingOrigin(path, header, geo);
    readMetaDirection(path, header, geo);
    MetaEncoding enc;
    readMetaElementType(path, header, enc);
    readMetaStorage(path, header, enc);
    validateGeometry(geo.dims, geo.spacing, path.string());

    const std::vector<DataPart> parts = locateMetaData(path, header, geo, enc, *in.rdbuf());
    Volume vol =
        emptyVolume(geo.dims, geo.spacing, geo.origin, geo.direction, volumeName(path), path);
    vol.orientationStated = geo.directionStated;
    readMetaData(path, parts, enc, vol.voxels.data());
    return vol;
}

// ------------------------------------------------------------------------------------------------
// NIfTI-1

namespace {

struct NiftiHeaderReader {
    const unsigned char* h;
    bool swap;
    template <class T>
    T get(std::size_t offset) const {
        T v;
        std::memcpy(&v, h + offset, sizeof v);
        return swap ? byteSwapped(v) : v;
    }
};

std::optional<ElementType> niftiType(int code) {
    switch (code) {
    case 2: return ElementType::UInt8;
    case 4: return ElementType::Int16;
    case 8: return ElementType::Int32;
    case 16: return ElementType::Float32;
    case 64: return ElementType::Float64;
    case 256: return ElementType::Int8;
    case 512: return ElementType::UInt16;
    case 768: return ElementType::UInt32;
    case 1024: return ElementType::Int64;
    case 1280: return ElementType::UInt64;
    default: return std::nullopt;
    }
}

const char* niftiTypeName(int code) {
    switch (code) {
    case 0: return "DT_UNKNOWN";
    case 1: return "DT_BINARY";
    case 32: return "DT_COMPLEX64";
    case 128: return "DT_RGB24";
    case 255: return "DT_ALL";
    case 1536: return "DT_FLOAT128";
    case 1792: return "DT_COMPLEX128";
    case 2048: return "DT_COMPLEX256";
    case 2304: return "DT_RGBA32";
    default: return "not a NIfTI-1 datatype";
    }
}

/** Whether the file starts with the gzip magic bytes. */
bool isGzipFile(const fs::path& path) {
    std::ifstream f(path, std::ios::binary);
    unsigned char magic[2] = {0, 0};
    f.read(reinterpret_cast<char*>(magic), 2);
    return f.gcount() == 2 && magic[0] == 0x1f && magic[1] == 0x8b;
}

/** The NIfTI byte stream (zlib reads plain files transparently) and how to name its errors. */
struct NiftiStream {
    GzSource& src;
    bool gz = false;
    std::uint64_t fileSize = 0;

    /** " (gzip: <zlib's error>)", or "" when the data simply ended. */
    std::string readNote() const {
        if (src.error().empty()) return {};
        return (gz ? " (gzip: " : " (") + src.error() + ")";
    }
};

constexpr std::size_t kNiftiHeaderBytes = 348;

/** "; it starts with text: 'hello world...'" when the file's first line is printable text. */
std::string textStartNote(const unsigned char* bytes, std::size_t got) {
    std::size_t n = 0;
    while (n < got && n < 60 && bytes[n] != '\n' && bytes[n] != '\r') {
        if ((bytes[n] < 0x20 && bytes[n] != '\t') || bytes[n] >= 0x7f) return {};
        ++n;
    }
    if (n < 4) return {};
    return "; it starts with text: " +
           quoteValue(std::string_view(reinterpret_cast<const char*>(bytes), n));
}

/** Refuses a file whose header size field `sizeofHdr` (as read) is no NIfTI-1's: a NIfTI-2
 *  file, plain data named .nii.gz, or no NIfTI at all. */
[[noreturn]] void failNotNifti1(const fs::path& path, const NiftiStream& in, std::int32_t sizeofHdr,
                                const unsigned char* h, std::size_t got) {
    if (!in.gz && endsWith(lower(path.filename().string()), ".nii.gz"))
        throw LoadError(path.string() + ": not gzip-compressed data (a .nii.gz file must be gzip)" +
                        textStartNote(h, got));
    if (got < 4)
        fail(path, "sizeof_hdr",
             "expected a 348-byte NIfTI-1 header, found a file of " + std::to_string(got) +
                 " bytes" + in.readNote());
    if (sizeofHdr == 540 || byteSwapped(sizeofHdr) == 540)
        throw LoadError(path.string() +
                        ": a NIfTI-2 file (header size 540): NIfTI-2 is not supported, only "
                        "NIfTI-1 (sizeof_hdr 348); save it as NIfTI-1 to open it");
    throw LoadError(path.string() + ": not a NIfTI file (its header size field (sizeof_hdr) is " +
                    std::to_string(sizeofHdr) +
                    ", expected 348 for NIfTI-1 or 540 for NIfTI-2, in either byte order" +
                    textStartNote(h, got) + ")");
}

/** Reads the 348-byte header into h and checks sizeof_hdr (which gives the byte order) and the
 *  single-file magic. */
NiftiHeaderReader readNiftiHeader(const fs::path& path, const NiftiStream& in,
                                  unsigned char (&h)[kNiftiHeaderBytes]) {
    const std::size_t got = in.src.read(h, sizeof h);
    if (got < sizeof h && !in.src.error().empty())
        fail(path, "header", "expected 348 bytes, found " + std::to_string(got) + in.readNote());
    std::int32_t sizeofHdr = 0;
    if (got >= 4) std::memcpy(&sizeofHdr, h, 4);
    bool swap = false;
    if (got >= 4 && sizeofHdr == 348) {
        swap = false;
    } else if (got >= 4 && byteSwapped(sizeofHdr) == 348) {
        swap = true; // written on a machine of the other byte order
    } else {
        failNotNifti1(path, in, sizeofHdr, h, got);
    }
    if (got < sizeof h)
        fail(path, "header", "expected 348 bytes, found " + std::to_string(got) + in.readNote());

    const std::string_view magic(reinterpret_cast<const char*>(h + 344), 4);
    if (magic == std::string_view("ni1\0", 4))
        fail(path, "magic",
             "expected \"n+1\" (single-file NIfTI-1), found \"ni1\" (a .hdr/.img pair, not "
             "supported)");
    if (magic != std::string_view("n+1\0", 4))
        fail(path, "magic", "expected \"n+1\" (single-file NIfTI-1), found " + quoteValue(magic));
    return NiftiHeaderReader{h, swap};
}

/** dim: 2 or 3 dimensions (or up to 7 with extent 1 beyond the third). */
Dims3 niftiDims(const fs::path& path, const NiftiHeaderReader& r) {
    std::int16_t dim[8];
    for (int i = 0; i < 8; ++i) dim[i] = r.get<std::int16_t>(40 + 2 * i);
    std::string dimText;
    for (int i = 0; i < 8; ++i) {
        if (i) dimText += ' '; // appended piecewise: GCC 12 warns falsely on "" + std::string here
        dimText += std::to_string(dim[i]);
    }
    if (dim[0] < 2 || dim[0] > 7)
        fail(path, "dim[0]",
             "expected 2 or 3 (or 4..7 with one time point), found " + std::to_string(dim[0]) +
                 " (dim = " + dimText + ")");
    for (int i = 4; i <= dim[0]; ++i) {
        if (dim[i] != 1)
            fail(path, "dim[" + std::to_string(i) + "]",
                 "expected 1 (a single 3D volume), found " + std::to_string(dim[i]) +
                     " (dim = " + dimText + ")");
    }
    Dims3 dims{dim[1], dim[2], dim[0] >= 3 ? dim[3] : 1};
    for (int a = 0; a < 3; ++a) {
        if (dims[a] < 1 || dims[a] > kMaxDimPerAxis)
            fail(path, "dim[" + std::to_string(a + 1) + "]",
                 "expected 1.." + std::to_string(kMaxDimPerAxis) + ", found " +
                     std::to_string(dims[a]) + " (dim = " + dimText + ")");
    }
    return dims;
}

ElementType niftiElementType(const fs::path& path, const NiftiHeaderReader& r) {
    const int datatype = r.get<std::int16_t>(70);
    const auto type = niftiType(datatype);
    if (!type)
        fail(path, "datatype",
             "expected a scalar type (2 uint8, 4 int16, 8 int32, 16 float32, 64 float64, 256 int8, "
             "512 uint16, 768 uint32, 1024 int64, 1280 uint64), found " +
                 std::to_string(datatype) + " (" + niftiTypeName(datatype) + ", not supported)");
    return *type;
}

/** mm per unit of xyzt_units' space unit (unknown: mm). */
double niftiUnitToMm(const NiftiHeaderReader& r) {
    const int spaceUnits = r.h[123] & 0x07;
    return spaceUnits == 1 ? 1000.0 : spaceUnits == 3 ? 0.001 : 1.0;
}

/** Spacing (mm) from pixdim[1..3]. */
Vec3 niftiSpacing(const fs::path& path, const NiftiHeaderReader& r, const Dims3& dims,
                  double unitToMm) {
    Vec3 spacing{1.0, 1.0, 1.0};
    for (int a = 0; a < 3; ++a) {
        const float pixdim = r.get<float>(76 + 4 * (a + 1));
        const double p = std::fabs(double(pixdim));
        if (std::isfinite(p) && p > 0.0) {
            spacing[a] = p * unitToMm;
        } else if (dims[a] == 1) {
            spacing[a] = unitToMm; // a single slice: the spacing does not matter
        } else {
            fail(path, "pixdim[" + std::to_string(a + 1) + "]",
                 "expected a finite voxel size > 0, found " + str(pixdim));
        }
    }
    return spacing;
}

/** Where the voxels are and how they scale: vox_offset, scl_slope/scl_inter, sizes. */
struct NiftiData {
    std::uint64_t voxOffset = 0;
    Scaling scaling;
    std::uint64_t dataBytes = 0; ///< voxel bytes
    std::uint64_t required = 0; ///< voxOffset + dataBytes
    std::string layout; ///< "vox_offset 352 + 4 x 4 x 4 voxels x 2 bytes int16"
};

/** Reads vox_offset and the scaling and checks that the file can hold the data. */
NiftiData niftiData(const fs::path& path, const NiftiHeaderReader& r, const NiftiStream& in,
                    const Dims3& dims, ElementType type) {
    NiftiData d;
    const float voxOffsetF = r.get<float>(108);
    if (!std::isfinite(voxOffsetF) || voxOffsetF < 352.0f || voxOffsetF > 1.0e12f ||
        voxOffsetF != std::floor(voxOffsetF))
        fail(path, "vox_offset",
             "expected a whole number of bytes >= 352 (single-file NIfTI-1), found " +
                 str(voxOffsetF));
    d.voxOffset = std::uint64_t(voxOffsetF);
    const float slope = r.get<float>(112);
    const float inter = r.get<float>(116);
    if (std::isfinite(slope) && slope != 0.0f) {
        d.scaling.slope = slope;
        d.scaling.inter = std::isfinite(inter) ? inter : 0.0;
        d.scaling.apply = !(d.scaling.slope == 1.0 && d.scaling.inter == 0.0);
    }

    const std::uint64_t es = elementSize(type);
    d.dataBytes = std::uint64_t(dims[0] * dims[1] * dims[2]) * es;
    d.required = d.voxOffset + d.dataBytes;
    d.layout = "vox_offset " + std::to_string(d.voxOffset) + " + " + std::to_string(dims[0]) +
               " x " + std::to_string(dims[1]) + " x " + std::to_string(dims[2]) + " voxels x " +
               std::to_string(es) + " bytes " + typeName(type);
    if (!in.gz && in.fileSize < d.required)
        fail(path, "data",
             "expected " + std::to_string(d.required) + " bytes (" + d.layout + "), found " +
                 std::to_string(in.fileSize) + " bytes");
    if (in.gz && d.required > maxInflatedBytes(in.fileSize))
        fail(path, "data",
             "expected " + std::to_string(d.required) + " bytes after decompression (" + d.layout +
                 "), found a gzip file of only " + std::to_string(in.fileSize) +
                 " bytes, which cannot hold that much");
    return d;
}

/** Index axis directions and origin in the NIfTI world frame (RAS, the file's units). */
struct NiftiOrientation {
    std::array<Vec3, 3> direction;
    Vec3 origin;
    bool stated = true; ///< from the sform or qform (false: identity assumed)
};

/** The sform (sform_code > 0); nullopt when absent or its axes are degenerate. */
std::optional<NiftiOrientation> niftiSform(const fs::path& path, const NiftiHeaderReader& r) {
    if (r.get<std::int16_t>(254) <= 0) return std::nullopt;
    double srow[3][4];
    bool finite = true;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 4; ++j) {
            srow[i][j] = r.get<float>(280 + 16 * i + 4 * j);
            finite = finite && std::isfinite(srow[i][j]);
        }
    if (!finite)
        fail(path, "srow_x/srow_y/srow_z",
             "expected finite numbers (sform_code > 0), found non-finite");
    const auto c0 = normalized({srow[0][0], srow[1][0], srow[2][0]});
    const auto c1 = normalized({srow[0][1], srow[1][1], srow[2][1]});
    auto c2 = normalized({srow[0][2], srow[1][2], srow[2][2]});
    if (c0 && c1 && !c2) c2 = normalized(cross(*c0, *c1));
    if (!c0 || !c1 || !c2) return std::nullopt;
    return NiftiOrientation{{*c0, *c1, *c2}, {srow[0][3], srow[1][3], srow[2][3]}};
}

/** The qform (qform_code > 0): a quaternion rotation, qfac flipping the third axis. */
std::optional<NiftiOrientation> niftiQform(const fs::path& path, const NiftiHeaderReader& r) {
    if (r.get<std::int16_t>(252) <= 0) return std::nullopt;
    double b = r.get<float>(256), c = r.get<float>(260), d = r.get<float>(264);
    const double qx = r.get<float>(268), qy = r.get<float>(272), qz = r.get<float>(276);
    if (!std::isfinite(b) || !std::isfinite(c) || !std::isfinite(d) || !std::isfinite(qx) ||
        !std::isfinite(qy) || !std::isfinite(qz))
        fail(path, "quatern_b/c/d, qoffset_x/y/z",
             "expected finite numbers (qform_code > 0), found non-finite");
    double a = 1.0 - (b * b + c * c + d * d);
    if (a < 1e-7) {
        // b, c, d describe a 180 degree rotation: renormalise them (as nifti1_io does).
        const double n = std::sqrt(b * b + c * c + d * d);
        if (n > 0.0) {
            b /= n;
            c /= n;
            d /= n;
        }
        a = 0.0;
    } else {
        a = std::sqrt(a);
    }
    const double qfac = r.get<float>(76) < 0.0f ? -1.0 : 1.0; // pixdim[0]
    const double R[3][3] = {
        {a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)},
        {2 * (b * c + a * d), a * a + c * c - b * b - d * d, 2 * (c * d - a * b)},
        {2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - c * c - b * b},
    };
    NiftiOrientation o;
    for (int ax = 0; ax < 3; ++ax) {
        const double f = ax == 2 ? qfac : 1.0;
        o.direction[ax] = {R[0][ax] * f, R[1][ax] * f, R[2][ax] * f};
    }
    o.origin = {qx, qy, qz};
    return o;
}

/** The Volume's direction and origin (LPS, mm) from the sform (preferred) or the qform;
 *  identity and 0 when neither is usable. */
NiftiOrientation niftiOrientation(const fs::path& path, const NiftiHeaderReader& r,
                                  double unitToMm) {
    auto o = niftiSform(path, r);
    if (!o) o = niftiQform(path, r);
    if (!o) {
        NiftiOrientation assumed{Volume{}.direction, Vec3{0.0, 0.0, 0.0}};
        assumed.stated = false;
        return assumed;
    }
    // NIfTI world coordinates are RAS; the Volume uses LPS like DICOM.
    for (Vec3& axis : o->direction) {
        axis[0] = -axis[0];
        axis[1] = -axis[1];
    }
    o->origin = {-o->origin[0] * unitToMm, -o->origin[1] * unitToMm, o->origin[2] * unitToMm};
    return *o;
}

/** Skips the extensions between the header and vox_offset. */
void skipNiftiExtensions(const fs::path& path, const NiftiStream& in, const NiftiData& data) {
    std::uint64_t toSkip = data.voxOffset - kNiftiHeaderBytes;
    unsigned char scratch[4096];
    while (toSkip > 0) {
        const std::size_t n = std::size_t(std::min<std::uint64_t>(toSkip, sizeof scratch));
        const std::size_t g = in.src.read(scratch, n);
        toSkip -= g;
        if (g < n) {
            fail(path, "data",
                 "expected " + std::to_string(data.required) + " bytes (" + data.layout +
                     "), found " + std::to_string(data.voxOffset - toSkip) + " bytes" +
                     in.readNote());
        }
    }
}

/** Reads the voxels into vol and, for gzip, checks the stream's trailer. */
void readNiftiVoxels(const fs::path& path, const NiftiStream& in, const NiftiData& data,
                     ElementType type, bool swap, Volume& vol) {
    const std::uint64_t read = readElements(in.src, type, swap, data.scaling,
                                            std::size_t(vol.voxelCount()), vol.voxels.data());
    if (read != data.dataBytes)
        fail(path, "data",
             "expected " + std::to_string(data.required) + " bytes (" + data.layout + "), found " +
                 std::to_string(data.voxOffset + read) + " bytes" + in.readNote());
    if (in.gz) {
        // Reading one byte past the data makes zlib check the gzip trailer (CRC and length) when
        // the data ends the stream, as it does in every .nii.gz: corruption is reported, not
        // hidden.
        unsigned char extra = 0;
        in.src.read(&extra, 1);
        if (!in.src.error().empty())
            fail(path, "data",
                 "gzip stream corrupt or truncated after " + std::to_string(data.required) +
                     " bytes (" + in.src.error() + ")");
    }
}

} // namespace

Volume loadNifti(const fs::path& path) {
    const std::uint64_t fileSize = regularFileSize(path, path, "file");
    const bool gz = isGzipFile(path);
    GzSource src(path); // zlib reads plain files transparently
    if (!src.ok()) fail(path, "file", "cannot open file");
    const NiftiStream in{src, gz, fileSize};

    unsigned char h[kNiftiHeaderBytes];
    const NiftiHeaderReader r = readNiftiHeader(path, in, h);
    const Dims3 dims = niftiDims(path, r);
    const ElementType type = niftiElementType(path, r);
    const double unitToMm = niftiUnitToMm(r);
    const Vec3 spacing = niftiSpacing(path, r, dims, unitToMm);
    validateGeometry(dims, spacing, path.string());
    const NiftiData data = niftiData(path, r, in, dims, type);
    const NiftiOrientation orientation = niftiOrientation(path, r, unitToMm);
    skipNiftiExtensions(path, in, data);

    Volume vol = emptyVolume(dims, spacing, orientation.origin, orientation.direction,
                             volumeName(path), path);
    vol.orientationStated = orientation.stated;
    readNiftiVoxels(path, in, data, type, r.swap, vol);
    return vol;
}

// ------------------------------------------------------------------------------------------------
// Raw

Volume loadRaw(const fs::path& path, const RawSpec& spec) {
    validateGeometry(spec.dims, spec.spacing, path.string());
    const std::uint64_t es = elementSize(spec.type);
    const std::int64_t voxelCount = spec.dims[0] * spec.dims[1] * spec.dims[2];
    const std::uint64_t dataBytes = std::uint64_t(voxelCount) * es;
    const std::uint64_t size = regularFileSize(path, path, "file");
    const std::string layout = "headerBytes " + std::to_string(spec.headerBytes) + " + " +
                               std::to_string(spec.dims[0]) + " x " + std::to_string(spec.dims[1]) +
                               " x " + std::to_string(spec.dims[2]) + " voxels x " +
                               std::to_string(es) + " bytes " + typeName(spec.type);
    if (spec.headerBytes > std::numeric_limits<std::uint64_t>::max() - dataBytes ||
        size != spec.headerBytes + dataBytes) {
        const std::string expected =
            spec.headerBytes > std::numeric_limits<std::uint64_t>::max() - dataBytes
                ? std::string("more than 2^64")
                : std::to_string(spec.headerBytes + dataBytes);
        fail(path, "file size",
             "expected " + expected + " bytes (" + layout + "), found " + std::to_string(size) +
                 " bytes");
    }
    FileSource src(path, spec.headerBytes);
    if (!src.ok()) fail(path, "file", "cannot open file");
    Volume vol = emptyVolume(spec.dims, spec.spacing, Vec3{0, 0, 0}, Volume{}.direction,
                             path.stem().string(), path);
    vol.orientationStated = false; // raw data carry none
    const std::uint64_t read = readElements(src, spec.type, spec.bigEndian, Scaling{},
                                            std::size_t(voxelCount), vol.voxels.data());
    if (read != dataBytes)
        fail(path, "data",
             "expected " + std::to_string(dataBytes) + " data bytes from byte " +
                 std::to_string(spec.headerBytes) + ", found " + std::to_string(read) + " bytes");
    return vol;
}

} // namespace fvr::core
