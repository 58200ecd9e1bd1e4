// The registration's parts against hand-worked cases: the pose's parameters and matrix, the
// camera at a pose, the target error, NCC and gradient NCC, the image and CT pyramids, the
// coverage mask, pose files and target points.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>

#include <unistd.h>

#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/registration/registration.h>
#include <fvr/core/registration/registration_io.h>

#include "test_support.h"

using namespace fvr::core;

namespace {

glm::dvec3 apply(const glm::dmat4& t, const glm::dvec3& x) {
    return glm::dvec3(t * glm::dvec4(x, 1.0));
}

ConeCamera testCamera() {
    CArm arm;
    arm.primaryDeg = 30.0;
    arm.secondaryDeg = -10.0;
    arm.isocentre = {5.0, -3.0, 12.0};
    return cArmCamera(arm, 96, 80, 1.5, 1.5, {2.0, -1.0});
}

/** A small CT in HU: a water cylinder along z with two bone rods, 4 mm voxels. */
Volume rodPhantom(int n = 40) {
    Volume v;
    v.dims = {n, n, n};
    v.spacing = {4.0, 4.0, 4.0};
    v.origin = {-(n - 1) * 2.0, -(n - 1) * 2.0, -(n - 1) * 2.0};
    v.units = ValueUnits::HounsfieldUnits;
    v.voxels.assign(std::size_t(n) * n * n, -1000.0f);
    for (int z = 0; z < n; ++z)
        for (int y = 0; y < n; ++y)
            for (int x = 0; x < n; ++x) {
                const double px = x * 4.0 + v.origin.x, py = y * 4.0 + v.origin.y;
                const double pz = z * 4.0 + v.origin.z;
                float hu = -1000.0f;
                if (px * px + py * py < 60.0 * 60.0) hu = 0.0f;
                if (std::hypot(px - 25.0, py + 10.0) < 8.0 && pz < 40.0) hu = 1200.0f;
                if (std::hypot(px + 20.0, py - 15.0 + 0.3 * pz) < 6.0) hu = 900.0f;
                v.voxels[v.index(x, y, z)] = hu;
            }
    return v;
}

/** A scratch folder of this test process (ctest runs tests in parallel processes). */
std::filesystem::path scratch(const std::string& name) {
    const auto p = fvr::test::tmpDir() / (name + "-" + std::to_string(::getpid()));
    std::filesystem::create_directories(p);
    return p;
}

} // namespace

TEST(RegistrationPose, RotationsFollowTheDocumentedOrderAndSigns) {
    // +90 about z turns x (left) into y (posterior).
    const glm::dvec3 x = rotationMatrix({0, 0, 90}) * glm::dvec3(1, 0, 0);
    EXPECT_NEAR(x.x, 0.0, 1e-12);
    EXPECT_NEAR(x.y, 1.0, 1e-12);
    // x first, then z: Rx(90) sends y to z, Rz(90) leaves z alone.
    const glm::dvec3 y = rotationMatrix({90, 0, 90}) * glm::dvec3(0, 1, 0);
    EXPECT_NEAR(y.z, 1.0, 1e-12);
    // The other order would send y to -x first (Rz), then Rx keeps -x: the order is visible.
    const glm::dvec3 yx =
        rotationMatrix({90, 0, 0}) * (rotationMatrix({0, 0, 90}) * glm::dvec3(0, 1, 0));
    EXPECT_NEAR(yx.x, -1.0, 1e-12);
}

TEST(RegistrationPose, MatrixRotatesAboutTheCentreThenTranslates) {
    const glm::dvec3 c(10, 20, 30);
    Pose p;
    p.rotationDeg = {0, 0, 90};
    p.translationMm = {1, 2, 3};
    const glm::dmat4 t = poseMatrix(p, c);
    // The centre moves by the translation only; a point 10 mm left of it turns to 10 mm behind.
    const glm::dvec3 tc = apply(t, c);
    EXPECT_NEAR(glm::length(tc - (c + glm::dvec3(1, 2, 3))), 0.0, 1e-12);
    const glm::dvec3 tl = apply(t, c + glm::dvec3(10, 0, 0));
    EXPECT_NEAR(glm::length(tl - (c + glm::dvec3(1, 12, 3))), 0.0, 1e-12);
}

