// Treatment beams (IEC 61217) as cone-beam cameras: the source, imager and image axes worked out
// by hand for an HFS patient at gantry 0/90/180/270, with couch and collimator turns and other
// patient positions; points left of and in front of the isocentre landing where a linac's beam's
// eye view puts them; and our box model against plastimatch's DRR driven by plastimatch's own
// gantry angle (its -a/-N options), which places the beam independently of our IEC code.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <tuple>

#include <gtest/gtest.h>

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/errors.h>
#include <fvr/core/geometry/camera.h>
#include <fvr/core/geometry/projection_matrix_file.h>
#include <fvr/core/geometry/treatment_beam.h>
#include <fvr/core/render/cone_projector.h>
#include <fvr/core/xray/phantom.h>

#include "image_metrics.h"
#include "support/plastimatch.h"
#include "test_support.h"

namespace {

using namespace fvr::core;

void expectNear(const glm::dvec3& a, const glm::dvec3& b, double tol = 1e-9) {
    EXPECT_NEAR(a.x, b.x, tol);
    EXPECT_NEAR(a.y, b.y, tol);
    EXPECT_NEAR(a.z, b.z, tol);
}

ConeCamera beamCamera(double gantry, double couch, double coll,
                      PatientPosition pos = PatientPosition::HFS,
                      glm::dvec3 iso = glm::dvec3(0.0)) {
    TreatmentBeam b;
    b.gantryDeg = gantry;
    b.couchDeg = couch;
    b.collimatorDeg = coll;
    b.isocentre = iso;
    b.position = pos;
    return treatmentBeamCamera(b, 128, 128, 0.5, 0.5);
}

// LPS: +x the patient's left, +y posterior, +z head. SAD 1000, SID 1500 (the defaults).
TEST(TreatmentBeam, HfsGantry0IsAnAPBeamSeenFromTheSource) {
    const ConeCamera c = beamCamera(0, 0, 0);
    expectNear(c.source, {0, -1000, 0}); // anterior, above the supine patient
    expectNear(c.detectorCentre, {0, 500, 0}); // under the couch
    expectNear(c.u, {1, 0, 0}); // columns toward the patient's left (seen from the source)
    expectNear(c.v, {0, 0, -1}); // rows toward the feet
    EXPECT_NEAR(c.sourceToDetector(), 1500.0, 1e-9);
}

TEST(TreatmentBeam, HfsGantry90IsALeftLateral180PAAnd270RightLateral) {
    // Gantry 90: IEC's clockwise turn seen from the couch's foot puts the source at +Xf, the
    // HFS patient's left; the columns (Xb) then point down, to the posterior.
    ConeCamera c = beamCamera(90, 0, 0);
    expectNear(c.source, {1000, 0, 0});
    expectNear(c.detectorCentre, {-500, 0, 0});
    expectNear(c.u, {0, 1, 0});
    expectNear(c.v, {0, 0, -1});
    c = beamCamera(180, 0, 0);
    expectNear(c.source, {0, 1000, 0}); // posterior, under the couch
    expectNear(c.detectorCentre, {0, -500, 0});
    expectNear(c.u, {-1, 0, 0}); // seen from below, the patient's left is on the left
    expectNear(c.v, {0, 0, -1});
    c = beamCamera(270, 0, 0);
    expectNear(c.source, {-1000, 0, 0}); // the patient's right
    expectNear(c.u, {0, -1, 0}); // columns up, to the anterior
    expectNear(c.v, {0, 0, -1});
    // -90 is 270, 450 is 90.
    expectNear(beamCamera(-90, 0, 0).source, {-1000, 0, 0});
    expectNear(beamCamera(450, 0, 0).source, {1000, 0, 0});
}

TEST(TreatmentBeam, APointLeftOfTheIsocentreLandsWhereTheBeamsEyeViewPutsIt) {
    const glm::dvec3 iso(10, -20, 30);
    const glm::dvec3 left = iso + glm::dvec3(50, 0, 0), front = iso + glm::dvec3(0, -50, 0);
    // Gantry 0: left of the isocentre, at the isocentre's depth: magnified SID/SAD = 1.5, so
    // 75 mm = 150 pixels right of the centre (63.5).
    glm::dvec3 p = beamCamera(0, 0, 0, PatientPosition::HFS, iso).matrix().apply(left);
    EXPECT_NEAR(p.x, 63.5 + 150.0, 1e-9);
    EXPECT_NEAR(p.y, 63.5, 1e-9);
    EXPECT_NEAR(p.z, 1000.0, 1e-9); // depth from the source
    // Gantry 180 (PA): the same point left of the centre.
    p = beamCamera(180, 0, 0, PatientPosition::HFS, iso).matrix().apply(left);
    EXPECT_NEAR(p.x, 63.5 - 150.0, 1e-9);
    // Gantry 90: the left point lies on the beam axis, 50 mm nearer the source; a point in front
    // of the isocentre lands left of the centre (the columns run posterior).
    p = beamCamera(90, 0, 0, PatientPosition::HFS, iso).matrix().apply(left);
    EXPECT_NEAR(p.x, 63.5, 1e-9);
    EXPECT_NEAR(p.z, 950.0, 1e-9);
    p = beamCamera(90, 0, 0, PatientPosition::HFS, iso).matrix().apply(front);
    EXPECT_NEAR(p.x, 63.5 - 150.0, 1e-9);
    // 50 mm toward the head: 150 pixels above the centre at every coplanar gantry angle.
    for (double g : {0.0, 37.0, 90.0, 211.0}) {
        p = beamCamera(g, 0, 0, PatientPosition::HFS, iso)
                .matrix()
                .apply(iso + glm::dvec3(0, 0, 50));
        EXPECT_NEAR(p.y, 63.5 - 150.0, 1e-9) << "gantry " << g;
    }
}

TEST(TreatmentBeam, CouchTurnsThePatientAboutTheVerticalThroughTheIsocentre) {
    // Couch 90: the patient support turns counter-clockwise seen from above (right-handed about
    // +Zf), so the HFS patient's head points to -Xf and the feet to +Xf.
    ConeCamera c = beamCamera(0, 90, 0);
    expectNear(c.source, {0, -1000, 0}); // still above the patient
    expectNear(c.u, {0, 0, -1}); // Xf: the columns run to the feet
    expectNear(c.v, {-1, 0, 0}); // -Yf: the rows run to the patient's right
    c = beamCamera(90, 90, 0); // the source at +Xf: below the feet
    expectNear(c.source, {0, 0, -1000});
    expectNear(c.detectorCentre, {0, 0, 500});
    c = beamCamera(90, 270, 0); // above the head (a vertex field)
    expectNear(c.source, {0, 0, 1000});
    // At gantry 0 the beam axis is the couch's axis: couch c equals collimator -c.
    const ConeCamera a = beamCamera(0, 37, 0), b = beamCamera(0, 0, -37);
    expectNear(a.source, b.source);
    expectNear(a.u, b.u);
    expectNear(a.v, b.v);
}

TEST(TreatmentBeam, CollimatorTurnsTheImagerAboutTheBeamAxis) {
    // Collimator 90: Xb turns right-handed about Zg (counter-clockwise seen from the source):
    // the columns run to the head, the rows to the patient's left.
    ConeCamera c = beamCamera(0, 0, 90);
    expectNear(c.source, {0, -1000, 0});
    expectNear(c.u, {0, 0, 1});
    expectNear(c.v, {1, 0, 0});
    // Any collimator angle keeps the source and the imager's centre.
    c = beamCamera(63, 10, 33);
    const ConeCamera d = beamCamera(63, 10, 0);
    expectNear(c.source, d.source);
    expectNear(c.detectorCentre, d.detectorCentre);
    EXPECT_NEAR(glm::dot(c.u, d.u), std::cos(33.0 * 3.14159265358979323846 / 180.0), 1e-12);
}

TEST(TreatmentBeam, OtherPatientPositions) {
    // FFS: feet toward the gantry, so +Xf is the patient's right.
    expectNear(beamCamera(90, 0, 0, PatientPosition::FFS).source, {-1000, 0, 0});
    expectNear(beamCamera(0, 0, 0, PatientPosition::FFS).source, {0, -1000, 0});
    expectNear(beamCamera(0, 0, 0, PatientPosition::FFS).v, {0, 0, 1}); // rows to the head
    // Prone: the back up; HFP gantry 90 at the patient's right, FFP at the left.
    expectNear(beamCamera(0, 0, 0, PatientPosition::HFP).source, {0, 1000, 0});
    expectNear(beamCamera(90, 0, 0, PatientPosition::HFP).source, {-1000, 0, 0});
    expectNear(beamCamera(0, 0, 0, PatientPosition::FFP).source, {0, 1000, 0});
    expectNear(beamCamera(90, 0, 0, PatientPosition::FFP).source, {1000, 0, 0});
    // Decubitus left: lying on the left side, the right side up, facing +Xf (left = head x
    // anterior points down): gantry 90 faces the front.
    expectNear(beamCamera(0, 0, 0, PatientPosition::HFDL).source, {-1000, 0, 0});
    expectNear(beamCamera(90, 0, 0, PatientPosition::HFDL).source, {0, -1000, 0});
    expectNear(beamCamera(0, 0, 0, PatientPosition::HFDR).source, {1000, 0, 0});
    expectNear(beamCamera(0, 0, 0, PatientPosition::FFDL).source, {-1000, 0, 0});
    expectNear(beamCamera(0, 0, 0, PatientPosition::FFDR).source, {1000, 0, 0});
    for (const char* name : {"HFS", "HFP", "FFS", "FFP", "HFDL", "HFDR", "FFDL", "FFDR"}) {
        const glm::dmat3 m = patientSupportToLps(parsePatientPosition(name));
        EXPECT_NEAR(glm::determinant(m), 1.0, 1e-12) << name; // a rotation, not a mirror
        EXPECT_STREQ(patientPositionName(parsePatientPosition(name)), name);
    }
    EXPECT_EQ(parsePatientPosition(" hfs "), PatientPosition::HFS);
    try {
        parsePatientPosition("SITTING");
        ADD_FAILURE() << "SITTING accepted";
    } catch (const SettingsError& e) {
        EXPECT_NE(std::string(e.what()).find("'SITTING'"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("HFS, HFP, FFS, FFP"), std::string::npos);
    }
    EXPECT_THROW(parsePatientPosition("AFDR"), SettingsError);
}

TEST(TreatmentBeam, Gantry180IsTheAPCArmMirrored) {
    // Another way in to the same geometry: the C-arm's AP (0/0) view has its source posterior,
    // as gantry 180; the C-arm looks from behind its detector and the beam from the source, so
    // the beam's column c is the C-arm's column W-1-c, rows alike, for every point.
    const glm::dvec3 iso(5, 7, -9);
    TreatmentBeam b;
    b.gantryDeg = 180;
    b.isocentre = iso;
    const ProjectionMatrix pb = treatmentBeamCamera(b, 200, 100, 0.4, 0.4).matrix();
    const ProjectionMatrix pc = cArmCamera({0, 0, 1500, 1000, iso}, 200, 100, 0.4, 0.4).matrix();
    for (const glm::dvec3 x : {glm::dvec3(0), glm::dvec3(40, -30, 20), glm::dvec3(-70, 55, 10)}) {
        const glm::dvec3 a = pb.apply(x), c = pc.apply(x);
        EXPECT_NEAR(a.x, 199.0 - c.x, 1e-9);
        EXPECT_NEAR(a.y, c.y, 1e-9);
        EXPECT_NEAR(a.z, c.z, 1e-9);
    }
}

TEST(TreatmentBeam, AMatrixFileOfTheBeamsGivesTheSameCameras) {
    // A third way in: the beams' P written to a projection-matrix file and read back rebuild
    // the same source, detector and axes (the file fixes P up to a factor, and the pitch).
    std::vector<ConeCamera> cams;
    for (const auto& [g, c, k, pos] : {std::tuple{30.0, 10.0, 20.0, PatientPosition::HFS},
                                       std::tuple{270.0, 350.0, 0.0, PatientPosition::FFS},
                                       std::tuple{181.5, 0.0, 90.0, PatientPosition::HFP}}) {
        TreatmentBeam b;
        b.gantryDeg = g;
        b.couchDeg = c;
        b.collimatorDeg = k;
        b.position = pos;
        b.isocentre = {12, -40, 101};
        cams.push_back(treatmentBeamCamera(b, 96, 64, 0.75, 0.75, glm::dvec2(2.5, -1.0)));
    }
    const auto path = fvr::test::tmpDir() / "treatment_beam_matrices.txt";
    writeProjectionMatrixFile(path, cams);
    const std::vector<ConeCamera> back = readProjectionMatrixFile(path);
    ASSERT_EQ(back.size(), cams.size());
    for (std::size_t i = 0; i < cams.size(); ++i) {
        expectNear(back[i].source, cams[i].source, 1e-6);
        expectNear(back[i].detectorCentre, cams[i].detectorCentre, 1e-6);
        expectNear(back[i].u, cams[i].u, 1e-9);
        expectNear(back[i].v, cams[i].v, 1e-9);
        EXPECT_NEAR(back[i].principalOffset.x, 2.5, 1e-9);
        EXPECT_NEAR(back[i].principalOffset.y, -1.0, 1e-9);
    }
}

TEST(TreatmentBeam, BadValuesAreRefusedNamingThem) {
    TreatmentBeam b;
    b.sid = 900; // the imager between the source and the isocentre
    try {
        treatmentBeamCamera(b, 64, 64, 1, 1);
        ADD_FAILURE() << "SID < SAD accepted";
    } catch (const SettingsError& e) {
        EXPECT_NE(std::string(e.what()).find("SAD 1000 mm, SID 900 mm"), std::string::npos)
            << e.what();
    }
    b = TreatmentBeam{};
    b.gantryDeg = std::nan("");
    EXPECT_THROW(treatmentBeamCamera(b, 64, 64, 1, 1), SettingsError);
    b = TreatmentBeam{};
    EXPECT_THROW(treatmentBeamCamera(b, 64, 64, 0.0, 1), SettingsError); // zero pitch
}

/** plastimatch's DRRs for its own gantry angles start, start + step, ... (its -y, -a, -N) of
 *  `v` (identity direction cosines: its frame is LPS) about `iso`; value x mm, our pixel order. */
std::vector<std::vector<float>> plastimatchGantryDrrs(const Volume& v, const glm::dvec3& iso,
                                                      int views, double stepDeg, double sad,
                                                      double sid, int size, double pitch,
                                                      const std::filesystem::path& dir) {
    std::filesystem::create_directories(dir);
    fvr::test::writePlastimatchVolume(v, dir / "volume.mha");
    char cmd[1024];
    // Only -N is read in degrees by plastimatch 1.9.4 (its -y is taken as radians, whatever
    // --help says), so the angles come from -y 0 and the step alone.
    std::snprintf(cmd, sizeof cmd,
                  "plastimatch drr -A cpu -i exact -P none -t pfm -y 0 -a %d -N %.17g --sad %.17g "
                  "--sid %.17g -o '%.17g %.17g %.17g' -r '%d %d' -z '%.17g %.17g' -O '%s' '%s' "
                  "> '%s' 2>&1",
                  views, stepDeg, sad, sid, iso.x, iso.y, iso.z, size, size, size * pitch,
                  size * pitch, (dir / "drr_").c_str(), (dir / "volume.mha").c_str(),
                  (dir / "log.txt").c_str());
    if (std::system(cmd) != 0) {
        ADD_FAILURE() << "plastimatch failed: " << cmd;
        return {};
    }
    std::vector<std::vector<float>> out;
    for (int k = 0; k < views; ++k) {
        char name[32];
        std::snprintf(name, sizeof name, "drr_%04d.pfm", k);
        int w = 0, h = 0;
        std::vector<float> px = fvr::test::readPlastimatchPfm(dir / name, w, h);
        EXPECT_EQ(w, size);
        EXPECT_EQ(h, size);
        for (float& x : px) x *= 10.0f; // plastimatch's cm back to mm
        out.push_back(std::move(px));
    }
    return out;
}

TEST(TreatmentBeamVsPlastimatch, BoxModelEqualsPlastimatchDrivenByItsOwnGantryAngle) {
    if (const std::string why = fvr::test::plastimatchMissing(); !why.empty()) GTEST_SKIP() << why;
    // plastimatch's gantry angle a puts its source at isocentre + SAD (cos a, -sin a, 0) (its
    // drr.cxx), which for an HFS patient in LPS is IEC gantry 90 - a; its image rows run along
    // -vup (default +z: to the feet) and its columns along vup x nrm (nrm toward the source):
    // the beam's eye view. No --nrm or --vup is given: plastimatch places the beam itself.
    Volume v = makeChestPhantomVolume(64);
    ASSERT_EQ(v.direction[0][0], 1.0f); // identity direction cosines: plastimatch's frame is LPS
    const double sad = 1000.0, sid = 1536.0, pitch = 3.0;
    const int size = 128, views = 8;
    for (const glm::dvec3 offset : {glm::dvec3(0.0), glm::dvec3(12.5, -20.0, 17.0)}) {
        const glm::dvec3 iso = volumeCentre(v) + offset;
        const auto theirs =
            plastimatchGantryDrrs(v, iso, views, 45.0, sad, sid, size, pitch,
                                  fvr::test::tmpDir() / "treatment_beam_plastimatch" /
                                      (offset == glm::dvec3(0.0) ? "centred" : "offset"));
        ASSERT_EQ(theirs.size(), std::size_t(views));
        ConeProjector ours(v, {RayModel::Box});
        for (int k = 0; k < views; ++k) {
            TreatmentBeam b;
            b.gantryDeg = 90.0 - 45.0 * k;
            b.sad = sad;
            b.sid = sid;
            b.isocentre = iso;
            const DetectorImage img =
                ours.project(treatmentBeamCamera(b, size, size, pitch, pitch));
            const auto cmp = fvr::test::compare(img.pixels, theirs[std::size_t(k)]);
            std::printf("IEC gantry %g (plastimatch angle %d), isocentre offset (%g, %g, %g): "
                        "%.1f dB (max error %.3g of peak %.4g)\n",
                        b.gantryDeg, 45 * k, offset.x, offset.y, offset.z, cmp.psnr,
                        cmp.maxAbsError, cmp.peak);
            EXPECT_GE(cmp.psnr, 60.0) << "gantry " << b.gantryDeg;
        }
    }
}

/** `in` averaged over b x b x 1 blocks (a smaller volume for plastimatch to read). */
Volume downsampleXY(const Volume& in, int b) {
    Volume out;
    out.dims = {in.dims[0] / b, in.dims[1] / b, in.dims[2]};
    out.spacing = {in.spacing[0] * b, in.spacing[1] * b, in.spacing[2]};
    out.direction = in.direction;
    out.units = in.units;
    for (int c = 0; c < 3; ++c) { // the block's centre: (b - 1) / 2 voxels in
        out.origin[c] = in.origin[c];
        for (int a = 0; a < 2; ++a)
            out.origin[c] += in.direction[a][c] * in.spacing[a] * (b - 1) / 2.0;
    }
    out.voxels.assign(std::size_t(out.voxelCount()), 0.0f);
    for (std::int64_t k = 0; k < out.dims[2]; ++k)
        for (std::int64_t j = 0; j < out.dims[1]; ++j)
            for (std::int64_t i = 0; i < out.dims[0]; ++i) {
                double sum = 0.0;
                for (int dj = 0; dj < b; ++dj)
                    for (int di = 0; di < b; ++di) sum += in.at(i * b + di, j * b + dj, k);
                out.voxels[out.index(i, j, k)] = float(sum / (b * b));
            }
    return out;
}

TEST(TreatmentBeamVsPlastimatch, BoxModelEqualsPlastimatchOnAnHfsCTAtItsFourCardinalGantryAngles) {
    if (const std::string why = fvr::test::plastimatchMissing(); !why.empty()) GTEST_SKIP() << why;
    FVR_REQUIRE_DATA("dicom/ct_phantom_philips_512x512x140");
    // A real CT scanned head first supine (its PatientPosition is HFS) with axial slices
    // (ImageOrientationPatient 1\0\0\0\1\0): gantry 90 must look at its left side.
    const Volume ct = downsampleXY(
        loadDicomFolder(fvr::test::sharedData() / "dicom/ct_phantom_philips_512x512x140").volume,
        4);
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
            ASSERT_EQ(ct.direction[a][b], a == b ? 1.0 : 0.0) << "plastimatch's frame is LPS";
    const glm::dvec3 iso = volumeCentre(ct) + glm::dvec3(10.0, -15.0, 20.0);
    const double sad = 1000.0, sid = 1500.0;
    const int size = 128;
    const double pitch = framingPitch(ct, sid, sad, size, size);
    const auto theirs =
        plastimatchGantryDrrs(ct, iso, 4, 90.0, sad, sid, size, pitch,
                              fvr::test::tmpDir() / "treatment_beam_plastimatch" / "philips");
    ASSERT_EQ(theirs.size(), 4u);
    ConeProjector ours(ct, {RayModel::Box});
    for (int k = 0; k < 4; ++k) {
        TreatmentBeam b;
        b.gantryDeg = 90.0 - 90.0 * k;
        b.isocentre = iso;
        const DetectorImage img = ours.project(treatmentBeamCamera(b, size, size, pitch, pitch));
        const auto cmp = fvr::test::compare(img.pixels, theirs[std::size_t(k)]);
        std::printf("Philips CT 128x128x140 (HU), IEC gantry %g: %.1f dB (max error %.3g of peak "
                    "%.4g)\n",
                    b.gantryDeg, cmp.psnr, cmp.maxAbsError, cmp.peak);
        EXPECT_GE(cmp.psnr, 60.0) << "gantry " << b.gantryDeg;
    }
}

} // namespace
