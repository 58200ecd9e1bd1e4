// fvr-render's defaults and presets come from core::RenderSettings: the sidecar records what the
// settings say, --preset paper gives the paper's Table 1 setting, options given with a preset
// win wherever they stand, and a default render is the image core renders with RenderSettings{}.
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fvr/core/errors.h>
#include <fvr/core/io/image_io.h>
#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/render/render_settings.h>
#include <fvr/core/xray/phantom.h>

#include "cli_support.h"
#include "image_metrics.h"
#include "test_support.h"

namespace {

using Json = nlohmann::json;
using namespace fvr::core;

std::string tmp(const std::string& name) {
    // Of this process: ctest runs each test in a process of its own, in parallel, and two tests
    // writing the same file (a volume one of them is reading) would race.
    return (fvr::test::tmpDir() / ("settings_" + std::to_string(getpid()) + "_" + name)).string();
}

using Result = fvr::test::RenderResult;
Result run(const std::string& args) { return fvr::test::runFvrRender(args); }

Json settingsOf(const std::string& out) { return fvr::test::readSidecar(out)["settings"]; }

TEST(FvrRenderSettings, TheDefaultsAreRenderSettingsDefaults) {
    const RenderSettings d;
    const Result r = run("phantom:shepp-logan:32 --size 128 --out " + tmp("default.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    const Json s = settingsOf(tmp("default.npy"));
    EXPECT_EQ(s["kernel"], kernelName(d.kernel)) << s;
    EXPECT_EQ(s["kernel"], "kaiser-bessel4") << s;
    EXPECT_EQ(s["oversampling"], 1.25) << s;
    EXPECT_EQ(s["values"], "mu") << s; // the phantom holds Hounsfield units
    EXPECT_EQ(s["deapodized"], true) << s;
    EXPECT_EQ(s["voxel_model"], "trilinear") << s;
    EXPECT_EQ(s["clip_to_volume"], true) << s;
    EXPECT_EQ(s["non_negative"], true) << s;
    EXPECT_EQ(s["transform"], "fft") << s;
}

TEST(FvrRenderSettings, PaperPresetIsTheTable1SettingAndOptionsWinWherever) {
    Result r = run("phantom:shepp-logan:32 --size 128 --preset paper --out " + tmp("paper.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    Json s = settingsOf(tmp("paper.npy"));
    EXPECT_EQ(s["kernel"], "linear") << s;
    EXPECT_EQ(s["oversampling"], 1.0) << s;
    EXPECT_EQ(s["values"], "raw") << s;
    EXPECT_EQ(s["deapodized"], false) << s;
    EXPECT_EQ(s["voxel_model"], "bandlimited") << s;
    EXPECT_EQ(s["clip_to_volume"], false) << s;
    EXPECT_EQ(s["non_negative"], false) << s;
    // An option before the preset still wins: the preset is the base, never an override.
    r = run("phantom:shepp-logan:32 --size 128 --kernel sinc4 --preset paper --out " +
            tmp("paper_sinc.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    s = settingsOf(tmp("paper_sinc.npy"));
    EXPECT_EQ(s["kernel"], "sinc4") << s;
    EXPECT_EQ(s["deapodized"], false) << s; // the paper's: no correction
    EXPECT_EQ(s["oversampling"], 1.0) << s;
    // What the paper preset turns off, turned back on.
    r = run("phantom:shepp-logan:32 --size 128 --preset paper --clip --non-negative --out " +
            tmp("paper_clip.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    s = settingsOf(tmp("paper_clip.npy"));
    EXPECT_EQ(s["clip_to_volume"], true) << s;
    EXPECT_EQ(s["non_negative"], false) << s; // raw HU can be negative: nothing to clamp
    r = run("phantom:shepp-logan:32 --clip --no-clip --out " + tmp("both.npy"));
    EXPECT_EQ(r.status, 2) << r.output;
    r = run("phantom:shepp-logan:32 --preset journal --out " + tmp("bad.npy"));
    EXPECT_EQ(r.status, 2) << r.output;
    EXPECT_NE(r.output.find("--preset"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("default or paper"), std::string::npos) << r.output;
}

TEST(FvrRenderSettings, DefaultImageIsCoresDefaultRenderOfTheApView) {
    // The oracle: core alone, RenderSettings{} for the phantom, the AP view of its LPS axes.
    const Volume v = makeSheppLoganVolume(40);
    const RenderSettings s = RenderSettings{}.forVolume(v);
    PreprocessOptions po = s.toPreprocessOptions();
    po.effort = PlannerEffort::Estimate;
    CpuFourierRenderer cpu(preprocess(v, po), 1);
    RenderSettings at128 = s;
    at128.size = 128;
    const auto truth = cpu.render(
        at128.toRenderParams(patientViewFrame(v, PatientView::AP), at128.imageGeometry(v)));
    const Result r = run("phantom:shepp-logan:40 --size 128 --backend cpu --out " + tmp("ap.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    const auto img = readNpy(tmp("ap.npy"), shape);
    ASSERT_EQ(shape, (std::vector<std::int64_t>{128, 128}));
    EXPECT_GT(fvr::test::compare(img, truth.pixels).psnr, 120.0);
    // Not the old default (along the slices): the AP view differs from the axial one.
    const auto axial = cpu.render(
        at128.toRenderParams(ViewFrame::fromDirUp({0, 0, 1}, {0, -1, 0}), at128.imageGeometry(v)));
    EXPECT_LT(fvr::test::compare(img, axial.pixels).psnr, 60.0);
}

TEST(FvrRenderSettings, DataInOtherUnitsIntegrateRawValues) {
    // A headerless float32 volume of small positive values: not taken for Hounsfield units.
    const std::string raw = tmp("vol.raw");
    {
        std::vector<float> vox(32 * 32 * 32, 0.0f);
        for (int z = 8; z < 24; ++z)
            for (int y = 8; y < 24; ++y)
                for (int x = 8; x < 24; ++x) vox[std::size_t((z * 32 + y) * 32 + x)] = 1.0f;
        std::ofstream out(raw, std::ios::binary);
        out.write(reinterpret_cast<const char*>(vox.data()), std::streamsize(vox.size() * 4));
    }
    const std::string input = raw + " --raw-dims 32,32,32 --raw-type float32 --size 128 ";
    Result r = run(input + "--out " + tmp("raw.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_EQ(settingsOf(tmp("raw.npy"))["values"], "raw");
    // The default is no request: no warning about it.
    EXPECT_EQ(r.output.find("not Hounsfield units"), std::string::npos) << r.output;
    // Asked for by name, the change is said.
    r = run(input + "--values mu --out " + tmp("raw_mu.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_EQ(settingsOf(tmp("raw_mu.npy"))["values"], "raw");
    EXPECT_NE(r.output.find("not Hounsfield units"), std::string::npos) << r.output;
    // A transmission needs attenuation.
    r = run(input + "--beer-lambert --out " + tmp("raw_bl.npy"));
    EXPECT_EQ(r.status, 2) << r.output;
    EXPECT_NE(r.output.find("--beer-lambert"), std::string::npos) << r.output;
}

TEST(FvrRenderSettings, ASweepAboutTheDefaultViewsAxisStartsAcrossIt) {
    // The default view (AP) looks along y; a sweep about y starts from LEFT instead of failing.
    const Result r =
        run("phantom:shepp-logan:32 --size 128 --sweep 2 --axis 0,1,0 --out " + tmp("sweep_y.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    std::ifstream in(tmp("sweep_y.npy") + ".json");
    const Json dir = Json::parse(in)["views"][0]["dir"];
    EXPECT_NEAR(std::abs(dir[0].get<double>()), 1.0, 1e-9) << dir; // along x: LEFT
}

TEST(FvrRenderSettings, TheDefaultBeamIsWaterAt70KeV) {
    const Result r =
        run("phantom:shepp-logan:32 --size 128 --beer-lambert --out " + tmp("beam.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    std::ifstream in(tmp("beam.npy") + ".json");
    const Json out = Json::parse(in)["output"];
    EXPECT_EQ(out["energy_kev"], 70.0) << out;
    EXPECT_DOUBLE_EQ(out["mu_water_per_mm"].get<double>(), waterAttenuationPerMm(70.0)) << out;
}

TEST(FvrRenderSettings, TheWorkstationsSizesAreAmongTheSizesThatRender) {
    for (int m : settingsSizes()) EXPECT_NO_THROW(validateSettingsSize(m)) << m;
    EXPECT_EQ(settingsSizes().front(), RenderSettings::kMinSize);
    EXPECT_EQ(settingsSizes().back(), RenderSettings::kMaxSize);
    for (int m : {16, 17, 200, 224, 975, 4096}) EXPECT_NO_THROW(validateSettingsSize(m)) << m;
    for (int m : {15, 0, -4, 4097}) EXPECT_THROW(validateSettingsSize(m), SettingsError) << m;
    const Result r = run("phantom:shepp-logan:32 --size 4097 --out " + tmp("s.npy"));
    EXPECT_EQ(r.status, 2) << r.output;
    EXPECT_NE(r.output.find("expected 16..4096 pixels, found 4097"), std::string::npos) << r.output;
}

TEST(FvrRenderSettings, AnyWidthAndHeightRenderWithTheCentreAtWHalfHHalf) {
    // 96 x 64 and the 128^2 square at the same pixel size, 3.5 mm: the phantom's 443 mm
    // diagonal fits 128 pixels, so the rectangle is transformed on the same 128^2 square and is
    // its centred crop (column 48 of 96 is column 64 of 128), to the bit.
    const std::string args = "phantom:shepp-logan:32 --dir 0.3,0.5,0.8 --pixel-size 3.5 ";
    Result r = run(args + "--size 96x64 --out " + tmp("rect.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_NE(r.output.find("96x64"), std::string::npos) << r.output;
    ASSERT_EQ(run(args + "--size 128 --out " + tmp("square.npy")).status, 0);
    std::vector<std::int64_t> shape;
    const auto rect = readNpy(tmp("rect.npy"), shape);
    ASSERT_EQ(shape, (std::vector<std::int64_t>{64, 96}));
    const auto square = readNpy(tmp("square.npy"), shape);
    std::vector<float> crop, shifted;
    for (int row = 0; row < 64; ++row)
        for (int col = 0; col < 96; ++col) {
            crop.push_back(square[std::size_t(row + 32) * 128 + std::size_t(col + 16)]);
            shifted.push_back(square[std::size_t(row + 32) * 128 + std::size_t(col + 17)]);
        }
    EXPECT_EQ(rect, crop);
    EXPECT_LT(fvr::test::compare(rect, shifted).psnr, 50.0); // one column off is far off
    const Json image = fvr::test::readSidecar(tmp("rect.npy"))["image"];
    EXPECT_EQ(image["width"], 96);
    EXPECT_EQ(image["height"], 64);
    EXPECT_FALSE(image.contains("size")); // M only where the image is square
    EXPECT_EQ(settingsOf(tmp("rect.npy"))["height"], 64);
    // Other formats write W columns and H rows too.
    ASSERT_EQ(run(args + "--size 96x64 --out " + tmp("rect.pfm")).status, 0);
    std::ifstream pfm(tmp("rect.pfm"));
    std::string magic;
    int w = 0, h = 0;
    pfm >> magic >> w >> h;
    EXPECT_EQ(magic, "Pf");
    EXPECT_EQ(w, 96);
    EXPECT_EQ(h, 64);
}

} // namespace