TEST(RegistrationPose, ParametersComeBackFromTheMatrix) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> a(-80, 80), m(-50, 50);
    const glm::dvec3 c(3, -4, 5);
    for (int i = 0; i < 50; ++i) {
        Pose p;
        p.rotationDeg = {a(rng), a(rng), a(rng)};
        p.translationMm = {m(rng), m(rng), m(rng)};
        const Pose q = poseFromMatrix(poseMatrix(p, c), c);
        for (int k = 0; k < 3; ++k) {
            EXPECT_NEAR(q.rotationDeg[k], p.rotationDeg[k], 1e-9);
            EXPECT_NEAR(q.translationMm[k], p.translationMm[k], 1e-9);
        }
    }
}

TEST(RegistrationPose, NonRigidMatricesAreRefused) {
    glm::dmat4 scale(1.0);
    scale[0][0] = 1.01;
    EXPECT_THROW(validateRigid(scale), SettingsError);
    glm::dmat4 mirror(1.0);
    mirror[2][2] = -1.0;
    EXPECT_THROW(validateRigid(mirror), SettingsError);
    glm::dmat4 row(1.0);
    row[0][3] = 0.5; // last row not 0 0 0 1
    EXPECT_THROW(validateRigid(row), SettingsError);
    EXPECT_NO_THROW(validateRigid(poseMatrix({{10, 20, 30}, {1, 2, 3}}, {0, 0, 0})));
}

TEST(RegistrationPose, PosedCameraShowsXWhereTheCameraShowsTX) {
    const ConeCamera cam = testCamera();
    const glm::dmat4 t = poseMatrix({{7, -4, 12}, {15, -8, 22}}, {1, 2, 3});
    const ConeCamera posed = posedCamera(cam, t);
    const ProjectionMatrix p = cam.matrix(), q = posed.matrix();
    for (const glm::dvec3 x :
         {glm::dvec3(0, 0, 0), glm::dvec3(40, -30, 55), glm::dvec3(-70, 20, -5)}) {
        const glm::dvec3 a = p.apply(apply(t, x)), b = q.apply(x);
        EXPECT_NEAR(a.x, b.x, 1e-9);
        EXPECT_NEAR(a.y, b.y, 1e-9);
        EXPECT_NEAR(a.z, b.z, 1e-9);
    }
    // The identity leaves the camera as it is.
    const ConeCamera same = posedCamera(cam, glm::dmat4(1.0));
    EXPECT_NEAR(glm::length(same.source - cam.source), 0.0, 1e-12);
}

TEST(RegistrationPose, TargetErrorOfAKnownShiftAndRotation) {
    const glm::dvec3 c(0, 0, 0);
    const std::vector<glm::dvec3> corners = cubeCorners(c, 100.0);
    ASSERT_EQ(corners.size(), 8u);
    // A 1 mm shift moves every target by 1 mm.
    EXPECT_NEAR(
        meanTargetError(glm::dmat4(1.0), poseMatrix({{0, 0, 0}, {0.6, 0, -0.8}}, c), corners), 1.0,
        1e-12);
    // A rotation by a about z moves each corner, 50 sqrt 2 from the axis, by 2 r sin(a / 2).
    const double a = 3.0;
    const double expected = 2.0 * 50.0 * std::sqrt(2.0) * std::sin(a * std::numbers::pi / 360.0);
    EXPECT_NEAR(meanTargetError(glm::dmat4(1.0), poseMatrix({{0, 0, a}, {0, 0, 0}}, c), corners),
                expected, 1e-12);
    EXPECT_NEAR(expected, 3.7020, 1e-4); // hand-worked: 141.42 x sin(1.5 deg)
    EXPECT_THROW(meanTargetError(glm::dmat4(1.0), glm::dmat4(1.0), {}), SettingsError);
}

