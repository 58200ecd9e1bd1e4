// fvr-render --kvp end to end: I/I0 against the exact spectral sum of the written
// material line integrals, the materials against the monochromatic mu projection (they keep
// the attenuation at 70 keV), kVp, noise, the sidecar and the option errors.
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fvr/core/io/image_io.h>
#include <fvr/core/xray/polychromatic.h>
#include <fvr/core/xray/spectrum_model.h>

#include "poly_support.h"
#include "test_support.h"

using namespace fvr::core;

namespace {

std::string tmp(const std::string& name) {
    // Of this process: ctest runs the tests in parallel processes.
    return (fvr::test::tmpDir() / ("poly_" + std::to_string(getpid()) + "_" + name)).string();
}

fvr::test::CommandOutput render(const std::string& args) {
    return fvr::test::runCommand(std::string(FVR_RENDER_EXE) + " " + args + " 2>&1");
}

std::vector<float> load(const std::string& path, std::vector<std::int64_t>& shape) {
    return readNpy(path, shape);
}

const std::string kChest = "phantom:chest:64 --view AP --size 128";

} // namespace

TEST(FvrRenderPoly, TransmissionIsTheSpectralSumOfTheWrittenMaterials) {
    const auto r = render(kChest + " --kvp 80 --filtration-al 2.5 --out " + tmp("poly.npy") +
                          " --material-out " + tmp("poly_mat.npy"));
    ASSERT_EQ(r.status, 0) << r.out;
    std::vector<std::int64_t> shape, mshape;
    const auto t = load(tmp("poly.npy"), shape);
    const auto m = load(tmp("poly_mat.npy"), mshape);
    ASSERT_EQ(shape, (std::vector<std::int64_t>{128, 128}));
    ASSERT_EQ(mshape, (std::vector<std::int64_t>{3, 128, 128}));
    const SpectralResponse ref(tubeSpectrum(80.0, 2.5), {}, defaultMaterials());
    const fvr::test::SpectralSumCheck sum = fvr::test::checkSpectralSum(t, m, ref);
    EXPECT_LT(sum.worstLogError, 1e-3);
    EXPECT_LT(sum.darkest, 0.05); // through the spine and mediastinum
    std::ifstream in(tmp("poly.npy.json"));
    const auto j = nlohmann::json::parse(in);
    EXPECT_EQ(j["settings"]["materials"],
              (nlohmann::json{"Air, Dry (near sea level)", "Tissue, Soft (ICRP)",
                              "Bone, Cortical (ICRP)"}));
    EXPECT_EQ(j["settings"]["polychromatic"]["kvp"], 80.0);
    EXPECT_NEAR(double(j["settings"]["polychromatic"]["hvl_al_mm"]),
                halfValueLayerAlMm(tubeSpectrum(80.0, 2.5)), 1e-9);
}

TEST(FvrRenderPoly, MaterialsKeepTheAttenuationOfTheMonochromaticProjection) {
    // Without the clamp at 0 (--keep-negative), which acts on each material there and on the
    // sum here: the renderer is linear, so the two then agree to float rounding.
    const std::string common = kChest + " --keep-negative";
    ASSERT_EQ(render(common + " --values mu --out " + tmp("mono.npy")).status, 0);
    ASSERT_EQ(
        render(common + " --kvp 70 --out " + tmp("p70.npy") + " --material-out " + tmp("m70.npy"))
            .status,
        0);
    std::vector<std::int64_t> s1, s2;
    const auto mono = load(tmp("mono.npy"), s1); // mm of water
    const auto m = load(tmp("m70.npy"), s2);
    const std::size_t n = mono.size();
    const char* names[3] = {"Air, Dry (near sea level)", "Tissue, Soft (ICRP)",
                            "Bone, Cortical (ICRP)"};
    double mu[3], peak = 0.0, worst = 0.0;
    for (int k = 0; k < 3; ++k) mu[k] = massAttenuation(names[k], 70.0);
    const double muWater = massAttenuation("Water, Liquid", 70.0);
    for (std::size_t p = 0; p < n; ++p) {
        const double a = mu[0] * m[p] + mu[1] * m[n + p] + mu[2] * m[2 * n + p];
        const double b = muWater * mono[p] / 10.0; // mm of water -> g/cm^2
        peak = std::max(peak, b);
        worst = std::max(worst, std::abs(a - b));
    }
    EXPECT_GT(peak, 3.0);
    EXPECT_LT(worst, 1e-5 * peak);
}

