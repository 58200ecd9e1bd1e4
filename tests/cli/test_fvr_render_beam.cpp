// fvr-render --beam and --rtplan (treatment beams, IEC 61217) against cases worked out by hand: a
// blob left of and above the isocentre lands where the beam's eye view puts it (magnified
// SID/SAD, the columns +Xb, the rows -Yb) for HFS and FFS; an RT Plan written here with DCMTK
// gives one view per beam, each the image of the same beam given by hand; the sidecar records
// the beams; every bad beam option or plan is refused, naming it, before the input loads.
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

#include <fvr/core/dicom/xray_geometry.h>
#include <fvr/core/io/image_io.h>

#include "cli_support.h"
#include "support/rt_plan_writer.h"
#include "test_support.h"

namespace {

using Json = nlohmann::json;

std::string tmp(const std::string& name) {
    // Of this process: ctest runs each test in a process of its own, in parallel, and two tests
    // writing the same file (a volume one of them is reading) would race.
    return (fvr::test::tmpDir() / ("beam_" + std::to_string(getpid()) + "_" + name)).string();
}

using Result = fvr::test::RenderResult;
Result run(const std::string& args) { return fvr::test::runFvrRender(args); }

/** A 64 x 32 x 48 float32 MetaImage of 1 mm voxels centred on the LPS origin, zero but for a
 *  3 mm cube at (20, 0, 10): 20 mm to the patient's left, 10 mm toward the head. */
std::string blobVolume() {
    const int nx = 64, ny = 32, nz = 48;
    const std::string raw = tmp("blob.raw"), mhd = tmp("blob.mhd");
    std::vector<float> v(std::size_t(nx) * ny * nz);
    const double ox = -(nx - 1) / 2.0, oy = -(ny - 1) / 2.0, oz = -(nz - 1) / 2.0;
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const double x = ox + i, y = oy + j, z = oz + k;
                v[std::size_t(i) + std::size_t(nx) * (j + std::size_t(ny) * k)] =
                    std::abs(x - 20) <= 1 && std::abs(y) <= 1 && std::abs(z - 10) <= 1 ? 1.f : 0.f;
            }
    std::ofstream(raw, std::ios::binary)
        .write(reinterpret_cast<const char*>(v.data()), std::streamsize(v.size() * 4));
    std::ofstream(mhd) << "ObjectType = Image\nNDims = 3\nDimSize = " << nx << " " << ny << " "
                       << nz << "\nElementSpacing = 1 1 1\nOffset = " << ox << " " << oy << " "
                       << oz << "\nTransformMatrix = 1 0 0 0 1 0 0 0 1\n"
                       << "ElementType = MET_FLOAT\nElementDataFile = "
                       << std::filesystem::path(raw).filename().string() << "\n";
    return mhd;
}

/** The centroid (col, row) of an image's values (one view of `img` from `offset`). */
std::pair<double, double> centroid(const std::vector<float>& img, int w, int h,
                                   std::size_t offset = 0) {
    double s = 0, sc = 0, sr = 0;
    for (int r = 0; r < h; ++r)
        for (int c = 0; c < w; ++c) {
            const double v = img[offset + std::size_t(r) * w + c];
            s += v;
            sc += v * c;
            sr += v * r;
        }
    return {sc / s, sr / s};
}

const std::string kDetector = " --geometry cone --detector-size 256x192 --pitch 0.5 ";

/** The blob's image centroid for a beam's options. */
std::pair<double, double> blobCentroid(const std::string& beamArgs) {
    const std::string out = tmp("blob.npy");
    const Result r = run(blobVolume() + kDetector + beamArgs + " --out " + out);
    EXPECT_EQ(r.status, 0) << beamArgs << ": " << r.output;
    std::vector<std::int64_t> shape;
    const auto img = fvr::core::readNpy(out, shape);
    EXPECT_EQ(shape, (std::vector<std::int64_t>{192, 256}));
    return centroid(img, 256, 192);
}

