// A treatment beam's DRR written as a DICOM RT Image and read back (rt_image.h): the same
// camera for gantry, couch and collimator angles, the first pixel where PS3.3 C.8.8.2.7 puts it
// (worked by hand), the same image rendered again, dciodvfy, and RT Images from elsewhere.
#include <algorithm>
#include <array>
#include <cmath>
#include <functional>

#include <gtest/gtest.h>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include <fvr/core/dicom/rt_image.h>
#include <fvr/core/dicom/xray_geometry.h>
#include <fvr/core/errors.h>

#include "dicom_test_support.h"
#include "test_support.h"

namespace {

using namespace fvr::core;
using fvr::test::dicom::normalisedP;
namespace fs = std::filesystem;

DetectorImage drrOf(const TreatmentBeam& beam, int W, int H, double pu, double pv,
                    glm::dvec2 offset) {
    DetectorImage img;
    img.width = W;
    img.height = H;
    img.camera = treatmentBeamCamera(beam, W, H, pu, pv, offset);
    img.pixels.resize(std::size_t(W) * H);
    for (int r = 0; r < H; ++r)
        for (int c = 0; c < W; ++c)
            img.pixels[std::size_t(r) * W + c] = float(2.0 * std::cos(0.07 * r) * c + 0.5 * r);
    return img;
}

std::string joined(const std::vector<std::string>& v) {
    std::string s;
    for (const auto& w : v) s += w + "\n";
    return s;
}

std::string errorOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const std::exception& e) {
        return e.what();
    }
    return "no error";
}

std::string tagOf(const fs::path& path, const DcmTagKey& tag) {
    DcmFileFormat ff;
    EXPECT_TRUE(ff.loadFile(path.c_str()).good());
    OFString s;
    ff.getDataset()->findAndGetOFStringArray(tag, s);
    return s.c_str();
}

TEST(RtImageDicom, BeamsWrittenAsRtImageReadBackToTheSameProjectionMatrix) {
    struct Case {
        double gantry, couch, coll;
        PatientPosition position;
    };
    const Case cases[] = {
        {0, 0, 0, PatientPosition::HFS},      {33.5, 0, 0, PatientPosition::HFS},
        {270, 15, 0, PatientPosition::HFS},   {45, -20, 30, PatientPosition::HFS},
        {210, 90, -45, PatientPosition::HFS}, {120, 350, 10, PatientPosition::HFP},
        {300, 0, 90, PatientPosition::FFS}};
    for (const Case& k : cases) {
        TreatmentBeam beam;
        beam.gantryDeg = k.gantry;
        beam.couchDeg = k.couch;
        beam.collimatorDeg = k.coll;
        beam.sad = 1000.0;
        beam.sid = 1540.0;
        beam.isocentre = glm::dvec3(12.5, -40.0, 7.25);
        beam.position = k.position;
        const DetectorImage img = drrOf(beam, 200, 150, 0.392, 0.41, glm::dvec2(2.5, -1.25));
        RtPlanBeam planned;
        planned.beam = beam;
        planned.number = 3;
        planned.name = "LAT";
        const fs::path path = fvr::test::tmpDir() / "drr_beam.dcm";
        writeRtImageDicom(path, img, planned, {"Doe^Jane", "ID42", "", "FVR DRR", "mm"});

        const XrayGeometry g = readXrayGeometry(path);
        const std::string at = "gantry " + std::to_string(k.gantry) + " couch " +
                               std::to_string(k.couch) + " coll " + std::to_string(k.coll);
        EXPECT_TRUE(g.warnings.empty()) << at << "\n" << joined(g.warnings);
        EXPECT_EQ(g.modality, "RTIMAGE");
        ASSERT_EQ(g.frameCount(), 1u);
        ASSERT_EQ(g.beams.size(), 1u);
        EXPECT_TRUE(g.isocentreStated);
        EXPECT_NEAR(g.beams[0].gantryDeg, k.gantry, 1e-12) << at;
        EXPECT_NEAR(g.beams[0].couchDeg, k.couch, 1e-12) << at;
        EXPECT_NEAR(g.beams[0].collimatorDeg, k.coll, 1e-12) << at;
        EXPECT_EQ(g.beams[0].position, k.position) << at;
        const ConeCamera back = g.camera(0, glm::dvec3(0.0)); // the file's isocentre
        const auto a = normalisedP(img.camera), b = normalisedP(back);
        for (std::size_t i = 0; i < 12; ++i) EXPECT_NEAR(a[i], b[i], 1e-6) << at << " P " << i;
        const glm::dvec3 x(-30.0, 55.0, 20.0);
        const glm::dvec3 pa = img.camera.matrix().apply(x), pb = back.matrix().apply(x);
        EXPECT_NEAR(pa.x, pb.x, 1e-6) << at;
        EXPECT_NEAR(pa.y, pb.y, 1e-6) << at;
        const auto [lo, hi] = std::minmax_element(img.pixels.begin(), img.pixels.end());
        ASSERT_EQ(g.pixels.size(), img.pixels.size());
        for (std::size_t i = 0; i < img.pixels.size(); ++i)
            ASSERT_NEAR(g.pixels[i], img.pixels[i], (*hi - *lo) / 65535.0) << at << " " << i;
    }
}