TEST(FvrRenderPoly, HigherKvpTransmitsMoreAndNoiseIsSeeded) {
    ASSERT_EQ(render(kChest + " --kvp 70 --out " + tmp("k70.npy")).status, 0);
    ASSERT_EQ(render(kChest + " --kvp 120 --out " + tmp("k120.npy")).status, 0);
    std::vector<std::int64_t> s;
    const auto a = load(tmp("k70.npy"), s), b = load(tmp("k120.npy"), s);
    for (std::size_t p = 0; p < a.size(); ++p)
        if (a[p] < 0.99f) {
            ASSERT_GT(b[p], a[p]) << p;
        }
    const std::string noisy = kChest + " --kvp 70 --noise-mas 0.5 --detector counting --seed ";
    ASSERT_EQ(render(noisy + "3 --out " + tmp("n1.npy")).status, 0);
    ASSERT_EQ(render(noisy + "3 --out " + tmp("n2.npy")).status, 0);
    ASSERT_EQ(render(noisy + "4 --out " + tmp("n3.npy")).status, 0);
    const auto n1 = load(tmp("n1.npy"), s), n2 = load(tmp("n2.npy"), s),
               n3 = load(tmp("n3.npy"), s);
    EXPECT_EQ(n1, n2);
    EXPECT_NE(n1, n3);
}

TEST(FvrRenderPoly, BadOptionsNameTheOption) {
    auto expectError = [](const std::string& args, const std::string& what) {
        const auto r = render(args);
        EXPECT_EQ(r.status, 2) << args << "\n" << r.out;
        EXPECT_NE(r.out.find(what), std::string::npos) << args << "\n" << r.out;
    };
    const std::string out = " --out " + tmp("bad.npy");
    expectError(kChest + " --filtration-al 2" + out, "--filtration-al");
    expectError(kChest + " --kvp 200" + out, "30..140");
    expectError(kChest + " --kvp 80 --materials air,steel" + out, "steel");
    expectError(kChest + " --kvp 80 --detector film" + out, "energy or counting");
    expectError(kChest + " --kvp 80 --values mu --beer-lambert" + out, "--beer-lambert");
    expectError(kChest + " --kvp 80 --sweep 3 --material-out " + tmp("m.npy") + out,
                "--material-out");
    // It exited 0 and sent nothing: I/I0 has no DICOM object to send yet.
    expectError(kChest + " --kvp 80 --send dicom://PACS@127.0.0.1:1" + out,
                "--send: not with --kvp");
}

TEST(FvrRenderPoly, GpuMaterialFramesAndSpectralSumMatchTheCpu) {
    const std::string args = kChest + " --kvp 90 --filtration-cu 0.1";
    ASSERT_EQ(render(args + " --backend cpu --out " + tmp("pcpu.npy")).status, 0);
    const auto r = render(args + " --backend gpu --out " + tmp("pgpu.npy"));
    ASSERT_EQ(r.status, 0) << r.out;
    std::ifstream in(tmp("pgpu.npy.json"));
    const auto j = nlohmann::json::parse(in);
    if (j["settings"]["backend"] == "cpu") GTEST_SKIP() << "no OpenGL 4.3 here: " << r.out;
    EXPECT_EQ(j["output"]["spectral_sum_on"], "gpu"); // the sum runs where the frames lie
    std::vector<std::int64_t> s;
    const auto a = load(tmp("pcpu.npy"), s), b = load(tmp("pgpu.npy"), s);
    double worst = 0.0;
    for (std::size_t p = 0; p < a.size(); ++p)
        worst = std::max(worst, std::abs(std::log(double(a[p])) - std::log(double(b[p]))));
    EXPECT_LT(worst, 1e-4); // -ln(I/I0): the GPU and CPU renderers agree to float rounding
}
