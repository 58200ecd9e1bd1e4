#include <cmath>

#include <gtest/gtest.h>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/dicom/dicom_export.h>
#include <fvr/core/errors.h>

#include "test_support.h"

using namespace fvr::core;

TEST(DicomExport, RoundTripsValuesAndPixelSpacing) {
    ProjectionImage img;
    img.width = img.height = 64;
    img.pixelSize = 0.75;
    img.view = ViewFrame::fromDirUp({0, 1, 0}, {0, 0, 1});
    img.pixels.resize(64 * 64);
    for (int r = 0; r < 64; ++r)
        for (int c = 0; c < 64; ++c)
            img.pixels[r * 64 + c] = float(-12.5 + 3.0 * std::sin(0.1 * r) * c);
    const auto path = fvr::test::tmpDir() / "projection.dcm";
    writeDicomProjection(path, img, {"Doe^Jane", "ID42", "", "FVR test", "mm"});
    const DicomVolume back = loadDicomFile(path); // the loader applies the rescale
    ASSERT_EQ(back.volume.dims, (Dims3{64, 64, 1}));
    EXPECT_NEAR(back.volume.spacing[0], 0.75, 1e-9);
    EXPECT_NEAR(back.volume.spacing[1], 0.75, 1e-9);
    const auto [lo, hi] = std::minmax_element(img.pixels.begin(), img.pixels.end());
    const double quantum = (*hi - *lo) / 65535.0;
    for (int i = 0; i < 64 * 64; ++i)
        ASSERT_NEAR(back.volume.voxels[i], img.pixels[i], quantum) << i;
}

TEST(DicomExport, UnwritablePathNamesIt) {
    ProjectionImage img;
    img.width = img.height = 2;
    img.pixels.assign(4, 1.0f);
    try {
        writeDicomProjection("/no/such/dir/x.dcm", img);
        FAIL() << "expected WriteError";
    } catch (const WriteError& e) {
        EXPECT_NE(std::string(e.what()).find("/no/such/dir/x.dcm"), std::string::npos);
    }
}

TEST(DicomExport, SecondaryCapturePassesDciodvfyWithoutErrors) {
    if (fvr::test::runCommand("command -v dciodvfy").status != 0)
        GTEST_SKIP() << "dciodvfy (Debian package dicom3tools) is not installed";
    ProjectionImage img;
    img.width = img.height = 32;
    img.pixelSize = 1.0;
    img.view = ViewFrame::fromDirUp({0, 1, 0}, {0, 0, 1});
    img.pixels.assign(32 * 32, 2.5f);
    img.pixels[5] = 7.0f;
    const auto path = fvr::test::tmpDir() / "projection_dciodvfy.dcm";
    writeDicomProjection(path, img, {"Doe^Jane", "ID42", "1.2.3.4", "FVR test", "mm", "20240131"});
    // The export joins its source's study: same UID, same date.
    DcmFileFormat ff;
    ASSERT_TRUE(ff.loadFile(path.c_str()).good());
    OFString uid, date;
    ff.getDataset()->findAndGetOFString(DCM_StudyInstanceUID, uid);
    ff.getDataset()->findAndGetOFString(DCM_StudyDate, date);
    EXPECT_EQ(std::string(uid.c_str()), "1.2.3.4");
    EXPECT_EQ(std::string(date.c_str()), "20240131");
    const auto r = fvr::test::runCommand("dciodvfy -new '" + path.string() + "' 2>&1");
    EXPECT_NE(r.out.find("SCImage"), std::string::npos) << r.out; // the IOD it checked against
    EXPECT_EQ(r.out.find("Error"), std::string::npos) << r.out;
}

namespace {

/** A string attribute of the DICOM file at `path`. */
std::string dicomString(const std::filesystem::path& path, const DcmTagKey& key) {
    DcmFileFormat ff;
    EXPECT_TRUE(ff.loadFile(path.c_str()).good()) << path;
    OFString v;
    ff.getDataset()->findAndGetOFStringArray(key, v);
    return v.c_str();
}

ProjectionImage rampImage() {
    ProjectionImage img;
    img.width = img.height = 16;
    img.pixelSize = 1.0;
    img.view = ViewFrame::fromDirUp({0, 1, 0}, {0, 0, 1}); // AP: looks towards posterior
    for (int i = 0; i < 256; ++i) img.pixels.push_back(float(i));
    return img;
}

} // namespace

TEST(DicomExport, WritesTheUsersWindowOrientationAndSeries) {
    const auto path = fvr::test::tmpDir() / "projection_display.dcm";
    DicomExportInfo info;
    info.window = DisplayWindowValues{40.0, 80.0, true};
    info.patientDirection = glm::dmat3(1.0); // index axes = L, P, S
    info.seriesInstanceUid = "1.2.3.9";
    info.seriesNumber = 7;
    info.instanceNumber = 3;
    writeDicomProjection(path, rampImage(), info);
    EXPECT_EQ(dicomString(path, DCM_WindowCenter), "40");
    EXPECT_EQ(dicomString(path, DCM_WindowWidth), "80");
    EXPECT_EQ(dicomString(path, DCM_PhotometricInterpretation), "MONOCHROME1"); // low is bright
    // AP: rows towards the patient's left (right = dir x up = +x), columns towards the feet.
    EXPECT_EQ(dicomString(path, DCM_PatientOrientation), "L\\F");
    EXPECT_EQ(dicomString(path, DCM_SeriesInstanceUID), "1.2.3.9");
    EXPECT_EQ(dicomString(path, DCM_SeriesNumber), "7");
    EXPECT_EQ(dicomString(path, DCM_InstanceNumber), "3");
    // A volume whose index x runs to the patient's right and z to the feet: "R\H".
    info.patientDirection =
        glm::dmat3(glm::dvec3(-1, 0, 0), glm::dvec3(0, 1, 0), glm::dvec3(0, 0, -1));
    writeDicomProjection(path, rampImage(), info);
    EXPECT_EQ(dicomString(path, DCM_PatientOrientation), "R\\H");
}

