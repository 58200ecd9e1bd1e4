// fvr-render --geometry cone against facts worked out by hand: where a point lands (left of the
// isocentre lands right of centre, the head at the top), a box's shadow magnified by SID/SOD, the
// sidecar's P mapping the isocentre to the principal point, the orbit's views, the flat field
// as (SID/r)^3, the matrix file giving the C-arm's image, and every bad geometry refused, before
// the input loads where the volume is not needed.
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fvr/core/io/image_io.h>

#include "cli_support.h"
#include "image_metrics.h"
#include "test_support.h"

namespace {

using Json = nlohmann::json;

std::string tmp(const std::string& name) {
    // Of this process: ctest runs each test in a process of its own, in parallel, and two tests
    // writing the same file (a volume one of them is reading) would race.
    return (fvr::test::tmpDir() / ("cone_" + std::to_string(getpid()) + "_" + name)).string();
}

using Result = fvr::test::RenderResult;
Result run(const std::string& args) { return fvr::test::runFvrRender(args); }

Json sidecar(const std::string& out) { return fvr::test::readSidecar(out); }

std::vector<float> image(const std::string& path, std::vector<std::int64_t>& shape) {
    return fvr::core::readNpy(path, shape);
}

/** A float32 MetaImage of nx x ny x nz voxels of 1 mm (values in no units: they integrate as
 *  they are), centred on the origin of patient LPS; `value` gives each voxel from its centre's
 *  position in mm. */
template <class Value>
std::string writeVolume(const std::string& name, int nx, int ny, int nz, Value value) {
    const std::string raw = tmp(name + ".raw"), mhd = tmp(name + ".mhd");
    std::vector<float> v(std::size_t(nx) * ny * nz);
    const double ox = -(nx - 1) / 2.0, oy = -(ny - 1) / 2.0, oz = -(nz - 1) / 2.0;
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i)
                v[std::size_t(i) + std::size_t(nx) * (j + std::size_t(ny) * k)] =
                    float(value(ox + i, oy + j, oz + k));
    std::ofstream(raw, std::ios::binary)
        .write(reinterpret_cast<const char*>(v.data()), std::streamsize(v.size() * 4));
    std::ofstream(mhd) << "ObjectType = Image\nNDims = 3\nDimSize = " << nx << " " << ny << " "
                       << nz << "\nElementSpacing = 1 1 1\nOffset = " << ox << " " << oy << " "
                       << oz << "\nTransformMatrix = 1 0 0 0 1 0 0 0 1\n"
                       << "ElementType = MET_FLOAT\nElementDataFile = "
                       << std::filesystem::path(raw).filename().string() << "\n";
    return mhd;
}

/** The centroid (col, row) of an image's values. */
std::pair<double, double> centroid(const std::vector<float>& img, int w, int h) {
    double s = 0, sc = 0, sr = 0;
    for (int r = 0; r < h; ++r)
        for (int c = 0; c < w; ++c) {
            const double v = img[std::size_t(r) * w + c];
            s += v;
            sc += v * c;
            sr += v * r;
        }
    return {sc / s, sr / s};
}

TEST(FvrRenderCone, APointLeftOfTheIsocentreLandsRightOfCentreAndTheHeadAtTheTop) {
    // A 3 mm blob 20 mm to the patient's left (+x in LPS) and 10 mm toward the head (+z), at
    // the isocentre's depth: magnified SID/SOD = 4/3, so 26.67 and 13.33 mm from the centre
    // (127.5, 95.5) of pixels of 0.5 mm: right of it (columns run to the left) and above (rows
    // to the feet). (At 1 mm pixels the blob's image is too coarsely sampled for its centroid
    // to be its centre's projection within 0.02 pixels.)
    const std::string vol = writeVolume("blob", 64, 32, 48, [](double x, double y, double z) {
        return std::abs(x - 20) <= 1 && std::abs(y) <= 1 && std::abs(z - 10) <= 1 ? 1.0 : 0.0;
    });
    const std::string out = tmp("blob.npy");
    const Result r = run(vol + " --geometry cone --detector-size 256x192 --pitch 0.5 --out " + out);
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    const auto img = image(out, shape);
    ASSERT_EQ(shape, (std::vector<std::int64_t>{192, 256}));
    const auto [col, row] = centroid(img, 256, 192);
    EXPECT_NEAR(col, 127.5 + 2 * 20.0 * 4 / 3, 0.02);
    EXPECT_NEAR(row, 95.5 - 2 * 10.0 * 4 / 3, 0.02);
    // LAO 90: the detector at the patient's left, the source at the right; the columns run
    // along u = (0, 1, 0), toward posterior; a blob 20 mm to the left is now 20 mm nearer the
    // detector: it lands at the centre column, magnified 1000 / 770 along the rows.
    const Result lao = run(vol +
                           " --geometry cone --primary-angle 90 --detector-size 256x192 "
                           "--pitch 0.5 --out " +
                           out);
    ASSERT_EQ(lao.status, 0) << lao.output;
    const auto img90 = image(out, shape);
    const auto [col90, row90] = centroid(img90, 256, 192);
    EXPECT_NEAR(col90, 127.5, 0.02);
    EXPECT_NEAR(row90, 95.5 - 2 * 10.0 * 1000 / 770, 0.02);
}

