// fvr-register, the real binary: X-rays that fvr-render simulates with its polychromatic model
// (another image formation than the registration's monoenergetic DRRs) at the geometry's own
// pose, registered from a known offset; the mTRE checked against the offset worked here by hand;
// and the refusals, each before any work (no progress, no output).
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_support.h"
#include "test_support.h"

namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;
using fvr::test::runFvrRender;

struct RegisterRun {
    int status = -1;
    std::string output;
};

RegisterRun runFvrRegister(const std::string& args) {
    const std::string err =
        (fvr::test::tmpDir() / ("fvr_register_stderr_" + std::to_string(getpid()) + ".txt"))
            .string();
    const auto c = fvr::test::runCommand(std::string(FVR_REGISTER_EXE) + " " + args + " 2>" + err);
    std::ifstream in(err);
    RegisterRun r{c.status, c.out + std::string(std::istreambuf_iterator<char>(in), {})};
    std::remove(err.c_str());
    return r;
}

fs::path scratch(const std::string& name) {
    const fs::path p =
        fvr::test::tmpDir() / ("fvr_register_" + name + "_" + std::to_string(getpid()));
    fs::remove_all(p);
    fs::create_directories(p);
    return p;
}

/** fvr-render's polychromatic cone-beam X-ray of the chest phantom at `primary` degrees. */
void renderChest(const fs::path& out, double primary) {
    const auto r = runFvrRender("phantom:chest --geometry cone --size 128 --kvp 100 --threads 2 "
                                "--primary-angle " +
                                std::to_string(primary) + " --out " + out.string());
    ASSERT_EQ(r.status, 0) << r.output;
}

/** The mTRE of the pose (rx, ry, rz deg about the centre, then t) against the identity, over the
 *  corners of a 100 mm cube at the centre: R = Rz Ry Rx, worked out here without core. */
double offsetMtre(const double p[6]) {
    const double d = M_PI / 180.0;
    const double cx = std::cos(p[0] * d), sx = std::sin(p[0] * d), cy = std::cos(p[1] * d),
                 sy = std::sin(p[1] * d), cz = std::cos(p[2] * d), sz = std::sin(p[2] * d);
    const double R[3][3] = {{cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx},
                            {sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx},
                            {-sy, cy * sx, cy * cx}};
    double sum = 0.0;
    for (int k = 0; k < 8; ++k) {
        const double x[3] = {k & 1 ? 50.0 : -50.0, k & 2 ? 50.0 : -50.0, k & 4 ? 50.0 : -50.0};
        double e2 = 0.0;
        for (int i = 0; i < 3; ++i) {
            const double y = R[i][0] * x[0] + R[i][1] * x[1] + R[i][2] * x[2] + p[3 + i];
            e2 += (y - x[i]) * (y - x[i]);
        }
        sum += std::sqrt(e2);
    }
    return sum / 8.0;
}

Json readJson(const fs::path& p) {
    std::ifstream in(p);
    return Json::parse(in);
}

TEST(FvrRegister, PresetsAreLevelsOfImagePixels) {
    // A 128-pixel X-ray: "fast" works at 64 and 128 pixels across; "fine" at 64, 128 and full
    // size twice (its 256- and 512-pixel levels cannot upsample the image).
    const fs::path dir = scratch("presets");
    renderChest(dir / "ap.npy", 0.0);
    const std::vector<std::pair<std::string, std::vector<int>>> presets = {
        {"fast", {64, 128}}, {"fine", {64, 128, 128, 128}}};
    for (const auto& [preset, widths] : presets) {
        const RegisterRun r =
            runFvrRegister("phantom:chest:96 " + (dir / "ap.npy").string() + " --preset " + preset +
                           " --global 0 --offset 2,0,0,3,0,0 --threads 2 --out " +
                           (dir / (preset + ".json")).string());
        ASSERT_EQ(r.status, 0) << preset << ": " << r.output;
        const Json j = readJson(dir / (preset + ".json"));
        ASSERT_EQ(j["stages"].size(), widths.size()) << preset;
        for (std::size_t k = 0; k < widths.size(); ++k)
            EXPECT_EQ(j["stages"][k]["image_size"][0].get<int>(), widths[k]) << preset << " " << k;
    }
    const RegisterRun bad = runFvrRegister("phantom:chest:96 " + (dir / "ap.npy").string() +
                                           " --preset quick --out " + (dir / "q.json").string());
    EXPECT_NE(bad.status, 0);
    EXPECT_NE(bad.output.find("expected fast, default or fine"), std::string::npos) << bad.output;
}

