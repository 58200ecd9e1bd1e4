// fvr-render --geometry cone with DICOM X-rays: a DRR written as XA (--out x.dcm) carries its
// C-arm, so that --geometry-from x.dcm renders the same camera (the same P) and the same image;
// an orbit is one multi-frame XA whose frame K is the orbit's view K; a matrix-file camera is
// written as its C-arm, or refused where it has none; what we write passes dciodvfy; the tags the
// reader misses are said on stderr and in the sidecar; bad --geometry-from options are refused
// before the input loads.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include <fvr/core/dicom/xray_geometry.h>
#include <fvr/core/geometry/camera.h>
#include <fvr/core/io/image_io.h>

#include "cli_support.h"
#include "test_support.h"

namespace {

using Json = nlohmann::json;

std::string tmp(const std::string& name) {
    // Of this process: ctest runs each test in a process of its own, in parallel, and two tests
    // writing the same file (a volume one of them is reading) would race.
    return (fvr::test::tmpDir() / ("cone_dicom_" + std::to_string(getpid()) + "_" + name)).string();
}

using Result = fvr::test::RenderResult;
Result run(const std::string& args) { return fvr::test::runFvrRender(args); }

Json sidecar(const std::string& out) { return fvr::test::readSidecar(out); }

std::vector<float> npy(const std::string& path, std::vector<std::int64_t>& shape) {
    return fvr::core::readNpy(path, shape);
}

/** The largest difference between two views' P, relative to P's largest entry. */
double matrixDifference(const Json& a, const Json& b) {
    double worst = 0, scale = 0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 4; ++j) {
            const double x = a["projection_matrix"][i][j].get<double>();
            worst = std::max(worst, std::abs(x - b["projection_matrix"][i][j].get<double>()));
            scale = std::max(scale, std::abs(x));
        }
    return worst / scale;
}

double maxDifference(const float* a, const float* b, std::size_t n) {
    double worst = 0;
    for (std::size_t k = 0; k < n; ++k) worst = std::max(worst, double(std::abs(a[k] - b[k])));
    return worst;
}

/** PSNR of `test` against `ref` (peak: ref's largest value), in dB. */
double psnr(const std::vector<float>& ref, const std::vector<float>& test) {
    double peak = 0, se = 0;
    for (std::size_t k = 0; k < ref.size(); ++k) {
        peak = std::max(peak, double(ref[k]));
        se += (double(ref[k]) - test[k]) * (double(ref[k]) - test[k]);
    }
    return 10 * std::log10(peak * peak / (se / double(ref.size())));
}

/** dciodvfy's verdict on `path` (its output; empty where dicom3tools is missing). */
std::string dciodvfy(const std::string& path) {
    return fvr::test::runCommand("dciodvfy -new '" + path + "' 2>&1").out;
}

bool haveDciodvfy() { return fvr::test::runCommand("command -v dciodvfy").status == 0; }

// An oblique C-arm (LAO 35, CAUD 20) off the volume's centre, with a principal-point offset and
// unequal pitches: everything the file must carry.
const std::string kOblique = "phantom:chest:32 --geometry cone --primary-angle 35 "
                             "--secondary-angle -20 --sid 1100 --sod 720 --isocenter 5,-3,8 "
                             "--detector-size 48x40 --pitch 2.5,3 --principal-point 1.5,-2";

