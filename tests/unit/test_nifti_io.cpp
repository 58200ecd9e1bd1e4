// Tests of the NIfTI-1 loader (.nii, .nii.gz): scaling, every datatype, both byte orders,
// sform/qform orientation and units, and malformed or truncated files whose messages must name
// the file and the field.
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "volume_io_test_support.h"

using namespace fvr::test::volume_io;

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
