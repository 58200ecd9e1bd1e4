// fvr-render --geometry cone with --kvp and --pixel-aperture, end to end: I/I0 against the
// exact spectral sum of the written material line integrals, the materials against the
// monochromatic mu cone image (they keep the attenuation at 70 keV), noise quanta at the
// detector's SID and pitch, the flat field as (SID/r)^3, GPU = CPU, the pixel aperture against a
// finer detector binned down, and the option errors.
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fvr/core/io/image_io.h>
#include <fvr/core/xray/polychromatic.h>
#include <fvr/core/xray/spectrum_model.h>

#include "cli_support.h"
#include "poly_support.h"
#include "test_support.h"

using namespace fvr::core;

namespace {

std::string tmp(const std::string& name) {
    // Of this process: ctest runs the tests in parallel processes.
    return (fvr::test::tmpDir() / ("conepoly_" + std::to_string(getpid()) + "_" + name)).string();
}

using Result = fvr::test::RenderResult;
Result run(const std::string& args) { return fvr::test::runFvrRender(args); }

std::vector<float> load(const std::string& path, std::vector<std::int64_t>& shape) {
    return readNpy(path, shape);
}

/** The chest phantom (HU) seen by an oblique C-arm on a 96 x 64 detector. */
const std::string kCone = "phantom:chest:64 --geometry cone --primary-angle 30 "
                          "--secondary-angle -10 --sid 1100 --sod 750 --detector-size 96x64 ";

} // namespace

