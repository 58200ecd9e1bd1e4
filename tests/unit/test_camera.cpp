// The cone-beam camera contract against cases worked out by hand: where a C-arm's source and
// detector stand (DICOM's angle signs), where points land (left of the isocentre lands right of
// centre, magnification SID/z), and that P and the pixel positions agree.
#include <cmath>

#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/geometry/camera.h>

namespace {

using namespace fvr::core;

void expectNear(const glm::dvec3& a, const glm::dvec3& b, double tol = 1e-9) {
    EXPECT_NEAR(a.x, b.x, tol);
    EXPECT_NEAR(a.y, b.y, tol);
    EXPECT_NEAR(a.z, b.z, tol);
}

TEST(Camera, APositionAtZeroZeroIsSourceBehindAndFilmInFront) {
    // LPS: +x the patient's left, +y posterior, +z head. SID 1000, SOD 750.
    const ConeCamera c = cArmCamera(CArm{0.0, 0.0, 1000.0, 750.0}, 1240, 960, 0.2, 0.2);
    expectNear(c.source, {0.0, 750.0, 0.0}); // posterior
    expectNear(c.detectorCentre, {0.0, -250.0, 0.0}); // anterior
    expectNear(c.u, {1.0, 0.0, 0.0}); // columns toward the patient's left
    expectNear(c.v, {0.0, 0.0, -1.0}); // rows toward the feet
    EXPECT_NEAR(c.sourceToDetector(), 1000.0, 1e-9);
}

TEST(Camera, DicomAnglesPutTheDetectorWhereTheStandardSays) {
    // PS3.3 C.8.7.5.1.2: primary +90 at the patient's left (LAO), secondary +90 cranial; the
    // angles give the detector's direction from the isocentre.
    const glm::dvec3 iso(10.0, -20.0, 30.0);
    const ConeCamera lao = cArmCamera(CArm{90.0, 0.0, 1200.0, 800.0, iso}, 64, 64, 1.0, 1.0);
    expectNear(lao.detectorCentre - iso, {400.0, 0.0, 0.0});
    expectNear(lao.source - iso, {-800.0, 0.0, 0.0});
    const ConeCamera rao = cArmCamera(CArm{-90.0, 0.0, 1200.0, 800.0, iso}, 64, 64, 1.0, 1.0);
    expectNear(rao.detectorCentre - iso, {-400.0, 0.0, 0.0});
    const ConeCamera cran = cArmCamera(CArm{0.0, 30.0, 1200.0, 800.0, iso}, 64, 64, 1.0, 1.0);
    const glm::dvec3 d = glm::normalize(cran.detectorCentre - iso);
    EXPECT_NEAR(d.z, 0.5, 1e-12); // tilted toward the head
    EXPECT_NEAR(d.y, -std::sqrt(0.75), 1e-12); // still in front of the chest
    // The detector faces the source: the rows and columns span the plane normal to the beam.
    for (const ConeCamera* c : {&lao, &rao, &cran}) {
        const glm::dvec3 beam = glm::normalize(c->detectorCentre - c->source);
        EXPECT_NEAR(glm::dot(beam, c->u), 0.0, 1e-12);
        EXPECT_NEAR(glm::dot(beam, c->v), 0.0, 1e-12);
    }
}

TEST(Camera, PointsLandWhereARadiographShowsThem) {
    const int W = 1240, H = 960;
    const ConeCamera c = cArmCamera(CArm{0.0, 0.0, 1000.0, 750.0}, W, H, 0.2, 0.2);
    const ProjectionMatrix p = c.matrix();
    const glm::dvec3 centre = p.apply({0.0, 0.0, 0.0});
    EXPECT_NEAR(centre.x, (W - 1) / 2.0, 1e-9);
    EXPECT_NEAR(centre.y, (H - 1) / 2.0, 1e-9);
    EXPECT_NEAR(centre.z, 750.0, 1e-9); // w: the depth from the source
    // 10 mm to the patient's left: right of centre, magnified SID/SOD = 4/3.
    const glm::dvec3 left = p.apply({10.0, 0.0, 0.0});
    EXPECT_NEAR(left.x - centre.x, 10.0 * (1000.0 / 750.0) / 0.2, 1e-9);
    EXPECT_NEAR(left.y, centre.y, 1e-9);
    // Toward the head: up (a smaller row).
    EXPECT_LT(p.apply({0.0, 0.0, 10.0}).y, centre.y);
    // A sphere of 20 mm diameter at depth z from the source images at 20 SID/z mm.
    for (double y : {-150.0, 0.0, 150.0}) {
        const double z = 750.0 - y;
        const double a = p.apply({-10.0, y, 0.0}).x, b = p.apply({10.0, y, 0.0}).x;
        EXPECT_NEAR((b - a) * 0.2, 20.0 * 1000.0 / z, 1e-9) << "depth " << z;
    }
}

TEST(Camera, TheMatrixMapsEveryPixelCentreToItsIndices) {
    // Non-square, odd angles, a principal-point offset: P and pixelCentre agree exactly.
    const ConeCamera c = cArmCamera(CArm{-37.0, 21.0, 1100.0, 700.0, {5.0, -3.0, 40.0}}, 976, 200,
                                    0.3, 0.45, {12.5, -7.0});
    const ProjectionMatrix p = c.matrix();
    for (double col : {0.0, 100.5, 975.0})
        for (double row : {0.0, 33.0, 199.0}) {
            const glm::dvec3 x = c.pixelCentre(col, row);
            const glm::dvec3 r = p.apply(x);
            EXPECT_NEAR(r.x, col, 1e-7);
            EXPECT_NEAR(r.y, row, 1e-7);
            // Any point on the ray from the source through the pixel lands there too.
            const glm::dvec3 mid = p.apply(c.source + 0.4 * (x - c.source));
            EXPECT_NEAR(mid.x, col, 1e-7);
            EXPECT_NEAR(mid.y, row, 1e-7);
        }
    // The principal offset moves where the principal ray lands by that many pixels.
    const glm::dvec3 principal = p.apply(c.source + (c.detectorCentre - c.source) * 0.5);
    EXPECT_NEAR(principal.x, (976 - 1) / 2.0 - 12.5, 1e-7);
    EXPECT_NEAR(principal.y, (200 - 1) / 2.0 + 7.0, 1e-7);
}

TEST(Camera, BadGeometryIsRefusedNamingTheProblem) {
    auto message = [](auto&& make) -> std::string {
        try {
            make();
        } catch (const SettingsError& e) {
            return e.what();
        }
        return "(no error)";
    };
    EXPECT_NE(message([] {
                  cArmCamera(CArm{0, 0, 700.0, 750.0}, 64, 64, 1, 1);
              }).find("0 < SOD < SID"),
              std::string::npos);
    EXPECT_NE(message([] { cArmCamera(CArm{}, 64, 64, 0.0, 1.0); }).find("column pitch"),
              std::string::npos);
    EXPECT_NE(message([] { cArmCamera(CArm{}, 8, 64, 1.0, 1.0); }).find("detector width"),
              std::string::npos);
    ConeCamera c = cArmCamera(CArm{}, 64, 64, 1.0, 1.0);
    c.detectorCentre = c.source + glm::dvec3(10.0, 0.0, 0.0); // in the plane through the source
    EXPECT_NE(message([&] { c.validate(); }).find("does not face"), std::string::npos);
    c = cArmCamera(CArm{}, 64, 64, 1.0, 1.0);
    c.v = glm::dvec3(1.0, 0.0, 0.0);
    EXPECT_NE(message([&] { c.validate(); }).find("orthonormal"), std::string::npos);
}

} // namespace
