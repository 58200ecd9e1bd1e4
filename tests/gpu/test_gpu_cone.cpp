// The GPU cone-beam ray caster (gpu::ConeRayCaster) on a real OpenGL 4.3 context (headless EGL;
// Mesa llvmpipe where there is no GPU): against analytic chords and a fine-step trilinear
// integration in double (independent oracles, no GPU or core renderer code), against the CPU
// ray caster (core::ConeProjector), what the hardware texture filter costs, rays that miss, and
// a volume too large for the texture limits.
#include <epoxy/gl.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/geometry/camera.h>
#include <fvr/core/io/volume_io.h>
#include <fvr/core/render/cone_projector.h>
#include <fvr/core/xray/phantom.h>
#include <fvr/gpu/cone_ray_caster.h>
#include <fvr/gpu/errors.h>

#include "gl_fixture.h"
#include "image_metrics.h"
#include "test_support.h"

using namespace fvr::core;
using namespace fvr::gpu;
using fvr::test::GlTest;

namespace {

/** Unit vectors of a rotation by `deg` about the (normalized) axis, as direction cosines. */
glm::dmat3 rotatedAxes(glm::dvec3 axis, double deg) {
    axis = glm::normalize(axis);
    const double a = deg * M_PI / 180.0, c = std::cos(a), s = std::sin(a);
    glm::dmat3 out(1.0);
    for (int i = 0; i < 3; ++i) {
        glm::dvec3 e(0.0);
        e[i] = 1.0;
        // Rodrigues: e c + (k x e) s + k (k.e)(1 - c)
        const glm::dvec3 r = e * c + glm::cross(axis, e) * s + axis * glm::dot(axis, e) * (1 - c);
        out[i] = r;
    }
    return out;
}

/** A small volume, not a cube, anisotropic, obliquely oriented, far from the origin. */
Volume obliqueVolume(Dims3 dims, float (*value)(std::int64_t, std::int64_t, std::int64_t)) {
    Volume v;
    v.dims = dims;
    v.spacing = {1.5, 2.0, 2.5};
    v.origin = {-40.0, 25.0, 130.0};
    v.direction = rotatedAxes({0.3, -0.5, 0.8}, 27.0);
    v.name = "oblique";
    v.voxels.resize(std::size_t(v.voxelCount()));
    for (std::int64_t z = 0; z < dims[2]; ++z)
        for (std::int64_t y = 0; y < dims[1]; ++y)
            for (std::int64_t x = 0; x < dims[0]; ++x) v.voxels[v.index(x, y, z)] = value(x, y, z);
    return v;
}

/** Where the volume's index axis a reads x (continuous index, voxel centres at integers):
 *  dot(x - origin, direction[a]) / spacing[a]. Independent of any matrix inverse. */
double indexAlong(const Volume& v, int a, const glm::dvec3& x) {
    return glm::dot(x - v.origin, v.direction[a]) / v.spacing[a];
}

/** The part [t0, t1] of source + t (pixel - source), t in [0, 1], whose indices lie in
 *  [lo, N - 1 + hi]... per axis: the box from index -margin to N - 1 + margin. */
bool chordOf(const Volume& v, const glm::dvec3& s, const glm::dvec3& p, double margin, double& t0,
             double& t1) {
    t0 = 0.0;
    t1 = 1.0;
    for (int a = 0; a < 3; ++a) {
        const double is = indexAlong(v, a, s), ip = indexAlong(v, a, p);
        const double lo = -margin, hi = double(v.dims[a] - 1) + margin;
        const double di = ip - is;
        if (di == 0.0) {
            if (is < lo || is > hi) return false;
            continue;
        }
        const double ta = (lo - is) / di, tb = (hi - is) / di;
        t0 = std::max(t0, std::min(ta, tb));
        t1 = std::min(t1, std::max(ta, tb));
    }
    return t0 < t1;
}

/** The trilinear interpolant in double at continuous index (x, y, z), zero outside. */
double trilinearAt(const Volume& v, double x, double y, double z) {
    const double fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
    const std::int64_t i = std::int64_t(fx), j = std::int64_t(fy), k = std::int64_t(fz);
    double sum = 0.0;
    for (int c = 0; c < 8; ++c) {
        const std::int64_t a = i + (c & 1), b = j + ((c >> 1) & 1), d = k + ((c >> 2) & 1);
        if (a < 0 || b < 0 || d < 0 || a >= v.dims[0] || b >= v.dims[1] || d >= v.dims[2]) continue;
        const double w = ((c & 1) ? x - fx : 1 - (x - fx)) *
                         (((c >> 1) & 1) ? y - fy : 1 - (y - fy)) *
                         (((c >> 2) & 1) ? z - fz : 1 - (z - fz));
        sum += w * v.at(a, b, d);
    }
    return sum;
}

/** The oblique C-arm view of the brief: off-centre isocentre, a 96 x 64 detector, anisotropic
 *  pitch and a principal offset. */
ConeCamera obliqueCamera(const Volume& v, int width = 96, int height = 64) {
    CArm arm;
    arm.primaryDeg = 35.0;
    arm.secondaryDeg = -20.0;
    arm.sid = 1100.0;
    arm.sod = 700.0;
    arm.isocentre = volumeCentre(v) + glm::dvec3(6.0, -4.0, 5.0);
    const double pitch = framingPitch(v, arm.sid, arm.sod, width, height);
    return cArmCamera(arm, width, height, pitch, 1.1 * pitch, glm::dvec2(3.5, -2.25));
}

ConeProjectorOptions options(RayModel model, double step, ValueMapping mapping) {
    ConeProjectorOptions o;
    o.model = model;
    o.stepFraction = step;
    o.mapping = mapping;
    return o;
}

} // namespace