TEST(FvrRenderConeDicom, AnObliqueViewWrittenAsXaRendersTheSameImageFromGeometryFrom) {
    const std::string ref = tmp("oblique.npy"), dcm = tmp("oblique.dcm"),
                      back = tmp("oblique_back.npy");
    ASSERT_EQ(run(kOblique + " --out " + ref).status, 0);
    const Result w = run(kOblique + " --out " + dcm);
    ASSERT_EQ(w.status, 0) << w.output;
    EXPECT_EQ(sidecar(dcm)["output"]["files"], Json::array({dcm}));
    // The camera read back: the same P, and the file's own isocentre (private tags).
    const Result r =
        run("phantom:chest:32 --geometry cone --geometry-from " + dcm + " --out " + back);
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_EQ(r.output.find("warning"), std::string::npos) << r.output;
    const Json a = sidecar(ref), b = sidecar(back);
    EXPECT_LT(matrixDifference(a["views"][0], b["views"][0]), 1e-6);
    EXPECT_EQ(b["settings"]["geometry_from"]["isocenter_from"], "the file");
    EXPECT_EQ(b["settings"]["geometry_from"]["modality"], "XA");
    EXPECT_EQ(b["settings"]["geometry_from"]["warnings"], Json::array());
    EXPECT_NEAR(b["views"][0]["c_arm"]["primary_angle_deg"].get<double>(), 35.0, 1e-9);
    EXPECT_NEAR(b["views"][0]["c_arm"]["secondary_angle_deg"].get<double>(), -20.0, 1e-9);
    EXPECT_NEAR(b["views"][0]["principal_offset_px"][0].get<double>(), 1.5, 1e-12);
    // The image rendered from the file's camera is the first run's.
    std::vector<std::int64_t> shape;
    const auto first = npy(ref, shape), again = npy(back, shape);
    ASSERT_EQ(shape, (std::vector<std::int64_t>{40, 48}));
    EXPECT_LT(maxDifference(first.data(), again.data(), first.size()), 1e-4);
    // The file's pixels are the first run's line integrals within the 16-bit quantisation:
    // half a step of (max - min) / 65535 (and the DS rounding of the rescale).
    const fvr::core::XrayGeometry g = fvr::core::readXrayGeometry(dcm);
    ASSERT_EQ(g.pixels.size(), first.size());
    const auto [lo, hi] = std::minmax_element(first.begin(), first.end());
    EXPECT_GT(*hi, 50.0f);
    EXPECT_LE(maxDifference(first.data(), g.pixels.data(), first.size()),
              0.5 * (*hi - *lo) / 65535 * 1.001 + 1e-5 * *hi);
    EXPECT_GE(psnr(first, g.pixels), 80.0);
}

TEST(FvrRenderConeDicom, AnOrbitRunIsOneMultiFrameXaAndEachFrameRendersItsView) {
    const std::string c = "phantom:chest:32 --geometry cone --secondary-angle 10 "
                          "--detector-size 40x32 --orbit -30:60:4 --out ";
    const std::string ref = tmp("orbit.npy"), dcm = tmp("orbit.dcm");
    ASSERT_EQ(run(c + ref).status, 0);
    const Result w = run(c + dcm);
    ASSERT_EQ(w.status, 0) << w.output;
    const Json sc = sidecar(dcm);
    EXPECT_TRUE(sc["output"]["stacked"].get<bool>());
    EXPECT_EQ(sc["output"]["files"], Json::array({dcm})); // one file, no FILE_NNNN.dcm
    EXPECT_FALSE(std::filesystem::exists(tmp("orbit_0000.dcm")));
    const fvr::core::XrayGeometry g = fvr::core::readXrayGeometry(dcm);
    ASSERT_EQ(g.frames.size(), 4u);
    for (int k = 0; k < 4; ++k) {
        EXPECT_NEAR(g.frames[k].primaryDeg, -30.0 + 30.0 * k, 1e-9);
        EXPECT_NEAR(g.frames[k].secondaryDeg, 10.0, 1e-9);
    }
    std::vector<std::int64_t> shape;
    const auto stack = npy(ref, shape);
    ASSERT_EQ(shape, (std::vector<std::int64_t>{4, 32, 40}));
    const std::size_t n = 32 * 40;
    EXPECT_GE(psnr(stack, g.pixels), 80.0);
    // --frame 2: the orbit's third view, its P and its pixels.
    const std::string f2 = tmp("orbit_frame2.npy");
    const Result r =
        run("phantom:chest:32 --geometry cone --geometry-from " + dcm + " --frame 2 --out " + f2);
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_LT(matrixDifference(sidecar(ref)["views"][2], sidecar(f2)["views"][0]), 1e-6);
    EXPECT_EQ(sidecar(f2)["settings"]["geometry_from"]["frames"], Json::array({2}));
    const auto view2 = npy(f2, shape);
    ASSERT_EQ(shape, (std::vector<std::int64_t>{32, 40}));
    EXPECT_LT(maxDifference(stack.data() + 2 * n, view2.data(), n), 1e-4);
    // --frame all: the whole orbit again.
    const std::string all = tmp("orbit_all.npy");
    ASSERT_EQ(
        run("phantom:chest:32 --geometry cone --geometry-from " + dcm + " --frame all --out " + all)
            .status,
        0);
    const auto again = npy(all, shape);
    ASSERT_EQ(shape, (std::vector<std::int64_t>{4, 32, 40}));
    EXPECT_LT(maxDifference(stack.data(), again.data(), stack.size()), 1e-4);
    for (int k = 0; k < 4; ++k)
        EXPECT_LT(matrixDifference(sidecar(ref)["views"][k], sidecar(all)["views"][k]), 1e-6) << k;
}