/** The width at half the maximum of row `row` (linear between pixels), in pixels. */
double halfMaxWidth(const std::vector<float>& img, int w, int row) {
    const float* p = img.data() + std::size_t(row) * w;
    float peak = 0;
    for (int c = 0; c < w; ++c) peak = std::max(peak, p[c]);
    const double half = peak / 2.0;
    double left = -1, right = -1;
    for (int c = 1; c < w; ++c) {
        if (p[c - 1] < half && p[c] >= half) left = c - 1 + (half - p[c - 1]) / (p[c] - p[c - 1]);
        if (p[c - 1] >= half && p[c] < half) right = c - 1 + (p[c - 1] - half) / (p[c - 1] - p[c]);
    }
    return right - left;
}

TEST(FvrRenderCone, ABoxShadowIsMagnifiedBySidOverSod) {
    // Voxels of 1 at x = -20..20 mm (trilinear: half height at +-20.5 mm, 41 mm wide), 9 mm
    // deep about the isocentre: the AP shadow is 41 SID / SOD mm wide.
    const std::string vol = writeVolume(
        "box", 81, 9, 20, [](double x, double, double) { return std::abs(x) <= 20 ? 1.0 : 0.0; });
    const std::string out = tmp("box.npy");
    for (const auto& [sid, sod] : {std::pair{1000.0, 750.0}, std::pair{1500.0, 750.0}}) {
        const Result r =
            run(vol + " --geometry cone --sid " + std::to_string(sid) + " --sod " +
                std::to_string(sod) + " --detector-size 480x16 --pitch 0.25 --out " + out);
        ASSERT_EQ(r.status, 0) << r.output;
        std::vector<std::int64_t> shape;
        const auto img = image(out, shape);
        EXPECT_NEAR(halfMaxWidth(img, 480, 8) * 0.25, 41.0 * sid / sod, 0.1) << sid << "/" << sod;
    }
}

TEST(FvrRenderCone, TheSidecarRecordsTheCameraAndPMapsTheIsocentreToThePrincipalPoint) {
    const std::string out = tmp("sidecar.npy");
    const Result r = run("phantom:chest:32 --geometry cone --primary-angle 30 --secondary-angle "
                         "-15 --sid 1100 --sod 700 --isocenter 3,-4,5 --detector-size 64x48 "
                         "--pitch 2,3 --principal-point 2.5,-1.5 --ray-model box --out " +
                         out);
    ASSERT_EQ(r.status, 0) << r.output;
    const Json j = sidecar(out);
    EXPECT_EQ(j["geometry"], "cone");
    EXPECT_EQ(j["settings"]["ray_model"], "box");
    ASSERT_EQ(j["views"].size(), 1u);
    const Json& v = j["views"][0];
    EXPECT_EQ(v["c_arm"]["primary_angle_deg"], 30.0);
    EXPECT_EQ(v["c_arm"]["secondary_angle_deg"], -15.0);
    EXPECT_EQ(v["c_arm"]["sid_mm"], 1100.0);
    EXPECT_EQ(v["c_arm"]["sod_mm"], 700.0);
    EXPECT_EQ(v["c_arm"]["isocenter_mm"], Json::parse("[3, -4, 5]"));
    EXPECT_EQ(v["width"], 64);
    EXPECT_EQ(v["height"], 48);
    EXPECT_EQ(v["pitch_mm"], Json::parse("[2, 3]"));
    EXPECT_EQ(v["principal_offset_px"], Json::parse("[2.5, -1.5]"));
    // The source by hand: d = (sin a cos b, -cos a cos b, sin b), source = I - SOD d.
    const double a = 30 * M_PI / 180, b = -15 * M_PI / 180;
    const double d[3] = {std::sin(a) * std::cos(b), -std::cos(a) * std::cos(b), std::sin(b)};
    const double iso[3] = {3, -4, 5};
    for (int k = 0; k < 3; ++k) {
        EXPECT_NEAR(v["source_mm"][k].get<double>(), iso[k] - 700 * d[k], 1e-9);
        EXPECT_NEAR(v["detector_centre_mm"][k].get<double>(), iso[k] + 400 * d[k], 1e-9);
    }
    // P [I, 1] = w (col, row, 1) with (col, row) the principal point, (W-1)/2 - du, (H-1)/2 - dv.
    double h[3];
    for (int r3 = 0; r3 < 3; ++r3) {
        const Json& row = v["projection_matrix"][r3];
        h[r3] = row[3].get<double>();
        for (int k = 0; k < 3; ++k) h[r3] += row[k].get<double>() * iso[k];
    }
    EXPECT_NEAR(h[0] / h[2], 31.5 - 2.5, 1e-9);
    EXPECT_NEAR(h[1] / h[2], 23.5 + 1.5, 1e-9);
    EXPECT_NEAR(h[2], 700.0, 1e-9); // w: the depth from the source
}

