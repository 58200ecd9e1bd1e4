// fvr-render end to end: outputs, JSON, exit codes and messages for bad input.
#include <sys/wait.h>

#include <cmath>
#include <complex>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <sstream>
#include <string>

#include <unistd.h>

#include <fftw3.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/io/image_io.h>
#include <fvr/core/io/volume_io.h>
#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/render/voxel_model.h>
#include <fvr/core/xray/phantom.h>
#include <fvr/core/xray/xray.h>

#include "image_metrics.h"
#include "test_support.h"

using namespace fvr::core;

namespace {

using Json = nlohmann::json;

struct Result {
    int status = -1;
    std::string out; // stdout
    std::string output; // stdout, then stderr
};

std::string tmp(const std::string& name) { return (fvr::test::tmpDir() / name).string(); }

std::string readText(const std::string& path) {
    std::ifstream in(path);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

/** Runs fvr-render with `args`; `envPrefix` (e.g. "env -u DISPLAY") goes before the binary. */
Result run(const std::string& args, const std::string& envPrefix = {}) {
    static int calls = 0;
    const std::string err =
        tmp("stderr_" + std::to_string(getpid()) + "_" + std::to_string(++calls) + ".txt");
    const std::string cmd =
        envPrefix + " " + std::string(FVR_RENDER_EXE) + " " + args + " 2>" + err;
    const fvr::test::CommandOutput c = fvr::test::runCommand(cmd);
    Result r;
    r.status = c.status;
    r.out = c.out;
    r.output = r.out + readText(err);
    std::remove(err.c_str());
    return r;
}

/** The JSON fvr-render printed on stdout (a failed parse fails the test with the text). */
Json stdoutJson(const Result& r) {
    try {
        return Json::parse(r.out);
    } catch (const std::exception& e) {
        ADD_FAILURE() << e.what() << " in " << r.output;
        return Json::object();
    }
}

/** A sidecar (or any JSON file) parsed. */
Json jsonFile(const std::string& path) {
    try {
        return Json::parse(readText(path));
    } catch (const std::exception& e) {
        ADD_FAILURE() << path << ": " << e.what();
        return Json::object();
    }
}

/** The slice filter applied in double to an M x M image of pixel size d (mm): 2D DFT (FFTW),
 *  times H(|(m, n)| / (M d)) with (m, n) the signed frequency indices, inverse DFT. */
std::vector<float> filterInDouble(const std::vector<float>& image, int M, double d,
                                  const SliceFilter& filter) {
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
                         "--kernel catmull-rom --oversampling 2 --values mu --out " +
                         out);
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    const auto pixels = readNpy(out, shape);
    ASSERT_EQ(shape, (std::vector<std::int64_t>{128, 128}));
    // Independent oracle: exact line integrals of the same ellipsoids at the same pixels.
    const Volume v = makeSheppLoganVolume(64);
    const auto truth = EllipsoidPhantom::sheppLogan3D(256.0).project(
        ViewFrame::fromDirUp({0.35, 0.2, 0.92}, {0, -1, 0}),
        {128, defaultPixelSize(v.dims, v.spacing, 128)}, ValueMapping::Mu, v.dims, v.spacing);
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
        if (std::string(ext) == ".pfm")
            EXPECT_EQ(head.substr(0, 3), "Pf\n");
        else
            EXPECT_EQ(head, std::string("\x89PNG\r\n\x1a\n", 8));
    }
}

TEST(FvrRender, InfoJsonForPhantomAndSharedVolume) {
    Result r = run("phantom:shepp-logan:48 --info");
    ASSERT_EQ(r.status, 0) << r.output;
    Json j = stdoutJson(r);
    EXPECT_EQ(j["dims"], Json::parse("[48, 48, 48]")) << r.output;
    EXPECT_EQ(j["units"], "HU") << r.output;
    const auto headsq = fvr::test::sharedData() / "volumes/headsq/headsq.mhd";
    if (!std::filesystem::exists(headsq)) GTEST_SKIP() << "shared data not found: " << headsq;
    r = run(headsq.string() + " --info");
    ASSERT_EQ(r.status, 0) << r.output;
    j = stdoutJson(r);
    EXPECT_EQ(j["dims"], Json::parse("[64, 64, 93]")) << r.output;
    EXPECT_EQ(j["spacing_mm"].get<std::vector<double>>(), (std::vector<double>{3.2, 3.2, 1.5}))
        << r.output;
}