// Box model of a constant volume: every pixel is the value times the chord through the voxels'
// cubes (index box [-1/2, N - 1/2]), found by slabs along the direction cosines in double.
TEST_F(GlTest, ConeBoxModelOfAConstantVolumeIsValueTimesChord) {
    const Volume v = obliqueVolume({20, 16, 12}, [](auto, auto, auto) { return 2.0f; });
    const ConeCamera cam = obliqueCamera(v, 48, 40);
    ConeRayCaster gpu(v, options(RayModel::Box, 0.0, ValueMapping::Raw));
    const DetectorImage img = gpu.project(cam);
    ASSERT_EQ(img.pixels.size(), std::size_t(48 * 40));
    std::vector<float> ref(img.pixels.size());
    int hits = 0;
    for (int r = 0; r < cam.height; ++r)
        for (int c = 0; c < cam.width; ++c) {
            const glm::dvec3 p = cam.pixelCentre(c, r);
            double t0, t1;
            if (!chordOf(v, cam.source, p, 0.5, t0, t1)) continue;
            ref[std::size_t(r * cam.width + c)] =
                float(2.0 * (t1 - t0) * glm::length(p - cam.source));
            ++hits;
        }
    EXPECT_GT(hits, 200) << "the view should see the volume";
    EXPECT_LT(hits, 48 * 40) << "and its outline";
    const auto cmp = fvr::test::compare(img.pixels, ref);
    std::printf("[cone] box, constant volume vs analytic chords: %.1f dB, max error %.3g of %.3g\n",
                cmp.psnr, cmp.maxAbsError, cmp.peak);
    // Float rounding of the ray and of the walk's boundaries: 122 dB on llvmpipe. A relative
    // error of 1e-4 in every path length reads 87 dB.
    EXPECT_GT(cmp.psnr, 100.0);
    EXPECT_LT(cmp.maxAbsError, 1e-4 * cmp.peak);
}