TEST(RtImageDicom, FirstPixelIsWherePs33PutsItWorkedByHand) {
    // Gantry 0, HFS: the source anterior (IEC Zb = patient anterior, -y LPS), Xb the patient's
    // left (+x), Yb the head (+z). SAD 1000, SID 1500: the image plane 500 mm posterior of the
    // isocentre. A 16 x 20 image of 2 x 3 mm pixels centred on the axis: its first pixel (the
    // top left seen from the source: rows along +Xr, columns along -Yr) at x = -7.5 x 2 = -15,
    // y = +9.5 x 3 = +28.5 of the receptor: 15 mm to the patient's right, 28.5 toward the head.
    TreatmentBeam beam;
    beam.sid = 1500.0;
    beam.isocentre = glm::dvec3(10.0, 20.0, 30.0);
    const fs::path path = fvr::test::tmpDir() / "drr_hand.dcm";
    writeRtImageDicom(path, drrOf(beam, 16, 20, 2.0, 3.0, glm::dvec2(0.0)), beam);
    EXPECT_EQ(tagOf(path, DCM_RTImagePosition), "-15\\28.5");
    EXPECT_EQ(tagOf(path, DCM_ImagePlanePixelSpacing), "3\\2"); // rows, then columns
    EXPECT_EQ(tagOf(path, DCM_XRayImageReceptorTranslation), "0\\0\\-500");
    EXPECT_EQ(tagOf(path, DCM_RTImageSID), "1500");
    EXPECT_EQ(tagOf(path, DCM_RadiationMachineSAD), "1000");
    EXPECT_EQ(tagOf(path, DCM_IsocenterPosition), "10\\20\\30");
    EXPECT_EQ(tagOf(path, DCM_ImageType), "DERIVED\\SECONDARY\\DRR");
    EXPECT_EQ(tagOf(path, DCM_RTImagePlane), "NORMAL");
    EXPECT_EQ(tagOf(path, DCM_SOPClassUID), UID_RTImageStorage);
    const ConeCamera c = readXrayGeometry(path, false).camera(0, {});
    const glm::dvec3 first = c.pixelCentre(0, 0);
    EXPECT_NEAR(first.x, 10.0 - 15.0, 1e-9); // right of the axis
    EXPECT_NEAR(first.y, 20.0 + 500.0, 1e-9); // posterior, behind the patient
    EXPECT_NEAR(first.z, 30.0 + 28.5, 1e-9); // toward the head
    EXPECT_NEAR(glm::length(c.source - glm::dvec3(10.0, 20.0 - 1000.0, 30.0)), 0.0, 1e-9);

    // Collimator 90: the receptor turned with it, so the columns run along Yb's old direction
    // turned: Rz(90) Xg = Yg, toward the head; XRayImageReceptorAngle says 90.
    beam.collimatorDeg = 90.0;
    writeRtImageDicom(path, drrOf(beam, 16, 16, 2.0, 3.0, glm::dvec2(0.0)), beam);
    EXPECT_EQ(tagOf(path, DCM_XRayImageReceptorAngle), "90");
    EXPECT_EQ(tagOf(path, DCM_BeamLimitingDeviceAngle), "90");
    const ConeCamera turned = readXrayGeometry(path, false).camera(0, {});
    EXPECT_NEAR(glm::length(turned.u - glm::dvec3(0, 0, 1)), 0.0, 1e-12);
}