TEST(FvrRenderCone, OrbitAndSweepGiveTheirViewsAndAngles) {
    const std::string out = tmp("orbit.npy");
    Result r = run("phantom:chest:32 --geometry cone --orbit -30:60:4 --secondary-angle 10 "
                   "--detector-size 40x24 --out " +
                   out);
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    const auto stack = image(out, shape);
    EXPECT_EQ(shape, (std::vector<std::int64_t>{4, 24, 40}));
    Json j = sidecar(out);
    ASSERT_EQ(j["views"].size(), 4u);
    for (int i = 0; i < 4; ++i) {
        EXPECT_NEAR(j["views"][i]["c_arm"]["primary_angle_deg"].get<double>(), -30.0 + 30 * i,
                    1e-12);
        EXPECT_EQ(j["views"][i]["c_arm"]["secondary_angle_deg"], 10.0);
    }
    EXPECT_EQ(j["output"]["stacked"], true);
    r = run("phantom:chest:32 --geometry cone --sweep 4 --primary-angle 10 --detector-size 40x24 "
            "--numbered --out " +
            tmp("sweep.pfm"));
    ASSERT_EQ(r.status, 0) << r.output;
    j = sidecar(tmp("sweep.pfm"));
    ASSERT_EQ(j["views"].size(), 4u);
    for (int i = 0; i < 4; ++i) {
        EXPECT_NEAR(j["views"][i]["c_arm"]["primary_angle_deg"].get<double>(), 10.0 + 90 * i,
                    1e-12);
        EXPECT_TRUE(std::filesystem::exists(tmp("sweep_000" + std::to_string(i) + ".pfm")));
    }
}