// Trilinear, exact per cell, on random values: against the interpolant integrated in double by
// the midpoint rule at 20,000 steps per ray (the oracle's own error is ~1e-8 of the peak).
TEST_F(GlTest, ConeTrilinearExactEqualsAFineIntegrationInDouble) {
    const Volume v = obliqueVolume({14, 11, 9}, [](auto x, auto y, auto z) {
        return float(std::sin(1.7 * x + 0.3 * y * y) + std::cos(0.9 * z - 0.4 * x * y) + 2.5);
    });
    const ConeCamera cam = obliqueCamera(v, 32, 24);
    std::vector<float> ref(std::size_t(cam.width * cam.height));
    for (int r = 0; r < cam.height; ++r)
        for (int c = 0; c < cam.width; ++c) {
            const glm::dvec3 p = cam.pixelCentre(c, r);
            double t0, t1;
            if (!chordOf(v, cam.source, p, 1.0, t0, t1)) continue;
            constexpr int kSteps = 20000;
            const double dt = (t1 - t0) / kSteps;
            double sum = 0.0;
            for (int k = 0; k < kSteps; ++k) {
                const glm::dvec3 x = cam.source + (t0 + (k + 0.5) * dt) * (p - cam.source);
                sum +=
                    trilinearAt(v, indexAlong(v, 0, x), indexAlong(v, 1, x), indexAlong(v, 2, x));
            }
            ref[std::size_t(r * cam.width + c)] = float(sum * dt * glm::length(p - cam.source));
        }
    for (TrilinearFetch fetch : {TrilinearFetch::Manual, TrilinearFetch::Hardware}) {
        ConeRayCaster gpu(v, options(RayModel::Trilinear, 0.0, ValueMapping::Raw), fetch);
        const auto cmp = fvr::test::compare(gpu.project(cam).pixels, ref);
        std::printf("[cone] trilinear exact (%s fetch) vs fine integration in double: %.1f dB\n",
                    trilinearFetchName(fetch), cmp.psnr);
        // Manual: float rounding only. Hardware: whatever the filter's weights cost (measured
        // below against the CPU); a bound that catches a wrong coordinate convention (half a
        // voxel off is ~30 dB here).
        EXPECT_GT(cmp.psnr, fetch == TrilinearFetch::Manual ? 100.0 : 45.0)
            << trilinearFetchName(fetch);
    }
}

// A camera beside the volume (its field 400 mm to the patient's left of it): every ray misses,
// every pixel is exactly 0, for every model.
TEST_F(GlTest, ConeRaysThatMissTheVolumeGiveZeros) {
    const Volume v = makeSheppLoganVolume(32);
    CArm arm;
    arm.isocentre = volumeCentre(v) + glm::dvec3(400.0, 0.0, 0.0);
    const ConeCamera cam = cArmCamera(arm, 24, 16, 1.0, 1.0);
    for (RayModel model : {RayModel::Box, RayModel::Trilinear})
        for (double step : {0.0, 0.5}) {
            ConeRayCaster gpu(v, options(model, step, ValueMapping::Raw));
            const DetectorImage img = gpu.project(cam);
            ASSERT_EQ(img.pixels.size(), std::size_t(24 * 16));
            EXPECT_EQ(std::count(img.pixels.begin(), img.pixels.end(), 0.0f), 24 * 16)
                << rayModelName(model) << " step " << step;
            ConeProjector cpu(v, options(model, step, ValueMapping::Raw));
            EXPECT_EQ(cpu.project(cam).pixels, img.pixels) << "the CPU's zeros";
        }
}