TEST(FvrRenderConePoly, TransmissionIsTheSpectralSumOfTheWrittenMaterials) {
    const Result r = run(kCone + "--kvp 80 --filtration-al 2.5 --out " + tmp("poly.npy") +
                         " --material-out " + tmp("mat.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape, mshape;
    const auto t = load(tmp("poly.npy"), shape);
    const auto m = load(tmp("mat.npy"), mshape);
    ASSERT_EQ(shape, (std::vector<std::int64_t>{64, 96})); // rows, columns
    ASSERT_EQ(mshape, (std::vector<std::int64_t>{3, 64, 96}));
    const SpectralResponse ref(tubeSpectrum(80.0, 2.5), {}, defaultMaterials());
    const fvr::test::SpectralSumCheck sum = fvr::test::checkSpectralSum(t, m, ref);
    EXPECT_LT(sum.worstLogError, 1e-3);
    EXPECT_LT(sum.darkest, 0.05); // through the spine and mediastinum
    const auto j = fvr::test::readSidecar(tmp("poly.npy"));
    EXPECT_EQ(j["geometry"], "cone");
    EXPECT_EQ(j["settings"]["values"], "materials");
    EXPECT_EQ(j["settings"]["polychromatic"]["kvp"], 80.0);
    EXPECT_EQ(j["settings"]["polychromatic"]["filtration_al_mm"], 2.5);
    EXPECT_EQ(j["settings"]["materials"].size(), 3u);
    EXPECT_EQ(j["output"]["values"], "I/I0 (polychromatic, relative to the unattenuated beam)");
    ASSERT_EQ(j["views"].size(), 1u);
    EXPECT_EQ(j["views"][0]["c_arm"]["primary_angle_deg"], 30.0);
    EXPECT_EQ(j["views"][0]["projection_matrix"].size(), 3u);
    EXPECT_EQ(j["image"]["width"], 96);
    EXPECT_EQ(j["image"]["height"], 64);
}

TEST(FvrRenderConePoly, MaterialsKeepTheAttenuationOfTheMonochromaticConeImage) {
    // The ray caster is linear and the decomposition keeps each voxel's attenuation at 70 keV:
    // sum_m (mu/rho)_m(70) rhoL_m = mu_water(70) x the mu image (mm of water), to rounding.
    ASSERT_EQ(run(kCone + "--values mu --out " + tmp("mono.npy")).status, 0);
    const Result r =
        run(kCone + "--kvp 70 --out " + tmp("p70.npy") + " --material-out " + tmp("m70.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> s1, s2;
    const auto mono = load(tmp("mono.npy"), s1);
    const auto m = load(tmp("m70.npy"), s2);
    const std::size_t n = mono.size();
    ASSERT_EQ(m.size(), 3 * n);
    double mu[3], peak = 0.0, worst = 0.0;
    for (int k = 0; k < 3; ++k)
        mu[k] = massAttenuation(materialNistName(defaultMaterials()[k]), 70.0);
    const double muWater = massAttenuation("Water, Liquid", 70.0);
    for (std::size_t p = 0; p < n; ++p) {
        const double a = mu[0] * m[p] + mu[1] * m[n + p] + mu[2] * m[2 * n + p];
        const double b = muWater * mono[p] / 10.0; // mm of water -> g/cm^2
        peak = std::max(peak, b);
        worst = std::max(worst, std::abs(a - b));
    }
    std::printf("[phys] cone materials vs mu image: worst %.2e of peak %.2f\n", worst, peak);
    EXPECT_GT(peak, 3.0);
    EXPECT_LT(worst, 1e-5 * peak);
}

TEST(FvrRenderConePoly, NoiseQuantaAreTheDetectorsAndSeeded) {
    // Photon counting, 0.5 mAs at SID 1100 mm, pitch 0.8 x 0.6 mm: N0 = fluence x mAs x
    // (1000/1100)^2 x 0.48 mm^2.
    const std::string noisy = kCone + "--pitch 0.8,0.6 --kvp 70 --noise-mas 0.5 "
                                      "--detector counting --seed ";
    ASSERT_EQ(run(noisy + "3 --out " + tmp("n1.npy")).status, 0);
    ASSERT_EQ(run(noisy + "3 --out " + tmp("n2.npy")).status, 0);
    ASSERT_EQ(run(noisy + "4 --out " + tmp("n3.npy")).status, 0);
    std::vector<std::int64_t> s;
    const auto n1 = load(tmp("n1.npy"), s), n2 = load(tmp("n2.npy"), s),
               n3 = load(tmp("n3.npy"), s);
    EXPECT_EQ(n1, n2);
    EXPECT_NE(n1, n3);
    const TubeSpectrum spectrum = tubeSpectrum(70.0);
    const double n0 = spectrum.totalFluence() * 0.5 * (1000.0 / 1100.0) * (1000.0 / 1100.0) * 0.48;
    const auto j = fvr::test::readSidecar(tmp("n1.npy"));
    EXPECT_NEAR(double(j["settings"]["polychromatic"]["noise_quanta_per_pixel"]), n0, 1e-6 * n0);
    // Counts are whole numbers of quanta: I/I0 x N0 is an integer in every pixel.
    double worst = 0.0;
    for (float v : n1) worst = std::max(worst, std::abs(v * n0 - std::round(v * n0)));
    std::printf("[phys] cone noise: N0 %.0f quanta per pixel, worst distance from a whole count "
                "%.3f\n",
                n0, worst);
    EXPECT_LT(worst, 0.1);
}

TEST(FvrRenderConePoly, FlatFieldIsInverseSquareTimesObliquity) {
    const std::string args = kCone + "--pitch 4 --kvp 80 --out ";
    ASSERT_EQ(run(args + tmp("plain.npy")).status, 0);
    ASSERT_EQ(run(args + tmp("flat.npy") + " --flat-field").status, 0);
    std::vector<std::int64_t> s;
    const auto plain = load(tmp("plain.npy"), s), flat = load(tmp("flat.npy"), s);
    // Pixel (c, r) lies (c - 47.5) x 4 and (r - 31.5) x 4 mm from the principal point.
    double worst = 0.0;
    for (int r = 0; r < 64; r += 7)
        for (int c = 0; c < 96; c += 5) {
            const double x = (c - 47.5) * 4.0, y = (r - 31.5) * 4.0;
            const double f = std::pow(1100.0 / std::sqrt(1100.0 * 1100.0 + x * x + y * y), 3);
            const std::size_t k = std::size_t(r) * 96 + c;
            worst = std::max(worst, std::abs(flat[k] - plain[k] * f));
        }
    EXPECT_LT(worst, 1e-6);
    EXPECT_EQ(fvr::test::readSidecar(tmp("flat.npy"))["settings"]["flat_field"], true);
}

TEST(FvrRenderConePoly, GpuMaterialCastersMatchTheCpu) {
    const std::string args = kCone + "--kvp 90 --ray-model box --material-out ";
    ASSERT_EQ(run(args + tmp("mcpu.npy") + " --backend cpu --out " + tmp("cpu.npy")).status, 0);
    const Result r = run(args + tmp("mgpu.npy") + " --backend gpu --out " + tmp("gpu.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    const auto j = fvr::test::readSidecar(tmp("gpu.npy"));
    if (j["settings"]["backend"] == "cpu") GTEST_SKIP() << "no OpenGL 4.3 here: " << r.output;
    std::vector<std::int64_t> s;
    const auto a = load(tmp("cpu.npy"), s), b = load(tmp("gpu.npy"), s);
    const auto ma = load(tmp("mcpu.npy"), s), mb = load(tmp("mgpu.npy"), s);
    double worst = 0.0, worstM = 0.0, peak = 0.0;
    for (std::size_t p = 0; p < a.size(); ++p)
        worst = std::max(worst, double(std::abs(a[p] - b[p])));
    for (std::size_t p = 0; p < ma.size(); ++p) {
        worstM = std::max(worstM, double(std::abs(ma[p] - mb[p])));
        peak = std::max(peak, double(ma[p]));
    }
    std::printf("[gpu] cone --kvp: worst |I/I0| difference %.2e, rhoL %.2e of %.2f g/cm^2\n", worst,
                worstM, peak);
    EXPECT_LT(worst, 1e-4);
    EXPECT_LT(worstM, 1e-5 * peak);
}

namespace {

/** A float32 MetaImage of n^3 voxels of 1 mm about the origin: a cube of value 1 with faces at
 *  -6.5 and +9.5 mm (sharp edges), zeros around. */
std::string writeCube(int n) {
    const std::string raw = tmp("cube.raw"), mhd = tmp("cube.mhd");
    std::vector<float> v(std::size_t(n) * n * n, 0.0f);
    const double o = -(n - 1) / 2.0;
    for (int k = 0; k < n; ++k)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                auto in = [&](int a) { return o + a >= -6.0 && o + a <= 9.0; };
                if (in(i) && in(j) && in(k))
                    v[std::size_t(i) + std::size_t(n) * (j + std::size_t(n) * k)] = 1.0f;
            }
    std::ofstream(raw, std::ios::binary)
        .write(reinterpret_cast<const char*>(v.data()), std::streamsize(v.size() * 4));
    std::ofstream(mhd) << "ObjectType = Image\nNDims = 3\nDimSize = " << n << " " << n << " " << n
                       << "\nElementSpacing = 1 1 1\nOffset = " << o << " " << o << " " << o
                       << "\nTransformMatrix = 1 0 0 0 1 0 0 0 1\nElementType = MET_FLOAT\n"
                       << "ElementDataFile = " << std::filesystem::path(raw).filename().string()
                       << "\n";
    return mhd;
}

/** The image binned f x f (the mean of each block). */
std::vector<double> binned(const std::vector<float>& img, int w, int h, int f) {
    std::vector<double> out(std::size_t(w / f) * (h / f), 0.0);
    for (int r = 0; r < h; ++r)
        for (int c = 0; c < w; ++c)
            out[std::size_t(r / f) * (w / f) + c / f] += img[std::size_t(r) * w + c] / (f * f);
    return out;
}

} // namespace

TEST(FvrRenderConePoly, PixelApertureIsAFinerDetectorBinnedDown) {
    // The box model of a cube with sharp faces: an edge's profile on a 24^2 detector of 2 mm
    // pixels. The aperture averages n x n rays over each pixel: n = 4 is the 4x finer point-
    // sampled detector binned 4 x 4 (the same rays), and approaches the box filter of the pixel
    // (a 16x finer detector binned 16 x 16).
    const std::string base = writeCube(32) + " --geometry cone --ray-model box --sid 900 "
                                             "--sod 600 --primary-angle 20 --secondary-angle 10 ";
    auto render = [&](const std::string& name, int size, double pitch, const std::string& more) {
        const Result r =
            run(base + "--detector-size " + std::to_string(size) + "x" + std::to_string(size) +
                " --pitch " + std::to_string(pitch) + " " + more + " --out " + tmp(name));
        EXPECT_EQ(r.status, 0) << r.output;
        std::vector<std::int64_t> s;
        return load(tmp(name), s);
    };
    const auto point = render("point.npy", 24, 2.0, "");
    const auto ap4 = render("ap4.npy", 24, 2.0, "--pixel-aperture");
    const auto ap8 = render("ap8.npy", 24, 2.0, "--pixel-aperture --pixel-subsamples 8");
    const auto fine4 = binned(render("fine4.npy", 96, 0.5, ""), 96, 96, 4);
    const auto fine16 = binned(render("fine16.npy", 384, 0.125, ""), 384, 384, 16);
    double same = 0.0, toBox4 = 0.0, toBox8 = 0.0, pointToBox = 0.0;
    for (std::size_t p = 0; p < ap4.size(); ++p) {
        same = std::max(same, std::abs(ap4[p] - fine4[p]));
        toBox4 = std::max(toBox4, std::abs(ap4[p] - fine16[p]));
        toBox8 = std::max(toBox8, std::abs(ap8[p] - fine16[p]));
        pointToBox = std::max(pointToBox, std::abs(point[p] - fine16[p]));
    }
    std::printf("[aperture] worst |aperture - box-filtered| n=4 %.3f, n=8 %.3f mm; point "
                "sampling %.3f mm; n=4 vs 4x finer binned %.1e\n",
                toBox4, toBox8, pointToBox, same);
    EXPECT_LT(same, 1e-4); // the same rays, averaged in another order
    EXPECT_GT(pointToBox, 0.5); // at the edges, a point sample misses the pixel's partial path
    EXPECT_LT(toBox8, toBox4 + 1e-6);
    EXPECT_LT(toBox4, 0.25 * pointToBox);
    const auto j = fvr::test::readSidecar(tmp("ap4.npy"));
    EXPECT_EQ(j["settings"]["pixel_aperture"], true);
    EXPECT_EQ(j["settings"]["pixel_subsamples"], 4);
    EXPECT_NE(std::string(j["settings"]["renderer"]).find("4 x 4 rays per pixel"),
              std::string::npos);
}

TEST(FvrRenderConePoly, BadOptionsNameTheOption) {
    auto expectError = [](const std::string& args, const std::string& what) {
        const Result r = run(args);
        EXPECT_EQ(r.status, 2) << args << "\n" << r.output;
        EXPECT_NE(r.output.find(what), std::string::npos) << args << "\n" << r.output;
    };
    const std::string out = " --out " + tmp("bad.npy");
    expectError(kCone + "--pixel-subsamples 4" + out, "--pixel-aperture");
    expectError(kCone + "--pixel-aperture --pixel-subsamples 20" + out, "--pixel-subsamples");
    expectError("phantom:chest:64 --pixel-aperture --pixel-subsamples 2" + out,
                "--pixel-subsamples: only with --geometry cone");
    expectError(kCone + "--kvp 80 --sweep 3 --material-out " + tmp("m.npy") + out,
                "--material-out: needs one view (found 3)");
    expectError(kCone + "--kvp 80 --out " + tmp("bad.dcm"), "--kvp: writes .npy, .pfm or .png");
    expectError(kCone + "--kvp 80 --bench 2", "--kvp: not with --bench");
    expectError(writeCube(16) + " --geometry cone --kvp 80" + out, // values in no units
                "--kvp: the materials come from CT numbers");
}
