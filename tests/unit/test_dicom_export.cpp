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