TEST(RtImageDicom, DrrRenderedAgainFromItsOwnFileGivesTheSameImage) {
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
    TreatmentBeam beam;
    beam.gantryDeg = 62.0;
    beam.couchDeg = 12.0;
    beam.collimatorDeg = 25.0;
    beam.sid = 1500.0;
    beam.isocentre = volumeCentre(vol);
    const ConeCamera cam = treatmentBeamCamera(beam, 96, 80, 1.2, 1.1, glm::dvec2(3.0, -2.0));
    ConeProjector projector(vol);
    const DetectorImage drr = projector.project(cam);
    const fs::path path = fvr::test::tmpDir() / "drr_beam_rendered.dcm";
    writeRtImageDicom(path, drr, beam);
    const XrayGeometry g = readXrayGeometry(path);
    const DetectorImage again = projector.project(g.camera(0, glm::dvec3(0.0)));
    ASSERT_EQ(again.pixels.size(), drr.pixels.size());
    const float peak = *std::max_element(drr.pixels.begin(), drr.pixels.end());
    ASSERT_GT(peak, 1.0f); // the blob is in view
    for (std::size_t i = 0; i < drr.pixels.size(); ++i)
        ASSERT_NEAR(again.pixels[i], drr.pixels[i], 1e-5 * peak) << i;
}

TEST(RtImageDicom, WrittenRtImagePassesDciodvfyWithoutErrors) {
    if (fvr::test::runCommand("command -v dciodvfy").status != 0)
        GTEST_SKIP() << "dciodvfy (Debian package dicom3tools) is not installed";
    TreatmentBeam beam;
    beam.gantryDeg = 45.0;
    beam.couchDeg = 10.0;
    beam.collimatorDeg = 15.0;
    RtPlanBeam planned{2, "RAO", "TREATMENT", beam, true};
    const fs::path path = fvr::test::tmpDir() / "drr_beam_dciodvfy.dcm";
    writeRtImageDicom(path, drrOf(beam, 64, 48, 0.5, 0.5, glm::dvec2(1.0, 0.0)), planned);
    const auto r = fvr::test::runCommand("dciodvfy -new '" + path.string() + "' 2>&1");
    EXPECT_NE(r.out.find("RTImage"), std::string::npos) << r.out; // the IOD it checked against
    EXPECT_EQ(r.out.find("Error"), std::string::npos) << r.out;
}

TEST(RtImageDicom, WriterRefusesACameraThatIsNotTheBeams) {
    TreatmentBeam beam;
    beam.gantryDeg = 10.0;
    DetectorImage img = drrOf(beam, 32, 32, 1.0, 1.0, glm::dvec2(0.0));
    TreatmentBeam other = beam;
    other.couchDeg = 5.0;
    const std::string e =
        errorOf([&] { writeRtImageDicom(fvr::test::tmpDir() / "x.dcm", img, other); });
    EXPECT_NE(e.find("not the treatment beam's imager"), std::string::npos) << e;
    try {
        writeRtImageDicom("/no/such/dir/drr.dcm", img, beam);
        FAIL() << "expected WriteError";
    } catch (const WriteError& w) {
        EXPECT_NE(std::string(w.what()).find("/no/such/dir/drr.dcm"), std::string::npos);
    }
}

/** An RT Image as another system might write it: 16 x 16, `fill` adds the geometry. */
fs::path writeRtImage(const std::string& name, const std::function<void(DcmDataset*)>& fill) {
    DcmFileFormat ff;
    DcmDataset* ds = ff.getDataset();
    char uid[100];
    ds->putAndInsertString(DCM_SOPClassUID, UID_RTImageStorage);
    ds->putAndInsertString(DCM_SOPInstanceUID, dcmGenerateUniqueIdentifier(uid));
    ds->putAndInsertString(DCM_Modality, "RTIMAGE");
    ds->putAndInsertString(DCM_PhotometricInterpretation, "MONOCHROME2");
    ds->putAndInsertUint16(DCM_SamplesPerPixel, 1);
    ds->putAndInsertUint16(DCM_Rows, 16);
    ds->putAndInsertUint16(DCM_Columns, 16);
    ds->putAndInsertUint16(DCM_BitsAllocated, 16);
    ds->putAndInsertUint16(DCM_BitsStored, 16);
    ds->putAndInsertUint16(DCM_HighBit, 15);
    ds->putAndInsertUint16(DCM_PixelRepresentation, 0);
    std::vector<Uint16> px(256, 7);
    ds->putAndInsertUint16Array(DCM_PixelData, px.data(), px.size());
    fill(ds);
    const fs::path path = fvr::test::tmpDir() / name;
    EXPECT_TRUE(ff.saveFile(path.c_str(), EXS_LittleEndianExplicit).good());
    return path;
}