/** A projection-matrix file: P of each camera (one detector and pitch, the first's). */
std::string matrixFile(const std::string& name, const std::vector<fvr::core::ConeCamera>& cameras) {
    const std::string path = tmp(name);
    std::ofstream m(path);
    m.precision(17);
    const fvr::core::ConeCamera& c = cameras.front();
    m << "detector " << c.width << " " << c.height << "\npitch " << c.pitchU << " " << c.pitchV
      << "\n";
    for (const auto& camera : cameras)
        for (const auto& row : camera.matrix().rows)
            m << row.x << " " << row.y << " " << row.z << " " << row.w << "\n";
    return path;
}
std::string matrixFile(const std::string& name, const fvr::core::ConeCamera& camera) {
    return matrixFile(name, std::vector<fvr::core::ConeCamera>{camera});
}

TEST(FvrRenderConeDicom, AMatrixCameraIsWrittenAsItsCArmAndARolledOneIsRefused) {
    using namespace fvr::core;
    // RAO 25 CRAN 20 about the phantom's centre: the file's C-arm is found again.
    const CArm arm{-25.0, 20.0, 1200.0, 800.0, glm::dvec3(0.0)};
    const ConeCamera c = cArmCamera(arm, 40, 30, 3.0, 3.0);
    const std::string dcm = tmp("matrix.dcm");
    const Result r = run("phantom:chest:32 --geometry cone --projection-matrix " +
                         matrixFile("carm.txt", c) + " --out " + dcm);
    ASSERT_EQ(r.status, 0) << r.output;
    const XrayGeometry g = readXrayGeometry(dcm, false);
    ASSERT_EQ(g.frames.size(), 1u);
    EXPECT_NEAR(g.frames[0].primaryDeg, -25.0, 1e-9);
    EXPECT_NEAR(g.frames[0].secondaryDeg, 20.0, 1e-9);
    EXPECT_NEAR(g.frames[0].sid, 1200.0, 1e-9);
    EXPECT_NEAR(g.frames[0].sod, 800.0, 1e-6);
    EXPECT_TRUE(g.isocentreStated);
    EXPECT_NEAR(glm::length(g.frames[0].isocentre), 0.0, 1e-6);
    if (haveDciodvfy()) {
        EXPECT_EQ(dciodvfy(dcm).find("Error"), std::string::npos);
    }
    // The same detector rolled 30 degrees about the principal ray: no C-arm has it.
    ConeCamera rolled = c;
    const double t = 30.0 * 3.14159265358979323846 / 180.0;
    rolled.u = std::cos(t) * c.u + std::sin(t) * c.v;
    rolled.v = -std::sin(t) * c.u + std::cos(t) * c.v;
    const std::string bad = tmp("rolled.dcm");
    std::filesystem::remove(bad);
    const Result refused = run("phantom:chest:32 --geometry cone --projection-matrix " +
                               matrixFile("rolled.txt", rolled) + " --out " + bad);
    EXPECT_EQ(refused.status, 2) << refused.output;
    EXPECT_NE(refused.output.find("this camera is no C-arm's"), std::string::npos)
        << refused.output;
    EXPECT_NE(refused.output.find("write .npy, .pfm or .png"), std::string::npos) << refused.output;
    EXPECT_FALSE(std::filesystem::exists(bad));
    // .npy still takes it.
    EXPECT_EQ(run("phantom:chest:32 --geometry cone --projection-matrix " + tmp("rolled.txt") +
                  " --out " + tmp("rolled.npy"))
                  .status,
              0);
}