TEST(FvrRegister, BiplaneFromAnOffsetFindsTheGeometrysPose) {
    const fs::path dir = scratch("biplane");
    renderChest(dir / "ap.npy", 0.0);
    renderChest(dir / "lat.npy", 90.0);
    std::ofstream(dir / "truth.json")
        << R"({"rotation_deg": [0, 0, 0], "translation_mm": [0, 0, 0]})";
    const double offset[6] = {4.0, -3.0, 5.0, 6.0, -8.0, 5.0};
    const RegisterRun r = runFvrRegister(
        "phantom:chest " + (dir / "ap.npy").string() + " " + (dir / "lat.npy").string() +
        " --truth " + (dir / "truth.json").string() + " --offset 4,-3,5,6,-8,5 --threads 2 --out " +
        (dir / "result.json").string());
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_NE(r.output.find("fvr-register: level 1"), std::string::npos) << r.output; // progress
    EXPECT_EQ(r.output.find("another volume"), std::string::npos) << r.output; // the CT's own
    const Json j = readJson(dir / "result.json");
    // The pose: a rigid 4x4 (row-major, last row 0 0 0 1), its angles, translation and centre.
    const Json& m = j["pose"]["matrix"];
    ASSERT_EQ(m.size(), 4u);
    for (const auto& row : m) ASSERT_EQ(row.size(), 4u);
    EXPECT_EQ(m[3], Json::array({0.0, 0.0, 0.0, 1.0}));
    EXPECT_EQ(j["pose"]["rotation_deg"].size(), 3u);
    EXPECT_EQ(j["pose"]["translation_mm"].size(), 3u);
    EXPECT_EQ(j["pose"]["centre_mm"], j["inputs"]["isocenter_mm"]);
    EXPECT_NE(j["pose"]["convention"].get<std::string>().find("LPS"), std::string::npos);
    // The chest phantom's centre is the origin: the offset's mTRE is the hand-worked one.
    EXPECT_EQ(j["inputs"]["isocenter_mm"], Json::array({0.0, 0.0, 0.0}));
    EXPECT_NEAR(j["evaluation"]["mtre_before_mm"].get<double>(), offsetMtre(offset), 1e-9);
    EXPECT_LT(j["evaluation"]["mtre_after_mm"].get<double>(), 2.0) << j["evaluation"].dump();
    EXPECT_TRUE(j["evaluation"]["success"].get<bool>());
    EXPECT_GT(j["similarity"]["after"].get<double>(), j["similarity"]["before"].get<double>());
    // Stages: each with its renderer, size, voxel, evaluations, DRRs (two views each), time.
    ASSERT_GE(j["stages"].size(), 2u);
    int evaluations = 0;
    for (const Json& s : j["stages"]) {
        EXPECT_FALSE(s["name"].get<std::string>().empty());
        EXPECT_NE(s["renderer"].get<std::string>().find("ray casting"), std::string::npos);
        EXPECT_EQ(s["drrs"].get<int>(), 2 * s["evaluations"].get<int>());
        EXPECT_GT(s["seconds"].get<double>(), 0.0);
        evaluations += s["evaluations"].get<int>();
    }
    EXPECT_EQ(j["evaluations"].get<int>(), evaluations);
    EXPECT_EQ(j["history"].size(), std::size_t(evaluations));
    ASSERT_EQ(j["inputs"]["xrays"].size(), 2u);
    EXPECT_NE(j["inputs"]["xrays"][0]["values"].get<std::string>().find("-ln(I/I0), I0 = 1"),
              std::string::npos);
    // Overlays of each view, before and after, blend and checkerboard.
    ASSERT_EQ(j["overlays"].size(), 8u);
    for (const char* f : {"result-view1-before-blend.png", "result-view2-after-checker.png"})
        EXPECT_TRUE(fs::is_regular_file(dir / f)) << f;
    std::printf("biplane: mTRE %.3f -> %.3f mm in %.2f s, %d evaluations\n",
                j["evaluation"]["mtre_before_mm"].get<double>(),
                j["evaluation"]["mtre_after_mm"].get<double>(), j["seconds"].get<double>(),
                evaluations);
}

