// FFTW planning policy (fftw_planning.h): estimate plans at once, measured plans made on the
// background planner, saved as wisdom and swapped in; the images do not change beyond float
// rounding. Every test points FVR_FFTW_WISDOM at a fresh file (CTest runs each test in its own
// process, so FFTW starts without wisdom).
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/render/fftw_planning.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/xray/phantom.h>

#include "image_metrics.h"
#include "phantom_fixture.h"
#include "test_support.h"

using namespace fvr::core;

namespace {

/** A fresh wisdom file for this test (removed first), named after the test. */
std::filesystem::path freshWisdom() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    const auto dir = fvr::test::tmpDir() / "fftw_planning";
    std::filesystem::create_directories(dir);
    const auto p = dir / (std::string(info->name()) + ".wisdom");
    std::filesystem::remove(p);
    ::setenv("FVR_FFTW_WISDOM", p.c_str(), 1);
    return p;
}

std::string readFile(const std::filesystem::path& p) {
    std::ifstream in(p);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

std::shared_ptr<const Spectrum> phantomSpectrum(TransformKind t, PlannerEffort effort,
                                                const Volume& v, double oversampling = 1.0) {
    PreprocessOptions o;
    o.effort = effort;
    o.transform = t;
    o.mapping = ValueMapping::Mu;
    o.oversampling = oversampling;
    return preprocess(v, o);
}

/** max |a - b| relative to max |b|: the two plans' roundings differ, nothing else. */
double relativeDifference(const std::vector<float>& a, const std::vector<float>& b) {
    const auto c = fvr::test::compare(a, b);
    return c.maxAbsError / c.peak;
}

} // namespace

// A size no plan was made for: the renderer plans ESTIMATE at once, the background planner makes
// the measured plan and writes the wisdom file; the next frame uses the measured plan (same image
// to float rounding) and a new renderer plans from wisdom without queueing anything. The counts
// and the file are checked in a process of its own (CTest), where no plan was made before.
TEST(FftwPlanning, BackgroundPlanIsSavedAndSwappedIn) {
    const auto wisdom = freshWisdom();
    setFftwPlanning(FftwPlanning::Background);
    finishBackgroundPlanning();
    const bool fresh = backgroundPlansMade() == 0;
    const fvr::test::PhantomFixture fx;
    const ViewFrame view = ViewFrame::fromDirUp({0.3, 1, 0.2}, {0, 0, 1});
    for (auto t : {TransformKind::Fft, TransformKind::Fht}) {
        const auto s = phantomSpectrum(t, PlannerEffort::Estimate, fx.volume);
        const ImageGeometry geometry{64, fx.d * fx.kM / 64.0};
        CpuFourierRenderer r(s, 2);
        const int before = backgroundPlansMade();
        const auto estimated = r.render({view, geometry, Kernel::Linear});
        finishBackgroundPlanning();
        if (fresh) {
            EXPECT_EQ(backgroundPlansMade(), before + 1) << transformName(t);
            ASSERT_TRUE(std::filesystem::exists(wisdom)) << transformName(t);
            EXPECT_NE(readFile(wisdom).find("fftwf_wisdom"), std::string::npos);
        }
        const auto measured = r.render({view, geometry, Kernel::Linear});
        EXPECT_LT(relativeDifference(estimated.pixels, measured.pixels), 1e-5) << transformName(t);

        CpuFourierRenderer fromWisdom(s, 2);
        const auto again = fromWisdom.render({view, geometry, Kernel::Linear});
        finishBackgroundPlanning();
        if (fresh) {
            EXPECT_EQ(backgroundPlansMade(), before + 1) << "the plan came from wisdom";
        }
        EXPECT_EQ(again.pixels, measured.pixels) << "the same measured plan, the same image";
    }
}

// The 3D transform of a study: ESTIMATE plans at once when wisdom has none, the measured plans
// made in the background; a second preprocess plans from that wisdom. Both spectra agree to
// float rounding.
TEST(FftwPlanning, PreprocessMeasuresInBackground) {
    freshWisdom();
    setFftwPlanning(FftwPlanning::Background);
    setPlannerQuietPeriod(std::chrono::milliseconds(0)); // no need to wait between steps
    finishBackgroundPlanning();
    const bool fresh = backgroundPlansMade() == 0; // a process of its own (CTest)
    const Volume v = makeSheppLoganVolume(36);
    for (auto method : {HartleyMethod::FromFft, HartleyMethod::Dht}) {
        PreprocessOptions o;
        o.transform = TransformKind::Fht;
        o.hartleyMethod = method;
        o.oversampling = 1.3; // 48^3 padded: a size nothing else here plans
        const int before = backgroundPlansMade();
        const auto a = preprocess(v, o);
        finishBackgroundPlanning();
        if (fresh) {
            EXPECT_EQ(backgroundPlansMade(), before + 1);
        }
        const auto b = preprocess(v, o);
        finishBackgroundPlanning();
        if (fresh) {
            EXPECT_EQ(backgroundPlansMade(), before + 1) << "planned from wisdom";
        }
        double peak = 0, err = 0;
        const auto& P = a->padded;
        for (std::int64_t z = 0; z < P[2]; ++z)
            for (std::int64_t y = 0; y < P[1]; ++y)
                for (std::int64_t x = 0; x < P[0]; ++x) {
                    peak = std::max(peak, std::abs(a->hartleyAt(x, y, z)));
                    err = std::max(err, std::abs(a->hartleyAt(x, y, z) - b->hartleyAt(x, y, z)));
                }
        EXPECT_LT(err / peak, 1e-5);
    }
    setPlannerQuietPeriod(std::chrono::milliseconds(2000));
}