// A volume wider than GL_MAX_3D_TEXTURE_SIZE is refused before any upload, naming both sizes.
TEST_F(GlTest, ConeVolumeBeyondTheTextureLimitIsRefusedWithTheSizes) {
    GLint max3d = 0;
    glGetIntegerv(GL_MAX_3D_TEXTURE_SIZE, &max3d);
    ASSERT_GT(max3d, 0);
    Volume v;
    v.dims = {max3d + 1, 1, 2};
    v.voxels.assign(std::size_t(v.voxelCount()), 1.0f);
    try {
        ConeRayCaster gpu(v);
        FAIL() << "a " << max3d + 1 << "-voxel-wide volume was accepted";
    } catch (const GpuMemoryError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find(std::to_string(max3d + 1) + "x1x2"), std::string::npos) << what;
        EXPECT_NE(what.find("3D texture limit of " + std::to_string(max3d)), std::string::npos)
            << what;
    }
}

TEST_F(GlTest, ConeRefusesWhatItCannotDo) {
    const Volume v = makeSheppLoganVolume(16);
    try {
        ConeRayCaster gpu(v, options(RayModel::BSpline, 0.25, ValueMapping::Raw));
        FAIL() << "B-spline accepted";
    } catch (const SettingsError& e) {
        EXPECT_NE(std::string(e.what()).find("B-spline model runs on the CPU only"),
                  std::string::npos)
            << e.what();
    }
    Volume broken = v;
    broken.voxels.resize(10);
    try {
        ConeRayCaster gpu(broken);
        FAIL() << "10 voxels for 16^3 accepted";
    } catch (const SettingsError& e) {
        EXPECT_NE(std::string(e.what()).find("holds 10 voxels, its dims 16x16x16 say 4096"),
                  std::string::npos)
            << e.what();
    }
    ConeProjectorOptions o;
    o.pixelSubsamples = 17;
    EXPECT_THROW(ConeRayCaster(v, o), SettingsError);
    // A view the CPU refuses (the source inside the volume's box) is refused the same way.
    CArm inside;
    inside.isocentre = volumeCentre(v);
    inside.sod = 50.0; // the phantom's box is 256 mm wide
    const ConeCamera cam = cArmCamera(inside, 16, 16, 1.0, 1.0);
    ConeRayCaster gpu(v);
    std::string cpuWhat, gpuWhat;
    try {
        ConeProjector(v).project(cam);
    } catch (const SettingsError& e) {
        cpuWhat = e.what();
    }
    try {
        gpu.project(cam);
    } catch (const SettingsError& e) {
        gpuWhat = e.what();
    }
    EXPECT_FALSE(gpuWhat.empty()) << "a source inside the volume was accepted";
    EXPECT_EQ(gpuWhat, cpuWhat);
}

namespace {

/** The Shepp-Logan phantom, 128^3, turned obliquely and moved off the origin. */
const Volume& orientedPhantom() {
    static const Volume v = [] {
        Volume p = makeSheppLoganVolume(128);
        p.direction = rotatedAxes({0.2, 0.9, -0.4}, 17.0);
        p.origin = {-70.0, -180.0, 95.0};
        p.name = "oriented phantom";
        return p;
    }();
    return v;
}

struct Case {
    RayModel model;
    double step;
    TrilinearFetch fetch;
    int subsamples;
};

/** PSNR of the GPU's view against the CPU's (same model, step and subsamples), mu values. */
double gpuVsCpu(const Case& c, const ConeCamera& cam, const Volume& v = orientedPhantom()) {
    ConeProjectorOptions o = options(c.model, c.step, ValueMapping::Mu);
    o.pixelSubsamples = c.subsamples;
    ConeProjector cpu(v, o);
    ConeRayCaster gpu(v, o, c.fetch);
    const DetectorImage g = gpu.project(cam);
    EXPECT_EQ(g.width, cam.width);
    EXPECT_EQ(g.height, cam.height);
    EXPECT_EQ(g.mapping, ValueMapping::Mu);
    const auto cmp = fvr::test::compare(g.pixels, cpu.project(cam).pixels);
    std::printf("[cone] GPU vs CPU, %s, %s: %.1f dB (max error %.3g of %.4g mm)\n", v.name.c_str(),
                describeConeRayCaster(o, c.fetch).c_str(), cmp.psnr, cmp.maxAbsError, cmp.peak);
    return cmp.psnr;
}

} // namespace

