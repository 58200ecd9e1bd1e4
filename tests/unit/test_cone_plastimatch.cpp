// The cone-beam box model against `plastimatch drr -i exact` (Siddon's exact path lengths, the
// same voxel model, written independently). First the oracle's own conventions are checked
// against facts that need neither renderer: plastimatch's projection matrix against our P, a
// uniform box's chord lengths worked out here, one bright voxel landing where P says (in
// plastimatch's image and in ours); then the box model against plastimatch on a phantom and on
// the Philips CT at oblique C-arm angles. Skipped, with the reason, where plastimatch is missing
// (`make test` installs it).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/geometry/camera.h>
#include <fvr/core/render/cone_projector.h>
#include <fvr/core/xray/phantom.h>

#include "image_metrics.h"
#include "support/plastimatch.h"
#include "test_support.h"

namespace {

using namespace fvr::core;
using fvr::test::compare;
using fvr::test::runPlastimatchDrr;

#define FVR_REQUIRE_PLASTIMATCH()                                                                  \
    do {                                                                                           \
        if (const std::string why = fvr::test::plastimatchMissing(); !why.empty())                 \
            GTEST_SKIP() << why;                                                                   \
    } while (0)

/** A scratch folder of the running test's own (ctest runs tests in parallel processes). */
std::filesystem::path work(const std::string& name) {
    const auto* test = ::testing::UnitTest::GetInstance()->current_test_info();
    return fvr::test::tmpDir() / "plastimatch" / (std::string(test->name()) + "_" + name);
}

/** N voxels of spacing s filled by f(i, j, k), index axes along `dir`, centred on `centre`. */
template <class F>
Volume makeVolume(const Dims3& n, const Vec3& s, F&& f, const glm::dmat3& dir,
                  const glm::dvec3& centre) {
    Volume v;
    v.dims = n;
    v.spacing = s;
    v.direction = dir;
    for (int b = 0; b < 3; ++b) {
        v.origin[b] = centre[b];
        for (int a = 0; a < 3; ++a) v.origin[b] -= dir[a][b] * s[a] * (n[a] - 1) / 2.0;
    }
    v.voxels.resize(std::size_t(n[0] * n[1] * n[2]));
    for (std::int64_t k = 0; k < n[2]; ++k)
        for (std::int64_t j = 0; j < n[1]; ++j)
            for (std::int64_t i = 0; i < n[0]; ++i) v.voxels[v.index(i, j, k)] = f(i, j, k);
    return v;
}

const glm::dmat3 kIdentity{Vec3{1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}};
/** A proper rotation that permutes the axes: index x runs toward -z, y toward +x, z toward -y. */
const glm::dmat3 kRotated{Vec3{0, 0, -1}, Vec3{1, 0, 0}, Vec3{0, -1, 0}};
/** A mirror (determinant -1): index x runs toward the patient's right. */
const glm::dmat3 kMirrored{Vec3{-1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}};

/** Voxel (i, j, k)'s centre in LPS. */
glm::dvec3 voxelCentre(const Volume& v, double i, double j, double k) {
    const double q[3] = {i, j, k};
    glm::dvec3 x(v.origin[0], v.origin[1], v.origin[2]);
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) x[b] += v.direction[a][b] * v.spacing[a] * q[a];
    return x;
}

/** The path-length-weighted centroid (col, row) of an image. */
glm::dvec2 centroid(const std::vector<float>& px, int w, int h) {
    double sw = 0, sc = 0, sr = 0;
    for (int row = 0; row < h; ++row)
        for (int col = 0; col < w; ++col) {
            const double p = px[std::size_t(row) * w + col];
            sw += p;
            sc += p * col;
            sr += p * row;
        }
    return {sc / sw, sr / sw};
}

/** The chord of the segment [from, to] through the index box [lo, hi] (index units, per axis),
 *  by the slab method in the volume's index frame: independent of both renderers. */