TEST(RegistrationSimilarity, NccIsOneForAffineCopiesAndMinusOneForNegatives) {
    std::vector<float> a(200), b(200), c(200);
    for (int i = 0; i < 200; ++i) {
        a[i] = float(std::sin(i * 0.1) + 0.01 * i);
        b[i] = 3.0f * a[i] + 7.0f;
        c[i] = -a[i];
    }
    EXPECT_NEAR(ncc(a.data(), b.data(), nullptr, a.size()), 1.0, 1e-6);
    EXPECT_NEAR(ncc(a.data(), c.data(), nullptr, a.size()), -1.0, 1e-6);
    std::vector<float> flat(200, 2.0f);
    EXPECT_EQ(ncc(a.data(), flat.data(), nullptr, a.size()), 0.0);
    // The mask leaves out a disagreeing half.
    std::vector<std::uint8_t> mask(200, 0);
    for (int i = 0; i < 100; ++i) mask[i] = 1;
    for (int i = 100; i < 200; ++i) b[i] = float(i % 7);
    EXPECT_NEAR(ncc(a.data(), b.data(), mask.data(), a.size()), 1.0, 1e-6);
    EXPECT_LT(ncc(a.data(), b.data(), nullptr, a.size()), 0.9);
}

TEST(RegistrationSimilarity, GradientNccIgnoresARampThatNccDoesNot) {
    const int w = 64, h = 48;
    std::vector<float> a(w * h), b(w * h);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            a[y * w + x] = float(std::exp(-((x - 30) * (x - 30) + (y - 20) * (y - 20)) / 40.0));
            b[y * w + x] = 2.0f * a[y * w + x] + 0.05f * x + 0.03f * y; // + a plane
        }
    EXPECT_NEAR(gradientNcc(a.data(), b.data(), nullptr, w, h), 1.0, 1e-5);
    EXPECT_LT(ncc(a.data(), b.data(), nullptr, w * h), 0.8);
    // A shift of the blob lowers it.
    std::vector<float> s(w * h);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            s[y * w + x] = float(std::exp(-((x - 33) * (x - 33) + (y - 20) * (y - 20)) / 40.0));
    EXPECT_LT(gradientNcc(a.data(), s.data(), nullptr, w, h), 0.8);
    EXPECT_EQ(parseSimilarity("gc"), SimilarityMeasure::GradientNcc);
    EXPECT_THROW(parseSimilarity("mi"), SettingsError);
}

TEST(RegistrationSimilarity, APreparedTargetScoresAsTheMeasureDoes) {
    // The X-ray's derivatives taken once give the same numbers as taking them at every call,
    // over the target's mask and an extra mask together.
    const int w = 40, h = 30;
    MaskedImage x{w, h, std::vector<float>(w * h), std::vector<std::uint8_t>(w * h, 1)};
    std::vector<float> m(w * h);
    std::vector<std::uint8_t> extra(w * h, 1), both(w * h, 1);
    for (int i = 0; i < w * h; ++i) {
        x.pixels[i] = float(std::sin(i * 0.37));
        m[i] = float(std::cos(i * 0.21));
        x.mask[i] = i % 7 != 0;
        extra[i] = i % 5 != 0;
        both[i] = x.mask[i] && extra[i];
    }
    for (SimilarityMeasure s : {SimilarityMeasure::Ncc, SimilarityMeasure::GradientNcc}) {
        const SimilarityTarget t(s, x);
        EXPECT_EQ(t.score(m.data(), extra.data()),
                  similarity(s, m.data(), x.pixels.data(), both.data(), w, h));
        EXPECT_EQ(t.score(m.data()), similarity(s, m.data(), x.pixels.data(), x.mask.data(), w, h));
        EXPECT_LT(std::abs(t.score(m.data())), 0.9); // unrelated images
    }
}