TEST(FvrRenderConeDicom, MatrixViewsMakeOneRunOnlyWhereOnlyTheirAnglesDiffer) {
    using namespace fvr::core;
    // Two views of one C-arm about the volume's centre: one two-frame XA.
    CArm a{10.0, 5.0, 1000.0, 750.0, glm::dvec3(0.0)}, b = a;
    b.primaryDeg = 40.0;
    const std::string run2 = tmp("matrix_run.dcm");
    Result r = run(
        "phantom:chest:32 --geometry cone --projection-matrix " +
        matrixFile("run.txt", {cArmCamera(a, 32, 24, 4.0, 4.0), cArmCamera(b, 32, 24, 4.0, 4.0)}) +
        " --out " + run2);
    ASSERT_EQ(r.status, 0) << r.output;
    const XrayGeometry g = readXrayGeometry(run2, false);
    ASSERT_EQ(g.frames.size(), 2u);
    EXPECT_NEAR(g.frames[1].primaryDeg, 40.0, 1e-9);
    EXPECT_NEAR(g.frames[1].secondaryDeg, 5.0, 1e-9);
    // The second at another SID: two single-frame files, each with its own.
    b.sid = 1200.0;
    const std::string two = tmp("matrix_two.dcm");
    r = run(
        "phantom:chest:32 --geometry cone --projection-matrix " +
        matrixFile("two.txt", {cArmCamera(a, 32, 24, 4.0, 4.0), cArmCamera(b, 32, 24, 4.0, 4.0)}) +
        " --out " + two);
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_EQ(sidecar(two)["output"]["files"],
              Json::array({tmp("matrix_two_0000.dcm"), tmp("matrix_two_0001.dcm")}));
    EXPECT_NEAR(readXrayGeometry(tmp("matrix_two_0000.dcm"), false).frames[0].sid, 1000.0, 1e-9);
    const XrayGeometry second = readXrayGeometry(tmp("matrix_two_0001.dcm"), false);
    EXPECT_NEAR(second.frames[0].sid, 1200.0, 1e-9);
    EXPECT_NEAR(second.frames[0].primaryDeg, 40.0, 1e-9);
}

