// Shared by the volume loader tests (test_volume_io.cpp, test_metaimage_io.cpp,
// test_nifti_io.cpp, test_volume_io_shared_data.cpp): scratch folders, files written byte by byte
// in either byte order, synthetic NIfTI-1 headers, and the check that a loader throws LoadError.
#pragma once

#include <fvr/core/errors.h>
#include <fvr/core/io/volume_io.h>
#include <fvr/core/volume.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include <gtest/gtest.h>

#include "stored_deflate.h"
#include "test_support.h"

namespace fvr::test::volume_io {

namespace fs = std::filesystem;
using fvr::core::Dims3;
using fvr::core::ElementType;
using fvr::core::LoadError;
using fvr::core::Vec3;
using fvr::core::Volume;

// ------------------------------------------------------------------------------------------------
// Helpers

inline fs::path caseDir(const std::string& name) {
    const fs::path d = fvr::test::tmpDir() / "volume_io" / name;
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

inline void writeFile(const fs::path& p, const std::string& bytes) {
    std::ofstream out(p, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), std::streamsize(bytes.size()));
    ASSERT_TRUE(out.good()) << p;
}

inline std::string readFile(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream os;
    os << in.rdbuf();
    return os.str();
}

template <class T>
void appendValue(std::string& out, T v, bool bigEndian) {
    unsigned char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    if (bigEndian != (std::endian::native == std::endian::big)) std::reverse(b, b + sizeof(T));
    out.append(reinterpret_cast<const char*>(b), sizeof(T));
}

template <class T>
void putValue(std::string& buf, std::size_t offset, T v, bool bigEndian) {
    std::string tmp;
    appendValue(tmp, v, bigEndian);
    buf.replace(offset, sizeof(T), tmp);
}

using fvr::test::gzipStored;
using fvr::test::zlibStored;

inline bool contains(const std::string& s, const std::string& part) {
    return s.find(part) != std::string::npos;
}

/** Runs f, which must throw LoadError; returns its message (empty if it did not throw). */
inline std::string loadErrorOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const LoadError& e) {
        return e.what();
    } catch (const std::exception& e) {
        ADD_FAILURE() << "expected fvr::core::LoadError, got another exception: " << e.what();
        return {};
    }
    ADD_FAILURE() << "expected fvr::core::LoadError, nothing was thrown";
    return {};
}

inline void expectVec(const Vec3& v, const Vec3& expected, double tol, const char* what) {
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(v[i], expected[i], tol) << what << "[" << i << "]";
}

inline double voxelSum(const Volume& v) {
    double s = 0.0;
    for (const float x : v.voxels) s += x;
    return s;
}

// ------------------------------------------------------------------------------------------------
// Synthetic MetaImage of every element type

/** Values of type T that survive the conversion to float in a known way (extremes included). */
template <class T>
std::vector<T> sampleValues() {
    using L = std::numeric_limits<T>;
    std::vector<T> v{T(0), T(1), L::max(), L::lowest(), T(100), T(7)};
    if constexpr (L::is_signed) {
        v.push_back(T(-1));
        v.push_back(T(-100));
    } else {
        v.push_back(T(L::max() - 1));
        v.push_back(T(L::max() / 2));
    }
    if constexpr (!L::is_integer) {
        v.push_back(T(0.5));
        v.push_back(T(-1234.25));
    } else {
        v.push_back(T(42));
        v.push_back(T(L::max() / 3));
    }
    while (v.size() < 12) v.push_back(T(v.size()));
    v.resize(12); // a 3 x 2 x 2 volume
    return v;
}

/** What the loaders make of a value of type T: the nearest float, +-infinity beyond its range. */
template <class T>
float expectedFloat(T v) {
    if constexpr (std::is_same_v<T, double>) {
        if (v > double(std::numeric_limits<float>::max()))
            return std::numeric_limits<float>::infinity();
        if (v < -double(std::numeric_limits<float>::max()))
            return -std::numeric_limits<float>::infinity();
    }
    return static_cast<float>(v);
}

// ------------------------------------------------------------------------------------------------
// Synthetic NIfTI-1

struct NiftiSpec {
    std::array<std::int16_t, 8> dim{3, 4, 3, 2, 1, 1, 1, 1};
    std::int16_t datatype = 4; // int16
    std::int16_t bitpix = 16;
    std::array<float, 8> pixdim{1, 1, 1, 1, 1, 1, 1, 1};
    float voxOffset = 352;
    float slope = 0;
    float inter = 0;
    std::uint8_t xyztUnits = 2; // mm
    std::int16_t qformCode = 0;
    std::int16_t sformCode = 0;
    std::array<float, 6> quatern{0, 0, 0, 0, 0, 0}; // b c d, qoffset x y z
    float srow[3][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}};
    std::int32_t sizeofHdr = 348;
    std::string magic{"n+1\0", 4};
    bool bigEndian = false;
};

inline std::string niftiHeader(const NiftiSpec& s) {
    std::string h(352, '\0');
    const bool be = s.bigEndian;
    putValue<std::int32_t>(h, 0, s.sizeofHdr, be);
    for (int i = 0; i < 8; ++i) putValue<std::int16_t>(h, 40 + 2 * i, s.dim[i], be);
    putValue<std::int16_t>(h, 70, s.datatype, be);
    putValue<std::int16_t>(h, 72, s.bitpix, be);
    for (int i = 0; i < 8; ++i) putValue<float>(h, 76 + 4 * i, s.pixdim[i], be);
    putValue<float>(h, 108, s.voxOffset, be);
    putValue<float>(h, 112, s.slope, be);
    putValue<float>(h, 116, s.inter, be);
    h[123] = char(s.xyztUnits);
    putValue<std::int16_t>(h, 252, s.qformCode, be);
    putValue<std::int16_t>(h, 254, s.sformCode, be);
    for (int i = 0; i < 6; ++i) putValue<float>(h, 256 + 4 * i, s.quatern[i], be);
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 4; ++j) putValue<float>(h, 280 + 16 * i + 4 * j, s.srow[i][j], be);
    h.replace(344, 4, s.magic.substr(0, 4));
    return h;
}

template <class T>
std::string niftiFile(const NiftiSpec& s, const std::vector<T>& values) {
    std::string f = niftiHeader(s);
    f.resize(std::size_t(s.voxOffset), '\0');
    for (const T v : values) appendValue(f, v, s.bigEndian);
    return f;
}

inline std::vector<std::int16_t> rampInt16(std::size_t n) {
    std::vector<std::int16_t> v(n);
    for (std::size_t i = 0; i < n; ++i) v[i] = std::int16_t(int(i) * 37 - 300);
    return v;
}

/** A small valid .mha (LOCAL) file used by the robustness tests. */
inline std::string smallMha() {
    std::string f = "ObjectType = Image\nNDims = 3\nDimSize = 4 3 2\nElementSpacing = 1 1 1\n"
                    "Offset = 0 0 0\nTransformMatrix = 1 0 0 0 1 0 0 0 1\nElementType = MET_SHORT\n"
                    "ElementByteOrderMSB = False\nHeaderSize = 0\nElementDataFile = LOCAL\n";
    for (const std::int16_t v : rampInt16(24)) appendValue(f, v, false);
    return f;
}

} // namespace fvr::test::volume_io

#define EXPECT_MESSAGE_HAS(msg, part)                                                              \
    EXPECT_TRUE(contains((msg), (part))) << "message: " << (msg) << "\nlacks: " << (part)