TEST(FvrRenderCone, TransmissionAndTheFlatFieldFollowBeerLambertAndTheInverseSquare) {
    const std::string base = "phantom:chest:32 --geometry cone --primary-angle 20 --detector-size "
                             "48x32 --pitch 8 --sid 1000 --sod 600 ";
    ASSERT_EQ(run(base + "--out " + tmp("p.npy")).status, 0);
    ASSERT_EQ(run(base + "--beer-lambert --exposure 2 --out " + tmp("t.npy")).status, 0);
    const Result r = run(base + "--beer-lambert --exposure 2 --flat-field --out " + tmp("f.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    const auto p = image(tmp("p.npy"), shape), t = image(tmp("t.npy"), shape),
               f = image(tmp("f.npy"), shape);
    const Json j = sidecar(tmp("f.npy"));
    const double mu = j["output"]["mu_water_per_mm"];
    const Json& v = j["views"][0];
    EXPECT_EQ(j["settings"]["flat_field"], true);
    double src[3], c[3], u[3], w[3];
    for (int k = 0; k < 3; ++k) {
        src[k] = v["source_mm"][k];
        c[k] = v["detector_centre_mm"][k];
        u[k] = v["u"][k];
        w[k] = v["v"][k];
    }
    for (int row : {0, 13, 31})
        for (int col : {0, 20, 47}) {
            const std::size_t at = std::size_t(row) * 48 + col;
            EXPECT_NEAR(t[at], 2.0 * std::exp(-mu * p[at]), 1e-5 * t[at]);
            // (SID / r)^3, r from the source to the pixel's centre.
            double r2 = 0;
            for (int k = 0; k < 3; ++k) {
                const double x = c[k] + (col - 23.5) * 8 * u[k] + (row - 15.5) * 8 * w[k];
                r2 += (x - src[k]) * (x - src[k]);
            }
            EXPECT_NEAR(f[at] / t[at], std::pow(1000.0 / std::sqrt(r2), 3), 1e-5)
                << col << "," << row;
        }
    // A film PNG of W x H.
    const Result png = run(base + "--beer-lambert --flat-field --out " + tmp("f.png"));
    ASSERT_EQ(png.status, 0) << png.output;
    std::ifstream in(tmp("f.png"), std::ios::binary);
    unsigned char hdr[24];
    in.read(reinterpret_cast<char*>(hdr), 24);
    EXPECT_EQ((hdr[16] << 24) | (hdr[17] << 16) | (hdr[18] << 8) | hdr[19], 48);
    EXPECT_EQ((hdr[20] << 24) | (hdr[21] << 16) | (hdr[22] << 8) | hdr[23], 32);
}

TEST(FvrRenderCone, AMatrixFileGivesTheCArmsImage) {
    const std::string carm = tmp("carm.npy");
    ASSERT_EQ(run("phantom:chest:32 --geometry cone --primary-angle -25 --secondary-angle 20 "
                  "--detector-size 40x30 --pitch 3,3 --principal-point 1.5,-2 --out " +
                  carm)
                  .status,
              0);
    const Json v = sidecar(carm)["views"][0];
    std::ofstream m(tmp("carm.txt"));
    m.precision(17);
    m << "# from the sidecar\ndetector 40 30\npitch 3\n";
    for (const auto& row : v["projection_matrix"])
        m << row[0].get<double>() << " " << row[1].get<double>() << " " << row[2].get<double>()
          << " " << row[3].get<double>() << "\n";
    m.close();
    const std::string fromFile = tmp("fromfile.npy");
    const Result r = run("phantom:chest:32 --geometry cone --projection-matrix " + tmp("carm.txt") +
                         " --out " + fromFile);
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    const auto a = image(carm, shape), b = image(fromFile, shape);
    ASSERT_EQ(a.size(), b.size());
    double worst = 0, peak = 0;
    for (std::size_t k = 0; k < a.size(); ++k) {
        worst = std::max(worst, double(std::abs(a[k] - b[k])));
        peak = std::max(peak, double(a[k]));
    }
    EXPECT_GT(peak, 10.0);
    EXPECT_LT(worst, 1e-4 * peak);
    const Json w = sidecar(fromFile)["views"][0];
    EXPECT_FALSE(w.contains("c_arm"));
    for (int k = 0; k < 3; ++k)
        EXPECT_NEAR(w["source_mm"][k].get<double>(), v["source_mm"][k].get<double>(), 1e-9);
}

TEST(FvrRenderCone, BenchTimesTheRayCasterPerView) {
    const Result r = run("phantom:chest:32 --geometry cone --detector-size 32x32 --bench 3");
    ASSERT_EQ(r.status, 0) << r.output;
    const Json j = Json::parse(r.output.substr(0, r.output.rfind('}') + 1));
    EXPECT_EQ(j["frames"], 3);
    EXPECT_EQ(j["views_ms"].size(), 3u);
    EXPECT_TRUE(j["ray_cast"]["median_ms"].is_number());
    EXPECT_EQ(j["settings"]["geometry"], "cone");
}

// --backend gpu casts the cone beam on the GPU (a software one too: Mesa's llvmpipe here), the
// same image as the CPU's to float rounding; the B-spline model stays on the CPU and says so.
TEST(FvrRenderCone, TheGpuCastsTheSameImageAsTheCpu) {
    const std::string base = "phantom:chest:48 --geometry cone --primary-angle 35 "
                             "--secondary-angle -20 --detector-size 64x48 --sid 1000 --sod 650 ";
    for (const char* model : {"box", "trilinear"}) {
        const std::string m = std::string("--ray-model ") + model + " ";
        const std::string cpu = tmp(std::string("cpu_") + model + ".npy"),
                          gpu = tmp(std::string("gpu_") + model + ".npy");
        ASSERT_EQ(run(base + m + "--backend cpu --out " + cpu).status, 0);
        const Result r = run(base + m + "--backend gpu --out " + gpu);
        ASSERT_EQ(r.status, 0) << r.output;
        const std::string backend = sidecar(gpu)["settings"]["backend"];
        if (backend.rfind("gpu", 0) != 0) GTEST_SKIP() << "no OpenGL 4.3 here (" << r.output << ")";
        EXPECT_EQ(sidecar(cpu)["settings"]["backend"], "cpu");
        std::vector<std::int64_t> shape;
        const auto a = image(cpu, shape), b = image(gpu, shape);
        EXPECT_GT(fvr::test::compare(b, a).psnr, 100.0) << model;
    }
    const Result r = run(base + "--ray-model bspline --backend gpu --out " + tmp("gpu_bs.npy"));
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_NE(r.output.find("B-spline ray model runs on the CPU only"), std::string::npos)
        << r.output;
    EXPECT_EQ(sidecar(tmp("gpu_bs.npy"))["settings"]["backend"], "cpu");
}

TEST(FvrRenderCone, BadGeometryIsRefusedBeforeTheInputLoads) {
    // The input does not exist: the geometry's error must come first.
    const std::string none = "/no/such/volume.mhd --out " + tmp("x.npy") + " ";
    std::ofstream(tmp("bad.txt")) << "detector 64 64\npitch 1\n1 2 3\n";
    const std::pair<std::string, std::string> cases[] = {
        {"--geometry cone --sid 900 --sod 1000", "0 < SOD < SID, found SOD 1000 mm, SID 900 mm"},
        {"--geometry cone --pitch 0", "--pitch: expected a positive number of mm"},
        {"--geometry cone --pitch 1,-2", "--pitch: expected a positive number of mm"},
        {"--geometry cone --detector-size 8x64", "16..4096"},
        {"--geometry cone --detector-size 64x5000", "16..4096"},
        {"--geometry cone --projection-matrix " + tmp("bad.txt"),
         tmp("bad.txt") + ":3: expected a row of P: four numbers, found 3"},
        {"--geometry cone --projection-matrix /no/such/matrix.txt", "/no/such/matrix.txt"},
        {"--sid 1000", "--sid: only with --geometry cone"},
        {"--geometry parallel --ray-model box", "--ray-model: only with --geometry cone"},
        {"--geometry cone --view AP", "--view: not with --geometry cone"},
        {"--geometry cone --kernel sinc4", "--kernel: not with --geometry cone"},
        {"--pixel-aperture --pixel-subsamples 2", "--pixel-subsamples: only with --geometry cone"},
        {"--geometry cone --flat-field", "--flat-field: multiplies transmitted intensity"},
        {"--geometry cone --ray-model box --step 0.5", "--step: not with --ray-model box"},
        {"--geometry cone --orbit 0:90:1", "--orbit"},
        {"--geometry cone --orbit 0:90:3 --sweep 4", "--orbit: not with --sweep"},
        {"--geometry cone --projection-matrix " + tmp("bad.txt") + " --sid 1200",
         "--sid: not with --projection-matrix"},
        {"--geometry cone --ray-model cubicle", "--ray-model"},
    };
    for (const auto& [args, expect] : cases) {
        const Result r = run(none + args);
        EXPECT_EQ(r.status, 2) << args << ": " << r.output;
        EXPECT_NE(r.output.find(expect), std::string::npos) << args << ": " << r.output;
        EXPECT_EQ(r.output.find("/no/such/volume.mhd"), std::string::npos)
            << args << ": " << r.output;
    }
}

TEST(FvrRenderCone, ViewsThatNeedTheVolumeAreRefusedBeforeRendering) {
    // The chest phantom at 32^3 spans 420 mm about the origin.
    const std::pair<std::string, std::string> cases[] = {
        {"--sod 100 --sid 1000", "the source lies inside the volume"},
        {"--isocenter 0,-2000,0", "the volume lies behind the source"},
        {"--isocenter 0,2000,0", "the volume lies beyond the detector"},
    };
    for (const auto& [args, expect] : cases) {
        const Result r = run("phantom:chest:32 --geometry cone --detector-size 32x32 " + args +
                             " --out " + tmp("late.npy"));
        EXPECT_EQ(r.status, 2) << args << ": " << r.output;
        EXPECT_NE(r.output.find(expect), std::string::npos) << args << ": " << r.output;
        EXPECT_FALSE(std::filesystem::exists(tmp("late.npy"))) << args;
    }
}

} // namespace