TEST(FvrRegister, OneDicomXaFromAnOffset) {
    // fvr-render's XA (line integrals, LOG, its C-arm and isocentre in the file), one view.
    const fs::path dir = scratch("dicom");
    const auto rr = runFvrRender("phantom:chest --geometry cone --size 128 --values mu "
                                 "--primary-angle 20 --threads 2 --out " +
                                 (dir / "xa.dcm").string());
    ASSERT_EQ(rr.status, 0) << rr.output;
    const RegisterRun r =
        runFvrRegister("phantom:chest " + (dir / "xa.dcm").string() +
                       " --offset 0,0,3,4,0,-4 --threads 2 --overlay-prefix " +
                       (dir / "ov").string() + " --out " + (dir / "r.json").string());
    ASSERT_EQ(r.status, 0) << r.output;
    const Json j = readJson(dir / "r.json");
    EXPECT_NE(j["inputs"]["xrays"][0]["values"].get<std::string>().find("line integrals"),
              std::string::npos);
    // No truth: no evaluation; the pose near the identity all the same (mTRE about it < 2 mm).
    EXPECT_FALSE(j.contains("evaluation"));
    const double p[6] = {j["pose"]["rotation_deg"][0],   j["pose"]["rotation_deg"][1],
                         j["pose"]["rotation_deg"][2],   j["pose"]["translation_mm"][0],
                         j["pose"]["translation_mm"][1], j["pose"]["translation_mm"][2]};
    EXPECT_LT(offsetMtre(p), 2.0) << j["pose"].dump();
    for (const char* f : {"ov-before-blend.png", "ov-after-blend.png", "ov-before-checker.png",
                          "ov-after-checker.png"})
        EXPECT_TRUE(fs::is_regular_file(dir / f)) << f;
}

TEST(FvrRegister, BadInputIsRefusedBeforeAnyWork) {
    const fs::path dir = scratch("refusals");
    renderChest(dir / "ap.npy", 0.0);
    const auto sl = runFvrRender("phantom:shepp-logan:64 --geometry cone --size 64 --values mu "
                                 "--out " +
                                 (dir / "sl.npy").string());
    ASSERT_EQ(sl.status, 0) << sl.output;
    fs::copy_file(dir / "ap.npy", dir / "bare.npy");
    // An XA without its SID (nor the magnification that would give it).
    const auto xa = runFvrRender("phantom:chest --geometry cone --size 64 --values mu --out " +
                                 (dir / "nosid.dcm").string());
    ASSERT_EQ(xa.status, 0) << xa.output;
    DcmFileFormat ff;
    ASSERT_TRUE(ff.loadFile((dir / "nosid.dcm").c_str()).good());
    ff.loadAllDataIntoMemory(); // the file is written over
    ff.getDataset()->findAndDeleteElement(DCM_DistanceSourceToDetector);
    ff.getDataset()->findAndDeleteElement(DCM_EstimatedRadiographicMagnificationFactor);
    ASSERT_TRUE(ff.saveFile((dir / "nosid.dcm").c_str(), EXS_LittleEndianExplicit).good());
    std::ofstream(dir / "bad.json") << R"({"rotation_deg": [1, 2], "translation_mm": [0, 0, 0]})";
    const std::string ap = (dir / "ap.npy").string(), out = " --out " + (dir / "r.json").string();
    const struct {
        std::string args, message;
    } cases[] = {
        {ap + " --init " + (dir / "bad.json").string() + out,
         "bad.json: \"rotation_deg\" must be an array of 3 numbers"},
        {(dir / "bare.npy").string() + out, "bare.npy: no camera sidecar bare.npy.json"},
        {(dir / "nosid.dcm").string() + out,
         "nosid.dcm: DistanceSourceToDetector (0018,1110) missing: a registration needs"},
        {ap + " " + (dir / "sl.npy").string() + out, "sl.npy: images of different frames"},
        {ap + " --out " + (dir / "none" / "r.json").string(), "does not exist"},
        {ap + " --targets " + (dir / "none.csv").string() + out, "none.csv"},
        {ap + " --offset 1,2,3" + out, "--offset '1,2,3': expected 6 comma-separated numbers"},
        {ap + " --levels 64:4" + out, "is not PIXELS:VOXELMM:EVALS"},
        {ap + " --values raw" + out, "expected auto, line-integrals or intensity"},
    };
    for (const auto& c : cases) {
        const RegisterRun r = runFvrRegister("phantom:chest " + c.args);
        EXPECT_EQ(r.status, 2) << c.args << "\n" << r.output;
        EXPECT_NE(r.output.find(c.message), std::string::npos) << c.args << "\n" << r.output;
        EXPECT_EQ(r.output.find("level 1"), std::string::npos) << r.output; // no registration
        EXPECT_FALSE(fs::exists(dir / "r.json"));
        EXPECT_FALSE(fs::exists(dir / "r-before-blend.png"));
    }
}

} // namespace
