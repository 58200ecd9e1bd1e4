// Tests of the DICOM series geometry (order, spacing, direction, gantry tilt, uneven gaps,
// duplicates, mixed sizes) checked against the single slices in physical space, on synthetic
// series written here with DCMTK and on the shared tilted series.
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

/** Bilinear value of a single-slice volume at physical point p (nullopt outside the slice). */
std::optional<double> sliceValueAt(const Volume& s, const Vec3& p) {
    Vec3 d{p[0] - s.origin[0], p[1] - s.origin[1], p[2] - s.origin[2]};
    const double fx = glm::dot(d, s.direction[0]) / s.spacing[0];
    const double fy = glm::dot(d, s.direction[1]) / s.spacing[1];
    if (fx < 0 || fy < 0 || fx > double(s.dims[0] - 1) || fy > double(s.dims[1] - 1))
        return std::nullopt;
    const auto x0 = std::min<std::int64_t>(std::int64_t(fx), s.dims[0] - 2);
    const auto y0 = std::min<std::int64_t>(std::int64_t(fy), s.dims[1] - 2);
    const double ax = fx - double(x0), ay = fy - double(y0);
    const double v00 = s.at(x0, y0, 0), v10 = s.at(x0 + 1, y0, 0);
    const double v01 = s.at(x0, y0 + 1, 0), v11 = s.at(x0 + 1, y0 + 1, 0);
    return (1 - ay) * ((1 - ax) * v00 + ax * v10) + ay * ((1 - ax) * v01 + ax * v11);
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
        slices.emplace_back(glm::dot(d, v.volume.direction[2]), std::move(s.volume));
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

} // namespace