TEST(RegistrationPyramid, DownsampledPixelsSitAtTheirBlocksCentres) {
    const ConeCamera cam = testCamera(); // 96 x 80, principal offset (2, -1)
    for (int f : {2, 3, 5}) {
        const ConeCamera d = downsampleCamera(cam, f);
        EXPECT_EQ(d.width, 96 / f);
        EXPECT_EQ(d.height, 80 / f);
        for (int row : {0, d.height - 1})
            for (int col : {0, 3, d.width - 1}) {
                glm::dvec3 mean(0.0);
                for (int j = 0; j < f; ++j)
                    for (int i = 0; i < f; ++i) mean += cam.pixelCentre(col * f + i, row * f + j);
                mean /= double(f * f);
                EXPECT_NEAR(glm::length(d.pixelCentre(col, row) - mean), 0.0, 1e-9) << f;
            }
    }
    MaskedImage img{4,
                    4,
                    {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16},
                    {1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0}};
    const MaskedImage half = downsampleImage(img, 2);
    ASSERT_EQ(half.pixels.size(), 4u);
    EXPECT_FLOAT_EQ(half.pixels[0], 3.5f); // (1 + 2 + 5 + 6) / 4
    EXPECT_FLOAT_EQ(half.pixels[3], 13.5f);
    EXPECT_EQ(half.mask[0], 1);
    EXPECT_EQ(half.mask[3], 0); // one pixel of its block was out
}

TEST(RegistrationPyramid, BlockMeanCtKeepsItsCentreAndLineIntegrals) {
    const Volume ct = rodPhantom(40);
    const Volume half = downsampleVolume(ct, 8.0);
    EXPECT_EQ(half.dims[0], 20);
    EXPECT_DOUBLE_EQ(half.spacing[0], 8.0);
    EXPECT_NEAR(glm::length(volumeCentre(half) - volumeCentre(ct)), 0.0, 1e-9);
    // The mean value, hence a broad view's total line integral, is kept.
    double a = 0.0, b = 0.0;
    for (float v : ct.voxels) a += v;
    for (float v : half.voxels) b += v;
    EXPECT_NEAR(a / double(ct.voxels.size()), b / double(half.voxels.size()), 1e-3);
    // 1 voxel left over of 41: the centre moves by half an input voxel at most.
    const Volume odd = downsampleVolume(rodPhantom(41), 8.0);
    const glm::dvec3 moved = volumeCentre(odd) - volumeCentre(rodPhantom(41));
    for (int axis = 0; axis < 3; ++axis) EXPECT_LE(std::abs(moved[axis]), 2.0 + 1e-9);
    EXPECT_EQ(downsampleVolume(ct, 0.0).dims, ct.dims);
    EXPECT_EQ(volumeBlockFactors(ct, 8.0), (Dims3{2, 2, 2}));
    EXPECT_EQ(volumeBlockFactors(ct, 5.0), (Dims3{1, 1, 1})); // round(5 / 4) = 1
    EXPECT_EQ(volumeBlockFactors(ct, 0.0), (Dims3{1, 1, 1}));
    EXPECT_EQ(volumeBlockFactors(ct, 1000.0), (Dims3{40, 40, 40})); // at most the whole axis
}