TEST(FvrRender, BenchPrintsStageJson) {
    const Result r = run("phantom:shepp-logan:32 --size 128 --bench 5 --kernel sinc4");
    ASSERT_EQ(r.status, 0) << r.output;
    const Json j = stdoutJson(r);
    for (const char* stage : {"preprocess", "slice", "inverse", "total"}) {
        EXPECT_TRUE(j[stage]["median_ms"].is_number()) << stage << " in " << r.output;
        EXPECT_TRUE(j[stage]["p95_ms"].is_number()) << stage << " in " << r.output;
    }
    EXPECT_EQ(j["settings"]["kernel"], "sinc4") << r.output;
    EXPECT_EQ(j["frames"], 5) << r.output;
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
        {"phantom:shepp-logan:32 --size 8 --out " + tmp("x.npy"), "size"},
        {"phantom:shepp-logan:32 --oversampling 3 --out " + tmp("x.npy"), "oversampling"},
        {"phantom:shepp-logan:32 --dir 0,0,1 --up 0,0,1 --out " + tmp("x.npy"), "up"},
        {"phantom:shepp-logan:32", "--out"},
        {"phantom:cube --out " + tmp("x.npy"), "phantom"},
        {"phantom:shepp-logan:32 --frobnicate --out " + tmp("x.npy"), "--frobnicate"},
        {"phantom:shepp-logan:32 --backend vulkan --out " + tmp("x.npy"), "backend"},
        {"phantom:shepp-logan:32 --threads -1 --out " + tmp("x.npy"),
         "--threads: expected a whole number of threads"},
        // Said before any network (nothing listens at port 1): a day that is not in the
        // calendar went to the PACS, and --query-series without --query retrieved the study.
        {"dicom://PACS@127.0.0.1:1 --query StudyDate=20231301", "\"20231301\" is not a date"},
        {"dicom://PACS@127.0.0.1:1 --query StudyDate=20231231-20230101", "ends before it begins"},
        {"dicom://PACS@127.0.0.1:1/1.2.3 --query-series --out " + tmp("x.npy"),
         "--query-series requires --query"},
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
    const std::string args =
        "phantom:shepp-logan:48 --dir 0.3,0.5,0.8 --size 128 --kernel sinc4 --oversampling 1.5 ";
    // A GPU that cannot be had (an EGL device that does not exist): the CPU renders and says why.
    const Result noGpu =
        run("--backend gpu " + args + "--out " + tmp("nogpu.npy"), "env FVR_EGL_DEVICE=99");
    EXPECT_EQ(noGpu.status, 0) << noGpu.output;
    EXPECT_NE(noGpu.output.find("rendering on the CPU"), std::string::npos) << noGpu.output;
    EXPECT_NE(noGpu.output.find("FVR_EGL_DEVICE=99"), std::string::npos) << noGpu.output;
    // The GPU backend is headless (EGL): no X display, no Qt platform (llvmpipe where no GPU).
    const std::string headless = "env -u DISPLAY -u QT_QPA_PLATFORM -u WAYLAND_DISPLAY";
    Result r = run("--backend gpu " + args + "--out " + tmp("gpu.npy"), headless);
    ASSERT_EQ(r.status, 0) << r.output;
    ASSERT_NE(r.output.find("gpu: "), std::string::npos) << "GPU backend not used: " << r.output;
    r = run("--backend cpu " + args + "--out " + tmp("cpu.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    const auto g = readNpy(tmp("gpu.npy"), shape);
    const auto c = readNpy(tmp("cpu.npy"), shape);
    EXPECT_GT(fvr::test::compare(g, c).psnr, 90.0);
    // Depth cue and slice filter reach both renderers the same way.
    const std::string xray =
        "--values mu --depth-cue 0.6 --sharpen 1 --sharpen-radius 2 --band-limit 0.1 ";
    r = run("--backend gpu " + args + xray + "--out " + tmp("gpux.npy"), headless);
    ASSERT_EQ(r.status, 0) << r.output;
    ASSERT_NE(r.output.find("gpu: "), std::string::npos) << "GPU backend not used: " << r.output;
    ASSERT_EQ(run("--backend cpu " + args + xray + "--out " + tmp("cpux.npy")).status, 0);
    EXPECT_GT(
        fvr::test::compare(readNpy(tmp("gpux.npy"), shape), readNpy(tmp("cpux.npy"), shape)).psnr,
        90.0);
    // A W x H image: the GPU crops its power-of-two square as the CPU crops its own (both 128
    // here, so the same transform: the crops must agree to float precision).
    const std::string rect = "phantom:shepp-logan:48 --dir 0.3,0.5,0.8 --size 128x72 ";
    r = run("--backend gpu " + rect + "--out " + tmp("gpur.npy"), headless);
    ASSERT_EQ(r.status, 0) << r.output;
    ASSERT_NE(r.output.find("gpu: "), std::string::npos) << "GPU backend not used: " << r.output;
    ASSERT_EQ(run("--backend cpu " + rect + "--out " + tmp("cpur.npy")).status, 0);
    const auto gr = readNpy(tmp("gpur.npy"), shape);
    EXPECT_EQ(shape, (std::vector<std::int64_t>{72, 128}));
    EXPECT_GT(fvr::test::compare(gr, readNpy(tmp("cpur.npy"), shape)).psnr, 90.0);
}

// --backend auto (the default) renders on the GPU only when it is hardware: on a software
// OpenGL (llvmpipe here) on the CPU, saying so; --backend gpu takes any GPU.
TEST(FvrRender, AutoBackendTakesTheGpuOnlyWhenItIsHardware) {
    const std::string headless = "env -u DISPLAY -u QT_QPA_PLATFORM -u WAYLAND_DISPLAY";
    const Json info = stdoutJson(run("--gpu-info", headless));
    const std::string args = "phantom:shepp-logan:32 --size 128 ";
    Result r = run(args + "--out " + tmp("auto.npy"), headless);
    ASSERT_EQ(r.status, 0) << r.output;
    const std::string backend = jsonFile(tmp("auto.npy") + ".json")["settings"]["backend"];
    if (!info["available"].get<bool>()) {
        EXPECT_EQ(backend, "cpu");
        EXPECT_NE(r.output.find("GPU backend unavailable"), std::string::npos) << r.output;
    } else if (info["gl"]["software"].get<bool>()) {
        EXPECT_EQ(backend, "cpu") << info["gl"]["renderer"];
        EXPECT_NE(r.output.find("software renderer"), std::string::npos) << r.output;
        r = run("--backend gpu " + args + "--out " + tmp("forced.npy"), headless);
        ASSERT_EQ(r.status, 0) << r.output;
        EXPECT_EQ(
            jsonFile(tmp("forced.npy") + ".json")["settings"]["backend"].get<std::string>().rfind(
                "gpu", 0),
            0u);
    } else {
        EXPECT_EQ(backend.rfind("gpu", 0), 0u) << backend;
    }
}

TEST(FvrRender, GpuInfoListsTheEglDevicesAndTheChosenContext) {
    // Headless: no display, no INPUT. The devices are eglQueryDevicesEXT's; the context is
    // OpenGL >= 4.3 core, whose spec requires a 3D texture limit of at least 2048.
    const std::string headless = "env -u DISPLAY -u QT_QPA_PLATFORM -u WAYLAND_DISPLAY";
    Result r = run("--gpu-info", headless);
    ASSERT_EQ(r.status, 0) << r.output;
    Json j = stdoutJson(r);
    ASSERT_TRUE(j["available"].get<bool>()) << r.output;
    ASSERT_TRUE(j["devices"].is_array()) << r.output;
    for (std::size_t i = 0; i < j["devices"].size(); ++i) {
        EXPECT_EQ(j["devices"][i]["index"], int(i));
        EXPECT_TRUE(j["devices"][i]["extensions"].is_string());
    }
    const int chosen = j["chosen"]["device"];
    EXPECT_GE(chosen, -1);
    EXPECT_LT(chosen, int(j["devices"].size()));
    const auto& gl = j["gl"];
    EXPECT_TRUE(gl["major"].get<int>() > 4 || (gl["major"] == 4 && gl["minor"].get<int>() >= 3));
    EXPECT_TRUE(gl["coreProfile"].get<bool>());
    EXPECT_GE(gl["max3dTextureSize"].get<int>(), 2048);
    EXPECT_FALSE(gl["renderer"].get<std::string>().empty());
    EXPECT_EQ(gl["version"].get<std::string>().rfind(std::to_string(gl["major"].get<int>()) + "." +
                                                         std::to_string(gl["minor"].get<int>()),
                                                     0),
              0u)
        << gl;
    // FVR_EGL_DEVICE picks the surfaceless platform; a device that does not exist is named.
    r = run("--gpu-info", headless + " FVR_EGL_DEVICE=surfaceless");
    ASSERT_EQ(r.status, 0) << r.output;
    j = stdoutJson(r);
    EXPECT_EQ(j["chosen"]["device"], -1) << r.output;
    r = run("--gpu-info", headless + " FVR_EGL_DEVICE=99");
    ASSERT_EQ(r.status, 0) << r.output;
    j = stdoutJson(r);
    EXPECT_FALSE(j["available"].get<bool>());
    EXPECT_NE(j["reason"].get<std::string>().find("FVR_EGL_DEVICE=99"), std::string::npos) << j;
}

TEST(FvrRender, DicomFolderInfoListsSeriesWithWarnings) {
    FVR_REQUIRE_DATA("dicom/ct_head_ge_gantrytilt_28");
    const auto dir = fvr::test::sharedData() / "dicom/ct_head_ge_gantrytilt_28";
    const Result r = run(dir.string() + " --info");
    ASSERT_EQ(r.status, 0) << r.output;
    const Json j = stdoutJson(r);
    ASSERT_TRUE(j["series"].is_array()) << r.output;
    ASSERT_EQ(j["series"].size(), 1u) << r.output;
    const Json& s = j["series"][0];
    EXPECT_EQ(s["modality"], "CT") << r.output;
    EXPECT_EQ(s["images"], 28) << r.output;
    const std::string warnings = s["warnings"].dump();
    EXPECT_NE(warnings.find("gantry tilt"), std::string::npos) << r.output;
    EXPECT_NE(warnings.find("uneven slice spacing"), std::string::npos) << r.output;
}

// --info says once what the scan skipped (here the folder's README.md).
TEST(FvrRender, DicomFolderInfoSaysWhatWasSkipped) {
    FVR_REQUIRE_DATA("dicom_edge/enhanced_multiframe_mr");
    const auto dir = fvr::test::sharedData() / "dicom_edge/enhanced_multiframe_mr";
    const Result r = run(dir.string() + " --info");
    ASSERT_EQ(r.status, 0) << r.output;
    const Json j = stdoutJson(r);
    ASSERT_TRUE(j["warnings"].is_array()) << r.output;
    ASSERT_EQ(j["warnings"].size(), 1u) << r.output;
    EXPECT_EQ(j["warnings"][0], "skipped 1 file that is not DICOM: README.md") << r.output;
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
    const std::string common =
        "phantom:shepp-logan:40 --size 128 --kernel catmull-rom --values mu ";
    Result r =
        run(common + "--dir 0,0,1 --up 0,-1,0 --sweep 4 --axis 0,1,0 --out " + tmp("sweep.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    const auto stack = readNpy(tmp("sweep.npy"), shape);
    ASSERT_EQ(shape, (std::vector<std::int64_t>{4, 128, 128}));
    // View 1 of the sweep is the first view turned by 90 degrees about y: D = (0,0,1) -> (1,0,0).
    r = run(common + "--dir 1,0,0 --up 0,-1,0 --out " + tmp("view1.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    const auto single = readNpy(tmp("view1.npy"), shape);
    const std::vector<float> frame1(stack.begin() + 128 * 128, stack.begin() + 2 * 128 * 128);
    EXPECT_GT(fvr::test::compare(frame1, single).psnr, 100.0);
    const Json j = jsonFile(tmp("sweep.npy") + ".json");
    ASSERT_EQ(j["views"].size(), 4u) << j;
    for (const Json& v : j["views"])
        for (const char* axis : {"dir", "up", "right"}) EXPECT_EQ(v[axis].size(), 3u) << j;
    EXPECT_EQ(j["settings"]["kernel"], "catmull-rom") << j;
    EXPECT_EQ(j["output"]["stacked"], true) << j;
    EXPECT_TRUE(j["image"]["pixel_size_mm"].is_number()) << j;
    EXPECT_EQ(j["volume"]["spacing_mm"].size(), 3u) << j;
}

TEST(FvrRender, ViewsFileNumberedOutputsAndErrors) {
    {
        std::ofstream f(tmp("views.txt"));
        f << "# dir, up\n0 0 1  0 -1 0\n1,0,0, 0,0,1\n\n0 1 0 0 0 1  # lateral\n";
    }
    const std::string out = tmp("v.pfm");
    Result r =
        run("phantom:shepp-logan:32 --size 128 --views " + tmp("views.txt") + " --out " + out);
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
    r = run("phantom:shepp-logan:32 --size 128 --sweep 3 --views " + tmp("views.txt") + " --out " +
            out);
    EXPECT_EQ(r.status, 2) << r.output;
    r = run("phantom:shepp-logan:32 --size 128 --values raw --beer-lambert --out " + out);
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
    for (std::size_t i = 0; i < mu.size(); ++i)
        maxErr = std::max(maxErr, std::abs(bl[i] - std::exp(-0.02 * mu[i])));
    EXPECT_LT(maxErr, 1e-6);
}

TEST(FvrRender, BenchComparesWithRayCasting) {
    const Result r = run("phantom:shepp-logan:32 --size 128 --bench 4");
    ASSERT_EQ(r.status, 0) << r.output;
    const Json j = stdoutJson(r);
    EXPECT_TRUE(j["spatial_projector"]["median_ms"].is_number()) << r.output;
    EXPECT_TRUE(j["speedup_per_view"].is_number()) << r.output;
}

TEST(FvrRender, KaiserBesselDeapodizedBeatsThePapersSetting) {
    const std::string common =
        "phantom:shepp-logan:64 --dir 0.35,0.2,0.92 --up 0,-1,0 --size 128 --values mu ";
    ASSERT_EQ(
        run(common + "--kernel kaiser-bessel --oversampling 1.25 --out " + tmp("kb.npy")).status,
        0);
    ASSERT_EQ(run(common + "--kernel linear --out " + tmp("tl.npy")).status, 0);
    std::vector<std::int64_t> shape;
    const Volume v = makeSheppLoganVolume(64);
    const auto truth = EllipsoidPhantom::sheppLogan3D(256.0).project(
        ViewFrame::fromDirUp({0.35, 0.2, 0.92}, {0, -1, 0}),
        {128, defaultPixelSize(v.dims, v.spacing, 128)}, ValueMapping::Mu, v.dims, v.spacing);
    const double kb = fvr::test::compare(readNpy(tmp("kb.npy"), shape), truth.pixels).psnr;
    const double tl = fvr::test::compare(readNpy(tmp("tl.npy"), shape), truth.pixels).psnr;
    std::printf("[cli] kaiser-bessel4 oversampling 1.25 deapodized %.2f dB, trilinear oversampling "
                "1 %.2f dB\n",
                kb, tl);
    EXPECT_GT(kb, tl + 12.0);
    EXPECT_EQ(jsonFile(tmp("kb.npy") + ".json")["settings"]["deapodized"], true);
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
    const Result r =
        run(common + "--beer-lambert --energy 60 --exposure 1.5 --out " + tmp("xbl.npy"));
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
    std::printf("[cli] beer-lambert 60 keV (mu_water %.5f/mm) exposure 1.5: max relative error "
                "%.2e, min %.4f\n",
                mu, maxRel, minI);
    EXPECT_LT(maxRel, 1e-5);
    EXPECT_LT(minI,
              1.0); // the phantom attenuates: the test sees the exponential, not just the exposure
    const Json out = jsonFile(tmp("xbl.npy") + ".json")["output"];
    EXPECT_EQ(out["mu_water_per_mm"].get<double>(), mu) << out; // full precision
    EXPECT_EQ(out["energy_kev"], 60.0) << out;
    EXPECT_EQ(out["exposure"], 1.5) << out;
    // mu-bone is an attenuation mapping too.
    const Result bone =
        run("phantom:shepp-logan:32 --size 128 --values mu-bone --beer-lambert --out " +
            tmp("xbb.npy"));
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
    std::printf(
        "[cli] depth cue 0.6: %.2f dB vs the depth-weighted oracle, %.2f dB vs the plain oracle, "
        "%.2f dB vs the run without depth cue\n",
        psnr, vsPlainTruth, vsPlainRun);
    EXPECT_GT(psnr, 37.0); // measured 40.3 dB
    EXPECT_LT(vsPlainRun, 40.0); // the depth cue changes the image
    EXPECT_GT(psnr, vsPlainTruth + 10.0);
    EXPECT_EQ(jsonFile(tmp("dc.npy") + ".json")["settings"]["depth_cue"], 0.6);
}

TEST(FvrRender, SliceFilterEqualsTheFilterAppliedInDouble) {
    // Pixel 1 mm: the slice reaches 0.5 lp/mm; the volume (2 mm voxels) holds up to 0.25 lp/mm per
    // axis, about 0.35 along an oblique slice, so the band limit at 0.3 lp/mm acts as well.
    const std::string common =
        "phantom:shepp-logan:128 --dir 0.35,0.2,0.92 --up 0,-1,0 --size 256 --pixel-size 1 "
        "--values mu --kernel linear --oversampling 1 ";
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
                "filter's own change %.3g max, %.2f dB\n",
                c.maxAbsError, c.peak, c.psnr, change.maxAbsError, change.psnr);
    EXPECT_LT(c.maxAbsError, 1e-5 * c.peak); // measured 4.6e-7 x peak (float rendering)
    EXPECT_GT(change.maxAbsError,
              0.02 * c.peak); // the filter does something measurable (6.6% of the peak)
    const Json filter = jsonFile(tmp("filt.npy") + ".json")["settings"]["filter"];
    EXPECT_EQ(
        filter,
        Json::parse(R"({"sharpen": 1.0, "sharpen_radius_mm": 2.0, "band_limit_lp_per_mm": 0.3})"))
        << filter;
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
    std::printf("[cli] total of the projection: mu %.1f, mu-bone %.1f (ratio %.3f)\n", mu, bone,
                bone / mu);
    // The skull (+1000 HU) counts (1.1 + 2 x 0.9) / 2 = 1.45 times as much, the soft tissue (below
    // the +100 HU knee) the same: measured 1.043 times in total.
    EXPECT_GT(bone, 1.02 * mu);
    EXPECT_EQ(jsonFile(tmp("vbone.npy") + ".json")["settings"]["values"], "mu-bone");
}

TEST(FvrRender, BenchPassesTheDepthCueToRayCastingAndNotesTheFilter) {
    Result r = run("phantom:shepp-logan:32 --size 128 --bench 3 --depth-cue 0.5");
    ASSERT_EQ(r.status, 0) << r.output;
    // The spatial projector weights depth the same way (and integrates the same voxel model).
    Json j = stdoutJson(r);
    EXPECT_EQ(j["spatial_projector"]["reference"],
              "trilinear ray casting (step s/4, one ray per pixel, depth-weighted)")
        << r.output;
    EXPECT_FALSE(j.contains("note")) << r.output;
    r = run("phantom:shepp-logan:32 --size 128 --bench 3 --sharpen 1");
    ASSERT_EQ(r.status, 0) << r.output;
    j = stdoutJson(r);
    EXPECT_EQ(j.value("note", "").rfind("the spatial projector cannot apply the slice filter", 0),
              0u)
        << r.output;
}

TEST(FvrRender, ClipsOutsideTheVolumeUnlessNoClip) {
    // A wide field (3 mm pixels, 384 mm) around a 256 mm phantom: the kernel's ghost copies land
    // in the image outside the volume's shadow. By default those pixels are 0 (as in the exact
    // projection); --no-clip keeps them.
    const std::string common =
        "phantom:shepp-logan:64 --dir 0.35,0.2,0.92 --up 0,-1,0 --size 128 --pixel-size 3 "
        "--kernel linear --values mu --out ";
    ASSERT_EQ(run(common + tmp("clip.npy")).status, 0);
    const Result r = run(common + tmp("noclip.npy") + " --no-clip");
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    const auto clip = readNpy(tmp("clip.npy"), shape);
    const auto noclip = readNpy(tmp("noclip.npy"), shape);
    const Volume v = makeSheppLoganVolume(64);
    const ViewFrame view = ViewFrame::fromDirUp({0.35, 0.2, 0.92}, {0, -1, 0});
    const auto truth = EllipsoidPhantom::sheppLogan3D(256.0).project(
        view, {128, 3.0}, ValueMapping::Mu, v.dims, v.spacing);
    const Vec3 half =
        supportHalfExtents(v.dims, v.spacing, voxelModelReach(VoxelModel::BandLimited));
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
    EXPECT_GT(fvr::test::compare(clip, truth.pixels).psnr,
              fvr::test::compare(noclip, truth.pixels).psnr);
    EXPECT_EQ(jsonFile(tmp("noclip.npy") + ".json")["settings"]["clip_to_volume"], false);
    EXPECT_EQ(jsonFile(tmp("clip.npy") + ".json")["settings"]["clip_to_volume"], true);
}

TEST(FvrRender, VoxelModelsRenderRecordAndCompareLikeWithLike) {
    const Result bad =
        run("phantom:shepp-logan:32 --size 128 --voxel-model cubic-catmull --out " + tmp("vm.npy"));
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
        const Result r = run(
            std::string(
                "phantom:shepp-logan:40 --values mu --kernel linear --oversampling 1 --size 128 "
                "--dir 0.3,0.5,0.8 --up 0,-1,0 ") +
            (*model ? std::string("--voxel-model ") + model + " " : std::string()) + "--out " +
            out);
        ASSERT_EQ(r.status, 0) << r.output;
        RenderParams p{view, {128, defaultPixelSize(v.dims, v.spacing, 128)}, Kernel::Linear};
        p.voxelModel = *model ? parseVoxelModel(model) : VoxelModel::Trilinear; // the default
        p.clipToVolume = p.nonNegative = true;
        std::vector<std::int64_t> shape;
        EXPECT_GT(fvr::test::compare(readNpy(out, shape), cpu.render(p).pixels).psnr, 120.0)
            << model;
        EXPECT_EQ(jsonFile(out + ".json")["settings"]["voxel_model"], voxelModelName(p.voxelModel))
            << model;
    }
}

TEST(FvrRender, BenchMeasuresTheModelAgainstItsRayCasterAndNegativesAreKeptOnRequest) {
    FVR_REQUIRE_DATA("volumes/body_ct_hu_3mm/example_ct.mhd");
    const std::string ct =
        (fvr::test::sharedData() / "volumes/body_ct_hu_3mm/example_ct.mhd").string();
    const std::string common =
        ct + " --values mu --kernel kaiser-bessel --oversampling 1.25 --view AP --size 256 ";
    std::map<std::string, double> psnr;
    for (const char* model : {"bandlimited", "trilinear"}) {
        const Result r = run(common + "--bench 1 --keep-negative --voxel-model " + model);
        ASSERT_EQ(r.status, 0) << r.output;
        const Json j = stdoutJson(r);
        const auto p = j["accuracy"]["psnr_db"].get<std::vector<double>>();
        const auto lowest = j["accuracy"]["most_negative_percent"].get<std::vector<double>>();
        ASSERT_EQ(p.size(), 1u) << r.output;
        ASSERT_EQ(lowest.size(), 1u) << r.output;
        psnr[model] = p[0];
        std::printf("[cli] body CT AP, %s model against trilinear ray casting: %.2f dB, most "
                    "negative %.3f %%\n",
                    model, p[0], lowest[0]);
        EXPECT_EQ(j["spatial_projector"]["reference"].get<std::string>().rfind(
                      "trilinear ray casting (step s/4, one ray per pixel", 0),
                  0u);
        // The band-limited model rings below zero at the scan ends (measured -12.4 %); the
        // trilinear model does not (measured 0).
        if (std::string(model) == "bandlimited")
            EXPECT_LT(lowest[0], -5.0);
        else
            EXPECT_GT(lowest[0], -0.01);
    }
    EXPECT_GT(psnr["trilinear"], psnr["bandlimited"] + 8.0); // measured 49.6 and 39.5 dB
    // With the pixel aperture the reference integrates each pixel's area.
    const Result ap = run(common + "--bench 1 --pixel-aperture");
    ASSERT_EQ(ap.status, 0) << ap.output;
    EXPECT_NE(ap.output.find("3 x 3 rays per pixel"), std::string::npos) << ap.output;
    EXPECT_EQ(stdoutJson(ap)["settings"]["pixel_aperture"], true) << ap.output;
    // By default no line integral of this attenuation volume is negative, even band-limited.
    ASSERT_EQ(run(common + "--voxel-model bandlimited --out " + tmp("bl.npy")).status, 0);
    ASSERT_EQ(
        run(common + "--voxel-model bandlimited --keep-negative --out " + tmp("blneg.npy")).status,
        0);
    std::vector<std::int64_t> shape;
    EXPECT_EQ(mostNegativeFraction(readNpy(tmp("bl.npy"), shape)), 0.0);
    EXPECT_LT(mostNegativeFraction(readNpy(tmp("blneg.npy"), shape)), -0.05);
    EXPECT_EQ(jsonFile(tmp("bl.npy") + ".json")["settings"]["non_negative"], true);
    EXPECT_EQ(jsonFile(tmp("blneg.npy") + ".json")["settings"]["non_negative"], false);
}

TEST(FvrRender, BadSizeAndOutputFormatAreRejectedBeforeLoading) {
    // The input does not exist: an error about --size or --out shows that they were checked
    // before the input was opened (let alone preprocessed), and nothing is written.
    const std::string missing = "/no/such/volume.mhd";
    struct Case {
        std::string args, expect;
    };
    const Case cases[] = {
        {missing + " --size 15 --out " + tmp("early.npy"),
         "--size: expected 16..4096 pixels, found 15"},
        {missing + " --size 200x4097 --out " + tmp("early.npy"), "found 4097"},
        {missing + " --size 20y30 --out " + tmp("early.npy"), "expected N or WxH in pixels"},
        {missing + " --out " + tmp("early.tiff"), "--out: unknown output format '.tiff'"},
    };
    for (const Case& c : cases) {
        std::remove(tmp("early.npy").c_str());
        const Result r = run(c.args);
        EXPECT_EQ(r.status, 2) << c.args << "\n" << r.output;
        EXPECT_NE(r.output.find(c.expect), std::string::npos) << c.args << "\n" << r.output;
        EXPECT_EQ(r.output.find(missing), std::string::npos) << c.args << "\n" << r.output;
        EXPECT_EQ(r.output.find("preprocessing"), std::string::npos) << r.output;
        EXPECT_FALSE(std::filesystem::exists(tmp("early.npy")));
        EXPECT_FALSE(std::filesystem::exists(tmp("early.tiff")));
    }
}

TEST(FvrRender, ExclusiveOptionsAreRejectedNamingBoth) {
    {
        std::ofstream f(tmp("one_view.txt"));
        f << "0 0 1 0 -1 0\n";
    }
    const std::string missing = "/no/such/volume.mhd ";
    struct Case {
        std::string args, a, b;
    };
    for (const Case& c : {
             Case{"--sweep 3 --views " + tmp("one_view.txt"), "--sweep", "--views"},
             Case{"--values mu --beer-lambert --energy 60 --mu-water 0.02", "--energy",
                  "--mu-water"},
             // A patient view sets the direction and the up vector: neither may be given too.
             Case{"--view AP --dir 1,0,0", "--view", "--dir"},
             Case{"--up 0,0,1 --view LEFT", "--view", "--up"},
         }) {
        const std::string& args = c.args;
        const Result r = run(missing + args + " --out " + tmp("excl.npy"));
        EXPECT_EQ(r.status, 2) << args << "\n" << r.output;
        const std::string &a = c.a, &b = c.b;
        EXPECT_NE(r.output.find(a), std::string::npos) << r.output;
        EXPECT_NE(r.output.find(b), std::string::npos) << r.output;
        EXPECT_EQ(r.output.find("/no/such"), std::string::npos)
            << "checked before loading: " << r.output;
    }
}

TEST(FvrRender, SidecarOriginAndSpacingRoundTripExactly) {
    // Spacing and origin with more digits than 6 significant ones: the sidecar must give the
    // volume's doubles back exactly (it is meant for reproduction and registration).
    const std::string mhd = tmp("odd_geometry.mhd");
    {
        std::ofstream f(mhd);
        f << "NDims = 3\nDimSize = 8 8 8\nElementType = MET_SHORT\nElementSpacing = 0.48828125 "
             "0.7031250123456789 "
             "1.2500000000000002\nOffset = -123.45678901234567 0.1 98765.4321012345\n"
             "ElementDataFile = odd_geometry.raw\n";
        std::ofstream raw(tmp("odd_geometry.raw"), std::ios::binary);
        const std::vector<std::int16_t> voxels(512, 100);
        raw.write(reinterpret_cast<const char*>(voxels.data()), std::streamsize(voxels.size() * 2));
    }
    const Volume v = loadVolume(mhd);
    const std::string out = tmp("odd_geometry.npy");
    const Result r = run(mhd + " --size 128 --out " + out);
    ASSERT_EQ(r.status, 0) << r.output;
    const Json volume = jsonFile(out + ".json")["volume"];
    for (int a = 0; a < 3; ++a) {
        EXPECT_EQ(volume["spacing_mm"][a].get<double>(), v.spacing[a]) << a << " " << volume;
        EXPECT_EQ(volume["origin_mm"][a].get<double>(), v.origin[a]) << a << " " << volume;
    }
    EXPECT_EQ(volume["origin_mm"][0].get<double>(), -123.45678901234567);
    // --info gives the same numbers.
    const Json info = stdoutJson(run(mhd + " --info"));
    EXPECT_EQ(info["spacing_mm"], volume["spacing_mm"]);
    EXPECT_EQ(info["origin_mm"], volume["origin_mm"]);
}

TEST(FvrRender, SidecarDirectionListsTheIndexAxes) {
    // "direction" is the list of the index axes' unit vectors in the order the MetaImage's
    // TransformMatrix gives them (x, y, z axes), not its transpose: a permutation that is not
    // symmetric tells the two apart.
    const std::string mhd = tmp("permuted_axes.mhd");
    {
        std::ofstream f(mhd);
        f << "NDims = 3\nDimSize = 8 8 8\nElementType = MET_SHORT\nElementSpacing = 1 1 1\n"
             "TransformMatrix = 0 1 0 0 0 1 1 0 0\nElementDataFile = permuted_axes.raw\n";
        std::ofstream raw(tmp("permuted_axes.raw"), std::ios::binary);
        const std::vector<std::int16_t> voxels(512, 100);
        raw.write(reinterpret_cast<const char*>(voxels.data()), std::streamsize(voxels.size() * 2));
    }
    const std::string out = tmp("permuted_axes.npy");
    const Result r = run(mhd + " --size 128 --out " + out);
    ASSERT_EQ(r.status, 0) << r.output;
    const Json want = Json::parse("[[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]");
    EXPECT_EQ(jsonFile(out + ".json")["volume"]["direction"], want);
    EXPECT_EQ(stdoutJson(run(mhd + " --info"))["direction"], want);
}

TEST(FvrRender, InfoOfAVolumeHoldingInfinitySaysSoInValidJson) {
    // A float volume with an infinite voxel: the voxel is said and becomes the lowest finite
    // value (core::replaceNonFiniteVoxels; it would spread through the transform), so the value
    // range and the JSON stay finite.
    const std::string mhd = tmp("inf_volume.mhd");
    {
        std::ofstream f(mhd);
        f << "NDims = 3\nDimSize = 2 2 2\nElementType = MET_FLOAT\nElementDataFile = "
             "inf_volume.raw\n";
        std::ofstream raw(tmp("inf_volume.raw"), std::ios::binary);
        const float voxels[8] = {0, 1, 2, 3, 4, 5, 6, std::numeric_limits<float>::infinity()};
        raw.write(reinterpret_cast<const char*>(voxels), sizeof voxels);
    }
    const Result r = run(mhd + " --info");
    ASSERT_EQ(r.status, 0) << r.output;
    const Json j = stdoutJson(r);
    ASSERT_EQ(j["value_range"].size(), 2u) << r.output;
    EXPECT_EQ(j["value_range"][0], 0.0) << r.output;
    EXPECT_EQ(j["value_range"][1], 6.0) << r.output;
    EXPECT_NE(r.output.find("warning: 1 of 8 voxels are not finite"), std::string::npos)
        << r.output;
    EXPECT_EQ(j["dims"], Json::parse("[2, 2, 2]")) << r.output;
}

TEST(FvrRender, HelpListsEveryOptionGroupAndExitsZero) {
    const Result r = run("--help");
    EXPECT_EQ(r.status, 0) << r.output;
    for (const char* text :
         {"usage: fvr-render INPUT", "Input:", "Output:", "Rendering:", "X-ray:", "Benchmark:",
          "--size N|WxH", "--energy keV", "--voxel-model V", "Exit status"})
        EXPECT_NE(r.out.find(text), std::string::npos) << text << " in " << r.out;
}