// GPU = CPU with the same model, step and subsamples: float rounding on the GPU (positions in
// float relative to the grid's centre, float sums) against double on the CPU. llvmpipe measured
// 128-137 dB; the bound, 100 dB, lies above every modelling difference (the step 0.5 against the
// exact trilinear integral reads 86 dB here, half a voxel's shift about 30 dB).
TEST_F(GlTest, ConeGpuEqualsCpuOnAnObliqueCArmView) {
    const ConeCamera cam = obliqueCamera(orientedPhantom());
    for (const Case& c : {Case{RayModel::Box, 0.0, TrilinearFetch::Manual, 1},
                          Case{RayModel::Trilinear, 0.0, TrilinearFetch::Manual, 1},
                          Case{RayModel::Trilinear, 0.5, TrilinearFetch::Manual, 1},
                          Case{RayModel::Trilinear, 0.0, TrilinearFetch::Manual, 2}})
        EXPECT_GT(gpuVsCpu(c, cam), 100.0) << rayModelName(c.model) << " step " << c.step;
}

// The same on a real body CT in HU (mu values: air 0, bone above 1), with its own orientation.
TEST_F(GlTest, ConeGpuEqualsCpuOnRealCt) {
    FVR_REQUIRE_DATA("volumes/body_ct_hu_3mm/example_ct.mhd");
    const Volume v = loadVolume(fvr::test::sharedData() / "volumes/body_ct_hu_3mm/example_ct.mhd");
    const ConeCamera cam = obliqueCamera(v, 96, 64);
    for (const Case& c : {Case{RayModel::Box, 0.0, TrilinearFetch::Manual, 1},
                          Case{RayModel::Trilinear, 0.0, TrilinearFetch::Manual, 1},
                          Case{RayModel::Trilinear, 0.5, TrilinearFetch::Manual, 1}})
        EXPECT_GT(gpuVsCpu(c, cam, v), 100.0) << rayModelName(c.model) << " step " << c.step;
    EXPECT_GT(gpuVsCpu({RayModel::Trilinear, 0.0, TrilinearFetch::Hardware, 1}, cam, v), 45.0);
}

// What the texture unit's GL_LINEAR filter costs against exact weights, exact per cell and at
// the step 0.5. llvmpipe filters R32F textures with float weights: 133.5 dB against the CPU as
// the manual fetch (135.0 against 136.6 on the real CT). NVIDIA's filter weights carry 8
// fraction bits (not measured here). The bound only catches a wrong coordinate convention.
TEST_F(GlTest, ConeHardwareFilterCostAgainstTheCpu) {
    const ConeCamera cam = obliqueCamera(orientedPhantom());
    for (double step : {0.0, 0.5})
        EXPECT_GT(gpuVsCpu({RayModel::Trilinear, step, TrilinearFetch::Hardware, 1}, cam), 45.0)
            << "step " << step;
    // For scale: what the step 0.5 itself costs against the exact integral (both on the CPU).
    ConeProjector exact(orientedPhantom(), options(RayModel::Trilinear, 0.0, ValueMapping::Mu));
    ConeProjector stepped(orientedPhantom(), options(RayModel::Trilinear, 0.5, ValueMapping::Mu));
    const auto cmp = fvr::test::compare(stepped.project(cam).pixels, exact.project(cam).pixels);
    std::printf("[cone] CPU step 0.5 vs exact trilinear: %.1f dB\n", cmp.psnr);
}

