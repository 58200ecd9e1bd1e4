// The projection-matrix file and the camera back from P: a matrix written out by hand for a
// C-arm worked out on paper, round trips of oblique C-arms with principal offsets, and every
// malformed file refused with its file:line.
#include <cmath>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/geometry/camera.h>
#include <fvr/core/geometry/projection_matrix_file.h>

#include "test_support.h"

namespace {

using namespace fvr::core;

void expectNear(const glm::dvec3& a, const glm::dvec3& b, double tol) {
    EXPECT_NEAR(a.x, b.x, tol);
    EXPECT_NEAR(a.y, b.y, tol);
    EXPECT_NEAR(a.z, b.z, tol);
}

/** P entries equal to 1e-9 of each row's size. */
void expectSameMatrix(const ProjectionMatrix& a, const ProjectionMatrix& b) {
    for (int r = 0; r < 3; ++r) {
        const double size = glm::length(a.rows[r]);
        for (int k = 0; k < 4; ++k)
            EXPECT_NEAR(a.rows[r][k], b.rows[r][k], 1e-9 * size) << "P[" << r << "][" << k << "]";
    }
}

std::filesystem::path writeText(const std::string& name, const std::string& text) {
    const auto path = fvr::test::tmpDir() / name;
    std::ofstream(path) << text;
    return path;
}

/** The SettingsError message of reading `text` as a file (empty when it reads). */
std::string readError(const std::string& name, const std::string& text) {
    const auto path = writeText(name, text);
    try {
        readProjectionMatrixFile(path);
    } catch (const SettingsError& e) {
        return e.what();
    }
    return {};
}

TEST(ProjectionMatrixFile, HandWrittenMatrixIsTheCArmWorkedOnPaper) {
    // AP C-arm, SOD 500, SID 1000, isocentre 0, 64 x 64 pixels of 2 mm: source (0, 500, 0),
    // n = (0, -1, 0), u = (1, 0, 0), v = (0, 0, -1), f / pitch = 500 pixels, centre 31.5.
    // Row 0: a = 500 u + 31.5 n = (500, -31.5, 0), -a.s = 15750; row 1: b = 500 v + 31.5 n =
    // (0, -31.5, -500), -b.s = 15750; row 2: n, -n.s = 500. Scaled by 2 (any positive factor).
    const auto path = writeText("pm_hand.txt", "# hand-worked\n"
                                               "detector 64 64\n"
                                               "pitch 2   # square\n"
                                               "1000, -63, 0, 31500\n"
                                               "0 -63 -1000 31500\n"
                                               "\t0 -2 0 1000\n");
    const auto cams = readProjectionMatrixFile(path);
    ASSERT_EQ(cams.size(), 1u);
    const ConeCamera& c = cams[0];
    expectNear(c.source, {0.0, 500.0, 0.0}, 1e-9);
    expectNear(c.detectorCentre, {0.0, -500.0, 0.0}, 1e-9);
    expectNear(c.u, {1.0, 0.0, 0.0}, 1e-12);
    expectNear(c.v, {0.0, 0.0, -1.0}, 1e-12);
    EXPECT_EQ(c.width, 64);
    EXPECT_EQ(c.height, 64);
    EXPECT_NEAR(c.pitchU, 2.0, 1e-12);
    EXPECT_NEAR(c.pitchV, 2.0, 1e-12); // from P: square
    EXPECT_NEAR(c.principalOffset.x, 0.0, 1e-9);
    EXPECT_NEAR(c.principalOffset.y, 0.0, 1e-9);
    expectSameMatrix(c.matrix(),
                     cArmCamera(CArm{0.0, 0.0, 1000.0, 500.0}, 64, 64, 2.0, 2.0).matrix());
}

TEST(ProjectionMatrixFile, ObliqueCArmsRoundTripThroughTheFile) {
    const glm::dvec3 iso(12.5, -40.0, 71.0);
    std::vector<ConeCamera> cams;
    for (const auto& [a, b] : {std::pair{35.0, -20.0}, std::pair{-110.0, 42.0},
                               std::pair{179.0, 5.0}, std::pair{0.0, 0.0}})
        cams.push_back(
            cArmCamera(CArm{a, b, 1100.0, 700.0, iso}, 300, 200, 0.4, 0.3, glm::dvec2(3.5, -7.25)));
    const auto path = fvr::test::tmpDir() / "pm_orbit.txt";
    writeProjectionMatrixFile(path, cams);
    const auto back = readProjectionMatrixFile(path);
    ASSERT_EQ(back.size(), cams.size());
    for (std::size_t i = 0; i < cams.size(); ++i) {
        SCOPED_TRACE(i);
        expectSameMatrix(back[i].matrix(), cams[i].matrix());
        // The camera itself: the C-arm's detector centre is the source's foot on the plane.
        expectNear(back[i].source, cams[i].source, 1e-9);
        expectNear(back[i].detectorCentre, cams[i].detectorCentre, 1e-9);
        expectNear(back[i].u, cams[i].u, 1e-12);
        expectNear(back[i].v, cams[i].v, 1e-12);
        EXPECT_NEAR(back[i].pitchU, 0.4, 1e-12);
        EXPECT_NEAR(back[i].pitchV, 0.3, 1e-12);
        EXPECT_NEAR(back[i].principalOffset.x, 3.5, 1e-9);
        EXPECT_NEAR(back[i].principalOffset.y, -7.25, 1e-9);
        EXPECT_NEAR(back[i].sourceToDetector(), 1100.0, 1e-9);
    }
}

TEST(ProjectionMatrixFile, CameraFromAScaledMatrixIsTheSame) {
    const ConeCamera c = cArmCamera(CArm{-30.0, 15.0, 1200.0, 800.0, glm::dvec3(5.0, 6.0, 7.0)},
                                    1240, 960, 0.194, 0.194, glm::dvec2(-12.0, 4.5));
    ProjectionMatrix p = c.matrix();
    for (auto& r : p.rows) r *= 0.0137;
    const ConeCamera back = cameraFromMatrix(p, 1240, 960, 0.194);
    expectSameMatrix(back.matrix(), c.matrix());
    EXPECT_NEAR(back.pitchV, 0.194, 1e-12);
}

TEST(ProjectionMatrixFile, MalformedFilesNameTheFileAndLine) {
    const std::string head = "detector 64 64\npitch 2\n";
    const std::string good = "1000 -63 0 31500\n0 -63 -1000 31500\n0 -2 0 1000\n";
    EXPECT_EQ(readError("pm_ok.txt", head + good), "");
    const auto expectError = [&](const std::string& name, const std::string& text,
                                 const std::string& where, const std::string& what) {
        const std::string m = readError(name, text);
        EXPECT_NE(m.find((fvr::test::tmpDir() / name).string() + where), std::string::npos) << m;
        EXPECT_NE(m.find(what), std::string::npos) << m;
    };
    expectError("pm_three.txt", head + "1000 -63 0\n", ":3: ", "four numbers, found 3");
    expectError("pm_word.txt", head + "1000 -63 zero 31500\n", ":3: ", "found 'zero'");
    expectError("pm_rows.txt", head + good + "1 2 3 4\n", ":6: ", "not a multiple of three");
    expectError("pm_nodet.txt", "pitch 2\n" + good, "", "no 'detector W H' line");
    expectError("pm_nopitch.txt", "detector 64 64\n" + good, "", "no 'pitch PU [PV]' line");
    expectError("pm_twice.txt", head + "detector 32 32\n" + good, ":3: ", "second 'detector'");
    expectError("pm_key.txt", head + "size 3\n" + good, ":3: ", "unknown keyword 'size'");
    expectError("pm_pitch0.txt", "detector 64 64\npitch 0\n" + good, ":2: ", "positive pitch");
    expectError("pm_empty.txt", head, "", "no matrix");
    expectError("pm_singular.txt", head + "1 0 0 0\n2 0 0 0\n0 0 1 0\n", ":3: ", "singular");
    expectError("pm_skew.txt", head + "1000 -63 0 31500\n300 -63 -1000 31500\n0 -2 0 1000\n",
                ":3: ", "skewed");
    expectError("pm_aspect.txt", "detector 64 64\npitch 2 3\n" + good,
                ":3: ", "row pitch 3 mm disagrees with P, which gives 2 mm");
    expectError("pm_size.txt", "detector 8 64\npitch 2\n" + good,
                ":3: ", "detector width: expected 16..4096 pixels, found 8");
    EXPECT_THROW(readProjectionMatrixFile(fvr::test::tmpDir() / "pm_missing.txt"), LoadError);
}

} // namespace