TEST(DicomExport, UnknownOrientationAndStudyFieldsAreWrittenEmpty) {
    const auto path = fvr::test::tmpDir() / "projection_unknown.dcm";
    writeDicomProjection(path, rampImage(), {});
    DcmFileFormat ff;
    ASSERT_TRUE(ff.loadFile(path.c_str()).good());
    for (const DcmTagKey& k : {DCM_PatientOrientation, DCM_StudyTime, DCM_StudyID,
                               DCM_AccessionNumber, DCM_ReferringPhysicianName, DCM_PatientSex,
                               DCM_PatientBirthDate, DCM_Laterality, DCM_Manufacturer}) {
        EXPECT_TRUE(ff.getDataset()->tagExists(k)) << DcmTag(k).getTagName(); // type 2: present
        EXPECT_EQ(dicomString(path, k), "") << DcmTag(k).getTagName();
    }
    // Without a window of the user's the full range: centre 127.5, width 255.
    EXPECT_NEAR(std::stod(dicomString(path, DCM_WindowCenter)), 127.5, 1e-9);
    EXPECT_NEAR(std::stod(dicomString(path, DCM_WindowWidth)), 255.0, 1e-9);
    EXPECT_EQ(dicomString(path, DCM_PhotometricInterpretation), "MONOCHROME2");
}

TEST(DicomExport, NewSeriesNumbersAreTheTimeOfDayAndIncrease) {
    const int a = newExportSeriesNumber(), b = newExportSeriesNumber();
    EXPECT_GT(b, a);
    EXPECT_GE(a, 0);
    EXPECT_LE(a, 240000); // HHMMSS (bumped by one where two exports share a second)
    EXPECT_NE(newSeriesInstanceUid(), newSeriesInstanceUid());
}

TEST(DicomExport, OverlayPlaneHoldsItsBitsAndPassesDciodvfy) {
    // A 20 x 20 image (rows of 20 bits, not whole words) with its diagonal (pixels 21 k) and
    // pixel 398 on: pixel i is bit i % 16 of word i / 16.
    ProjectionImage img;
    img.width = img.height = 20;
    img.pixelSize = 1.0;
    img.view = ViewFrame::fromDirUp({0, 1, 0}, {0, 0, 1});
    img.pixels.assign(400, 1.5f);
    img.pixels[7] = 3.0f;
    DicomExportInfo info;
    info.overlay.bits.assign(400, 0);
    for (int i = 0; i < 20; ++i) info.overlay.bits[i * 20 + i] = 1;
    info.overlay.bits[398] = 1;
    info.overlay.description = "annotations";
    const auto path = fvr::test::tmpDir() / "projection_overlay.dcm";
    writeDicomProjection(path, img, info);
    DcmFileFormat ff;
    ASSERT_TRUE(ff.loadFile(path.c_str()).good());
    DcmDataset* ds = ff.getDataset();
    Uint16 rows = 0, cols = 0, bits = 0;
    ds->findAndGetUint16(DCM_OverlayRows, rows);
    ds->findAndGetUint16(DCM_OverlayColumns, cols);
    ds->findAndGetUint16(DCM_OverlayBitsAllocated, bits);
    EXPECT_EQ(rows, 20);
    EXPECT_EQ(cols, 20);
    EXPECT_EQ(bits, 1);
    const Uint16* words = nullptr;
    unsigned long n = 0;
    ASSERT_TRUE(ds->findAndGetUint16Array(DCM_OverlayData, words, &n).good());
    ASSERT_EQ(n, 25u); // 400 bits
    EXPECT_EQ(words[0], 0x0001); // pixel 0
    EXPECT_EQ(words[1], 0x0020); // pixel 21: bit 5 of word 1
    EXPECT_EQ(words[2], 0x0400); // pixel 42: bit 10 of word 2
    EXPECT_EQ(words[3], 0x8000); // pixel 63: bit 15 of word 3
    EXPECT_EQ(words[24], 0xC000); // pixels 398 and 399 (the diagonal's end)
    int on = 0;
    for (unsigned long w = 0; w < n; ++w) on += __builtin_popcount(words[w]);
    EXPECT_EQ(on, 21);
    if (fvr::test::runCommand("command -v dciodvfy").status == 0) {
        const auto r = fvr::test::runCommand("dciodvfy -new '" + path.string() + "' 2>&1");
        EXPECT_EQ(r.out.find("Error"), std::string::npos) << r.out;
    }
    // An overlay of another size is refused, naming the file.
    info.overlay.bits.resize(399);
    try {
        writeDicomProjection(path, img, info);
        FAIL() << "no error";
    } catch (const WriteError& e) {
        EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("overlay"), std::string::npos) << e.what();
    }
}
