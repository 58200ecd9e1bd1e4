// Tests of the volume loaders (MetaImage, NIfTI-1, raw): the shared data sets against values
// computed independently (Python, standard library only), synthetic files of every element type
// and layout, and malformed files whose messages must name the file and the field.
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
#include <random>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include <gtest/gtest.h>

#include "stored_deflate.h"
#include "test_support.h"

namespace {

namespace fs = std::filesystem;
using fvr::core::Dims3;
using fvr::core::ElementType;
using fvr::core::LoadError;
using fvr::core::Vec3;
using fvr::core::Volume;

// ------------------------------------------------------------------------------------------------
// Helpers

fs::path caseDir(const std::string& name) {
    const fs::path d = fvr::test::tmpDir() / "volume_io" / name;
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

void writeFile(const fs::path& p, const std::string& bytes) {
    std::ofstream out(p, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), std::streamsize(bytes.size()));
    ASSERT_TRUE(out.good()) << p;
}

std::string readFile(const fs::path& p) {
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

bool contains(const std::string& s, const std::string& part) {
    return s.find(part) != std::string::npos;
}

/** Runs f, which must throw LoadError; returns its message (empty if it did not throw). */
std::string loadErrorOf(const std::function<void()>& f) {
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

#define EXPECT_MESSAGE_HAS(msg, part)                                                              \
    EXPECT_TRUE(contains((msg), (part))) << "message: " << (msg) << "\nlacks: " << (part)

void expectVec(const Vec3& v, const Vec3& expected, double tol, const char* what) {
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(v[i], expected[i], tol) << what << "[" << i << "]";
}

double voxelSum(const Volume& v) {
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

template <class T>
void checkMetaImageType(const fs::path& dir, const char* met, bool bigEndian,
                        const char* byteOrderKey) {
    const std::vector<T> values = sampleValues<T>();
    std::string data;
    for (const T v : values) appendValue(data, v, bigEndian);
    const std::string stem = std::string(met) + (bigEndian ? "_msb" : "_lsb");
    writeFile(dir / (stem + ".raw"), data);
    std::ostringstream h;
    h << "ObjectType = Image\nNDims = 3\nDimSize = 3 2 2\nElementSpacing = 0.5 0.25 2\n"
      << "ElementType = " << met << "\n"
      << byteOrderKey << " = " << (bigEndian ? "True" : "False") << "\n"
      << "ElementDataFile = " << stem << ".raw\n";
    writeFile(dir / (stem + ".mhd"), h.str());
    const Volume vol = fvr::core::loadMetaImage(dir / (stem + ".mhd"));
    ASSERT_EQ(vol.dims, (Dims3{3, 2, 2})) << stem;
    expectVec(vol.spacing, {0.5, 0.25, 2.0}, 0.0, "spacing");
    ASSERT_EQ(vol.voxels.size(), values.size());
    for (std::size_t i = 0; i < values.size(); ++i)
        EXPECT_EQ(vol.voxels[i], expectedFloat(values[i])) << stem << " voxel " << i;
    EXPECT_EQ(vol.name, stem);
    EXPECT_EQ(vol.units, fvr::core::ValueUnits::Unknown);
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

std::string niftiHeader(const NiftiSpec& s) {
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

std::vector<std::int16_t> rampInt16(std::size_t n) {
    std::vector<std::int16_t> v(n);
    for (std::size_t i = 0; i < n; ++i) v[i] = std::int16_t(int(i) * 37 - 300);
    return v;
}

/** A small valid .mha (LOCAL) file used by the robustness tests. */
std::string smallMha() {
    std::string f = "ObjectType = Image\nNDims = 3\nDimSize = 4 3 2\nElementSpacing = 1 1 1\n"
                    "Offset = 0 0 0\nTransformMatrix = 1 0 0 0 1 0 0 0 1\nElementType = MET_SHORT\n"
                    "ElementByteOrderMSB = False\nHeaderSize = 0\nElementDataFile = LOCAL\n";
    for (const std::int16_t v : rampInt16(24)) appendValue(f, v, false);
    return f;
}

} // namespace

// ================================================================================================
// Basics

TEST(VolumeIo, ElementTypesParseAndHaveSizes) {
    using fvr::core::elementSize;
    using fvr::core::parseElementType;
    EXPECT_EQ(parseElementType("int16"), ElementType::Int16);
    EXPECT_EQ(parseElementType("UINT8"), ElementType::UInt8);
    EXPECT_EQ(parseElementType("float64"), ElementType::Float64);
    EXPECT_EQ(parseElementType("MET_CHAR"), ElementType::Int8);
    EXPECT_EQ(parseElementType("MET_UCHAR"), ElementType::UInt8);
    EXPECT_EQ(parseElementType("MET_SHORT"), ElementType::Int16);
    EXPECT_EQ(parseElementType("MET_USHORT"), ElementType::UInt16);
    EXPECT_EQ(parseElementType("MET_INT"), ElementType::Int32);
    EXPECT_EQ(parseElementType("MET_UINT"), ElementType::UInt32);
    EXPECT_EQ(parseElementType("MET_LONG"), ElementType::Int32); // 4 bytes in MetaIO
    EXPECT_EQ(parseElementType("MET_ULONG"), ElementType::UInt32);
    EXPECT_EQ(parseElementType("MET_LONG_LONG"), ElementType::Int64);
    EXPECT_EQ(parseElementType("MET_ULONG_LONG"), ElementType::UInt64);
    EXPECT_EQ(parseElementType("MET_FLOAT"), ElementType::Float32);
    EXPECT_EQ(parseElementType("MET_DOUBLE"), ElementType::Float64);
    EXPECT_THROW(parseElementType("MET_UCHAR_ARRAY"), fvr::core::SettingsError);
    EXPECT_THROW(parseElementType("complex64"), fvr::core::SettingsError);
    EXPECT_THROW(parseElementType(""), fvr::core::SettingsError);

    EXPECT_EQ(elementSize(ElementType::Int8), 1u);
    EXPECT_EQ(elementSize(ElementType::UInt8), 1u);
    EXPECT_EQ(elementSize(ElementType::Int16), 2u);
    EXPECT_EQ(elementSize(ElementType::UInt16), 2u);
    EXPECT_EQ(elementSize(ElementType::Int32), 4u);
    EXPECT_EQ(elementSize(ElementType::UInt32), 4u);
    EXPECT_EQ(elementSize(ElementType::Float32), 4u);
    EXPECT_EQ(elementSize(ElementType::Int64), 8u);
    EXPECT_EQ(elementSize(ElementType::UInt64), 8u);
    EXPECT_EQ(elementSize(ElementType::Float64), 8u);
}

TEST(VolumeIo, ValueRangeAndUnitsName) {
    Volume v;
    EXPECT_EQ(v.valueRange(), (std::pair<float, float>{0.0f, 0.0f}));
    v.dims = {2, 2, 1};
    v.voxels = {3.0f, -2.5f, std::numeric_limits<float>::quiet_NaN(), 7.0f};
    EXPECT_EQ(v.valueRange(), (std::pair<float, float>{-2.5f, 7.0f}));
    EXPECT_STREQ(fvr::core::unitsName(fvr::core::ValueUnits::HounsfieldUnits), "HU");
    EXPECT_STREQ(fvr::core::unitsName(fvr::core::ValueUnits::Unknown), "unknown");
}

TEST(VolumeIo, ValidateGeometryRejectsBadDimsAndSpacing) {
    using fvr::core::validateGeometry;
    EXPECT_NO_THROW(validateGeometry({1, 1, 1}, {1, 1, 1}, "src"));
    EXPECT_NO_THROW(validateGeometry({2048, 2048, 2048}, {0.1, 0.1, 0.1}, "src"));
    std::string m = loadErrorOf([] { validateGeometry({0, 4, 4}, {1, 1, 1}, "mysource"); });
    EXPECT_MESSAGE_HAS(m, "mysource");
    EXPECT_MESSAGE_HAS(m, "dimensions");
    m = loadErrorOf([] { validateGeometry({16385, 4, 4}, {1, 1, 1}, "src"); });
    EXPECT_MESSAGE_HAS(m, "16385");
    m = loadErrorOf([] { validateGeometry({16384, 16384, 64}, {1, 1, 1}, "src"); });
    EXPECT_MESSAGE_HAS(m, "at most");
    m = loadErrorOf([] { validateGeometry({4, 4, 4}, {1, 0, 1}, "src"); });
    EXPECT_MESSAGE_HAS(m, "spacing");
    m = loadErrorOf([] { validateGeometry({4, 4, 4}, {1, 1, std::nan("")}, "src"); });
    EXPECT_MESSAGE_HAS(m, "spacing");
    m = loadErrorOf([] { validateGeometry({4, 4, 4}, {1, -1, 1}, "src"); });
    EXPECT_MESSAGE_HAS(m, "spacing");
}

// ================================================================================================
// MetaImage, synthetic

TEST(VolumeIo, MetaImageEveryElementTypeBothByteOrdersRoundTrips) {
    const fs::path dir = caseDir("types");
    for (const bool msb : {false, true}) {
        // The two spellings of the byte-order key are exercised alternately.
        const char* key = msb ? "BinaryDataByteOrderMSB" : "ElementByteOrderMSB";
        for (const char* k : {key, msb ? "ElementByteOrderMSB" : "BinaryDataByteOrderMSB"}) {
            checkMetaImageType<std::int8_t>(dir, "MET_CHAR", msb, k);
            checkMetaImageType<std::uint8_t>(dir, "MET_UCHAR", msb, k);
            checkMetaImageType<std::int16_t>(dir, "MET_SHORT", msb, k);
            checkMetaImageType<std::uint16_t>(dir, "MET_USHORT", msb, k);
            checkMetaImageType<std::int32_t>(dir, "MET_INT", msb, k);
            checkMetaImageType<std::uint32_t>(dir, "MET_UINT", msb, k);
            checkMetaImageType<std::int32_t>(dir, "MET_LONG", msb, k);
            checkMetaImageType<std::uint32_t>(dir, "MET_ULONG", msb, k);
            checkMetaImageType<std::int64_t>(dir, "MET_LONG_LONG", msb, k);
            checkMetaImageType<std::uint64_t>(dir, "MET_ULONG_LONG", msb, k);
            checkMetaImageType<float>(dir, "MET_FLOAT", msb, k);
            checkMetaImageType<double>(dir, "MET_DOUBLE", msb, k);
        }
    }
}

TEST(VolumeIo, MetaImageGeometryKeys) {
    const fs::path dir = caseDir("geometry");
    std::string data;
    for (int i = 0; i < 24; ++i) appendValue<std::uint8_t>(data, std::uint8_t(i), false);
    writeFile(dir / "g.raw", data);
    // Axis 0 along +y, axis 1 along -x (given unnormalised), axis 2 along +z; ElementSize fallback.
    writeFile(dir / "g.mhd", "NDims = 3\nDimSize = 4 3 2\nElementSize = 0.7 0.8 3\n"
                             "Offset = -10.5 20 30.25\nTransformMatrix = 0 1 0 -2 0 0 0 0 1\n"
                             "AnatomicalOrientation = RAI\nElementType = MET_UCHAR\n"
                             "ElementDataFile = g.raw\n");
    Volume v = fvr::core::loadVolume(dir / "g.mhd");
    EXPECT_EQ(v.dims, (Dims3{4, 3, 2}));
    expectVec(v.spacing, {0.7, 0.8, 3.0}, 1e-12, "spacing");
    expectVec(v.origin, {-10.5, 20.0, 30.25}, 1e-12, "origin");
    expectVec(v.direction[0], {0, 1, 0}, 1e-12, "dir0");
    expectVec(v.direction[1], {-1, 0, 0}, 1e-12, "dir1");
    expectVec(v.direction[2], {0, 0, 1}, 1e-12, "dir2");
    EXPECT_EQ(v.at(3, 2, 1), 23.0f);
    EXPECT_EQ(v.at(1, 2, 0), 9.0f);

    // ElementSpacing wins over ElementSize; Origin and Orientation are accepted aliases.
    writeFile(dir / "h.mhd",
              "NDims = 3\nDimSize = 4 3 2\nElementSize = 9 9 9\nElementSpacing = 1 2 3\n"
              "Origin = 1 2 3\nOrientation = 1 0 0 0 0 1 0 -1 0\nElementType = MET_UCHAR\n"
              "ElementDataFile = g.raw\n");
    v = fvr::core::loadMetaImage(dir / "h.mhd");
    expectVec(v.spacing, {1, 2, 3}, 0.0, "spacing");
    expectVec(v.origin, {1, 2, 3}, 0.0, "origin");
    expectVec(v.direction[1], {0, 0, 1}, 0.0, "dir1");
    expectVec(v.direction[2], {0, -1, 0}, 0.0, "dir2");

    // NDims 2: one slice, with the 2D direction embedded.
    writeFile(dir / "s.raw", data.substr(0, 12));
    writeFile(dir / "s.mhd", "NDims = 2\nDimSize = 4 3\nElementSpacing = 0.5 0.25\n"
                             "Position = 5 6\nRotation = 0 1 1 0\nElementType = MET_UCHAR\n"
                             "ElementDataFile = s.raw\n");
    v = fvr::core::loadMetaImage(dir / "s.mhd");
    EXPECT_EQ(v.dims, (Dims3{4, 3, 1}));
    expectVec(v.spacing, {0.5, 0.25, 1.0}, 0.0, "spacing");
    expectVec(v.origin, {5, 6, 0}, 0.0, "origin");
    expectVec(v.direction[0], {0, 1, 0}, 0.0, "dir0");
    expectVec(v.direction[1], {1, 0, 0}, 0.0, "dir1");
    expectVec(v.direction[2], {0, 0, -1}, 0.0, "dir2 = dir0 x dir1");
    EXPECT_EQ(v.at(3, 2, 0), 11.0f);
}

TEST(VolumeIo, MetaImageLocalHeaderSizeAndCrlf) {
    const fs::path dir = caseDir("local");
    const std::vector<std::int16_t> values = rampInt16(24);
    std::string be, le;
    for (const auto v : values) {
        appendValue(be, v, true);
        appendValue(le, v, false);
    }
    // .mha, LOCAL, Windows line endings, big-endian data right after the header.
    writeFile(dir / "a.mha",
              "ObjectType = Image\r\nNDims = 3\r\nDimSize = 4 3 2\r\nElementType = MET_SHORT\r\n"
              "ElementByteOrderMSB = True\r\nElementDataFile = LOCAL\r\n" +
                  be);
    Volume v = fvr::core::loadVolume(dir / "a.mha");
    ASSERT_EQ(v.dims, (Dims3{4, 3, 2}));
    for (std::size_t i = 0; i < values.size(); ++i) EXPECT_EQ(v.voxels[i], float(values[i])) << i;
    EXPECT_EQ(v.name, "a");

    // .mha with HeaderSize = -1: the data is the last bytes of the file whatever precedes it.
    writeFile(dir / "b.mha",
              "NDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\nHeaderSize = -1\n"
              "ElementDataFile = LOCAL\n" +
                  std::string(13, 'x') + le);
    v = fvr::core::loadMetaImage(dir / "b.mha");
    for (std::size_t i = 0; i < values.size(); ++i) EXPECT_EQ(v.voxels[i], float(values[i])) << i;

    // External file with a 100-byte header to skip, and with HeaderSize = -1.
    writeFile(dir / "c.dat", std::string(100, '\x7f') + le);
    writeFile(dir / "c.mhd",
              "NDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\nHeaderSize = 100\n"
              "ElementDataFile = c.dat\n");
    v = fvr::core::loadMetaImage(dir / "c.mhd");
    for (std::size_t i = 0; i < values.size(); ++i) EXPECT_EQ(v.voxels[i], float(values[i])) << i;
    writeFile(dir / "d.mhd",
              "NDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\nHeaderSize = -1\n"
              "ElementDataFile = c.dat\n");
    v = fvr::core::loadMetaImage(dir / "d.mhd");
    for (std::size_t i = 0; i < values.size(); ++i) EXPECT_EQ(v.voxels[i], float(values[i])) << i;

    // Data file given by an absolute path.
    writeFile(dir / "e.raw", le);
    writeFile(dir / "e.mhd",
              "NDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\nElementDataFile = " +
                  (dir / "e.raw").string() + "\n");
    v = fvr::core::loadMetaImage(dir / "e.mhd");
    EXPECT_EQ(v.voxels[23], float(values[23]));
}

TEST(VolumeIo, MetaImageListAndPatternForms) {
    const fs::path dir = caseDir("multi");
    fs::create_directories(dir / "sl");
    const std::size_t nx = 5, ny = 4, nz = 3;
    std::vector<std::uint16_t> values(nx * ny * nz);
    for (std::size_t i = 0; i < values.size(); ++i) values[i] = std::uint16_t(1000 + i * 611);
    // One big-endian file per slice, numbered 0, 2, 4 with three digits.
    for (std::size_t z = 0; z < nz; ++z) {
        std::string slice;
        for (std::size_t i = 0; i < nx * ny; ++i) appendValue(slice, values[z * nx * ny + i], true);
        char name[32];
        std::snprintf(name, sizeof name, "img%03d.raw", int(2 * z));
        writeFile(dir / "sl" / name, slice);
    }
    writeFile(dir / "p.mhd",
              "NDims = 3\nDimSize = 5 4 3\nElementSpacing = 1 1 2.5\nElementType = MET_USHORT\n"
              "ElementByteOrderMSB = True\nElementDataFile = sl/img%03d.raw 0 4 2\n");
    Volume v = fvr::core::loadMetaImage(dir / "p.mhd");
    ASSERT_EQ(v.dims, (Dims3{5, 4, 3}));
    for (std::size_t i = 0; i < values.size(); ++i) EXPECT_EQ(v.voxels[i], float(values[i])) << i;

    // A descending pattern gives the slices in reverse.
    writeFile(dir / "r.mhd",
              "NDims = 3\nDimSize = 5 4 3\nElementType = MET_USHORT\n"
              "ElementByteOrderMSB = True\nElementDataFile = sl/img%03d.raw 4 0 -2\n");
    v = fvr::core::loadMetaImage(dir / "r.mhd");
    EXPECT_EQ(v.at(0, 0, 0), float(values[2 * nx * ny]));
    EXPECT_EQ(v.at(4, 3, 2), float(values[nx * ny - 1]));

    // LIST: file names after the header, one per line (blank lines ignored), relative to the
    // header.
    writeFile(dir / "l.mhd", "NDims = 3\nDimSize = 5 4 3\nElementType = MET_USHORT\n"
                             "ElementByteOrderMSB = True\nElementDataFile = LIST\n"
                             "sl/img000.raw\nsl/img002.raw\n\nsl/img004.raw\n");
    v = fvr::core::loadMetaImage(dir / "l.mhd");
    for (std::size_t i = 0; i < values.size(); ++i) EXPECT_EQ(v.voxels[i], float(values[i])) << i;

    // LIST 3D: each file a whole volume (here the only one).
    std::string all;
    for (const auto x : values) appendValue(all, x, false);
    writeFile(dir / "all.raw", all);
    writeFile(dir / "l3.mhd", "NDims = 3\nDimSize = 5 4 3\nElementType = MET_USHORT\n"
                              "ElementDataFile = LIST 3D\nall.raw\n");
    v = fvr::core::loadMetaImage(dir / "l3.mhd");
    for (std::size_t i = 0; i < values.size(); ++i) EXPECT_EQ(v.voxels[i], float(values[i])) << i;
}

TEST(VolumeIo, MetaImageCompressedData) {
    const fs::path dir = caseDir("compressed");
    const std::vector<std::int16_t> values = rampInt16(4 * 3 * 2);
    std::string le;
    for (const auto v : values) appendValue(le, v, false);
    const std::string z = zlibStored(le);
    writeFile(dir / "z.mha",
              "NDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\nCompressedData = True\n"
              "CompressedDataSize = " +
                  std::to_string(z.size()) + "\nElementDataFile = LOCAL\n" + z);
    Volume v = fvr::core::loadMetaImage(dir / "z.mha");
    for (std::size_t i = 0; i < values.size(); ++i) EXPECT_EQ(v.voxels[i], float(values[i])) << i;

    writeFile(dir / "z.zraw", gzipStored(le)); // gzip framing is accepted too
    writeFile(dir / "z.mhd",
              "NDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\nCompressedData = True\n"
              "ElementDataFile = z.zraw\n");
    v = fvr::core::loadMetaImage(dir / "z.mhd");
    for (std::size_t i = 0; i < values.size(); ++i) EXPECT_EQ(v.voxels[i], float(values[i])) << i;

    // Truncated compressed data: expected vs found after decompression.
    writeFile(dir / "t.zraw", z.substr(0, 20));
    writeFile(dir / "t.mhd",
              "NDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\nCompressedData = True\n"
              "ElementDataFile = t.zraw\n");
    const std::string m = loadErrorOf([&] { fvr::core::loadMetaImage(dir / "t.mhd"); });
    EXPECT_MESSAGE_HAS(m, "t.mhd");
    EXPECT_MESSAGE_HAS(m, "ElementDataFile");
    EXPECT_MESSAGE_HAS(m, "expected 48 bytes");

    // A tiny compressed file cannot claim gigabytes: rejected before allocating.
    writeFile(dir / "big.mhd", "NDims = 3\nDimSize = 2048 2048 1024\nElementType = MET_SHORT\n"
                               "CompressedData = True\nElementDataFile = t.zraw\n");
    const std::string mb = loadErrorOf([&] { fvr::core::loadMetaImage(dir / "big.mhd"); });
    EXPECT_MESSAGE_HAS(mb, "big.mhd");
    EXPECT_MESSAGE_HAS(mb, "CompressedData");
}

// ================================================================================================
// MetaImage, malformed

TEST(VolumeIo, MetaImageMalformedHeadersNameFileAndField) {
    const fs::path dir = caseDir("bad_mhd");
    writeFile(dir / "ok.raw", std::string(4 * 3 * 2 * 2, '\0'));
    writeFile(dir / "slice.raw", std::string(4 * 3 * 2, '\0'));
    struct Case {
        const char* name;
        std::string header;
        std::vector<std::string> parts;
    };
    const std::string tail = "ElementType = MET_SHORT\nElementDataFile = ok.raw\n";
    const std::vector<Case> cases = {
        {"no_dimsize", "NDims = 3\n" + tail, {"DimSize"}},
        {"dimsize0", "NDims = 3\nDimSize = 0 3 2\n" + tail, {"DimSize", "expected 1..16384"}},
        {"dimsize_neg", "NDims = 3\nDimSize = 4 -3 2\n" + tail, {"DimSize"}},
        {"dimsize_count", "NDims = 3\nDimSize = 4 3\n" + tail, {"DimSize", "expected 3 integers"}},
        {"dimsize_text", "NDims = 3\nDimSize = 4 three 2\n" + tail, {"DimSize", "three"}},
        {"dimsize_absurd",
         "NDims = 3\nDimSize = 100000 100000 100000\n" + tail,
         {"DimSize", "100000"}},
        {"dimsize_total",
         "NDims = 3\nDimSize = 16384 16384 16384\n" + tail,
         {"DimSize", "at most"}},
        {"dimsize_overflow", "NDims = 3\nDimSize = 99999999999999999999 1 1\n" + tail, {"DimSize"}},
        {"no_ndims", "DimSize = 4 3 2\n" + tail, {"NDims"}},
        {"ndims5", "NDims = 5\nDimSize = 4 3 2 1 1\n" + tail, {"NDims", "expected 1, 2 or 3"}},
        {"spacing0",
         "NDims = 3\nDimSize = 4 3 2\nElementSpacing = 1 0 1\n" + tail,
         {"ElementSpacing"}},
        {"spacing_nan",
         "NDims = 3\nDimSize = 4 3 2\nElementSpacing = 1 nan 1\n" + tail,
         {"ElementSpacing"}},
        {"elementsize_neg",
         "NDims = 3\nDimSize = 4 3 2\nElementSize = 1 1 -2\n" + tail,
         {"ElementSize"}},
        {"offset_short", "NDims = 3\nDimSize = 4 3 2\nOffset = 1 2\n" + tail, {"Offset"}},
        {"matrix_short",
         "NDims = 3\nDimSize = 4 3 2\nTransformMatrix = 1 0 0 0 1 0\n" + tail,
         {"TransformMatrix"}},
        {"matrix_zero",
         "NDims = 3\nDimSize = 4 3 2\nTransformMatrix = 1 0 0 0 0 0 0 0 1\n" + tail,
         {"TransformMatrix"}},
        {"bad_type",
         "NDims = 3\nDimSize = 4 3 2\nElementType = MET_FOO\nElementDataFile = ok.raw\n",
         {"ElementType", "MET_FOO"}},
        {"no_type", "NDims = 3\nDimSize = 4 3 2\nElementDataFile = ok.raw\n", {"ElementType"}},
        {"channels",
         "NDims = 3\nDimSize = 4 3 2\nElementNumberOfChannels = 3\n" + tail,
         {"ElementNumberOfChannels", "expected 1"}},
        {"byteorder",
         "NDims = 3\nDimSize = 4 3 2\nElementByteOrderMSB = maybe\n" + tail,
         {"ElementByteOrderMSB"}},
        {"ascii", "NDims = 3\nDimSize = 4 3 2\nBinaryData = False\n" + tail, {"BinaryData"}},
        {"compressed_bad",
         "NDims = 3\nDimSize = 4 3 2\nCompressedData = sometimes\n" + tail,
         {"CompressedData"}},
        {"headersize", "NDims = 3\nDimSize = 4 3 2\nHeaderSize = -7\n" + tail, {"HeaderSize"}},
        {"object", "ObjectType = Tube\nNDims = 3\nDimSize = 4 3 2\n" + tail, {"ObjectType"}},
        {"no_datafile",
         "NDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\n",
         {"ElementDataFile"}},
        {"no_equals", "NDims = 3\nDimSize 4 3 2\n" + tail, {"header", "Key = Value"}},
        {"missing_file",
         "NDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\nElementDataFile = nothere.raw\n",
         {"ElementDataFile", "nothere.raw", "no such file"}},
        {"too_short",
         "NDims = 3\nDimSize = 4 3 3\nElementType = MET_SHORT\nElementDataFile = ok.raw\n",
         {"ElementDataFile", "ok.raw", "expected 72 bytes", "found 48 bytes"}},
        {"too_long",
         "NDims = 3\nDimSize = 4 3 1\nElementType = MET_SHORT\nElementDataFile = ok.raw\n",
         {"ElementDataFile", "expected 24 bytes", "found 48 bytes"}},
        {"too_short_minus1",
         "NDims = 3\nDimSize = 4 3 3\nElementType = MET_SHORT\nHeaderSize = -1\nElementDataFile = "
         "ok.raw\n",
         {"ElementDataFile", "expected at least 72 bytes", "found 48 bytes"}},
        {"local_short",
         "NDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\nElementDataFile = LOCAL\n" +
             std::string(47, 'x'),
         {"ElementDataFile", "LOCAL", "expected 48", "found 47"}},
        {"list_short",
         "NDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\nElementDataFile = LIST\nslice.raw\n",
         {"ElementDataFile", "LIST", "expected 2 file names", "found 1"}},
        {"list_size",
         "NDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\nElementDataFile = "
         "LIST\nslice.raw\nok.raw\n",
         {"ElementDataFile", "ok.raw", "expected 24 bytes", "found 48 bytes"}},
        {"list_bad",
         "NDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\nElementDataFile = LIST x\nok.raw\n",
         {"ElementDataFile", "LIST"}},
        {"pattern_count",
         "NDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\nElementDataFile = s%d.raw 1 5 1\n",
         {"ElementDataFile", "expected 2 files", "giving 5"}},
        {"pattern_step0",
         "NDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\nElementDataFile = s%d.raw 1 2 0\n",
         {"ElementDataFile", "step"}},
        {"pattern_format",
         "NDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\nElementDataFile = s%s%n.raw 1 2 1\n",
         {"ElementDataFile", "%d"}},
        {"pattern_missing",
         "NDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\nElementDataFile = s%d.raw 1 2 1\n",
         {"ElementDataFile", "s1.raw", "no such file"}},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.name);
        const fs::path p = dir / (std::string(c.name) + ".mhd");
        writeFile(p, c.header);
        const std::string m = loadErrorOf([&] { fvr::core::loadMetaImage(p); });
        EXPECT_MESSAGE_HAS(m, p.string());
        for (const std::string& part : c.parts) EXPECT_MESSAGE_HAS(m, part);
    }

    // A binary file with an .mhd name, an empty file, a directory and a missing header.
    std::string garbage(200000, '\0');
    std::mt19937 rng(7);
    for (char& ch : garbage) ch = char(rng());
    writeFile(dir / "garbage.mhd", garbage);
    EXPECT_MESSAGE_HAS(loadErrorOf([&] { fvr::core::loadVolume(dir / "garbage.mhd"); }),
                       "garbage.mhd");
    writeFile(dir / "empty.mhd", "");
    EXPECT_MESSAGE_HAS(loadErrorOf([&] { fvr::core::loadVolume(dir / "empty.mhd"); }),
                       "ElementDataFile");
    fs::create_directories(dir / "folder.mhd");
    EXPECT_MESSAGE_HAS(loadErrorOf([&] { fvr::core::loadVolume(dir / "folder.mhd"); }),
                       "not a regular file");
    EXPECT_MESSAGE_HAS(loadErrorOf([&] { fvr::core::loadVolume(dir / "absent.mhd"); }),
                       "no such file");
}

// ================================================================================================
// NIfTI, synthetic

TEST(VolumeIo, NiftiScalingPlainAndGzip) {
    const fs::path dir = caseDir("nifti_scl");
    NiftiSpec s;
    s.slope = 0.5f;
    s.inter = -10.0f;
    s.pixdim = {1, 0.75f, 1.25f, 2.5f, 1, 1, 1, 1};
    const std::vector<std::int16_t> values = rampInt16(24);
    const std::string file = niftiFile(s, values);
    writeFile(dir / "scl.nii", file);
    writeFile(dir / "scl.nii.gz", gzipStored(file));
    for (const char* name : {"scl.nii", "scl.nii.gz"}) {
        SCOPED_TRACE(name);
        const Volume v = fvr::core::loadVolume(dir / name);
        ASSERT_EQ(v.dims, (Dims3{4, 3, 2}));
        expectVec(v.spacing, {0.75, 1.25, 2.5}, 1e-7, "spacing");
        for (std::size_t i = 0; i < values.size(); ++i)
            EXPECT_EQ(v.voxels[i], float(values[i] * 0.5 - 10.0)) << i;
        EXPECT_EQ(v.name, "scl");
        // No orientation codes: identity, origin 0.
        expectVec(v.direction[0], {1, 0, 0}, 0, "dir0");
        expectVec(v.origin, {0, 0, 0}, 0, "origin");
    }
    // Slope 0 and a non-finite slope both mean "no scaling".
    for (const float slope :
         {0.0f, std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
        s.slope = slope;
        writeFile(dir / "noscl.nii", niftiFile(s, values));
        const Volume v = fvr::core::loadNifti(dir / "noscl.nii");
        for (std::size_t i = 0; i < values.size(); ++i)
            EXPECT_EQ(v.voxels[i], float(values[i])) << i;
    }
    // Scaling applies to float data too, and an extension block before vox_offset is skipped.
    s.datatype = 16;
    s.bitpix = 32;
    s.slope = 2.0f;
    s.inter = 1.0f;
    s.voxOffset = 352 + 64;
    const std::vector<float> fv{0.25f, -3.5f, 1e6f, 0.0f, 1.0f, 2.0f,  3.0f, 4.0f,
                                5.0f,  6.0f,  7.0f, 8.0f, 9.0f, 10.0f, 11.f, 12.f,
                                13.f,  14.f,  15.f, 16.f, 17.f, 18.f,  19.f, 20.f};
    writeFile(dir / "f.nii.gz", gzipStored(niftiFile(s, fv)));
    const Volume v = fvr::core::loadNifti(dir / "f.nii.gz");
    for (std::size_t i = 0; i < fv.size(); ++i) EXPECT_EQ(v.voxels[i], fv[i] * 2.0f + 1.0f) << i;
}

TEST(VolumeIo, NiftiEveryDatatypeAndBigEndianHeader) {
    const fs::path dir = caseDir("nifti_types");
    const auto check = [&](auto tag, std::int16_t code, bool bigEndian) {
        using T = decltype(tag);
        NiftiSpec s;
        s.dim = {3, 3, 2, 2, 1, 1, 1, 1};
        s.datatype = code;
        s.bitpix = std::int16_t(8 * sizeof(T));
        s.bigEndian = bigEndian;
        const std::vector<T> values = sampleValues<T>();
        const std::string name = "t" + std::to_string(code) + (bigEndian ? "_be" : "_le") + ".nii";
        writeFile(dir / name, niftiFile(s, values));
        const Volume v = fvr::core::loadNifti(dir / name);
        ASSERT_EQ(v.dims, (Dims3{3, 2, 2})) << name;
        for (std::size_t i = 0; i < values.size(); ++i)
            EXPECT_EQ(v.voxels[i], expectedFloat(values[i])) << name << " voxel " << i;
    };
    for (const bool be : {false, true}) {
        check(std::uint8_t{}, 2, be);
        check(std::int16_t{}, 4, be);
        check(std::int32_t{}, 8, be);
        check(float{}, 16, be);
        check(double{}, 64, be);
        check(std::int8_t{}, 256, be);
        check(std::uint16_t{}, 512, be);
        check(std::uint32_t{}, 768, be);
        check(std::int64_t{}, 1024, be);
        check(std::uint64_t{}, 1280, be);
    }
}

TEST(VolumeIo, NiftiOrientationSformQformUnitsAndDims) {
    const fs::path dir = caseDir("nifti_geom");
    const std::vector<std::int16_t> values = rampInt16(24);
    const double h = std::sqrt(0.5);

    // sform (RAS) diag(2, 3, 4) + (10, 20, 30) -> LPS: x and y rows negated.
    NiftiSpec s;
    s.pixdim = {1, 2, 3, 4, 1, 1, 1, 1};
    s.sformCode = 1;
    s.srow[0][0] = 2;
    s.srow[1][1] = 3;
    s.srow[2][2] = 4;
    s.srow[0][3] = 10;
    s.srow[1][3] = 20;
    s.srow[2][3] = 30;
    // A different qform that must lose to the sform.
    s.qformCode = 1;
    s.quatern = {0, 0, float(h), -1, -2, -3};
    writeFile(dir / "sform.nii", niftiFile(s, values));
    Volume v = fvr::core::loadNifti(dir / "sform.nii");
    expectVec(v.spacing, {2, 3, 4}, 0, "spacing");
    expectVec(v.direction[0], {-1, 0, 0}, 1e-12, "dir0");
    expectVec(v.direction[1], {0, -1, 0}, 1e-12, "dir1");
    expectVec(v.direction[2], {0, 0, 1}, 1e-12, "dir2");
    expectVec(v.origin, {-10, -20, 30}, 1e-12, "origin");

    // qform only: 90 degrees about z (a = d = sqrt(1/2)); RAS columns i -> +y, j -> -x, k -> +z.
    s.sformCode = 0;
    writeFile(dir / "qform.nii", niftiFile(s, values));
    v = fvr::core::loadNifti(dir / "qform.nii");
    expectVec(v.direction[0], {0, -1, 0}, 1e-6, "dir0");
    expectVec(v.direction[1], {1, 0, 0}, 1e-6, "dir1");
    expectVec(v.direction[2], {0, 0, 1}, 1e-6, "dir2");
    expectVec(v.origin, {1, 2, -3}, 1e-6, "origin");
    // qfac = pixdim[0] = -1 flips the third axis.
    s.pixdim[0] = -1;
    writeFile(dir / "qfac.nii", niftiFile(s, values));
    v = fvr::core::loadNifti(dir / "qfac.nii");
    expectVec(v.direction[2], {0, 0, -1}, 1e-6, "dir2");
    s.pixdim[0] = 1;

    // Units: meters and micrometres are converted to mm (spacing and origin).
    s.xyztUnits = 1 | 8; // meters, seconds
    s.pixdim = {1, 0.002f, 0.003f, 0.004f, 1, 1, 1, 1};
    s.quatern = {0, 0, 0, 0.01f, 0.02f, 0.03f};
    writeFile(dir / "meters.nii", niftiFile(s, values));
    v = fvr::core::loadNifti(dir / "meters.nii");
    expectVec(v.spacing, {2, 3, 4}, 1e-5, "spacing");
    expectVec(v.origin, {-10, -20, 30}, 1e-4, "origin");
    expectVec(v.direction[0], {-1, 0, 0}, 1e-12, "dir0");
    s.xyztUnits = 3; // micrometres
    s.pixdim = {1, 500, 250, 125, 1, 1, 1, 1};
    writeFile(dir / "microns.nii", niftiFile(s, values));
    v = fvr::core::loadNifti(dir / "microns.nii");
    expectVec(v.spacing, {0.5, 0.25, 0.125}, 1e-9, "spacing");

    // dim[0] = 4 with one time point, and dim[0] = 2 (a single slice, pixdim[3] unused).
    NiftiSpec t;
    t.dim = {4, 4, 3, 2, 1, 1, 1, 1};
    writeFile(dir / "dim4.nii", niftiFile(t, values));
    EXPECT_EQ(fvr::core::loadNifti(dir / "dim4.nii").dims, (Dims3{4, 3, 2}));
    t.dim = {2, 4, 3, 7, 1, 1, 1, 1};
    t.pixdim = {1, 1, 1, 0, 0, 0, 0, 0};
    writeFile(dir / "dim2.nii",
              niftiFile(t, std::vector<std::int16_t>(values.begin(), values.begin() + 12)));
    v = fvr::core::loadNifti(dir / "dim2.nii");
    EXPECT_EQ(v.dims, (Dims3{4, 3, 1}));
    EXPECT_EQ(v.spacing[2], 1.0);
    EXPECT_EQ(v.at(3, 2, 0), float(values[11]));
}

// ================================================================================================
// NIfTI, malformed

TEST(VolumeIo, NiftiMalformedNameFileAndField) {
    const fs::path dir = caseDir("bad_nifti");
    const std::vector<std::int16_t> values = rampInt16(24);
    const auto expectError = [&](const std::string& name, const std::string& bytes,
                                 const std::vector<std::string>& parts) {
        SCOPED_TRACE(name);
        writeFile(dir / name, bytes);
        const std::string m = loadErrorOf([&] { fvr::core::loadVolume(dir / name); });
        EXPECT_MESSAGE_HAS(m, (dir / name).string());
        for (const std::string& part : parts) EXPECT_MESSAGE_HAS(m, part);
    };
    NiftiSpec s;
    s.sizeofHdr = 123;
    expectError("sizeof.nii", niftiFile(s, values), {"sizeof_hdr", "is 123", "expected 348"});
    expectError("sizeof.nii.gz", gzipStored(niftiFile(s, values)), {"sizeof_hdr", "is 123"});
    s.sizeofHdr = 540;
    expectError("nifti2.nii", niftiFile(s, values), {"sizeof_hdr", "NIfTI-2"});
    s = NiftiSpec{};
    s.datatype = 128;
    expectError("rgb.nii", niftiFile(s, values), {"datatype", "128", "RGB24"});
    s.datatype = 32;
    expectError("complex.nii.gz", gzipStored(niftiFile(s, values)), {"datatype", "32"});
    s.datatype = 9999;
    expectError("dt9999.nii", niftiFile(s, values), {"datatype", "9999"});
    s = NiftiSpec{};
    s.magic = std::string("ni1\0", 4);
    expectError("pair.nii", niftiFile(s, values), {"magic", "ni1"});
    s.magic = "abcd";
    expectError("magic.nii", niftiFile(s, values), {"magic", "n+1"});
    s = NiftiSpec{};
    s.dim = {4, 4, 3, 2, 5, 1, 1, 1};
    expectError("4d.nii", niftiFile(s, values), {"dim[4]", "expected 1", "found 5"});
    s.dim = {1, 24, 1, 1, 1, 1, 1, 1};
    expectError("1d.nii", niftiFile(s, values), {"dim[0]"});
    s.dim = {3, 4, 0, 2, 1, 1, 1, 1};
    expectError("dim0.nii", niftiFile(s, values), {"dim[2]", "found 0"});
    s.dim = {3, 4, -3, 2, 1, 1, 1, 1};
    expectError("dimneg.nii", niftiFile(s, values), {"dim[2]", "found -3"});
    s.dim = {3, 16000, 16000, 16000, 1, 1, 1, 1}; // 4e12 voxels: rejected before allocation
    expectError("huge.nii", niftiFile(s, values), {"dimensions", "at most"});
    s.dim = {3, 2000, 2000, 1000, 1, 1, 1, 1}; // 8 GB claimed by a 500-byte file
    expectError("huge.nii.gz", gzipStored(niftiFile(s, values)),
                {"data", "expected 8000000352 bytes", "cannot hold"});
    expectError("huge_plain.nii", niftiFile(s, values),
                {"data", "expected 8000000352 bytes", "found 400 bytes"});
    s = NiftiSpec{};
    s.pixdim = {1, 1, 0, 1, 1, 1, 1, 1};
    expectError("pixdim.nii", niftiFile(s, values), {"pixdim[2]"});
    s.pixdim = {1, 1, std::numeric_limits<float>::infinity(), 1, 1, 1, 1, 1};
    expectError("pixdim_inf.nii", niftiFile(s, values), {"pixdim[2]"});
    s = NiftiSpec{};
    s.voxOffset = 0;
    {
        std::string f = niftiHeader(s);
        for (const auto x : values) appendValue(f, x, false);
        expectError("voxoffset.nii", f, {"vox_offset", "352"});
    }

    // Truncated data, plain and gzip: the message gives expected and found byte counts.
    s = NiftiSpec{};
    const std::string full = niftiFile(s, values); // 352 + 48 bytes
    expectError("short.nii", full.substr(0, 380),
                {"data", "expected 400 bytes", "found 380 bytes"});
    const std::string gz = gzipStored(full);
    expectError("cut.nii.gz", gz.substr(0, gz.size() - 30),
                {"data", "expected 400 bytes", "found 378 bytes"});
    expectError("cut_header.nii.gz", gz.substr(0, 200), {"header", "expected 348 bytes"});
    expectError("cut_trailer.nii.gz", gz.substr(0, gz.size() - 4), {"gzip"});
    std::string badCrc = gz;
    badCrc[badCrc.size() - 6] ^= 0x55;
    expectError("crc.nii.gz", badCrc, {"gzip"});
    expectError("empty.nii", "", {"sizeof_hdr", "found a file of 0 bytes"});
    expectError("tiny.nii.gz", gzipStored("abc"), {"sizeof_hdr"});
}

TEST(VolumeIo, TextFilesNamedAsVolumesSayWhatIsWrong) {
    const fs::path dir = caseDir("text_as_volume");
    const std::string text = "hello world, this is not a volume\nsecond line\n";
    const auto errorOf = [&](const std::string& name, const std::string& bytes) {
        writeFile(dir / name, bytes);
        return loadErrorOf([&] { fvr::core::loadVolume(dir / name); });
    };
    // .nii.gz that is not gzip at all.
    std::string m = errorOf("text.nii.gz", text);
    EXPECT_MESSAGE_HAS(m, (dir / "text.nii.gz").string() +
                              ": not gzip-compressed data (a .nii.gz file must be gzip)");
    // .nii (and gzip data inside .nii.gz) whose header size field is no NIfTI's: "hell" read as
    // a little-endian int32 is 0x6c6c6568 = 1819043176.
    for (const std::string name : {"text.nii", "gz_text.nii.gz"}) {
        SCOPED_TRACE(name);
        m = errorOf(name, name == "text.nii" ? text : gzipStored(text));
        EXPECT_MESSAGE_HAS(m, (dir / name).string() + ": not a NIfTI file");
        EXPECT_MESSAGE_HAS(m, "header size field (sizeof_hdr) is 1819043176, expected 348 for "
                              "NIfTI-1 or 540 for NIfTI-2");
        EXPECT_MESSAGE_HAS(m, "it starts with text: 'hello world");
    }
    // NIfTI-2: said explicitly to be unsupported.
    NiftiSpec s;
    s.sizeofHdr = 540;
    m = errorOf("two.nii", niftiFile(s, rampInt16(24)));
    EXPECT_MESSAGE_HAS(m, (dir / "two.nii").string() + ": a NIfTI-2 file (header size 540)");
    EXPECT_MESSAGE_HAS(m, "NIfTI-2 is not supported");
    // A valid NIfTI-1 file that is not compressed but named .nii.gz still loads.
    writeFile(dir / "plain.nii.gz", niftiFile(NiftiSpec{}, rampInt16(24)));
    EXPECT_EQ(fvr::core::loadVolume(dir / "plain.nii.gz").dims, (Dims3{4, 3, 2}));
    // MetaImage: text that is no header at all.
    for (const std::string name : {"text.mhd", "text.mha"}) {
        SCOPED_TRACE(name);
        m = errorOf(name, text);
        EXPECT_MESSAGE_HAS(m, (dir / name).string() + ": not a MetaImage file");
        EXPECT_MESSAGE_HAS(m, "'Key = Value' lines");
        EXPECT_MESSAGE_HAS(m, "'hello world, this is not a volume'");
    }
}

TEST(VolumeIo, NiftiTruncatedRealGzip) {
    FVR_REQUIRE_DATA("volumes/body_ct_hu_3mm/example_ct.nii.gz");
    const fs::path dir = caseDir("nifti_truncated_real");
    const std::string full =
        readFile(fvr::test::sharedData() / "volumes/body_ct_hu_3mm/example_ct.nii.gz");
    ASSERT_GT(full.size(), 1000000u);
    writeFile(dir / "cut.nii.gz", full.substr(0, full.size() / 2));
    const std::string m = loadErrorOf([&] { fvr::core::loadVolume(dir / "cut.nii.gz"); });
    EXPECT_MESSAGE_HAS(m, "cut.nii.gz");
    EXPECT_MESSAGE_HAS(m, "data");
    EXPECT_MESSAGE_HAS(m, "expected 5520608 bytes"); // 352 + 122*101*112 * 4 (int32)
    EXPECT_MESSAGE_HAS(m, "found ");
}

// ================================================================================================
// Raw and dispatch

TEST(VolumeIo, RawLoaderChecksLengthExactly) {
    const fs::path dir = caseDir("raw");
    std::string data(16, 'h');
    const std::vector<std::int16_t> values = rampInt16(24);
    for (const auto v : values) appendValue(data, v, true);
    writeFile(dir / "vol.bin", data);
    fvr::core::RawSpec spec;
    spec.dims = {4, 3, 2};
    spec.spacing = {0.5, 0.5, 1.5};
    spec.type = ElementType::Int16;
    spec.bigEndian = true;
    spec.headerBytes = 16;
    const Volume v = fvr::core::loadRaw(dir / "vol.bin", spec);
    EXPECT_EQ(v.dims, (Dims3{4, 3, 2}));
    expectVec(v.spacing, {0.5, 0.5, 1.5}, 0, "spacing");
    for (std::size_t i = 0; i < values.size(); ++i) EXPECT_EQ(v.voxels[i], float(values[i])) << i;
    EXPECT_EQ(v.name, "vol");

    spec.headerBytes = 0;
    std::string m = loadErrorOf([&] { fvr::core::loadRaw(dir / "vol.bin", spec); });
    EXPECT_MESSAGE_HAS(m, "vol.bin");
    EXPECT_MESSAGE_HAS(m, "file size");
    EXPECT_MESSAGE_HAS(m, "expected 48 bytes");
    EXPECT_MESSAGE_HAS(m, "found 64 bytes");
    spec.headerBytes = 20;
    m = loadErrorOf([&] { fvr::core::loadRaw(dir / "vol.bin", spec); });
    EXPECT_MESSAGE_HAS(m, "expected 68 bytes");
    spec.headerBytes = std::numeric_limits<std::uint64_t>::max() - 5;
    m = loadErrorOf([&] { fvr::core::loadRaw(dir / "vol.bin", spec); });
    EXPECT_MESSAGE_HAS(m, "file size");
    spec.headerBytes = 16;
    spec.dims = {4, 3, 0};
    m = loadErrorOf([&] { fvr::core::loadRaw(dir / "vol.bin", spec); });
    EXPECT_MESSAGE_HAS(m, "dimensions");
    spec.dims = {4, 3, 2};
    spec.spacing = {1, 1, 0};
    m = loadErrorOf([&] { fvr::core::loadRaw(dir / "vol.bin", spec); });
    EXPECT_MESSAGE_HAS(m, "spacing");
    spec.spacing = {1, 1, 1};
    m = loadErrorOf([&] { fvr::core::loadRaw(dir / "nothing.bin", spec); });
    EXPECT_MESSAGE_HAS(m, "nothing.bin");
}

TEST(VolumeIo, LoadVolumeDispatchesByExtension) {
    const fs::path dir = caseDir("dispatch");
    const std::vector<std::int16_t> values = rampInt16(24);
    const std::string nii = niftiFile(NiftiSpec{}, values);
    writeFile(dir / "UPPER.NII.GZ", gzipStored(nii));
    writeFile(dir / "Mixed.Nii", nii);
    writeFile(dir / "UPPER.MHA", smallMha());
    EXPECT_EQ(fvr::core::loadVolume(dir / "UPPER.NII.GZ").dims, (Dims3{4, 3, 2}));
    EXPECT_EQ(fvr::core::loadVolume(dir / "UPPER.NII.GZ").name, "UPPER");
    EXPECT_EQ(fvr::core::loadVolume(dir / "Mixed.Nii").voxels[5], float(values[5]));
    EXPECT_EQ(fvr::core::loadVolume(dir / "UPPER.MHA").voxels[23], float(values[23]));
    writeFile(dir / "volume.vti", "whatever");
    const std::string m = loadErrorOf([&] { fvr::core::loadVolume(dir / "volume.vti"); });
    EXPECT_MESSAGE_HAS(m, "volume.vti");
    EXPECT_MESSAGE_HAS(m, "unknown volume format");
    EXPECT_MESSAGE_HAS(m, ".vti");
    EXPECT_MESSAGE_HAS(loadErrorOf([&] { fvr::core::loadVolume(dir / "noext"); }),
                       "unknown volume format");
}

// Every corrupted or truncated variant of a valid file either loads or throws an InputError;
// under the sanitizers this also shows that no garbage header reads out of bounds.
TEST(VolumeIo, CorruptedHeadersNeverCrash) {
    const fs::path dir = caseDir("fuzz");
    const std::string mha = smallMha();
    const std::string nii = niftiFile(NiftiSpec{}, rampInt16(24));
    std::mt19937 rng(12345);
    int loaded = 0, rejected = 0;
    const auto attempt = [&](const fs::path& p, const std::string& bytes) {
        writeFile(p, bytes);
        try {
            const Volume v = fvr::core::loadVolume(p);
            EXPECT_EQ(std::size_t(v.voxelCount()), v.voxels.size());
            ++loaded;
        } catch (const fvr::core::InputError&) {
            ++rejected;
        } catch (const std::exception& e) {
            ADD_FAILURE() << p << ": unexpected exception " << e.what();
        }
    };
    const std::size_t mhaHeader = mha.size() - 48;
    for (int it = 0; it < 400; ++it) {
        std::string m = mha;
        const int flips = 1 + int(rng() % 4);
        for (int k = 0; k < flips; ++k) m[rng() % mhaHeader] = char(rng());
        attempt(dir / "f.mha", m);
        std::string n = nii;
        for (int k = 0; k < flips; ++k) n[rng() % 352] = char(rng());
        attempt(dir / "f.nii", n);
        attempt(dir / "f.nii.gz", gzipStored(n));
    }
    for (std::size_t len = 0; len < nii.size(); len += 7)
        attempt(dir / "t.nii", nii.substr(0, len));
    for (std::size_t len = 0; len < mha.size(); len += 5)
        attempt(dir / "t.mha", mha.substr(0, len));
    EXPECT_GT(loaded, 0);
    EXPECT_GT(rejected, 0);
}

// ================================================================================================
// Shared data sets. Expected values were computed independently from the files with a Python
// script (standard library: struct, gzip): dims and spacing from the headers, min/max/sum over
// all voxels and a few voxels at given (x, y, z) with x fastest.

namespace {

struct Probe {
    int x, y, z;
    float value;
};

struct SharedCase {
    const char* path;
    Dims3 dims;
    Vec3 spacing;
    float min, max;
    double sum;
    std::vector<Probe> probes;
};

void checkShared(const SharedCase& c) {
    SCOPED_TRACE(c.path);
    const Volume v = fvr::core::loadVolume(fvr::test::sharedData() / c.path);
    ASSERT_EQ(v.dims, c.dims);
    expectVec(v.spacing, c.spacing, 1e-6, "spacing");
    ASSERT_EQ(v.voxels.size(), std::size_t(c.dims[0] * c.dims[1] * c.dims[2]));
    const auto [lo, hi] = v.valueRange();
    EXPECT_FLOAT_EQ(lo, c.min);
    EXPECT_FLOAT_EQ(hi, c.max);
    EXPECT_NEAR(voxelSum(v), c.sum, std::abs(c.sum) * 1e-9 + 1e-3);
    for (const Probe& p : c.probes)
        EXPECT_FLOAT_EQ(v.at(p.x, p.y, p.z), p.value)
            << "(" << p.x << ", " << p.y << ", " << p.z << ")";
    EXPECT_EQ(v.units, fvr::core::ValueUnits::Unknown);
    EXPECT_FALSE(v.name.empty());
}

} // namespace

TEST(VolumeIo, SharedMetaImageVolumes) {
    FVR_REQUIRE_DATA("volumes/headsq/headsq.mhd");
    const std::vector<SharedCase> cases = {
        {"volumes/headsq/headsq.mhd",
         {64, 64, 93},
         {3.2, 3.2, 1.5},
         0,
         3926,
         193392317.0,
         {{0, 0, 0, 0}, {32, 32, 46, 669}, {21, 16, 18, 1092}, {32, 21, 46, 1070}}},
        {"volumes/lidc2_lung_ct/LIDC2.mhd",
         {256, 256, 133},
         {1.40625, 1.40625, 2.5},
         0,
         255,
         61489178.0,
         {{128, 128, 66, 128}, {85, 64, 26, 16}, {128, 85, 66, 92}}},
        {"volumes/mr_head_mhd/HeadMRVolume.mhd",
         {48, 62, 42},
         {4, 4, 4},
         0,
         255,
         3058332.0,
         {{0, 0, 0, 1}, {24, 31, 21, 79}, {16, 15, 8, 45}, {24, 20, 21, 89}}},
        {"volumes/brain_pd_3slices_mha/BrainProtonDensity3Slices.mha",
         {181, 217, 3},
         {1, 1, 1},
         0,
         250,
         14725708.0,
         {{0, 0, 0, 7}, {90, 108, 1, 228}, {180, 216, 2, 1}, {60, 54, 0, 159}}},
    };
    for (const SharedCase& c : cases) checkShared(c);
}

TEST(VolumeIo, SharedStanfordCtHeadFromPatternOf113BigEndianFiles) {
    FVR_REQUIRE_DATA("volumes/stanford_cthead_256x256x113/CThead.mhd");
    checkShared({"volumes/stanford_cthead_256x256x113/CThead.mhd",
                 {256, 256, 113},
                 {1, 1, 2},
                 0,
                 3272,
                 2810724494.0,
                 {{0, 0, 0, 25},
                  {128, 128, 56, 2322},
                  {255, 255, 112, 25},
                  {85, 64, 22, 1043},
                  {128, 85, 56, 81}}});
}

TEST(VolumeIo, SharedNiftiVolumes) {
    FVR_REQUIRE_DATA("volumes/bonsai_256/bonsai.nii.gz");
    const float avmSlope = 2.208627462387085f; // scl_slope of AVM.nii.gz (uint8 data)
    const std::vector<SharedCase> cases = {
        {"volumes/bonsai_256/bonsai.nii.gz",
         {256, 256, 256},
         {1, 1, 1},
         0,
         255,
         225901147.0,
         {{0, 0, 0, 40}, {128, 128, 128, 69}, {85, 64, 51, 49}, {128, 85, 128, 5}}},
        {"volumes/engine_256x256x128/engine.nii.gz",
         {256, 256, 128},
         {1, 1, 1},
         0,
         255,
         173590544.0,
         {{128, 128, 64, 136}, {85, 64, 25, 145}}},
        {"volumes/avm_cta/AVM.nii.gz",
         {337, 319, 154},
         {0.5469, 0.5469, 1.0},
         0,
         255 * avmSlope,
         83847168.89089203,
         {{1, 160, 77, 49 * avmSlope}, {92, 149, 7, 255 * avmSlope}, {0, 0, 0, 0}}},
        {"volumes/ct_pitch_nifti/CT_pitch.nii.gz",
         {175, 248, 58},
         {0.8125, 0.8125, 2.3970494270324707},
         0,
         255,
         95678796.0,
         {{87, 124, 29, 156}, {0, 0, 0, 0}}},
        {"volumes/fuel_nifti/fuel.nii.gz",
         {64, 33, 32},
         {1, 1, 1},
         0,
         255,
         509815.0,
         {{32, 16, 16, 189}, {32, 11, 16, 10}}},
    };
    for (const SharedCase& c : cases) checkShared(c);

    // AVM: the scale factor is applied (uint8 0..255 -> 0..563.2); sform identity RAS -> LPS.
    const Volume avm =
        fvr::core::loadVolume(fvr::test::sharedData() / "volumes/avm_cta/AVM.nii.gz");
    EXPECT_NEAR(avm.valueRange().second, 563.2, 1e-3);
    expectVec(avm.direction[0], {-1, 0, 0}, 1e-12, "AVM dir0");
    expectVec(avm.direction[1], {0, -1, 0}, 1e-12, "AVM dir1");
    expectVec(avm.direction[2], {0, 0, 1}, 1e-12, "AVM dir2");
    expectVec(avm.origin, {73.39768981933594, 69.69419860839844, -64.11000061035156}, 1e-9,
              "AVM origin");

    // CT_pitch: a gantry-tilted CT whose sform (and qform, a rotation of -16.5 degrees about x)
    // tilts the slice axis; the in-plane row axis leans accordingly. sform in RAS: column 1 =
    // (0, 0.779041, -0.230762), column 2 = (0, 0.680799, 2.298338).
    const Volume pitch =
        fvr::core::loadVolume(fvr::test::sharedData() / "volumes/ct_pitch_nifti/CT_pitch.nii.gz");
    expectVec(pitch.direction[0], {-1, 0, 0}, 1e-6, "pitch dir0");
    expectVec(pitch.direction[1], {0, -0.779041051864624 / 0.8125, -0.23076248168945312 / 0.8125},
              1e-5, "pitch dir1");
    expectVec(
        pitch.direction[2],
        {0, -0.6807987689971924 / 2.3970494270324707, 2.2983384132385254 / 2.3970494270324707},
        1e-5, "pitch dir2");
    expectVec(pitch.origin, {69.02075958251953, 134.38560485839844, -13.56882095336914}, 1e-9,
              "pitch origin");
}

TEST(VolumeIo, SharedBodyCtMetaImageAndNiftiAgree) {
    FVR_REQUIRE_DATA("volumes/body_ct_hu_3mm/example_ct.mhd");
    FVR_REQUIRE_DATA("volumes/body_ct_hu_3mm/example_ct.nii.gz");
    const fs::path base = fvr::test::sharedData() / "volumes/body_ct_hu_3mm";
    const std::vector<Probe> probes = {{0, 0, 0, -1023},
                                       {61, 50, 56, 164},
                                       {121, 100, 111, -997},
                                       {40, 25, 22, 34},
                                       {61, 33, 56, 7}};
    // The .mhd/.raw (int16) and the .nii.gz (int32, sform_code 2) hold the same HU values.
    checkShared({"volumes/body_ct_hu_3mm/example_ct.mhd",
                 {122, 101, 112},
                 {3, 3, 3},
                 -1207,
                 3382,
                 -496851173.0,
                 probes});
    checkShared({"volumes/body_ct_hu_3mm/example_ct.nii.gz",
                 {122, 101, 112},
                 {3, 3, 3},
                 -1207,
                 3382,
                 -496851173.0,
                 probes});
    const Volume mhd = fvr::core::loadVolume(base / "example_ct.mhd");
    const Volume nii = fvr::core::loadVolume(base / "example_ct.nii.gz");
    // Voxel for voxel in the same index order: no axis flip between the two files. The derived
    // .mhd carries no Offset/TransformMatrix (identity, origin 0) while the NIfTI sform is
    // diag(3, 3, 3) in RAS, i.e. LPS axes (-x, -y, +z): same voxels, different stated orientation.
    ASSERT_EQ(mhd.voxels.size(), nii.voxels.size());
    std::size_t mismatches = 0;
    for (std::size_t i = 0; i < mhd.voxels.size(); ++i)
        mismatches += mhd.voxels[i] != nii.voxels[i];
    EXPECT_EQ(mismatches, 0u);
    expectVec(mhd.direction[0], {1, 0, 0}, 0, "mhd dir0");
    expectVec(mhd.origin, {0, 0, 0}, 0, "mhd origin");
    expectVec(nii.direction[0], {-1, 0, 0}, 1e-12, "nii dir0");
    expectVec(nii.direction[1], {0, -1, 0}, 1e-12, "nii dir1");
    expectVec(nii.direction[2], {0, 0, 1}, 1e-12, "nii dir2");
    expectVec(nii.origin, {177.95632934570312, -11.319000244140625, 94.3017578125}, 1e-9,
              "nii origin");
    // Plausible body CT in HU: air near -1024, bone above 1000.
    EXPECT_LT(nii.valueRange().first, -1000.0f);
    EXPECT_GT(nii.valueRange().second, 1000.0f);
}