TEST(RtImageDicom, OtherRtImagesReadWithTheirReceptorAndSayWhatIsAssumed) {
    // A portal image: collimator 30, the panel not turned (receptor angle 0) and shifted 20 mm
    // along Xg; its image 1 mm pixels, first pixel at (-7.5, 7.5): centred on the panel.
    const fs::path portal = writeRtImage("portal.dcm", [](DcmDataset* ds) {
        ds->putAndInsertString(DCM_RTImageSID, "1500");
        ds->putAndInsertString(DCM_RadiationMachineSAD, "1000");
        ds->putAndInsertString(DCM_GantryAngle, "0");
        ds->putAndInsertString(DCM_BeamLimitingDeviceAngle, "30");
        ds->putAndInsertString(DCM_XRayImageReceptorAngle, "0");
        ds->putAndInsertString(DCM_XRayImageReceptorTranslation, "20\\0\\-500");
        ds->putAndInsertString(DCM_ImagePlanePixelSpacing, "1\\1");
        ds->putAndInsertString(DCM_RTImagePosition, "-7.5\\7.5");
        ds->putAndInsertString(DCM_RTImagePlane, "NORMAL");
    });
    const XrayGeometry g = readXrayGeometry(portal, false);
    EXPECT_FALSE(g.isocentreStated);
    const std::string w = joined(g.warnings);
    EXPECT_NE(w.find("XRayImageReceptorAngle (3002,000E) 0 deg is not BeamLimitingDeviceAngle"),
              std::string::npos)
        << w;
    EXPECT_NE(w.find("PatientSupportAngle"), std::string::npos) << w;
    EXPECT_NE(w.find("PatientPosition (0018,5100) missing: assumed HFS"), std::string::npos) << w;
    const ConeCamera c = g.camera(0, glm::dvec3(1.0, 2.0, 3.0)); // no IsocenterPosition
    // HFS, gantry 0: Xg = patient left (+x), Yg = head (+z); the panel's centre 20 mm left.
    const glm::dvec3 centre = 0.5 * (c.pixelCentre(7, 7) + c.pixelCentre(8, 8));
    EXPECT_NEAR(glm::length(centre - glm::dvec3(21.0, 502.0, 3.0)), 0.0, 1e-9);
    EXPECT_NEAR(glm::length(c.u - glm::dvec3(1, 0, 0)), 0.0, 1e-12);
    EXPECT_NEAR(glm::length(c.v - glm::dvec3(0, 0, -1)), 0.0, 1e-12);
    EXPECT_NEAR(g.principalOffset.x, 20.0, 1e-9); // the axis lands 20 pixels off centre

    // No RTImageSID: the imager cannot be placed.
    const fs::path noSid = writeRtImage("rt_nosid.dcm", [](DcmDataset*) {});
    std::string e = errorOf([&] { readXrayGeometry(noSid); });
    EXPECT_NE(e.find(noSid.string()), std::string::npos) << e;
    EXPECT_NE(e.find("RTImageSID (3002,0026) missing"), std::string::npos) << e;
    EXPECT_NE(e.find("IEC 61217"), std::string::npos) << e;
    const fs::path tilted = writeRtImage("rt_nonnormal.dcm", [](DcmDataset* ds) {
        ds->putAndInsertString(DCM_RTImageSID, "1500");
        ds->putAndInsertString(DCM_RTImagePlane, "NON_NORMAL");
    });
    e = errorOf([&] { readXrayGeometry(tilted); });
    EXPECT_NE(e.find("RTImagePlane (3002,000C) 'NON_NORMAL'"), std::string::npos) << e;
    const fs::path atIso = writeRtImage(
        "rt_at_iso.dcm", [](DcmDataset* ds) { ds->putAndInsertString(DCM_RTImageSID, "1000"); });
    e = errorOf([&] { readXrayGeometry(atIso); });
    EXPECT_NE(e.find("expected 0 < SAD < SID"), std::string::npos) << e;
}

} // namespace