TEST(FvrRenderBeam, TheBlobLandsWhereTheBeamsEyeViewPutsIt) {
    // Gantry 0 for HFS: the source anterior at SAD 1000, the imager at SID 1500 under the couch;
    // seen from the source the columns run to the patient's left, the rows to the feet. The
    // blob at the isocentre's depth is magnified 1.5: 2 x 20 x 1.5 = 60 pixels right of the
    // centre (127.5) and 30 above it (95.5).
    auto [col, row] = blobCentroid("--beam 0,0,0");
    EXPECT_NEAR(col, 127.5 + 60, 0.02);
    EXPECT_NEAR(row, 95.5 - 30, 0.02);
    // Gantry 180 (PA): seen from below, the patient's left is on the left.
    std::tie(col, row) = blobCentroid("--beam 180,0,0");
    EXPECT_NEAR(col, 127.5 - 60, 0.02);
    EXPECT_NEAR(row, 95.5 - 30, 0.02);
    // Gantry 90: the source at the patient's left; the blob on the beam axis, 20 mm nearer the
    // source: magnified 1500 / 980.
    std::tie(col, row) = blobCentroid("--beam 90,0,0");
    EXPECT_NEAR(col, 127.5, 0.02);
    EXPECT_NEAR(row, 95.5 - 2 * 10 * 1500.0 / 980, 0.02);
    // FFS: +Xf is the patient's right, so gantry 90's source is there and the blob 20 mm
    // farther; the rows (-Yf) run to the head.
    std::tie(col, row) = blobCentroid("--beam 90,0,0 --patient-position FFS");
    EXPECT_NEAR(col, 127.5, 0.02);
    EXPECT_NEAR(row, 95.5 + 2 * 10 * 1500.0 / 1020, 0.02);
    // Another SAD and SID: magnified 1200 / 800 = 1.5 again, at gantry 0 with collimator 90
    // (the columns to the head, the rows to the patient's left).
    std::tie(col, row) = blobCentroid("--beam 0,0,90 --sad 800 --sid 1200");
    EXPECT_NEAR(col, 127.5 + 30, 0.02);
    EXPECT_NEAR(row, 95.5 + 60, 0.02);
}

TEST(FvrRenderBeam, AnRtPlanGivesOneViewPerBeamEachTheImageOfTheSameBeamByHand) {
    fvr::test::TestPlan plan;
    plan.setups = {{1, "HFS"}};
    fvr::test::TestBeam a, b;
    a.number = 2;
    a.name = "AP";
    a.gantry = "0";
    b.number = 5;
    b.name = "LAO";
    b.gantry = "45";
    b.couch = "10";
    b.collimator = "15";
    b.isocentre = "2\\-3\\4";
    plan.beams = {a, b};
    const std::string planFile = tmp("plan.dcm");
    fvr::test::writeTestRtPlan(planFile, plan);
    const std::string vol = blobVolume(), stack = tmp("plan.npy");
    const Result r = run(vol + kDetector + "--rtplan " + planFile + " --out " + stack);
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    const auto views = fvr::core::readNpy(stack, shape);
    ASSERT_EQ(shape, (std::vector<std::int64_t>{2, 192, 256}));
    const Json side = fvr::test::readSidecar(stack);
    EXPECT_EQ(side["settings"]["rtplan"], planFile);
    ASSERT_EQ(side["views"].size(), 2u);
    const Json& tb = side["views"][1]["treatment_beam"];
    EXPECT_EQ(tb["beam_number"], 5);
    EXPECT_EQ(tb["beam_name"], "LAO");
    EXPECT_EQ(tb["gantry_angle_deg"], 45.0);
    EXPECT_EQ(tb["couch_angle_deg"], 10.0);
    EXPECT_EQ(tb["collimator_angle_deg"], 15.0);
    EXPECT_EQ(tb["sad_mm"], 1000.0);
    EXPECT_EQ(tb["sid_mm"], 1500.0);
    EXPECT_EQ(tb["isocenter_mm"], Json::array({2.0, -3.0, 4.0}));
    EXPECT_EQ(tb["patient_position"], "HFS");
    EXPECT_EQ(side["views"][0]["treatment_beam"]["beam_number"], 2);
    // Each view equals the image of its beam given by hand.
    const std::pair<std::string, std::size_t> byHand[] = {
        {"--beam 0,0,0 --isocenter 0,0,0", 0}, {"--beam 45,10,15 --isocenter 2,-3,4", 1}};
    for (const auto& [args, k] : byHand) {
        const std::string one = tmp("hand.npy");
        const Result h = run(vol + kDetector + args + " --out " + one);
        ASSERT_EQ(h.status, 0) << h.output;
        const auto img = fvr::core::readNpy(one, shape);
        ASSERT_EQ(img.size(), std::size_t(192 * 256));
        const std::vector<float> view(views.begin() + std::ptrdiff_t(k * img.size()),
                                      views.begin() + std::ptrdiff_t((k + 1) * img.size()));
        EXPECT_EQ(view, img) << args;
    }
    // --beam-number picks one beam.
    const std::string single = tmp("plan5.npy");
    const Result s =
        run(vol + kDetector + "--rtplan " + planFile + " --beam-number 5 --out " + single);
    ASSERT_EQ(s.status, 0) << s.output;
    const auto five = fvr::core::readNpy(single, shape);
    EXPECT_EQ(shape, (std::vector<std::int64_t>{192, 256}));
    EXPECT_EQ(five, std::vector<float>(views.begin() + 192 * 256, views.end()));
}