TEST(FvrRenderConeDicom, WhatWeWritePassesDciodvfy) {
    if (!haveDciodvfy()) GTEST_SKIP() << "dciodvfy (Debian package dicom3tools) is not installed";
    const std::string one = tmp("check_one.dcm"), orbit = tmp("check_orbit.dcm"),
                      film = tmp("check_transmission.dcm");
    ASSERT_EQ(run(kOblique + " --out " + one).status, 0);
    ASSERT_EQ(run("phantom:chest:32 --geometry cone --detector-size 32x32 --sweep 3 --out " + orbit)
                  .status,
              0);
    ASSERT_EQ(run(kOblique + " --beer-lambert --out " + film).status, 0);
    for (const std::string& path : {one, orbit, film}) {
        const std::string v = dciodvfy(path);
        EXPECT_NE(v.find("XAImage"), std::string::npos) << path << ": " << v;
        EXPECT_EQ(v.find("Error"), std::string::npos) << path << ": " << v;
    }
    // Line integrals are a logarithm of the intensity; a Beer-Lambert output is the intensity
    // (it said LOG too).
    for (const auto& [path, relationship] : {std::pair{one, "LOG"}, {film, "LIN"}}) {
        DcmFileFormat ff;
        ASSERT_TRUE(ff.loadFile(path.c_str()).good());
        OFString value;
        ASSERT_TRUE(
            ff.getDataset()->findAndGetOFString(DCM_PixelIntensityRelationship, value).good());
        EXPECT_EQ(std::string(value.c_str()), relationship) << path;
    }
}

/** `from` without the tags named, saved as `to`. */
void withoutTags(const std::string& from, const std::string& to,
                 const std::vector<DcmTagKey>& tags) {
    DcmFileFormat ff;
    ASSERT_TRUE(ff.loadFile(from.c_str()).good());
    for (const DcmTagKey& t : tags) ff.getDataset()->findAndDeleteElement(t, true);
    ASSERT_TRUE(ff.saveFile(to.c_str(), EXS_LittleEndianExplicit).good());
}

TEST(FvrRenderConeDicom, MissingTagsAreSaidAndTheIsocentreIsTheGivenOrTheVolumes) {
    const std::string full = tmp("full.dcm"), part = tmp("part.dcm");
    ASSERT_EQ(run(kOblique + " --out " + full).status, 0);
    // No SID (the reader takes SOD x magnification) and none of our private tags: the file
    // states no isocentre, as no X-ray from a real C-arm does.
    withoutTags(full, part,
                {DCM_DistanceSourceToDetector, DcmTagKey(0x0009, 0x0010), DcmTagKey(0x0009, 0x1001),
                 DcmTagKey(0x0009, 0x1002)});
    const std::string given = tmp("part_given.npy");
    const Result r = run("phantom:chest:32 --geometry cone --geometry-from " + part +
                         " --isocenter 5,-3,8 --out " + given);
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_NE(r.output.find("fvr-render: warning: DistanceSourceToDetector (0018,1110) missing"),
              std::string::npos)
        << r.output;
    const Json j = sidecar(given);
    const Json& from = j["settings"]["geometry_from"];
    EXPECT_EQ(from["isocenter_from"], "--isocenter");
    ASSERT_FALSE(from["warnings"].empty());
    EXPECT_NE(from["warnings"].dump().find("DistanceSourceToDetector (0018,1110) missing"),
              std::string::npos);
    const Json& arm = j["views"][0]["c_arm"];
    EXPECT_EQ(arm["isocenter_mm"], Json::array({5.0, -3.0, 8.0}));
    EXPECT_NEAR(arm["sid_mm"].get<double>(), 1100.0, 1e-9);
    EXPECT_EQ(j["views"][0]["principal_offset_px"], Json::array({0.0, 0.0}));
    // Without --isocenter: the volume's centre (the chest phantom is centred on the origin).
    const std::string centred = tmp("part_centre.npy");
    ASSERT_EQ(run("phantom:chest:32 --geometry cone --geometry-from " + part + " --out " + centred)
                  .status,
              0);
    const Json k = sidecar(centred);
    EXPECT_EQ(k["settings"]["geometry_from"]["isocenter_from"], "the volume's centre");
    for (int a = 0; a < 3; ++a)
        EXPECT_NEAR(k["views"][0]["c_arm"]["isocenter_mm"][a].get<double>(), 0.0, 1e-9);
    // --isocenter with a file that states its own: the file's, with a warning.
    const Result stated = run("phantom:chest:32 --geometry cone --geometry-from " + full +
                              " --isocenter 1,2,3 --out " + tmp("stated.npy"));
    ASSERT_EQ(stated.status, 0) << stated.output;
    EXPECT_NE(stated.output.find("--isocenter 1,2,3 ignored"), std::string::npos) << stated.output;
    EXPECT_EQ(sidecar(tmp("stated.npy"))["views"][0]["c_arm"]["isocenter_mm"],
              Json::array({5.0, -3.0, 8.0}));
}

