// Tests of the MetaImage loader (.mhd, .mha): synthetic files of every element type and
// layout (LOCAL, external, LIST, pattern, compressed), and malformed headers whose messages must
// name the file and the field.
#include <cstdint>
#include <filesystem>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "volume_io_test_support.h"

using namespace fvr::test::volume_io;

namespace {

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

} // namespace

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