TEST(FvrRenderBeam, BadBeamsAndPlansAreRefusedBeforeTheInputLoads) {
    const std::string none = "/no/such/volume.mhd --out " + tmp("x.npy") + " ";
    fvr::test::TestPlan noGantry;
    noGantry.beams[0].gantry.reset();
    noGantry.beams[0].number = 3;
    const std::string badPlan = tmp("no_gantry.dcm"), goodPlan = tmp("good.dcm");
    fvr::test::writeTestRtPlan(badPlan, noGantry);
    fvr::test::writeTestRtPlan(goodPlan, fvr::test::TestPlan{});
    const std::pair<std::string, std::string> cases[] = {
        {"--beam 0,0,0", "--beam: only with --geometry cone"},
        {"--geometry cone --beam 0,0", "expected GANTRY,COUCH,COLL"},
        {"--geometry cone --beam 0,0,0 --primary-angle 30", "--primary-angle: not with --beam"},
        {"--geometry cone --beam 0,0,0 --sod 700", "--sod: not with --beam"},
        {"--geometry cone --beam 0,0,0 --sweep 4", "--sweep: not with --beam"},
        {"--geometry cone --beam 0,0,0 --sid 900", "SAD 1000 mm, SID 900 mm"},
        {"--geometry cone --beam 0,0,0 --sad 0", "--sad: expected a positive number"},
        {"--geometry cone --beam 0,0,0 --patient-position SITTING", "'SITTING'"},
        {"--geometry cone --sad 900", "--sad: only with --beam"},
        {"--geometry cone --beam-number 2", "--beam-number: only with --rtplan"},
        {"--geometry cone --beam 0,0,0 --beam-number 2", "--beam-number: only with --rtplan"},
        {"--geometry cone --rtplan " + goodPlan + " --beam 0,0,0", "--beam: not with --rtplan"},
        {"--geometry cone --rtplan " + goodPlan + " --sad 900", "--sad: not with --rtplan"},
        {"--geometry cone --rtplan " + goodPlan + " --isocenter 0,0,0",
         "--isocenter: not with --rtplan"},
        {"--geometry cone --rtplan /no/such/plan.dcm", "/no/such/plan.dcm"},
        {"--geometry cone --rtplan " + badPlan, badPlan + ": beam number 3"},
        {"--geometry cone --rtplan " + badPlan, "GantryAngle (300a,011e)"},
        {"--geometry cone --rtplan " + goodPlan + " --beam-number 9",
         "has no such beam (its beams: 1)"},
        {"--geometry cone --rtplan " + goodPlan + " --sid 800", "SAD 1000 mm, SID 800 mm"},
    };
    for (const auto& [args, expect] : cases) {
        const Result r = run(none + args);
        EXPECT_EQ(r.status, 2) << args << ": " << r.output;
        EXPECT_NE(r.output.find(expect), std::string::npos) << args << ": " << r.output;
        EXPECT_EQ(r.output.find("/no/such/volume.mhd"), std::string::npos)
            << args << ": " << r.output;
    }
}

/** The largest |a - b| of two images. */
double maxDifference(const std::vector<float>& a, const float* b) {
    double d = 0;
    for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, double(std::abs(a[i] - b[i])));
    return d;
}