TEST(FvrRenderConeDicom, BadGeometryFromIsRefusedBeforeTheInputLoads) {
    const std::string dcm = tmp("refuse.dcm");
    ASSERT_EQ(run(kOblique + " --out " + dcm).status, 0);
    std::ofstream(tmp("not_dicom.dcm")) << "not a DICOM file\n";
    const std::string none = "/no/such/volume.mhd --geometry cone --out " + tmp("x.npy") + " ";
    const std::pair<std::string, std::string> cases[] = {
        {"--geometry-from /no/such/xray.dcm", "/no/such/xray.dcm"},
        {"--geometry-from " + tmp("not_dicom.dcm"), tmp("not_dicom.dcm")},
        {"--geometry-from " + dcm + " --frame 1", "--frame 1: " + dcm + " has 1 frame (0)"},
        {"--geometry-from " + dcm + " --frame -1", "--frame"},
        {"--geometry-from " + dcm + " --frame first", "expected a frame number"},
        {"--frame 0", "--frame: only with --geometry-from"},
        {"--geometry-from " + dcm + " --sid 1000", "--sid: not with --geometry-from"},
        {"--geometry-from " + dcm + " --primary-angle 10", "--primary-angle: not with"},
        {"--geometry-from " + dcm + " --detector-size 64x64", "--detector-size: not with"},
        {"--geometry-from " + dcm + " --pitch 1", "--pitch: not with --geometry-from"},
        {"--geometry-from " + dcm + " --orbit 0:90:3", "--orbit: not with --geometry-from"},
        {"--geometry-from " + dcm + " --sweep 3", "--sweep: not with --geometry-from"},
        {"--geometry-from " + dcm + " --projection-matrix m.txt",
         "--geometry-from: not with --projection-matrix"},
    };
    for (const auto& [args, expect] : cases) {
        const Result r = run(none + args);
        EXPECT_EQ(r.status, 2) << args << ": " << r.output;
        EXPECT_NE(r.output.find(expect), std::string::npos) << args << ": " << r.output;
        EXPECT_EQ(r.output.find("/no/such/volume.mhd"), std::string::npos)
            << args << ": " << r.output;
    }
    // A CT slice of the shared data: no projection X-ray, said with its modality.
    const std::filesystem::path ct = std::filesystem::path(FVR_SHARED_DATA_DIR) / "dicom" /
                                     "ct_phantom_philips_512x512x140_jpeg_lossless" / "I1180";
    if (std::filesystem::exists(ct)) {
        const Result r = run(none + "--geometry-from " + ct.string());
        EXPECT_EQ(r.status, 2) << r.output;
        EXPECT_NE(r.output.find(ct.string() + ": Modality (0008,0060) 'CT'"), std::string::npos)
            << r.output;
        EXPECT_NE(r.output.find("is not a projection X-ray"), std::string::npos) << r.output;
    }
    const Result parallel = run("/no/such/volume.mhd --geometry-from " + dcm + " --out x.npy");
    EXPECT_EQ(parallel.status, 2);
    EXPECT_NE(parallel.output.find("--geometry-from: only with --geometry cone"), std::string::npos)
        << parallel.output;
    // A cone-beam .dcm output is no longer refused: the run goes on to the input.
    const Result out = run("/no/such/volume.mhd --geometry cone --out " + tmp("x.dcm"));
    EXPECT_EQ(out.status, 2);
    EXPECT_NE(out.output.find("/no/such/volume.mhd"), std::string::npos) << out.output;
}

} // namespace