TEST(RegistrationCoverage, RaysThroughTheCutEndsAreLeftOut) {
    // 40 slices of 4 mm: z in [-80, 80]. An AP C-arm (source posterior) at SOD 750 / SID 1000:
    // a row at the isocentre plane's z = 70 sees the CT across; the central row's rays cross
    // the whole cut; a row at z beyond 80 x 750/750 misses; rows whose rays enter through the
    // top face are out.
    const Volume ct = rodPhantom(40);
    CArm arm;
    arm.isocentre = volumeCentre(ct);
    const ConeCamera cam = cArmCamera(arm, 64, 64, 4.0, 4.0);
    const std::vector<std::uint8_t> mask = coverageMask(ct, cam, glm::dmat4(1.0));
    // Row j's ray reaches z = (j - 31.5) x 4 x (-1) at the detector (rows run to the feet)...
    auto in = [&](int col, int row) { return mask[std::size_t(row) * 64 + col] != 0; };
    EXPECT_TRUE(in(32, 32));
    EXPECT_FALSE(in(32, 0)); // z = +126 mm at the detector: above the CT at every depth
    // The top edge: a ray at detector height z_d is at z_d (750 - 80) / 1000 on the CT's
    // source side and z_d (750 + 80) / 1000 on the detector side; it is inside across the cut
    // only when the latter is below 80 (z_d < 96.4 mm: rows from 8 on).
    EXPECT_FALSE(in(32, 7)); // z_d = 98 mm
    EXPECT_TRUE(in(32, 9)); // z_d = 90 mm
    // A pose that lifts the CT by 20 mm lifts the covered band.
    const std::vector<std::uint8_t> up =
        coverageMask(ct, cam, poseMatrix({{0, 0, 0}, {0, 0, 20}}, arm.isocentre));
    EXPECT_TRUE(up[std::size_t(5) * 64 + 32] != 0); // z_d = 106 mm: now across the cut
}

TEST(RegistrationFiles, PoseFilesRoundTripAndBadShapesAreRefused) {
    const auto dir = scratch("registration_files");
    const glm::dvec3 c(1, 2, 3);
    const glm::dmat4 t = poseMatrix({{4, -5, 6}, {7, 8, -9}}, c);
    writePoseJson(dir / "pose.json", t, c);
    const glm::dmat4 back = readPoseJson(dir / "pose.json", {0, 0, 0});
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) EXPECT_NEAR(back[i][j], t[i][j], 1e-12);
    // Angles and translation about a stated centre give the same matrix.
    std::ofstream(dir / "angles.json")
        << R"({"rotation_deg": [4, -5, 6], "translation_mm": [7, 8, -9], "centre_mm": [1, 2, 3]})";
    const glm::dmat4 angles = readPoseJson(dir / "angles.json", {0, 0, 0});
    EXPECT_NEAR(angles[3][0], t[3][0], 1e-12);
    std::ofstream(dir / "short.json")
        << R"({"matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]]})";
    try {
        readPoseJson(dir / "short.json", c);
        FAIL() << "a 3-row matrix was read";
    } catch (const LoadError& e) {
        EXPECT_NE(std::string(e.what()).find("short.json"), std::string::npos);
        EXPECT_NE(std::string(e.what()).find("4 rows"), std::string::npos);
    }
    std::ofstream(dir / "scaled.json")
        << R"({"matrix": [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]})";
    EXPECT_THROW(readPoseJson(dir / "scaled.json", c), LoadError);
    std::ofstream(dir / "text.json") << "not json";
    EXPECT_THROW(readPoseJson(dir / "text.json", c), LoadError);
}

TEST(RegistrationFiles, TargetPointsWithHeaderAndCommentsAndBadLines) {
    const auto dir = scratch("registration_targets");
    std::ofstream(dir / "t.csv") << "x,y,z\n# a comment\n1,2,3\n\n-4.5, 5, 6e1 # tip\n";
    const std::vector<glm::dvec3> t = readTargetsCsv(dir / "t.csv");
    ASSERT_EQ(t.size(), 2u);
    EXPECT_DOUBLE_EQ(t[1].z, 60.0);
    std::ofstream(dir / "bad.csv") << "1,2,3\n4,5\n";
    try {
        readTargetsCsv(dir / "bad.csv");
        FAIL();
    } catch (const LoadError& e) {
        EXPECT_NE(std::string(e.what()).find("line 2"), std::string::npos);
    }
}