/** The largest difference of two views' projection matrices (the sidecar's), each scaled to
 *  unit norm. */
double matrixDifference(const Json& a, const Json& b) {
    double na = 0, nb = 0, d = 0;
    for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 4; ++k) {
            na += std::pow(a["projection_matrix"][r][k].get<double>(), 2);
            nb += std::pow(b["projection_matrix"][r][k].get<double>(), 2);
        }
    for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 4; ++k)
            d = std::max(d, std::abs(a["projection_matrix"][r][k].get<double>() / std::sqrt(na) -
                                     b["projection_matrix"][r][k].get<double>() / std::sqrt(nb)));
    return d;
}

TEST(FvrRenderBeam, DicomOutputIsOneRtImagePerBeamThatReadsBackToTheSameImage) {
    // Two beams of a plan (the second with couch and collimator turned) as .dcm: one RT Image
    // each (FILE_NNNN.dcm), its pixels the DRR, its geometry the beam's, and --geometry-from
    // each file renders the same image again.
    fvr::test::TestPlan plan;
    fvr::test::TestBeam a, b;
    a.number = 2;
    a.name = "AP";
    a.gantry = "0";
    b.number = 5;
    b.name = "LAO";
    b.gantry = "45";
    b.couch = "10";
    b.collimator = "15";
    b.isocentre = "2\\-3\\4";
    plan.beams = {a, b};
    const std::string planFile = tmp("dcm_plan.dcm");
    fvr::test::writeTestRtPlan(planFile, plan);
    const std::string vol = blobVolume(), stack = tmp("dcm_plan.npy"), dcm = tmp("beams.dcm");
    const std::string args = vol + kDetector + "--rtplan " + planFile + " --out ";
    ASSERT_EQ(run(args + stack).status, 0);
    const Result w = run(args + dcm);
    ASSERT_EQ(w.status, 0) << w.output;
    const std::string files[] = {tmp("beams_0000.dcm"), tmp("beams_0001.dcm")};
    EXPECT_EQ(fvr::test::readSidecar(dcm)["output"]["files"], Json::array({files[0], files[1]}));
    EXPECT_FALSE(std::filesystem::exists(dcm)); // one file per beam, none unnumbered
    std::vector<std::int64_t> shape;
    const auto views = fvr::core::readNpy(stack, shape);
    ASSERT_EQ(shape, (std::vector<std::int64_t>{2, 192, 256}));
    const std::size_t n = 192 * 256;
    const double gantry[] = {0, 45}, couch[] = {0, 10}, coll[] = {0, 15};
    for (std::size_t k = 0; k < 2; ++k) {
        const fvr::core::XrayGeometry g = fvr::core::readXrayGeometry(files[k]);
        EXPECT_EQ(g.modality, "RTIMAGE");
        EXPECT_TRUE(g.warnings.empty()) << g.warnings.front();
        ASSERT_EQ(g.beams.size(), 1u);
        EXPECT_EQ(g.beams[0].gantryDeg, gantry[k]);
        EXPECT_EQ(g.beams[0].couchDeg, couch[k]);
        EXPECT_EQ(g.beams[0].collimatorDeg, coll[k]);
        // The pixels are the DRR within the 16-bit quantisation (half a step of its range).
        const std::vector<float> view(views.begin() + std::ptrdiff_t(k * n),
                                      views.begin() + std::ptrdiff_t((k + 1) * n));
        const auto [lo, hi] = std::minmax_element(view.begin(), view.end());
        ASSERT_GT(*hi, 1.0f); // the blob is in view
        ASSERT_EQ(g.pixels.size(), n);
        EXPECT_LE(maxDifference(view, g.pixels.data()), 0.5 * (*hi - *lo) / 65535 * 1.001 + 1e-6);
        // --geometry-from the RT Image: the same camera and the same image.
        const std::string back = tmp("beam_back.npy");
        const Result r =
            run(vol + " --geometry cone --geometry-from " + files[k] + " --out " + back);
        ASSERT_EQ(r.status, 0) << r.output;
        EXPECT_EQ(r.output.find("warning"), std::string::npos) << r.output;
        const Json sb = fvr::test::readSidecar(back), sa = fvr::test::readSidecar(stack);
        EXPECT_LT(matrixDifference(sa["views"][k], sb["views"][0]), 1e-6) << k;
        EXPECT_EQ(sb["settings"]["geometry_from"]["modality"], "RTIMAGE");
        EXPECT_EQ(sb["settings"]["geometry_from"]["isocenter_from"], "the file");
        EXPECT_EQ(sb["views"][0]["treatment_beam"]["gantry_angle_deg"], gantry[k]);
        const auto again = fvr::core::readNpy(back, shape);
        ASSERT_EQ(again.size(), n);
        EXPECT_LE(maxDifference(view, again.data()), 1e-5 * *hi) << k;
    }
    if (fvr::test::runCommand("command -v dciodvfy").status == 0)
        for (const std::string& f : files) {
            const auto v = fvr::test::runCommand("dciodvfy -new '" + f + "' 2>&1");
            EXPECT_NE(v.out.find("RTImage"), std::string::npos) << v.out;
            EXPECT_EQ(v.out.find("Error"), std::string::npos) << v.out;
        }
    // The RT Image read back is written again as the same beam.
    const std::string rewritten = tmp("beam_again.dcm");
    const Result again =
        run(vol + " --geometry cone --geometry-from " + files[1] + " --out " + rewritten);
    ASSERT_EQ(again.status, 0) << again.output;
    const fvr::core::XrayGeometry g1 = fvr::core::readXrayGeometry(files[1], false),
                                  g2 = fvr::core::readXrayGeometry(rewritten, false);
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c)
            EXPECT_NEAR(g1.camera(0, {}).matrix().rows[r][c], g2.camera(0, {}).matrix().rows[r][c],
                        1e-6 * std::abs(g1.camera(0, {}).matrix().rows[2][3]));
    // One --beam: one RT Image, unnumbered, about the volume's centre (stated in the file).
    const std::string one = tmp("one_beam.dcm");
    const Result r = run(vol + kDetector + "--beam 90,0,30 --out " + one);
    ASSERT_EQ(r.status, 0) << r.output;
    const fvr::core::XrayGeometry g = fvr::core::readXrayGeometry(one, false);
    EXPECT_EQ(g.beams.at(0).gantryDeg, 90.0);
    EXPECT_EQ(g.beams.at(0).collimatorDeg, 30.0);
    EXPECT_TRUE(g.isocentreStated);
}