double indexBoxChord(const Volume& v, const glm::dvec3& from, const glm::dvec3& to,
                     const glm::dvec3& lo, const glm::dvec3& hi) {
    double t0 = 0.0, t1 = 1.0;
    for (int a = 0; a < 3; ++a) {
        const glm::dvec3 dir(v.direction[a][0], v.direction[a][1], v.direction[a][2]);
        const glm::dvec3 o(v.origin[0], v.origin[1], v.origin[2]);
        const double p = glm::dot(dir, from - o) / v.spacing[a];
        const double d = glm::dot(dir, to - from) / v.spacing[a];
        double ta = (lo[a] - p) / d, tb = (hi[a] - p) / d;
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    return t1 > t0 ? (t1 - t0) * glm::length(to - from) : 0.0;
}

/** The chord through the voxel cells' box, [-1/2, N - 1/2] per index axis. */
double boxChord(const Volume& v, const glm::dvec3& from, const glm::dvec3& to) {
    return indexBoxChord(v, from, to, glm::dvec3(-0.5),
                         glm::dvec3(v.dims[0], v.dims[1], v.dims[2]) - 0.5);
}

TEST(PlastimatchOracle, ItsMatrixPutsPointsWhereOurPDoes) {
    FVR_REQUIRE_PLASTIMATCH();
    // A non-square detector, unequal pitches, a principal-point offset, and every kind of
    // volume frame: the mapping of plastimatch.h must hold for each.
    const glm::dvec3 centre(12.0, -30.0, 40.0);
    std::mt19937 rng(29);
    std::uniform_real_distribution<double> inside(-20.0, 20.0);
    for (const auto& dir : {kIdentity, kRotated, kMirrored}) {
        const Volume v = makeVolume(
            {20, 16, 12}, {2.0, 2.5, 3.0}, [](auto...) { return 1.0f; }, dir, centre);
        const ConeCamera cam =
            cArmCamera({30.0, 20.0, 1000.0, 700.0, centre}, 96, 64, 0.8, 1.1, {3.5, -2.25});
        const auto plm = runPlastimatchDrr(v, cam, work("matrix"));
        const ProjectionMatrix p = cam.matrix();
        for (int n = 0; n < 50; ++n) {
            const glm::dvec3 x = centre + glm::dvec3(inside(rng), inside(rng), inside(rng));
            const glm::dvec3 ours = p.apply(x);
            const glm::dvec2 theirs = plm.project(v, x);
            // plastimatch parses its options as float: ~1e-5 pixel.
            EXPECT_NEAR(theirs.x, ours.x, 1e-3) << "direction " << dir[0][0] << dir[0][2];
            EXPECT_NEAR(theirs.y, ours.y, 1e-3) << "direction " << dir[0][0] << dir[0][2];
        }
        // plastimatch looks from the source: its columns are ours mirrored, unless the volume's
        // frame is itself a mirror.
        EXPECT_EQ(plm.mirrorColumns, glm::dot(dir[0], glm::cross(dir[1], dir[2])) > 0.0);
    }
}

TEST(PlastimatchOracle, AUniformBoxGivesItsChordLengths) {
    FVR_REQUIRE_PLASTIMATCH();
    // Value 1: every pixel is the chord through the voxel cells' box. Unpadded, plastimatch
    // would leave out each ray's last voxel (up to 3 mm here); the helper's zero layer makes it
    // exact.
    const glm::dvec3 centre(5.0, 10.0, -20.0);
    for (const auto& dir : {kIdentity, kRotated, kMirrored}) {
        const Volume v = makeVolume(
            {20, 16, 12}, {2.0, 2.5, 3.0}, [](auto...) { return 1.0f; }, dir, centre);
        const ConeCamera cam =
            cArmCamera({-40.0, 15.0, 900.0, 600.0, centre}, 64, 48, 1.5, 1.5, {1.0, 0.5});
        const auto plm = runPlastimatchDrr(v, cam, work("chord"));
        double maxErr = 0.0, maxChord = 0.0;
        for (int row = 0; row < cam.height; ++row)
            for (int col = 0; col < cam.width; ++col) {
                const double chord = boxChord(v, cam.source, cam.pixelCentre(col, row));
                maxChord = std::max(maxChord, chord);
                maxErr = std::max(maxErr, std::abs(plm.pixels[row * cam.width + col] - chord));
            }
        std::printf("plastimatch vs the box's chords: max error %.2g mm (longest chord %.1f mm)\n",
                    maxErr, maxChord);
        EXPECT_GT(maxChord, 40.0); // the box is in view
        EXPECT_LT(maxErr, 1e-3);
    }
}

TEST(PlastimatchOracle, ABrightVoxelLandsWherePSaysInItsImageAndOurs) {
    FVR_REQUIRE_PLASTIMATCH();
    // One voxel of 1 x 1.5 x 2 mm, 25 mm to the patient's left, 16 mm toward the head and 9 mm
    // anterior of the isocentre, in a mirrored volume. Every pixel must hold 1000 x the chord of
    // its ray through that voxel (worked out here), and the footprint sit where P puts the
    // voxel's centre: at AP (0/0) right of centre (the patient's left on the viewer's right, as
    // a radiograph is read) and above it, magnified by SID over its depth.
    const glm::dvec3 iso(0.0);
    Volume v = makeVolume(
        {71, 61, 51}, {1.0, 1.5, 2.0}, [](auto...) { return 0.0f; }, kMirrored, iso);
    const glm::dvec3 spot(25.0, -9.0, 16.0); // voxel (10, 24, 33): x = 35 - i, y = -45 + 1.5 j
    const glm::dvec3 voxel(10, 24, 33);
    v.voxels[v.index(10, 24, 33)] = 1000.0f;
    ASSERT_LT(glm::length(voxelCentre(v, 10, 24, 33) - spot), 1e-9);
    ConeProjector ours(v, {RayModel::Box});
    for (const auto& [a, b] : {std::pair{0.0, 0.0}, std::pair{30.0, 20.0}}) {
        const ConeCamera cam = cArmCamera({a, b, 1000.0, 750.0, iso}, 320, 256, 0.25, 0.25);
        const glm::dvec3 expected = cam.matrix().apply(spot);
        ASSERT_TRUE(expected.x > 20 && expected.x < 300 && expected.y > 20 && expected.y < 236);
        const auto plm = runPlastimatchDrr(v, cam, work("voxel"));
        const DetectorImage img = ours.project(cam);
        double maxErrTheirs = 0.0, maxErrOurs = 0.0;
        int lit = 0;
        for (int row = 0; row < cam.height; ++row)
            for (int col = 0; col < cam.width; ++col) {
                const double want = 1000.0 * indexBoxChord(v, cam.source, cam.pixelCentre(col, row),
                                                           voxel - 0.5, voxel + 0.5);
                lit += want > 0.0;
                const std::size_t k = std::size_t(row) * cam.width + col;
                maxErrTheirs = std::max(maxErrTheirs, std::abs(plm.pixels[k] - want));
                maxErrOurs = std::max(maxErrOurs, std::abs(img.pixels[k] - want));
            }
        const glm::dvec2 theirs = centroid(plm.pixels, cam.width, cam.height);
        const glm::dvec2 mine = centroid(img.pixels, cam.width, cam.height);
        std::printf("bright voxel at LAO %g CRAN %g: %d pixels lit, max error against its chords "
                    "%.2g (plastimatch), %.2g (ours); footprint centroid (%.3f, %.3f) "
                    "(plastimatch), (%.3f, %.3f) (ours); P (%.3f, %.3f)\n",
                    a, b, lit, maxErrTheirs, maxErrOurs, theirs.x, theirs.y, mine.x, mine.y,
                    expected.x, expected.y);
        EXPECT_GT(lit, 20);
        EXPECT_LT(maxErrTheirs, 1e-2) << "LAO " << a << " CRAN " << b; // of chords x 1000 ~ 2000
        EXPECT_LT(maxErrOurs, 1e-2) << "LAO " << a << " CRAN " << b;
        // The footprint is a few pixels wide and sampled at pixel centres: its centroid is off
        // the projected centre by less than half a pixel (the samples of a box), whichever way.
        for (const glm::dvec2& c : {theirs, mine}) {
            EXPECT_NEAR(c.x, expected.x, 0.5) << "LAO " << a << " CRAN " << b;
            EXPECT_NEAR(c.y, expected.y, 0.5) << "LAO " << a << " CRAN " << b;
        }
        if (a == 0.0) {
            // At AP the source is 750 mm posterior: the voxel, 9 mm anterior, is 759 mm deep.
            EXPECT_NEAR(expected.x, 159.5 + 25.0 * 1000.0 / 759.0 / 0.25, 1e-9);
            EXPECT_NEAR(expected.y, 127.5 - 16.0 * 1000.0 / 759.0 / 0.25, 1e-9);
            EXPECT_GT(theirs.x, 159.5 + 100.0); // far right of centre
            EXPECT_LT(theirs.y, 127.5 - 60.0); // far above it
        }
    }
}

/** Our box model against plastimatch for one camera: the PSNR, printed. */
double boxAgainstPlastimatch(const Volume& v, ConeProjector& ours, const ConeCamera& cam,
                             const std::string& what, bool reuseVolume) {
    const auto t0 = std::chrono::steady_clock::now();
    const DetectorImage img = ours.project(cam);
    const double oursS =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const auto plm = runPlastimatchDrr(v, cam, work("box"), "exact", reuseVolume);
    const auto cmp = compare(img.pixels, plm.pixels);
    std::printf("box model vs plastimatch -i exact, %s: %.1f dB (max error %.3g of peak %.4g; "
                "ours %.3f s, plastimatch %.3f s)\n",
                what.c_str(), cmp.psnr, cmp.maxAbsError, cmp.peak, oursS, plm.seconds);
    return cmp.psnr;
}

TEST(ConeVsPlastimatch, BoxModelEqualsPlastimatchExactOnThePhantomAtObliqueAngles) {
    FVR_REQUIRE_PLASTIMATCH();
    // The chest phantom in HU (air -1000 inside the box), raw values: both integrate HU x mm.
    Volume v = makeChestPhantomVolume(64);
    const glm::dvec3 iso = volumeCentre(v);
    ConeProjector ours(v, {RayModel::Box});
    bool reuse = false;
    for (const auto& [a, b] : {std::pair{30.0, 20.0}, std::pair{-45.0, -15.0}}) {
        const double pitch = framingPitch(v, 1200.0, 750.0, 128, 128);
        const ConeCamera cam = cArmCamera({a, b, 1200.0, 750.0, iso}, 128, 128, pitch, pitch);
        char what[64];
        std::snprintf(what, sizeof what, "chest phantom 64^3, LAO %g CRAN %g", a, b);
        EXPECT_GE(boxAgainstPlastimatch(v, ours, cam, what, reuse), 60.0) << what;
        reuse = true;
    }
}

TEST(ConeVsPlastimatch, BoxModelEqualsPlastimatchExactOnARotatedAndOnAMirroredVolume) {
    FVR_REQUIRE_PLASTIMATCH();
    // Shepp-Logan voxels on a grid whose index axes are permuted, then mirrored: our caster
    // reads the direction cosines, plastimatch gets the camera moved into the grid's frame.
    const Volume sl = makeSheppLoganVolume(48);
    for (const auto& dir : {kRotated, kMirrored}) {
        const Volume v = makeVolume(sl.dims, {4.0, 5.0, 6.0},
                                    [&](auto i, auto j, auto k) { return sl.at(i, j, k); }, dir,
                                    {10.0, -5.0, 20.0});
        ConeProjector ours(v, {RayModel::Box});
        const ConeCamera cam = cArmCamera({30.0, 20.0, 1200.0, 750.0, {10.0, -5.0, 20.0}}, 128, 96,
                                          3.0, 3.5, {4.0, -3.0});
        const std::string what = dir[0][0] == -1.0 ? "mirrored Shepp-Logan 48^3, LAO 30 CRAN 20"
                                                   : "rotated Shepp-Logan 48^3, LAO 30 CRAN 20";
        EXPECT_GE(boxAgainstPlastimatch(v, ours, cam, what, false), 60.0) << what;
    }
}

/** The mean of each bx x by x bz block (the CT made small enough for a test of seconds). */
Volume downsample(const Volume& in, int bx, int by, int bz) {
    Volume out;
    const int b[3] = {bx, by, bz};
    for (int a = 0; a < 3; ++a) {
        out.dims[a] = in.dims[a] / b[a];
        out.spacing[a] = in.spacing[a] * b[a];
    }
    out.direction = in.direction;
    out.units = in.units;
    // The block's centre: (b - 1) / 2 voxels in from the first voxel.
    for (int c = 0; c < 3; ++c) {
        out.origin[c] = in.origin[c];
        for (int a = 0; a < 3; ++a)
            out.origin[c] += in.direction[a][c] * in.spacing[a] * (b[a] - 1) / 2.0;
    }
    out.voxels.assign(std::size_t(out.voxelCount()), 0.0f);
    for (std::int64_t k = 0; k < out.dims[2]; ++k)
        for (std::int64_t j = 0; j < out.dims[1]; ++j)
            for (std::int64_t i = 0; i < out.dims[0]; ++i) {
                double s = 0.0;
                for (int dk = 0; dk < bz; ++dk)
                    for (int dj = 0; dj < by; ++dj)
                        for (int di = 0; di < bx; ++di)
                            s += in.at(i * bx + di, j * by + dj, k * bz + dk);
                out.voxels[out.index(i, j, k)] = float(s / (bx * by * bz));
            }
    return out;
}

TEST(ConeVsPlastimatch, BoxModelEqualsPlastimatchExactOnThePhilipsCT) {
    FVR_REQUIRE_PLASTIMATCH();
    FVR_REQUIRE_DATA("dicom/ct_phantom_philips_512x512x140");
    const Volume ct = downsample(
        loadDicomFolder(fvr::test::sharedData() / "dicom/ct_phantom_philips_512x512x140").volume, 4,
        4, 2);
    ASSERT_EQ(ct.dims, (Dims3{128, 128, 70}));
    const glm::dvec3 iso = volumeCentre(ct);
    ConeProjector ours(ct, {RayModel::Box});
    bool reuse = false;
    for (const auto& [a, b] : {std::pair{30.0, 20.0}, std::pair{-60.0, -25.0}}) {
        const double pitch = framingPitch(ct, 1200.0, 750.0, 128, 128);
        const ConeCamera cam = cArmCamera({a, b, 1200.0, 750.0, iso}, 128, 128, pitch, pitch);
        char what[80];
        std::snprintf(what, sizeof what, "Philips CT 128x128x70 (HU), LAO %g CRAN %g", a, b);
        EXPECT_GE(boxAgainstPlastimatch(ct, ours, cam, what, reuse), 60.0) << what;
        reuse = true;
    }
}

} // namespace