// An orbit rendered in one dispatch equals its views rendered one by one, bit for bit (the same
// rays, the same arithmetic); cameras of different sizes are refused, and so are more images
// than the largest storage buffer holds, before anything is allocated.
TEST_F(GlTest, ConeManyViewsInOneDispatchEqualSingleViews) {
    const Volume& v = orientedPhantom();
    std::vector<ConeCamera> orbit;
    for (int i = 0; i < 5; ++i) {
        CArm arm;
        arm.primaryDeg = -150.0 + 67.0 * i;
        arm.secondaryDeg = 10.0 * (i - 2);
        arm.isocentre = volumeCentre(v);
        orbit.push_back(cArmCamera(arm, 40, 30, 2.0, 2.0));
    }
    ConeRayCaster gpu(v, options(RayModel::Trilinear, 0.0, ValueMapping::Mu));
    const auto many = gpu.projectMany(orbit);
    ASSERT_EQ(many.size(), orbit.size());
    for (std::size_t i = 0; i < orbit.size(); ++i) {
        EXPECT_EQ(many[i].pixels, gpu.project(orbit[i]).pixels) << "view " << i;
        EXPECT_EQ(many[i].camera.source, orbit[i].source) << "view " << i;
    }
    EXPECT_NE(many[0].pixels, many[1].pixels);

    orbit.push_back(cArmCamera(CArm{0, 0, 1000, 750, volumeCentre(v)}, 41, 30, 2.0, 2.0));
    try {
        gpu.projectMany(orbit);
        FAIL() << "40x30 and 41x30 in one dispatch";
    } catch (const SettingsError& e) {
        EXPECT_NE(std::string(e.what()).find("found 40x30 and 41x30"), std::string::npos)
            << e.what();
    }

    GLint64 maxBlock = 0;
    glGetInteger64v(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &maxBlock);
    const std::int64_t perView = std::int64_t(4096) * 4096 * 4;
    if (maxBlock <= 0 || maxBlock / perView > 256) GTEST_SKIP() << "storage blocks of " << maxBlock;
    const std::vector<ConeCamera> big(
        std::size_t(maxBlock / perView + 1),
        cArmCamera(CArm{0, 0, 1000, 750, volumeCentre(v)}, 4096, 4096, 0.1, 0.1));
    try {
        gpu.projectToGpu(big);
        FAIL() << big.size() << " views of 4096^2 in one storage buffer of " << maxBlock;
    } catch (const GpuMemoryError& e) {
        EXPECT_NE(std::string(e.what()).find(std::to_string(big.size()) + " views of 4096x4096"),
                  std::string::npos)
            << e.what();
        EXPECT_NE(std::string(e.what()).find("largest storage buffer"), std::string::npos)
            << e.what();
    }
}

// Leaving out the 8^3 blocks of zeros (the default, as on the CPU) changes nothing but the
// time: against the full walk, every model, on the phantom whose air maps to 0. Blocks marked
// wrongly (a trilinear cell's corners c - 1 and c taken as the box's c) read 77 dB here.
TEST_F(GlTest, ConeSkippingEmptyBlocksChangesNothing) {
    const ConeCamera cam = obliqueCamera(orientedPhantom());
    for (const auto& [model, step] :
         {std::pair{RayModel::Box, 0.0}, std::pair{RayModel::Trilinear, 0.0},
          std::pair{RayModel::Trilinear, 0.5}})
        for (TrilinearFetch fetch : {TrilinearFetch::Manual, TrilinearFetch::Hardware}) {
            ConeProjectorOptions o = options(model, step, ValueMapping::Mu);
            o.skipEmpty = true;
            ConeRayCaster skipping(orientedPhantom(), o, fetch);
            o.skipEmpty = false;
            ConeRayCaster full(orientedPhantom(), o, fetch);
            const auto cmp =
                fvr::test::compare(skipping.project(cam).pixels, full.project(cam).pixels);
            std::printf("[cone] skipping empty blocks vs not, %s: %.1f dB\n",
                        describeConeRayCaster(o, fetch).c_str(), cmp.psnr);
            EXPECT_GT(cmp.psnr, 120.0) << describeConeRayCaster(o, fetch);
        }
}
