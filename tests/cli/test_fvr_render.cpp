// fvr-render end to end: outputs, JSON, exit codes and messages for bad input.
#include <sys/wait.h>

#include <cstdio>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <cmath>
#include <complex>
#include <string>

#include <fftw3.h>
#include <gtest/gtest.h>

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/io/image_io.h>
#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/xray/phantom.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/render/voxel_model.h>
#include <fvr/core/xray/xray.h>

#include "image_metrics.h"
#include "test_support.h"

using namespace fvr::core;

namespace {

struct Result {
    int status = -1;
    std::string output; // stdout and stderr
};

/** Runs fvr-render with `args`; `envPrefix` (e.g. "env -u DISPLAY") goes before the binary. */
Result run(const std::string& args, const std::string& envPrefix = {}) {
    const std::string cmd = envPrefix + " " + std::string(FVR_RENDER_EXE) + " " + args + " 2>&1";
    Result r;
    FILE* p = popen(cmd.c_str(), "r");
    if (!p) return r;
    char buf[4096];
    std::size_t n;
    while ((n = fread(buf, 1, sizeof buf, p)) > 0) r.output.append(buf, n);
    const int st = pclose(p);
    r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
    return r;
}

std::string tmp(const std::string& name) { return (fvr::test::tmpDir() / name).string(); }

std::string readText(const std::string& path) {
    std::ifstream in(path);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

/** The slice filter applied in double to an M x M image of pixel size d (mm): 2D DFT (FFTW),
 *  times H(|(m, n)| / (M d)) with (m, n) the signed frequency indices, inverse DFT. */
std::vector<float> filterInDouble(const std::vector<float>& image, int M, double d, const SliceFilter& filter) {
    auto* buf = static_cast<fftw_complex*>(fftw_malloc(sizeof(fftw_complex) * std::size_t(M) * M));
    const fftw_plan fwd = fftw_plan_dft_2d(M, M, buf, buf, FFTW_FORWARD, FFTW_ESTIMATE);
    const fftw_plan inv = fftw_plan_dft_2d(M, M, buf, buf, FFTW_BACKWARD, FFTW_ESTIMATE);
    for (std::size_t i = 0; i < image.size(); ++i) {
        buf[i][0] = image[i];
        buf[i][1] = 0.0;
    }
    fftw_execute(fwd);
    for (int r = 0; r < M; ++r)
        for (int c = 0; c < M; ++c) {
            const double m = r < M / 2 ? r : r - M, n = c < M / 2 ? c : c - M;
            const double h = filter.response(std::hypot(m, n) / (M * d)) / (double(M) * M);
            buf[std::size_t(r) * M + c][0] *= h;
            buf[std::size_t(r) * M + c][1] *= h;
        }
    fftw_execute(inv);
    std::vector<float> out(image.size());
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = float(buf[i][0]);
    fftw_destroy_plan(fwd);
    fftw_destroy_plan(inv);
    fftw_free(buf);
    return out;
}

} // namespace

TEST(FvrRender, PhantomNpyMatchesAnalyticProjection) {
    const std::string out = tmp("cli_phantom.npy");
    const Result r = run("phantom:shepp-logan:64 --dir 0.35,0.2,0.92 --up 0,-1,0 --size 128 "
                         "--kernel catmull-rom --oversampling 2 --values mu --out " + out);
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    const auto pixels = readNpy(out, shape);
    ASSERT_EQ(shape, (std::vector<std::int64_t>{128, 128}));
    // Independent oracle: exact line integrals of the same ellipsoids at the same pixels.
    const Volume v = makeSheppLoganVolume(64);
    const auto truth = EllipsoidPhantom::sheppLogan3D(256.0).project(
        ViewFrame::fromDirUp({0.35, 0.2, 0.92}, {0, -1, 0}), {128, defaultPixelSize(v.dims, v.spacing, 128)},
        ValueMapping::Mu, v.dims, v.spacing);
    EXPECT_GT(fvr::test::compare(pixels, truth.pixels).psnr, 38.0);
}

TEST(FvrRender, WritesPfmAndPng) {
    for (const char* ext : {".pfm", ".png"}) {
        const std::string out = tmp(std::string("cli_out") + ext);
        std::remove(out.c_str());
        const Result r = run("phantom:shepp-logan:32 --size 128 --transform fht --out " + out);
        ASSERT_EQ(r.status, 0) << r.output;
        std::ifstream in(out, std::ios::binary);
        std::string head(8, '\0');
        in.read(head.data(), 8);
        if (std::string(ext) == ".pfm") EXPECT_EQ(head.substr(0, 3), "Pf\n");
        else EXPECT_EQ(head, std::string("\x89PNG\r\n\x1a\n", 8));
    }
}

TEST(FvrRender, InfoJsonForPhantomAndSharedVolume) {
    Result r = run("phantom:shepp-logan:48 --info");
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_NE(r.output.find("\"dims\": [48, 48, 48]"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("\"units\": \"HU\""), std::string::npos) << r.output;
    const auto headsq = fvr::test::sharedData() / "volumes/headsq/headsq.mhd";
    if (!std::filesystem::exists(headsq)) GTEST_SKIP() << "shared data not found: " << headsq;
    r = run(headsq.string() + " --info");
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_NE(r.output.find("\"dims\": [64, 64, 93]"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("\"spacing_mm\": [3.2, 3.2, 1.5]"), std::string::npos) << r.output;
}

TEST(FvrRender, BenchPrintsStageJson) {
    const Result r = run("phantom:shepp-logan:32 --size 128 --bench 5 --kernel sinc4");
    ASSERT_EQ(r.status, 0) << r.output;
    for (const char* key : {"\"preprocess\"", "\"slice\"", "\"inverse\"", "\"total\"", "\"median_ms\"",
                            "\"p95_ms\"", "\"kernel\": \"sinc4\"", "\"frames\": 5"})
        EXPECT_NE(r.output.find(key), std::string::npos) << key << " in " << r.output;
}

TEST(FvrRender, BadInputExitsTwoWithAClearMessage) {
    struct Case {
        std::string args, expect;
    };
    const std::string bad = tmp("bad.mhd");
    {
        std::ofstream f(bad);
        f << "NDims = 3\nDimSize = 10 10\nElementType = MET_SHORT\nElementDataFile = bad.raw\n";
    }
    const Case cases[] = {
        {"/no/such/volume.nii.gz --out " + tmp("x.npy"), "/no/such/volume.nii.gz"},
        {bad + " --out " + tmp("x.npy"), "DimSize"},
        {"phantom:shepp-logan:32 --kernel lanczos --out " + tmp("x.npy"), "kernel"},
        {"phantom:shepp-logan:32 --size 100 --out " + tmp("x.npy"), "size"},
        {"phantom:shepp-logan:32 --oversampling 3 --out " + tmp("x.npy"), "oversampling"},
        {"phantom:shepp-logan:32 --dir 0,0,1 --up 0,0,1 --out " + tmp("x.npy"), "up"},
        {"phantom:shepp-logan:32", "--out"},
        {"phantom:cube --out " + tmp("x.npy"), "phantom"},
        {"phantom:shepp-logan:32 --frobnicate --out " + tmp("x.npy"), "--frobnicate"},
        {"phantom:shepp-logan:32 --backend vulkan --out " + tmp("x.npy"), "backend"},
    };
    for (const Case& c : cases) {
        const Result r = run(c.args);
        EXPECT_EQ(r.status, 2) << c.args << "\n" << r.output;
        EXPECT_NE(r.output.find(c.expect), std::string::npos) << c.args << "\n" << r.output;
        EXPECT_EQ(r.output.find("terminate"), std::string::npos) << r.output;
    }
}

TEST(FvrRender, UnwritableOutputExitsOne) {
    const Result r = run("phantom:shepp-logan:32 --size 128 --out /no/such/dir/out.npy");
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_NE(r.output.find("/no/such/dir/out.npy"), std::string::npos) << r.output;
}

TEST(FvrRender, GpuBackendMatchesCpuOrFallsBackWithANotice) {
    const std::string args = "phantom:shepp-logan:48 --dir 0.3,0.5,0.8 --size 128 --kernel sinc4 --oversampling 1.5 ";
    // Without any display the GPU cannot be used here: the CPU renders and says so.
    const Result noDisplay = run("--backend gpu " + args + "--out " + tmp("nogpu.npy"),
                                 "env -u DISPLAY -u QT_QPA_PLATFORM -u WAYLAND_DISPLAY");
    EXPECT_EQ(noDisplay.status, 0) << noDisplay.output;
    EXPECT_NE(noDisplay.output.find("rendering on the CPU"), std::string::npos) << noDisplay.output;
    if (!std::getenv("DISPLAY")) GTEST_SKIP() << "no X display (make test runs the suite under xvfb-run)";
    Result r = run("--backend gpu " + args + "--out " + tmp("gpu.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    ASSERT_NE(r.output.find("gpu: "), std::string::npos) << "GPU backend not used: " << r.output;
    r = run("--backend cpu " + args + "--out " + tmp("cpu.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    const auto g = readNpy(tmp("gpu.npy"), shape);
    const auto c = readNpy(tmp("cpu.npy"), shape);
    EXPECT_GT(fvr::test::compare(g, c).psnr, 90.0);
    // Depth cue and slice filter reach both renderers the same way.
    const std::string xray = "--values mu --depth-cue 0.6 --sharpen 1 --sharpen-radius 2 --band-limit 0.1 ";
    r = run("--backend gpu " + args + xray + "--out " + tmp("gpux.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    ASSERT_NE(r.output.find("gpu: "), std::string::npos) << "GPU backend not used: " << r.output;
    ASSERT_EQ(run("--backend cpu " + args + xray + "--out " + tmp("cpux.npy")).status, 0);
    EXPECT_GT(fvr::test::compare(readNpy(tmp("gpux.npy"), shape), readNpy(tmp("cpux.npy"), shape)).psnr, 90.0);
}

TEST(FvrRender, DicomFolderInfoListsSeriesWithWarnings) {
    FVR_REQUIRE_DATA("dicom/ct_head_ge_gantrytilt_28");
    const auto dir = fvr::test::sharedData() / "dicom/ct_head_ge_gantrytilt_28";
    const Result r = run(dir.string() + " --info");
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_NE(r.output.find("\"series\": ["), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("\"modality\": \"CT\""), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("\"images\": 28"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("gantry tilt"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("uneven slice spacing"), std::string::npos) << r.output;
}

TEST(FvrRender, DicomPatientViewsFollowTheDirectionCosines) {
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93");
    const auto dir = (fvr::test::sharedData() / "dicom/ct_head_slicer_64x64x93").string();
    // AP and PA look along opposite directions: the same line integrals, mirrored left-right.
    ASSERT_EQ(run(dir + " --view AP --size 128 --values mu --out " + tmp("ap.npy")).status, 0);
    ASSERT_EQ(run(dir + " --view PA --size 128 --values mu --out " + tmp("pa.npy")).status, 0);
    std::vector<std::int64_t> shape;
    const auto ap = readNpy(tmp("ap.npy"), shape);
    const auto pa = readNpy(tmp("pa.npy"), shape);
    std::vector<float> mirrored(pa.size());
    for (int row = 0; row < 128; ++row)
        for (int col = 0; col < 128; ++col) {
            // Mirror about the image centre column M/2: col -> M - col (col 0 has no partner).
            const int mc = (128 - col) % 128;
            mirrored[std::size_t(row) * 128 + col] = pa[std::size_t(row) * 128 + mc];
        }
    EXPECT_GT(fvr::test::compare(mirrored, ap).psnr, 60.0);
    // A wrong series UID is bad input.
    const Result bad = run(dir + " --series 1.2.3.4 --out " + tmp("x.npy"));
    EXPECT_EQ(bad.status, 2) << bad.output;
    EXPECT_NE(bad.output.find("1.2.3.4"), std::string::npos) << bad.output;
    const Result badView = run(dir + " --view OBLIQUE --out " + tmp("x.npy"));
    EXPECT_EQ(badView.status, 2) << badView.output;
}

TEST(FvrRender, SweepStackEqualsSingleViewsAndSidecarRecordsThem) {
    const std::string common = "phantom:shepp-logan:40 --size 128 --kernel catmull-rom --values mu ";
    Result r = run(common + "--sweep 4 --axis 0,1,0 --out " + tmp("sweep.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    const auto stack = readNpy(tmp("sweep.npy"), shape);
    ASSERT_EQ(shape, (std::vector<std::int64_t>{4, 128, 128}));
    // View 1 of the sweep is the default view turned by 90 degrees about y: D = (0,0,1) -> (1,0,0).
    r = run(common + "--dir 1,0,0 --up 0,-1,0 --out " + tmp("view1.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    const auto single = readNpy(tmp("view1.npy"), shape);
    const std::vector<float> frame1(stack.begin() + 128 * 128, stack.begin() + 2 * 128 * 128);
    EXPECT_GT(fvr::test::compare(frame1, single).psnr, 100.0);
    std::ifstream js(tmp("sweep.npy") + ".json");
    const std::string json((std::istreambuf_iterator<char>(js)), std::istreambuf_iterator<char>());
    for (const char* key : {"\"views\": [", "\"kernel\": \"catmull-rom\"", "\"stacked\": true", "\"pixel_size_mm\"",
                            "\"spacing_mm\"", "\"right\""})
        EXPECT_NE(json.find(key), std::string::npos) << key << " in " << json;
}

TEST(FvrRender, ViewsFileNumberedOutputsAndErrors) {
    {
        std::ofstream f(tmp("views.txt"));
        f << "# dir, up\n0 0 1  0 -1 0\n1,0,0, 0,0,1\n\n0 1 0 0 0 1  # lateral\n";
    }
    const std::string out = tmp("v.pfm");
    Result r = run("phantom:shepp-logan:32 --size 128 --views " + tmp("views.txt") + " --out " + out);
    ASSERT_EQ(r.status, 0) << r.output;
    for (int i = 0; i < 3; ++i)
        EXPECT_TRUE(std::filesystem::exists(tmp("v_000" + std::to_string(i) + ".pfm"))) << i;
    {
        std::ofstream f(tmp("badviews.txt"));
        f << "0 0 1 0 -1 0\n0 0 1 0 0\n";
    }
    r = run("phantom:shepp-logan:32 --size 128 --views " + tmp("badviews.txt") + " --out " + out);
    EXPECT_EQ(r.status, 2) << r.output;
    EXPECT_NE(r.output.find("badviews.txt:2"), std::string::npos) << r.output;
    r = run("phantom:shepp-logan:32 --size 128 --sweep 3 --views " + tmp("views.txt") + " --out " + out);
    EXPECT_EQ(r.status, 2) << r.output;
    r = run("phantom:shepp-logan:32 --size 128 --beer-lambert --out " + out);
    EXPECT_EQ(r.status, 2) << r.output;
    EXPECT_NE(r.output.find("--values mu"), std::string::npos) << r.output;
}

TEST(FvrRender, BeerLambertIsExpOfTheLineIntegrals) {
    const std::string common = "phantom:shepp-logan:32 --size 128 --values mu --dir 0.2,0.3,0.9 ";
    ASSERT_EQ(run(common + "--out " + tmp("mu.npy")).status, 0);
    ASSERT_EQ(run(common + "--beer-lambert --mu-water 0.02 --out " + tmp("bl.npy")).status, 0);
    std::vector<std::int64_t> shape;
    const auto mu = readNpy(tmp("mu.npy"), shape);
    const auto bl = readNpy(tmp("bl.npy"), shape);
    double maxErr = 0;
    for (std::size_t i = 0; i < mu.size(); ++i) maxErr = std::max(maxErr, std::abs(bl[i] - std::exp(-0.02 * mu[i])));
    EXPECT_LT(maxErr, 1e-6);
}

TEST(FvrRender, BenchComparesWithRayCasting) {
    const Result r = run("phantom:shepp-logan:32 --size 128 --bench 4");
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_NE(r.output.find("\"spatial_projector\""), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("\"speedup_per_view\""), std::string::npos) << r.output;
}

TEST(FvrRender, KaiserBesselDeapodizedBeatsThePapersSetting) {
    const std::string common = "phantom:shepp-logan:64 --dir 0.35,0.2,0.92 --up 0,-1,0 --size 128 --values mu ";
    ASSERT_EQ(run(common + "--kernel kaiser-bessel --oversampling 1.25 --out " + tmp("kb.npy")).status, 0);
    ASSERT_EQ(run(common + "--kernel linear --out " + tmp("tl.npy")).status, 0);
    std::vector<std::int64_t> shape;
    const Volume v = makeSheppLoganVolume(64);
    const auto truth = EllipsoidPhantom::sheppLogan3D(256.0).project(
        ViewFrame::fromDirUp({0.35, 0.2, 0.92}, {0, -1, 0}), {128, defaultPixelSize(v.dims, v.spacing, 128)},
        ValueMapping::Mu, v.dims, v.spacing);
    const double kb = fvr::test::compare(readNpy(tmp("kb.npy"), shape), truth.pixels).psnr;
    const double tl = fvr::test::compare(readNpy(tmp("tl.npy"), shape), truth.pixels).psnr;
    std::printf("[cli] kaiser-bessel4 oversampling 1.25 deapodized %.2f dB, trilinear oversampling 1 %.2f dB\n", kb, tl);
    EXPECT_GT(kb, tl + 12.0);
    std::ifstream js(tmp("kb.npy") + ".json");
    const std::string json((std::istreambuf_iterator<char>(js)), std::istreambuf_iterator<char>());
    EXPECT_NE(json.find("\"deapodized\": true"), std::string::npos);
    const Result bad = run(common + "--kernel linear --kernel-width 6 --out " + tmp("x.npy"));
    EXPECT_EQ(bad.status, 2);
}

TEST(FvrRender, WritesDicomThatLoadsBackAsTheProjection) {
    const std::string common = "phantom:shepp-logan:32 --size 128 --values mu --dir 0.2,0.3,0.9 ";
    ASSERT_EQ(run(common + "--out " + tmp("d.npy")).status, 0);
    const Result r = run(common + "--out " + tmp("d.dcm"));
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    const auto ref = readNpy(tmp("d.npy"), shape);
    const auto back = fvr::core::loadDicomFile(tmp("d.dcm"));
    ASSERT_EQ(back.volume.voxels.size(), ref.size());
    EXPECT_GT(fvr::test::compare(back.volume.voxels, ref).psnr, 90.0); // 16-bit quantisation only
}

TEST(FvrRender, BeerLambertEnergyAndExposureScaleTheTransmission) {
    const std::string common = "phantom:shepp-logan:32 --size 128 --values mu --dir 0.2,0.3,0.9 ";
    ASSERT_EQ(run(common + "--out " + tmp("xl.npy")).status, 0);
    const Result r = run(common + "--beer-lambert --energy 60 --exposure 1.5 --out " + tmp("xbl.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    const auto L = readNpy(tmp("xl.npy"), shape);
    const auto bl = readNpy(tmp("xbl.npy"), shape);
    ASSERT_EQ(bl.size(), L.size());
    const double mu = waterAttenuationPerMm(60.0);
    double maxRel = 0, minI = 1e9;
    for (std::size_t i = 0; i < L.size(); ++i) {
        const double expect = 1.5 * std::exp(-mu * double(L[i]));
        maxRel = std::max(maxRel, std::abs(bl[i] - expect) / expect);
        minI = std::min(minI, double(bl[i]));
    }
    std::printf("[cli] beer-lambert 60 keV (mu_water %.5f/mm) exposure 1.5: max relative error %.2e, min %.4f\n", mu,
                maxRel, minI);
    EXPECT_LT(maxRel, 1e-5);
    EXPECT_LT(minI, 1.0); // the phantom attenuates: the test sees the exponential, not just the exposure
    const std::string json = readText(tmp("xbl.npy") + ".json");
    for (const char* key : {"\"mu_water_per_mm\": 0.02059", "\"energy_kev\": 60", "\"exposure\": 1.5"})
        EXPECT_NE(json.find(key), std::string::npos) << key << " in " << json;
    // mu-bone is an attenuation mapping too.
    const Result bone = run("phantom:shepp-logan:32 --size 128 --values mu-bone --beer-lambert --out " + tmp("xbb.npy"));
    EXPECT_EQ(bone.status, 0) << bone.output;
}

TEST(FvrRender, DepthCueMatchesTheAnalyticDepthWeightedProjection) {
    const std::string common = "phantom:shepp-logan:64 --dir 0.35,0.2,0.92 --up 0,-1,0 --size 128 "
                               "--kernel catmull-rom --oversampling 2 --values mu ";
    Result r = run(common + "--depth-cue 0.6 --out " + tmp("dc.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    r = run(common + "--out " + tmp("nodc.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    const auto cued = readNpy(tmp("dc.npy"), shape);
    ASSERT_EQ(shape, (std::vector<std::int64_t>{128, 128}));
    const auto plain = readNpy(tmp("nodc.npy"), shape);
    const Volume v = makeSheppLoganVolume(64);
    const ViewFrame view = ViewFrame::fromDirUp({0.35, 0.2, 0.92}, {0, -1, 0});
    const ImageGeometry geom{128, defaultPixelSize(v.dims, v.spacing, 128)};
    const auto phantom = EllipsoidPhantom::sheppLogan3D(256.0);
    const auto truth = phantom.project(view, geom, ValueMapping::Mu, v.dims, v.spacing, 0.6);
    const auto plainTruth = phantom.project(view, geom, ValueMapping::Mu, v.dims, v.spacing);
    const double psnr = fvr::test::compare(cued, truth.pixels).psnr;
    const double vsPlainTruth = fvr::test::compare(cued, plainTruth.pixels).psnr;
    const double vsPlainRun = fvr::test::compare(cued, plain).psnr;
    std::printf("[cli] depth cue 0.6: %.2f dB vs the depth-weighted oracle, %.2f dB vs the plain oracle, "
                "%.2f dB vs the run without depth cue\n", psnr, vsPlainTruth, vsPlainRun);
    EXPECT_GT(psnr, 37.0); // measured 40.3 dB
    EXPECT_LT(vsPlainRun, 40.0); // the depth cue changes the image
    EXPECT_GT(psnr, vsPlainTruth + 10.0);
    EXPECT_NE(readText(tmp("dc.npy") + ".json").find("\"depth_cue\": 0.6"), std::string::npos);
}

TEST(FvrRender, SliceFilterEqualsTheFilterAppliedInDouble) {
    // Pixel 1 mm: the slice reaches 0.5 lp/mm; the volume (2 mm voxels) holds up to 0.25 lp/mm per
    // axis, about 0.35 along an oblique slice, so the band limit at 0.3 lp/mm acts as well.
    const std::string common = "phantom:shepp-logan:128 --dir 0.35,0.2,0.92 --up 0,-1,0 --size 256 --pixel-size 1 "
                               "--values mu ";
    Result r = run(common + "--out " + tmp("unf.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    r = run(common + "--sharpen 1 --sharpen-radius 2 --band-limit 0.3 --out " + tmp("filt.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    const auto unfiltered = readNpy(tmp("unf.npy"), shape);
    const auto filtered = readNpy(tmp("filt.npy"), shape);
    ASSERT_EQ(shape, (std::vector<std::int64_t>{256, 256}));
    SliceFilter f;
    f.sharpenAmount = 1.0;
    f.sharpenSigmaMm = 2.0;
    f.bandLimitLpMm = 0.3;
    const auto oracle = filterInDouble(unfiltered, 256, 1.0, f);
    const auto c = fvr::test::compare(filtered, oracle);
    const auto change = fvr::test::compare(unfiltered, oracle);
    std::printf("[cli] slice filter vs FFTW double: max abs error %.3g (peak %.4g), %.2f dB; "
                "filter's own change %.3g max, %.2f dB\n", c.maxAbsError, c.peak, c.psnr, change.maxAbsError, change.psnr);
    EXPECT_LT(c.maxAbsError, 1e-5 * c.peak); // measured 4.6e-7 x peak (float rendering)
    EXPECT_GT(change.maxAbsError, 0.02 * c.peak); // the filter does something measurable (6.6% of the peak)
    const std::string json = readText(tmp("filt.npy") + ".json");
    EXPECT_NE(json.find("\"filter\": {\"sharpen\": 1, \"sharpen_radius_mm\": 2, \"band_limit_lp_per_mm\": 0.3}"),
              std::string::npos) << json;
}

TEST(FvrRender, XrayOptionsBadInputExitsTwoNamingTheOption) {
    struct Case {
        std::string args, expect;
    };
    const std::string common = "phantom:shepp-logan:32 --size 128 --out " + tmp("x.npy") + " ";
    const Case cases[] = {
        {"--depth-cue 2", "--depth-cue"},
        {"--depth-cue 0.5 --kernel nearest", "--depth-cue"},
        {"--values mu --beer-lambert --energy 5", "--energy"},
        {"--values mu --beer-lambert --energy 60 --mu-water 0.02", "--mu-water"},
        {"--values mu --beer-lambert --exposure 0", "--exposure"},
        {"--sharpen -1", "--sharpen"},
        {"--sharpen 1 --sharpen-radius 0", "--sharpen-radius"},
        {"--band-limit -1", "--band-limit"},
        {"--values mu --energy 60", "--beer-lambert"},
        {"--values bone", "values"},
    };
    for (const Case& c : cases) {
        const Result r = run(common + c.args);
        EXPECT_EQ(r.status, 2) << c.args << "\n" << r.output;
        EXPECT_NE(r.output.find(c.expect), std::string::npos) << c.args << "\n" << r.output;
        EXPECT_EQ(r.output.find("terminate"), std::string::npos) << r.output;
    }
    // With --energy and --mu-water both named.
    const Result both = run(common + "--values mu --beer-lambert --energy 60 --mu-water 0.02");
    EXPECT_NE(both.output.find("--energy"), std::string::npos) << both.output;
}

TEST(FvrRender, MuBoneIntegratesMoreThanMu) {
    const std::string common = "phantom:shepp-logan:32 --size 128 --dir 0.2,0.3,0.9 ";
    Result r = run(common + "--values mu --out " + tmp("vmu.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    r = run(common + "--values mu-bone --out " + tmp("vbone.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    double mu = 0, bone = 0;
    for (float v : readNpy(tmp("vmu.npy"), shape)) mu += v;
    for (float v : readNpy(tmp("vbone.npy"), shape)) bone += v;
    std::printf("[cli] total of the projection: mu %.1f, mu-bone %.1f (ratio %.3f)\n", mu, bone, bone / mu);
    // The skull (+1000 HU) counts (1.1 + 2 x 0.9) / 2 = 1.45 times as much, the soft tissue (below
    // the +100 HU knee) the same: measured 1.043 times in total.
    EXPECT_GT(bone, 1.02 * mu);
    EXPECT_NE(readText(tmp("vbone.npy") + ".json").find("\"values\": \"mu-bone\""), std::string::npos);
}

TEST(FvrRender, BenchPassesTheDepthCueToRayCastingAndNotesTheFilter) {
    Result r = run("phantom:shepp-logan:32 --size 128 --bench 3 --depth-cue 0.5");
    ASSERT_EQ(r.status, 0) << r.output;
    // The spatial projector weights depth the same way (and integrates the same voxel model).
    EXPECT_NE(r.output.find("\"reference\": \"trilinear ray casting (step s/4, one ray per pixel, depth-weighted)\""),
              std::string::npos)
        << r.output;
    EXPECT_EQ(r.output.find("\"note\""), std::string::npos) << r.output;
    r = run("phantom:shepp-logan:32 --size 128 --bench 3 --sharpen 1");
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_NE(r.output.find("\"note\": \"the spatial projector cannot apply the slice filter"), std::string::npos)
        << r.output;
}

TEST(FvrRender, ClipsOutsideTheVolumeUnlessNoClip) {
    // A wide field (3 mm pixels, 384 mm) around a 256 mm phantom: the kernel's ghost copies land
    // in the image outside the volume's shadow. By default those pixels are 0 (as in the exact
    // projection); --no-clip keeps them.
    const std::string common = "phantom:shepp-logan:64 --dir 0.35,0.2,0.92 --up 0,-1,0 --size 128 --pixel-size 3 "
                               "--kernel linear --values mu --out ";
    ASSERT_EQ(run(common + tmp("clip.npy")).status, 0);
    const Result r = run(common + tmp("noclip.npy") + " --no-clip");
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    const auto clip = readNpy(tmp("clip.npy"), shape);
    const auto noclip = readNpy(tmp("noclip.npy"), shape);
    const Volume v = makeSheppLoganVolume(64);
    const ViewFrame view = ViewFrame::fromDirUp({0.35, 0.2, 0.92}, {0, -1, 0});
    const auto truth = EllipsoidPhantom::sheppLogan3D(256.0).project(view, {128, 3.0}, ValueMapping::Mu, v.dims, v.spacing);
    const Vec3 half = supportHalfExtents(v.dims, v.spacing, voxelModelReach(VoxelModel::BandLimited));
    int outside = 0;
    double ghost = 0;
    for (int row = 0; row < 128; ++row)
        for (int col = 0; col < 128; ++col) {
            if (!rayMissesVolume(view, half, 128, 3.0, col, row)) continue;
            const std::size_t i = std::size_t(row) * 128 + col;
            ++outside;
            EXPECT_EQ(clip[i], 0.0f);
            ghost = std::max(ghost, double(std::abs(noclip[i])));
        }
    EXPECT_GT(outside, 1000);
    EXPECT_GT(ghost, 1.0);
    EXPECT_GT(fvr::test::compare(clip, truth.pixels).psnr, fvr::test::compare(noclip, truth.pixels).psnr);
    EXPECT_NE(readText(tmp("noclip.npy") + ".json").find("\"clip_to_volume\": false"), std::string::npos);
    EXPECT_NE(readText(tmp("clip.npy") + ".json").find("\"clip_to_volume\": true"), std::string::npos);
}

namespace {
/** The numbers of a JSON array field ("name": [a, b, ...]) in fvr-render's output. */
std::vector<double> jsonNumbers(const std::string& text, const std::string& name) {
    std::vector<double> v;
    auto at = text.find("\"" + name + "\": [");
    if (at == std::string::npos) return v;
    at = text.find('[', at) + 1;
    const auto end = text.find(']', at);
    std::stringstream ss(text.substr(at, end - at));
    std::string tok;
    while (std::getline(ss, tok, ',')) v.push_back(std::stod(tok));
    return v;
}
} // namespace

TEST(FvrRender, VoxelModelsRenderRecordAndCompareLikeWithLike) {
    const Result bad = run("phantom:shepp-logan:32 --size 128 --voxel-model cubic-catmull --out " + tmp("vm.npy"));
    EXPECT_EQ(bad.status, 2);
    EXPECT_NE(bad.output.find("--voxel-model"), std::string::npos) << bad.output;
    EXPECT_NE(bad.output.find("bandlimited|trilinear|bspline"), std::string::npos) << bad.output;
    // Each model's output is the CPU renderer's with that model; the sidecar says which.
    const Volume v = makeSheppLoganVolume(40);
    const ViewFrame view = ViewFrame::fromDirUp({0.3, 0.5, 0.8}, {0, -1, 0});
    PreprocessOptions o;
    o.effort = PlannerEffort::Estimate;
    o.mapping = ValueMapping::Mu;
    CpuFourierRenderer cpu(preprocess(v, o), 1);
    for (const char* model : {"", "bandlimited", "trilinear", "bspline"}) {
        const std::string out = tmp(std::string("vm_") + (*model ? model : "default") + ".npy");
        const Result r = run(std::string("phantom:shepp-logan:40 --values mu --size 128 --dir 0.3,0.5,0.8 --up 0,-1,0 ") +
                             (*model ? std::string("--voxel-model ") + model + " " : std::string()) + "--out " + out);
        ASSERT_EQ(r.status, 0) << r.output;
        RenderParams p{view, {128, defaultPixelSize(v.dims, v.spacing, 128)}, Kernel::Linear};
        p.voxelModel = *model ? parseVoxelModel(model) : VoxelModel::Trilinear; // the default
        p.clipToVolume = p.nonNegative = true;
        std::vector<std::int64_t> shape;
        EXPECT_GT(fvr::test::compare(readNpy(out, shape), cpu.render(p).pixels).psnr, 120.0) << model;
        EXPECT_NE(readText(out + ".json").find(std::string("\"voxel_model\": \"") + voxelModelName(p.voxelModel) + "\""),
                  std::string::npos)
            << model;
    }
}

TEST(FvrRender, BenchMeasuresTheModelAgainstItsRayCasterAndNegativesAreKeptOnRequest) {
    FVR_REQUIRE_DATA("volumes/body_ct_hu_3mm/example_ct.mhd");
    const std::string ct = (fvr::test::sharedData() / "volumes/body_ct_hu_3mm/example_ct.mhd").string();
    const std::string common = ct + " --values mu --kernel kaiser-bessel --oversampling 1.25 --view AP --size 256 ";
    std::map<std::string, double> psnr;
    for (const char* model : {"bandlimited", "trilinear"}) {
        const Result r = run(common + "--bench 1 --keep-negative --voxel-model " + model);
        ASSERT_EQ(r.status, 0) << r.output;
        const auto p = jsonNumbers(r.output, "psnr_db");
        const auto lowest = jsonNumbers(r.output, "most_negative_percent");
        ASSERT_EQ(p.size(), 1u) << r.output;
        ASSERT_EQ(lowest.size(), 1u) << r.output;
        psnr[model] = p[0];
        std::printf("[cli] body CT AP, %s model against trilinear ray casting: %.2f dB, most negative %.3f %%\n", model,
                    p[0], lowest[0]);
        EXPECT_NE(r.output.find("\"reference\": \"trilinear ray casting (step s/4, one ray per pixel"), std::string::npos);
        // The band-limited model rings below zero at the scan ends (measured -12.4 %); the
        // trilinear model does not (measured 0).
        if (std::string(model) == "bandlimited") EXPECT_LT(lowest[0], -5.0);
        else EXPECT_GT(lowest[0], -0.01);
    }
    EXPECT_GT(psnr["trilinear"], psnr["bandlimited"] + 8.0); // measured 49.6 and 39.5 dB
    // With the pixel aperture the reference integrates each pixel's area.
    const Result ap = run(common + "--bench 1 --pixel-aperture");
    ASSERT_EQ(ap.status, 0) << ap.output;
    EXPECT_NE(ap.output.find("3 x 3 rays per pixel"), std::string::npos) << ap.output;
    EXPECT_NE(ap.output.find("\"pixel_aperture\": true"), std::string::npos) << ap.output;
    // By default no line integral of this attenuation volume is negative, even band-limited.
    ASSERT_EQ(run(common + "--voxel-model bandlimited --out " + tmp("bl.npy")).status, 0);
    ASSERT_EQ(run(common + "--voxel-model bandlimited --keep-negative --out " + tmp("blneg.npy")).status, 0);
    std::vector<std::int64_t> shape;
    EXPECT_EQ(mostNegativeFraction(readNpy(tmp("bl.npy"), shape)), 0.0);
    EXPECT_LT(mostNegativeFraction(readNpy(tmp("blneg.npy"), shape)), -0.05);
    EXPECT_NE(readText(tmp("bl.npy") + ".json").find("\"non_negative\": true"), std::string::npos);
    EXPECT_NE(readText(tmp("blneg.npy") + ".json").find("\"non_negative\": false"), std::string::npos);
}
