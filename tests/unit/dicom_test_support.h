// Shared by the DICOM tests (test_dicom.cpp, test_dicom_pixels.cpp, test_dicom_geometry.cpp,
// test_dicom_scan.cpp): the shared data's paths, message checks, voxel positions in physical
// space, and synthetic slices written with DCMTK for every geometry and pixel format rule.
#pragma once

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/errors.h>
#include <fvr/core/geometry/camera.h>
#include <fvr/core/volume.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcpixseq.h>
#include <dcmtk/dcmdata/dcpxitem.h>
#include <dcmtk/dcmdata/dctk.h>

#include <gtest/gtest.h>

#include "test_support.h"

namespace fvr::test::dicom {

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

inline fs::path data(const std::string& rel) { return fvr::test::sharedData() / rel; }

/** A fresh scratch folder for one test. */
inline fs::path scratch(const std::string& name) {
    const fs::path p = fvr::test::tmpDir() / ("dicom_" + name);
    fs::remove_all(p);
    fs::create_directories(p);
    return p;
}

inline double voxelSum(const Volume& v) {
    double s = 0;
    for (float x : v.voxels) s += x;
    return s;
}

/** prefix + n + suffix (spelled out: GCC 12 warns falsely on "literal" + std::to_string()). */
inline std::string numbered(const char* prefix, long long n, const char* suffix = ".dcm") {
    std::string s(prefix);
    s += std::to_string(n);
    s += suffix;
    return s;
}

inline bool contains(const std::string& haystack, const std::string& needle) {
    return haystack.find(needle) != std::string::npos;
}

inline bool anyWarningContains(const std::vector<std::string>& warnings,
                               const std::string& needle) {
    return std::any_of(warnings.begin(), warnings.end(),
                       [&](const std::string& w) { return contains(w, needle); });
}

inline std::string joined(const std::vector<std::string>& v) {
    std::string s;
    for (const auto& x : v) s += x + "\n";
    return s;
}

inline void expectVec(const Vec3& got, const Vec3& want, double tol, const std::string& what) {
    for (int i = 0; i < 3; ++i)
        EXPECT_NEAR(got[static_cast<std::size_t>(i)], want[static_cast<std::size_t>(i)], tol)
            << what << " component " << i;
}

/** Physical position (LPS) of voxel (x, y, z). */
inline Vec3 physical(const Volume& v, double x, double y, double z) {
    Vec3 p = v.origin;
    for (int a = 0; a < 3; ++a) {
        p[static_cast<std::size_t>(a)] +=
            x * v.spacing[0] * v.direction[0][static_cast<std::size_t>(a)] +
            y * v.spacing[1] * v.direction[1][static_cast<std::size_t>(a)] +
            z * v.spacing[2] * v.direction[2][static_cast<std::size_t>(a)];
    }
    return p;
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

inline std::string ds(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6f", v);
    return buf;
}

inline void writeSlice(const fs::path& path, const SliceSpec& s) {
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
inline std::vector<std::uint16_t> pattern(
    std::int64_t cols, std::int64_t rows,
    const std::function<std::uint16_t(std::int64_t, std::int64_t)>& f) {
    std::vector<std::uint16_t> w(static_cast<std::size_t>(cols * rows));
    for (std::int64_t y = 0; y < rows; ++y)
        for (std::int64_t x = 0; x < cols; ++x) w[static_cast<std::size_t>(y * cols + x)] = f(x, y);
    return w;
}

/** P scaled to unit Frobenius norm, for comparing cameras. */
inline std::array<double, 12> normalisedP(const core::ConeCamera& c) {
    const core::ProjectionMatrix P = c.matrix();
    std::array<double, 12> a{};
    double n = 0;
    for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 4; ++k) n += P.rows[r][k] * P.rows[r][k];
    n = std::sqrt(n);
    for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 4; ++k) a[std::size_t(r * 4 + k)] = P.rows[r][k] / n;
    return a;
}

} // namespace fvr::test::dicom
