// Volume loaders: file checks, element conversion to float and the voxel allocation they share.
#include "volume_io_internal.h"

#include <algorithm>
#include <bit>
#include <cstring>
#include <fstream>
#include <limits>
#include <new>
#include <string>
#include <system_error>
#include <type_traits>
#include <vector>

#include <fvr/core/errors.h>
#include <fvr/core/memory_budget.h>

namespace fvr::core::detail {

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
// Element conversion

namespace {

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

} // namespace

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

/** A volume with its geometry and room for its voxels (allocated after every check passed). */
Volume emptyVolume(const Dims3& dims, const Vec3& spacing, const Vec3& origin,
                   const glm::dmat3& direction, std::string name, const fs::path& file) {
    Volume vol;
    vol.dims = dims;
    vol.spacing = spacing;
    vol.origin = origin;
    vol.direction = direction;
    vol.name = std::move(name);
    vol.voxels = allocateVoxels(dims, file);
    return vol;
}

} // namespace fvr::core::detail