TEST(FvrRenderBeam, TheSidecarRecordsTheBeamAndItsP) {
    const std::string out = tmp("side.npy");
    const Result r =
        run(blobVolume() + kDetector + "--beam 30,0,0 --isocenter 1,2,3 --sid 1600 --out " + out);
    ASSERT_EQ(r.status, 0) << r.output;
    const Json side = fvr::test::readSidecar(out);
    const Json& v = side["views"][0];
    EXPECT_EQ(v["treatment_beam"]["gantry_angle_deg"], 30.0);
    EXPECT_EQ(v["treatment_beam"]["sid_mm"], 1600.0);
    EXPECT_EQ(v["treatment_beam"]["patient_position"], "HFS");
    EXPECT_FALSE(v["treatment_beam"].contains("beam_number")); // not from a plan
    EXPECT_FALSE(v.contains("c_arm"));
    // The source at gantry 30 for HFS: isocentre + 1000 (sin 30, -cos 30, 0) in LPS.
    const double s30 = 0.5, c30 = std::sqrt(3.0) / 2;
    EXPECT_NEAR(v["source_mm"][0].get<double>(), 1 + 1000 * s30, 1e-9);
    EXPECT_NEAR(v["source_mm"][1].get<double>(), 2 - 1000 * c30, 1e-9);
    EXPECT_NEAR(v["source_mm"][2].get<double>(), 3, 1e-9);
    // P maps the isocentre to the principal point.
    const Json& p = v["projection_matrix"];
    double h[3];
    for (int k = 0; k < 3; ++k)
        h[k] = p[k][0].get<double>() * 1 + p[k][1].get<double>() * 2 + p[k][2].get<double>() * 3 +
               p[k][3].get<double>();
    EXPECT_NEAR(h[0] / h[2], 127.5, 1e-9);
    EXPECT_NEAR(h[1] / h[2], 95.5, 1e-9);
    EXPECT_NEAR(h[2], 1000.0, 1e-9);
}

} // namespace
