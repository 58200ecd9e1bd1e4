// Tests of what the volume loaders share: element types, geometry checks, the raw loader,
// dispatch by file name, text files named as volumes, and corrupted headers that must end in an
// InputError, never a crash. The format tests are in test_metaimage_io.cpp and test_nifti_io.cpp,
// the shared data sets in test_volume_io_shared_data.cpp.
#include <cstdint>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "volume_io_test_support.h"

using namespace fvr::test::volume_io;

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
