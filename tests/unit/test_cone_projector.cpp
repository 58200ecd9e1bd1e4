// The cone-beam ray caster against independent oracles: a plain fine-step trilinear integration
// written here, the analytic chord integrals of ellipsoids, the parallel reference projector in
// the limit SID -> infinity, the camera's projection matrix (where a blob lands), and
// hand-worked cases (a uniform cube's chord, the flat field, bad views).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>

#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/io/volume_io.h>
#include <fvr/core/render/cone_projector.h>
#include <fvr/core/render/spatial_projector.h>
#include <fvr/core/xray/patient_views.h>
#include <fvr/core/xray/phantom.h>
#include <fvr/core/xray/xray.h>

#include "image_metrics.h"
#include "test_support.h"

namespace {

using namespace fvr::core;
using fvr::test::compare;

/** A volume of N^3 voxels of the given spacing filled by f(i, j, k), origin so that its centre
 *  is `centre`, direction cosines the identity. */
template <class F>
Volume makeVolume(const Dims3& N, const Vec3& s, F&& f, const Vec3& centre = {0, 0, 0}) {
    Volume v;
    v.dims = N;
    v.spacing = s;
    for (int a = 0; a < 3; ++a) v.origin[a] = centre[a] - (N[a] - 1) / 2.0 * s[a];
    v.voxels.resize(std::size_t(N[0] * N[1] * N[2]));
    for (std::int64_t k = 0; k < N[2]; ++k)
        for (std::int64_t j = 0; j < N[1]; ++j)
            for (std::int64_t i = 0; i < N[0]; ++i) v.voxels[v.index(i, j, k)] = f(i, j, k);
    return v;
}

/** The independent oracle: trilinear interpolation with explicit bounds (zero outside the
 *  voxel grid), integrated from the source to each pixel centre with the midpoint rule at a
 *  fine step, in LPS through the volume's matrix inverted by hand for its axis-aligned case. */
std::vector<float> fineTrilinear(const Volume& v, const ConeCamera& c, double stepMm) {
    auto sample = [&](const glm::dvec3& x) {
        double q[3];
        for (int a = 0; a < 3; ++a) {
            double proj = 0.0;
            for (int b = 0; b < 3; ++b) proj += (x[b] - v.origin[b]) * v.direction[a][b];
            q[a] = proj / v.spacing[a];
        }
        double acc = 0.0;
        const std::int64_t i0 = std::int64_t(std::floor(q[0])), j0 = std::int64_t(std::floor(q[1])),
                           k0 = std::int64_t(std::floor(q[2]));
        for (int dk = 0; dk < 2; ++dk)
            for (int dj = 0; dj < 2; ++dj)
                for (int di = 0; di < 2; ++di) {
                    const std::int64_t i = i0 + di, j = j0 + dj, k = k0 + dk;
                    if (i < 0 || j < 0 || k < 0 || i >= v.dims[0] || j >= v.dims[1] ||
                        k >= v.dims[2])
                        continue;
                    const double w = (1 - std::abs(q[0] - double(i))) *
                                     (1 - std::abs(q[1] - double(j))) *
                                     (1 - std::abs(q[2] - double(k)));
                    acc += w * v.at(i, j, k);
                }
        return acc;
    };
    std::vector<float> out(std::size_t(c.width * c.height));
    for (int row = 0; row < c.height; ++row)
        for (int col = 0; col < c.width; ++col) {
            const glm::dvec3 p = c.pixelCentre(col, row);
            const double len = glm::length(p - c.source);
            const int n = int(std::ceil(len / stepMm));
            double sum = 0.0;
            for (int k = 0; k < n; ++k) sum += sample(c.source + (k + 0.5) / n * (p - c.source));
            out[std::size_t(row * c.width + col)] = float(sum * len / n);
        }
    return out;
}

/** A lumpy, anisotropic test object: a few Gaussian blobs over a slab, zeros around. */
Volume lumpyVolume(const glm::dvec3& centre) {
    return makeVolume(
        {40, 32, 24}, {1.5, 2.0, 2.5},
        [](std::int64_t i, std::int64_t j, std::int64_t k) {
            const double x = i - 20.0, y = j - 15.0, z = k - 11.0;
            double v = std::exp(-(x * x + y * y + z * z) / 60.0) +
                       0.5 * std::exp(-((x - 9) * (x - 9) + (y + 6) * (y + 6) + z * z) / 8.0);
            if (i > 4 && i < 34 && j > 20 && j < 28 && k > 3 && k < 20) v += 0.3;
            return float(v);
        },
        {centre.x, centre.y, centre.z});
}

TEST(ConeProjector, TrilinearExactEqualsAFineStepIntegrationAtObliqueAngles) {
    const glm::dvec3 centre(12.0, -30.0, 40.0);
    const Volume v = lumpyVolume(centre);
    ConeProjector exact(v, {RayModel::Trilinear});
    for (const auto& [a, b] : {std::pair{30.0, 20.0}, std::pair{-55.0, -10.0}}) {
        CArm arm{a, b, 1000.0, 700.0, centre + glm::dvec3(5.0, 3.0, -4.0)};
        const ConeCamera cam = cArmCamera(arm, 48, 40, 2.5, 2.2, {1.5, -2.0});
        const DetectorImage img = exact.project(cam);
        const auto ref = fineTrilinear(v, cam, 0.04);
        const auto cmp = compare(img.pixels, ref);
        std::printf("trilinear exact vs fine step, LAO %g CRAN %g: %.1f dB\n", a, b, cmp.psnr);
        EXPECT_GT(cmp.psnr, 80.0) << "LAO " << a << " CRAN " << b;
        EXPECT_GT(cmp.peak, 10.0); // the object is in view
    }
}

TEST(ConeProjector, TrilinearExactEqualsAFineStepIntegrationOnRealCt) {
    // The body CT (122 x 101 x 112 at 3 mm, HU) in attenuation: the oracle integrates the
    // mapped voxels, so the mapping is applied here first.
    FVR_REQUIRE_DATA("volumes/body_ct_hu_3mm/example_ct.mhd");
    Volume v = loadVolume(fvr::test::sharedData() / "volumes/body_ct_hu_3mm/example_ct.mhd");
    ConeProjectorOptions o{RayModel::Trilinear};
    o.mapping = ValueMapping::Mu;
    ConeProjector caster(v, o);
    for (float& x : v.voxels) x = mapValue(ValueMapping::Mu, x);
    const double sid = 1200.0, sod = 750.0;
    for (const auto& [a, b] : {std::pair{35.0, 25.0}, std::pair{-60.0, -15.0}}) {
        const ConeCamera cam =
            cArmCamera({a, b, sid, sod, volumeCentre(v)}, 48, 40, 12.0, 12.0, {0.5, 2.0});
        const auto cmp = compare(caster.project(cam).pixels, fineTrilinear(v, cam, 0.1));
        std::printf("body CT, trilinear exact vs fine step, LAO %g CRAN %g: %.1f dB\n", a, b,
                    cmp.psnr);
        // The target is 55 dB; the exact integral gives about 128, and a quadrature
        // error (the trapezoid rule per cell instead of Simpson's: 61 dB) must fail here.
        EXPECT_GT(cmp.psnr, 100.0);
    }
}

TEST(ConeProjector, SteppedTrilinearAndSkippingAgreeWithTheExactIntegral) {
    const glm::dvec3 centre(0.0);
    const Volume v = lumpyVolume(centre);
    const ConeCamera cam = cArmCamera({25.0, -15.0, 1100.0, 800.0, centre}, 40, 40, 2.0, 2.0);
    ConeProjectorOptions o;
    o.skipEmpty = false;
    const auto noSkip = ConeProjector(v, o).project(cam).pixels;
    const auto skip = ConeProjector(v, {RayModel::Trilinear}).project(cam).pixels;
    EXPECT_GT(compare(skip, noSkip).psnr, 120.0); // skipping only leaves out zeros
    o.stepFraction = 0.25;
    o.skipEmpty = true;
    const auto stepped = ConeProjector(v, o).project(cam).pixels;
    o.skipEmpty = false;
    const auto steppedNoSkip = ConeProjector(v, o).project(cam).pixels;
    EXPECT_GT(compare(stepped, steppedNoSkip).psnr, 120.0); // the same samples, zeros left out
    const double coarse = compare(stepped, noSkip).psnr;
    o.stepFraction = 0.05;
    const double fine = compare(ConeProjector(v, o).project(cam).pixels, noSkip).psnr;
    EXPECT_GT(coarse, 45.0);
    EXPECT_GT(fine, coarse + 10.0); // the midpoint rule converges to the exact integral
}

TEST(ConeProjector, BoxModelOfAUniformCubeGivesTheChordLength) {
    // 20^3 voxels of 1 mm, value 1: the box model is the cube [-10, 10]^3 mm exactly.
    const Volume v = makeVolume({20, 20, 20}, {1, 1, 1}, [](auto, auto, auto) { return 1.0f; });
    const ConeCamera cam = cArmCamera({35.0, 25.0, 600.0, 400.0}, 32, 32, 1.5, 1.5);
    const DetectorImage img = ConeProjector(v, {RayModel::Box}).project(cam);
    for (int row = 0; row < 32; row += 3)
        for (int col = 0; col < 32; col += 3) {
            // The chord through the cube, by the slab method in LPS, worked out independently.
            const glm::dvec3 s = cam.source, d = cam.pixelCentre(col, row) - s;
            double t0 = 0.0, t1 = 1.0;
            for (int a = 0; a < 3; ++a) {
                double ta = (-10.0 - s[a]) / d[a], tb = (10.0 - s[a]) / d[a];
                if (ta > tb) std::swap(ta, tb);
                t0 = std::max(t0, ta);
                t1 = std::min(t1, tb);
            }
            const double chord = t1 > t0 ? (t1 - t0) * glm::length(d) : 0.0;
            EXPECT_NEAR(img.at(col, row), chord, 2e-4) << col << "," << row;
        }
}

/** The image with FVR_CPU_SIMD=baseline (the scalar walk of one ray at a time) and without (on
 *  a CPU with AVX2, four neighbouring rays at a time for the box model). */
std::pair<std::vector<float>, std::vector<float>> baselineAndDefault(const Volume& v,
                                                                     ConeProjectorOptions o,
                                                                     const ConeCamera& cam) {
    ::setenv("FVR_CPU_SIMD", "baseline", 1);
    auto base = ConeProjector(v, o).project(cam).pixels;
    ::unsetenv("FVR_CPU_SIMD");
    auto simd = ConeProjector(v, o).project(cam).pixels;
    return {std::move(base), std::move(simd)};
}

TEST(ConeProjector, FourRaysAtOnceEqualOneRayAtATime) {
    // Oblique views (rays whose major axis is each of x, y and z, packets whose rays differ in
    // it near 45 degrees), a width that is no multiple of 4 (the last pixels of a row one at
    // a time), values with and without empty blocks, the grid's edge cut by the view.
    const glm::dvec3 centre(0.0);
    const Volume lumpy = lumpyVolume(centre);
    Volume noisy = lumpy;
    for (std::size_t i = 0; i < noisy.voxels.size(); ++i) noisy.voxels[i] += 0.01f * float(i % 7);
    const struct {
        double primary, secondary;
    } views[] = {{0.0, 0.0}, {45.0, 10.0}, {-30.0, 50.0}, {95.0, -20.0}, {160.0, 80.0}};
    for (RayModel model : {RayModel::Box, RayModel::Trilinear})
        for (const Volume* v : {&lumpy, static_cast<const Volume*>(&noisy)})
            for (const auto& view : views) {
                const ConeCamera cam = cArmCamera(
                    {view.primary, view.secondary, 900.0, 600.0, centre}, 43, 37, 1.6, 1.6);
                ConeProjectorOptions o;
                o.model = model;
                const auto [base, simd] = baselineAndDefault(*v, o, cam);
                float peak = 0.0f, diff = 0.0f;
                for (std::size_t i = 0; i < base.size(); ++i) {
                    peak = std::max(peak, std::abs(base[i]));
                    diff = std::max(diff, std::abs(base[i] - simd[i]));
                }
                EXPECT_GT(peak, 1.0f);
                EXPECT_LE(diff, 1e-5f * peak)
                    << rayModelName(model) << " at " << view.primary << "/" << view.secondary;
            }
}

TEST(ConeProjector, ABlobLandsWherePSaysAndLeftOfTheIsocentreIsRightOfCentre) {
    // A small ball 30 mm to the patient's left (+x) and 20 mm toward the head of the isocentre.
    const glm::dvec3 ball(30.0, 0.0, 20.0);
    const Volume v = makeVolume({64, 64, 64}, {1.25, 1.25, 1.25}, [&](auto i, auto j, auto k) {
        const double x = (i - 31.5) * 1.25, y = (j - 31.5) * 1.25, z = (k - 31.5) * 1.25;
        const glm::dvec3 p(x, y, z);
        return float(glm::length(p - ball) < 4.0 ? 1.0 : 0.0);
    });
    const ConeCamera cam = cArmCamera({0.0, 0.0, 1000.0, 750.0}, 128, 128, 1.0, 1.0);
    const DetectorImage img = ConeProjector(v, {RayModel::Box}).project(cam);
    double sw = 0, sc = 0, sr = 0;
    for (int row = 0; row < 128; ++row)
        for (int col = 0; col < 128; ++col) {
            const double w = img.at(col, row);
            sw += w;
            sc += w * col;
            sr += w * row;
        }
    const glm::dvec3 expected = cam.matrix().apply(ball);
    // The weighted centroid of a perspective image sits a little off the projected centre (the
    // ball's near half magnifies more): a tenth of a pixel here.
    EXPECT_NEAR(sc / sw, expected.x, 0.2);
    EXPECT_NEAR(sr / sw, expected.y, 0.2);
    EXPECT_GT(sc / sw, 63.5 + 30.0 * 1000.0 / 750.0 - 1.0); // right of centre, magnified 4/3
    EXPECT_LT(sr / sw, 63.5); // toward the head: above the centre
}

TEST(ConeProjector, ASphereImagesWithItsConeBeamDiameter) {
    // A ball of radius 12 mm at the isocentre: its shadow is a disc of diameter
    // 2 SID R / sqrt(SOD^2 - R^2) (the tangent cone), i.e. about 2 R SID / SOD.
    const double R = 12.0, sid = 900.0, sod = 300.0;
    const Volume v = makeVolume({64, 64, 64}, {0.5, 0.5, 0.5}, [&](auto i, auto j, auto k) {
        const double x = (i - 31.5) * 0.5, y = (j - 31.5) * 0.5, z = (k - 31.5) * 0.5;
        return float(x * x + y * y + z * z < R * R ? 1.0 : 0.0);
    });
    const ConeCamera cam = cArmCamera({0.0, 0.0, sid, sod}, 128, 128, 0.75, 0.75);
    const DetectorImage img = ConeProjector(v, {RayModel::Box}).project(cam);
    // The shadow's area (pixels with any path through the ball) against the disc's area.
    int count = 0;
    for (float p : img.pixels) count += p > 1e-3f;
    const double diameter = 2.0 * sid * R / std::sqrt(sod * sod - R * R);
    const double expected = std::numbers::pi * diameter * diameter / 4.0 / (0.75 * 0.75);
    EXPECT_NEAR(count, expected, 0.03 * expected); // voxelization blurs the rim a little
    // The parallel shadow would be (SOD / SID)^2 = 1/9 of it.
    EXPECT_GT(count, 8.0 * (std::numbers::pi * R * R / (0.75 * 0.75)));
}

TEST(ConeProjector, FarSourceGivesTheParallelProjection) {
    // SID -> infinity: the cone beam becomes the parallel reference projector's AP image.
    const Volume v = makeSheppLoganVolume(48);
    const int M = 64;
    const double d = defaultPixelSize(v.dims, v.spacing, M);
    SpatialProjectorOptions po;
    po.stepFraction = 0.05;
    const ViewFrame ap = patientViewFrame(v, PatientView::AP);
    const auto parallel = SpatialProjector(v, po).project(ap, {M, d}).pixels;
    const double sid = 2.0e6, sod = sid - 400.0;
    // The parallel image's pixel (col, row) sits at (col - M/2) d: a principal offset of -1/2.
    const ConeCamera cam = cArmCamera({0.0, 0.0, sid, sod, volumeCentre(v)}, M, M, d * sid / sod,
                                      d * sid / sod, {-0.5, -0.5});
    const auto cone = ConeProjector(v, {RayModel::Trilinear}).project(cam).pixels;
    EXPECT_GT(compare(cone, parallel).psnr, 50.0);
}

TEST(ConeProjector, CArmAnglesAndTheParallelFrameAgree) {
    // An LPS volume: at 0/0 the C-arm shows what the AP view shows, the same way up.
    const Volume lps = makeChestPhantomVolume(16);
    const ViewFrame f0 = cArmViewFrame(lps, 0.0, 0.0);
    const ViewFrame ap = patientViewFrame(lps, PatientView::AP);
    for (int a = 0; a < 3; ++a) {
        EXPECT_NEAR(f0.d[a], ap.d[a], 1e-12);
        EXPECT_NEAR(f0.u[a], ap.u[a], 1e-12);
        EXPECT_NEAR(f0.r[a], ap.r[a], 1e-12);
    }
    // A volume stored feet-first and mirrored left-right: the angles survive the round trip.
    Volume odd = lps;
    odd.direction = {Vec3{-1, 0, 0}, Vec3{0, 0, 1}, Vec3{0, -1, 0}};
    for (const auto& [p, q] : {std::pair{30.0, 15.0}, std::pair{-120.0, -40.0},
                               std::pair{179.0, 5.0}, std::pair{0.0, -89.0}}) {
        const CArmAngles back = cArmAngles(odd, cArmViewFrame(odd, p, q));
        EXPECT_NEAR(back.primaryDeg, p, 1e-9);
        EXPECT_NEAR(back.secondaryDeg, q, 1e-9);
    }
    EXPECT_EQ(cArmLabel(30.2, 14.6), "LAO 30\u00b0 CRAN 15\u00b0");
    EXPECT_EQ(cArmLabel(-20.0, -10.0), "RAO 20\u00b0 CAUD 10\u00b0");
}

TEST(ConeProjector, FarSourceMatchesTheParallelFrameOfTheSameAnglesInAnOrientedVolume) {
    // Index axes: x toward the patient's right, y toward the head, z anterior (mirrored against
    // LPS), origin off the isocentre: the caster's LPS mapping and the frame's must agree.
    Volume v = makeSheppLoganVolume(40);
    v.direction = {Vec3{-1, 0, 0}, Vec3{0, 0, 1}, Vec3{0, -1, 0}};
    v.origin = {100.0, -50.0, 20.0};
    const int M = 64;
    const double d = defaultPixelSize(v.dims, v.spacing, M);
    SpatialProjectorOptions po;
    po.stepFraction = 0.05;
    SpatialProjector parallel(v, po);
    ConeProjector cone(v, {RayModel::Trilinear});
    const double sid = 2.0e6, sod = sid - 400.0;
    for (const auto& [a, b] : {std::pair{35.0, -20.0}, std::pair{-70.0, 30.0}}) {
        const ViewFrame f = cArmViewFrame(v, a, b);
        const auto ref = parallel.project(f, {M, d}).pixels;
        const ConeCamera cam = cArmCamera({a, b, sid, sod, volumeCentre(v)}, M, M, d * sid / sod,
                                          d * sid / sod, {-0.5, -0.5});
        EXPECT_GT(compare(cone.project(cam).pixels, ref).psnr, 50.0) << a << " " << b;
    }
}

TEST(ConeProjector, VoxelizedSheppLoganMatchesItsAnalyticConeBeamChords) {
    const double field = 256.0;
    const EllipsoidPhantom ph = EllipsoidPhantom::sheppLogan3D(field);
    const int N = 64, M = 128;
    const Volume v = ph.voxelize({N, N, N}, {field / N, field / N, field / N}, 4);
    // Today's parallel case: the trilinear reference projector against the analytic
    // projections, an oblique view, the default pixel size.
    const double d = defaultPixelSize(v.dims, v.spacing, M);
    SpatialProjectorOptions po;
    po.mapping = ValueMapping::Mu;
    const ViewFrame oblique = ViewFrame::fromDirUp({0.5, 0.3, 0.81}, {0.0, 1.0, 0.0});
    const double parallel =
        compare(SpatialProjector(v, po).project(oblique, {M, d}).pixels,
                ph.project(oblique, {M, d}, ValueMapping::Mu, v.dims, v.spacing).pixels)
            .psnr;
    ConeProjectorOptions o{RayModel::Trilinear};
    o.mapping = ValueMapping::Mu;
    ConeProjector caster(v, o);
    const glm::dvec3 c = volumeCentre(v);
    for (const auto& [a, b] : {std::pair{20.0, 10.0}, std::pair{-40.0, 25.0}}) {
        // The same pixel size at the isocentre as the parallel image's.
        const double sid = 1000.0, sod = 600.0, pitch = d * sid / sod;
        const ConeCamera cam = cArmCamera({a, b, sid, sod, c}, M, M, pitch, pitch);
        const auto img = caster.project(cam).pixels;
        std::vector<float> ref(img.size());
        for (int row = 0; row < M; ++row)
            for (int col = 0; col < M; ++col) {
                const glm::dvec3 s = cam.source - c, p = cam.pixelCentre(col, row) - c;
                const glm::dvec3 dir = glm::normalize(p - s);
                double sum = 0.0;
                for (const Ellipsoid& e : ph.ellipsoids)
                    sum += e.density * e.chord({s.x, s.y, s.z}, {dir.x, dir.y, dir.z});
                ref[std::size_t(row * M + col)] = float(sum);
            }
        const double cone = compare(img, ref).psnr;
        EXPECT_GT(cone, parallel - 1.5)
            << "LAO " << a << " CRAN " << b << ": parallel " << parallel;
        std::printf("Shepp-Logan 64^3 vs analytic: cone LAO %g CRAN %g %.1f dB, parallel %.1f dB\n",
                    a, b, cone, parallel);
    }
}

TEST(ConeProjector, BSplineApproachesTheParallelReferenceBSpline) {
    const Volume v = makeSheppLoganVolume(32);
    const int M = 64;
    const double d = defaultPixelSize(v.dims, v.spacing, M);
    SpatialProjectorOptions po;
    po.voxelModel = VoxelModel::BSpline;
    const ViewFrame ap = patientViewFrame(v, PatientView::AP);
    const auto parallel = SpatialProjector(v, po).project(ap, {M, d}).pixels;
    const double sid = 2.0e6, sod = sid - 400.0;
    const ConeCamera cam = cArmCamera({0.0, 0.0, sid, sod, volumeCentre(v)}, M, M, d * sid / sod,
                                      d * sid / sod, {-0.5, -0.5});
    const auto cone = ConeProjector(v, {RayModel::BSpline}).project(cam).pixels;
    EXPECT_GT(compare(cone, parallel).psnr, 50.0);
}

TEST(ConeProjector, PixelSubsamplesAverageTheRaysOverThePixel) {
    const Volume v = lumpyVolume(glm::dvec3(0.0));
    const ConeCamera cam = cArmCamera({10.0, 5.0, 1000.0, 700.0}, 24, 24, 3.0, 3.0);
    ConeProjectorOptions o{RayModel::Box};
    o.pixelSubsamples = 2;
    const DetectorImage img = ConeProjector(v, o).project(cam);
    // The same as a 2x finer detector, shifted by a quarter pixel, averaged 2 x 2.
    const ConeCamera fine = cArmCamera({10.0, 5.0, 1000.0, 700.0}, 48, 48, 1.5, 1.5);
    const DetectorImage f = ConeProjector(v, {RayModel::Box}).project(fine);
    std::vector<float> avg(24 * 24);
    for (int row = 0; row < 24; ++row)
        for (int col = 0; col < 24; ++col)
            avg[std::size_t(row * 24 + col)] =
                0.25f * (f.at(2 * col, 2 * row) + f.at(2 * col + 1, 2 * row) +
                         f.at(2 * col, 2 * row + 1) + f.at(2 * col + 1, 2 * row + 1));
    EXPECT_GT(compare(img.pixels, avg).psnr, 100.0);
}

TEST(ConeProjector, FlatFieldIsInverseSquareTimesObliquity) {
    const ConeCamera cam = cArmCamera({0.0, 0.0, 1000.0, 750.0}, 101, 81, 2.0, 2.0);
    const auto f = detectorFlatField(cam);
    EXPECT_NEAR(f[std::size_t(40 * 101 + 50)], 1.0, 1e-7); // the principal point
    // Corner pixel (0, 0): 100 mm and 80 mm off the principal point, r^2 = 1000^2 + 100^2 + 80^2.
    const double r = std::sqrt(1000.0 * 1000.0 + 100.0 * 100.0 + 80.0 * 80.0);
    EXPECT_NEAR(f[0], std::pow(1000.0 / r, 3.0), 1e-6);
}

TEST(ConeProjector, BadViewsAreRefusedWithTheReason) {
    const Volume v = makeVolume({20, 20, 20}, {2, 2, 2}, [](auto, auto, auto) { return 1.0f; });
    ConeProjector caster(v, {RayModel::Box});
    auto message = [&](const ConeCamera& c) {
        try {
            caster.project(c);
        } catch (const SettingsError& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    // SOD 10 mm: the source stands inside the 40 mm cube.
    EXPECT_NE(message(cArmCamera({0, 0, 1000, 10}, 32, 32, 1, 1)).find("source lies inside"),
              std::string::npos);
    ConeCamera away = cArmCamera({0, 0, 1000, 750}, 32, 32, 1, 1);
    away.detectorCentre = away.source + (away.source - away.detectorCentre);
    EXPECT_NE(message(away).find("behind the source"), std::string::npos);
    ConeCamera shortSid = cArmCamera({0, 0, 300, 200, {0, 1000, 0}}, 32, 32, 1, 1);
    EXPECT_NE(message(shortSid).find("beyond the detector"), std::string::npos);
    EXPECT_THROW(ConeProjector(v, {RayModel::Box, 5.0}), SettingsError);
    EXPECT_THROW(parseRayModel("nearest"), SettingsError);
    EXPECT_EQ(parseRayModel("Siddon"), RayModel::Box);
}

} // namespace