// Estimate and measured plans against the analytic line integrals of the accuracy fixture: both
// above the accuracy test's floor (Catmull-Rom, oversampling 2: 40 dB), the same PSNR to a
// hundredth of a dB, and the images equal to float rounding.
TEST(FftwPlanning, EstimateAndMeasuredPlansGiveTheSameAccuracy) {
    freshWisdom();
    const fvr::test::PhantomFixture fx;
    const ViewFrame view = ViewFrame::fromDirUp({0.8, -0.45, 0.4}, {0, 0, 1});
    const ImageGeometry geometry{fx.kM, fx.d};
    const RenderParams params{view, geometry, Kernel::CatmullRom};
    const auto truth =
        fx.phantom.project(view, geometry, ValueMapping::Mu, fx.volume.dims, fx.volume.spacing);
    for (auto t : {TransformKind::Fft, TransformKind::Fht}) {
        setFftwPlanning(FftwPlanning::EstimateOnly);
        CpuFourierRenderer estimate(phantomSpectrum(t, PlannerEffort::Measure, fx.volume, 2.0), 2);
        const auto e = estimate.render(params);
        setFftwPlanning(FftwPlanning::Foreground);
        CpuFourierRenderer measure(phantomSpectrum(t, PlannerEffort::Measure, fx.volume, 2.0), 2);
        const auto m = measure.render(params);
        const double pe = fvr::test::compare(e.pixels, truth.pixels).psnr;
        const double pm = fvr::test::compare(m.pixels, truth.pixels).psnr;
        EXPECT_GT(pe, 40.0) << transformName(t);
        EXPECT_GT(pm, 40.0) << transformName(t);
        EXPECT_NEAR(pe, pm, 0.01) << transformName(t);
        EXPECT_LT(relativeDifference(e.pixels, m.pixels), 1e-5) << transformName(t);
    }
    setFftwPlanning(FftwPlanning::Background);
}

// Renderers on several threads (one each) while the background planner makes their plans and
// they swap them in: every frame equals the single-threaded reference to float rounding.
// Run it repeatedly (--gtest_repeat) and under the sanitizers to look for races.
TEST(FftwPlanning, RenderersOnThreadsWhileThePlannerSwaps) {
    freshWisdom();
    setFftwPlanning(FftwPlanning::Background);
    const fvr::test::PhantomFixture fx;
    setPlannerQuietPeriod(std::chrono::milliseconds(0)); // measure while the threads render
    const auto s = phantomSpectrum(TransformKind::Fht, PlannerEffort::Estimate, fx.volume);
    const int sizes[] = {32, 64, 256};
    std::vector<ViewFrame> views;
    for (int i = 0; i < 12; ++i)
        views.push_back(
            ViewFrame::fromDirUp({std::cos(0.5 * i), std::sin(0.5 * i), 0.3}, {0, 0, 1}));
    std::vector<std::vector<std::vector<float>>> ref(std::size(sizes));
    {
        setFftwPlanning(FftwPlanning::EstimateOnly);
        CpuFourierRenderer r(s, 1);
        for (std::size_t k = 0; k < std::size(sizes); ++k)
            for (const auto& v : views)
                ref[k].push_back(r.render({v, {sizes[k], fx.d * fx.kM / sizes[k]}}).pixels);
        setFftwPlanning(FftwPlanning::Background);
    }
    finishBackgroundPlanning();
    const int before = backgroundPlansMade();
    std::vector<double> worst(std::size(sizes), 0.0);
    std::vector<std::thread> threads;
    for (std::size_t k = 0; k < std::size(sizes); ++k)
        threads.emplace_back([&, k] {
            CpuFourierRenderer r(s, 1);
            for (int pass = 0; pass < 3; ++pass)
                for (std::size_t i = 0; i < views.size(); ++i) {
                    const auto img = r.render({views[i], {sizes[k], fx.d * fx.kM / sizes[k]}});
                    worst[k] = std::max(worst[k], relativeDifference(img.pixels, ref[k][i]));
                }
        });
    for (auto& t : threads) t.join();
    finishBackgroundPlanning();
    if (before == 0) { // a fresh process (CTest); a repetition finds the plans in wisdom
        EXPECT_EQ(backgroundPlansMade(), int(std::size(sizes)));
    }
    for (std::size_t k = 0; k < std::size(sizes); ++k) EXPECT_LT(worst[k], 1e-5) << sizes[k];
    setPlannerQuietPeriod(std::chrono::milliseconds(2000));
}
