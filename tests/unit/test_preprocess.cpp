#include <malloc.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/thread_pool.h>

using namespace fvr::core;

namespace {

Volume randomVolume(Dims3 dims, unsigned seed, Vec3 spacing = {1, 1, 1}) {
    Volume v;
    v.dims = dims;
    v.spacing = spacing;
    v.name = "random";
    v.voxels.resize(std::size_t(v.voxelCount()));
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-1000.0f, 1500.0f);
    for (float& x : v.voxels) x = u(rng);
    return v;
}

/** Independent oracle: direct DFT in double of the centred volume at signed frequency k. */
std::complex<double> naiveCentredDft(const Volume& v, const Dims3& P, std::int64_t kx,
                                     std::int64_t ky, std::int64_t kz) {
    std::complex<double> sum = 0;
    for (std::int64_t z = 0; z < v.dims[2]; ++z)
        for (std::int64_t y = 0; y < v.dims[1]; ++y)
            for (std::int64_t x = 0; x < v.dims[0]; ++x) {
                const double ph = -2.0 * std::numbers::pi *
                                  (kx * (x - (v.dims[0] - 1) / 2.0) / P[0] +
                                   ky * (y - (v.dims[1] - 1) / 2.0) / P[1] +
                                   kz * (z - (v.dims[2] - 1) / 2.0) / P[2]);
                sum += double(v.at(x, y, z)) * std::polar(1.0, ph);
            }
    return sum;
}

void checkAgainstNaive(const Volume& v, const PreprocessOptions& o) {
    auto s = preprocess(v, o);
    double maxAbs = 0, maxErr = 0;
    // Every stored frequency and a margin beyond the band on either side: the spectrum is the
    // centred DTFT there too (periodic, with the sign of the period on even voxel counts).
    const std::int64_t m[3] = {s->padded[0] / 2 + 3, s->padded[1] / 2 + 3, s->padded[2] / 2 + 3};
    for (std::int64_t kz = -m[2]; kz <= m[2]; ++kz)
        for (std::int64_t ky = -m[1]; ky <= m[1]; ++ky)
            for (std::int64_t kx = -m[0]; kx <= m[0]; ++kx) {
                const auto e = naiveCentredDft(v, s->padded, kx, ky, kz);
                const auto g = s->valueAt(kx, ky, kz);
                maxAbs = std::max(maxAbs, std::abs(e));
                maxErr = std::max(maxErr, std::abs(g - e));
                const double h = s->hartleyAt(kx, ky, kz);
                maxErr = std::max(maxErr, std::abs(h - (e.real() - e.imag())));
            }
    EXPECT_LT(maxErr / maxAbs, 2e-6) << "dims " << v.dims[0] << "x" << v.dims[1] << "x" << v.dims[2]
                                     << " transform " << transformName(o.transform);
}

} // namespace

TEST(Preprocess, NextFftSize) {
    EXPECT_EQ(nextFftSize(1), 1);
    EXPECT_EQ(nextFftSize(113), 120);
    EXPECT_EQ(nextFftSize(128), 128);
    EXPECT_EQ(nextFftSize(131), 135);
    EXPECT_EQ(nextFftSize(140), 140);
    EXPECT_EQ(nextFftSize(257), 270);
}

TEST(Preprocess, PaddedDims) {
    PreprocessOptions o;
    EXPECT_EQ(paddedDimsFor({100, 64, 33}, o), (Dims3{100, 64, 35}));
    o.oversampling = 1.5;
    EXPECT_EQ(paddedDimsFor({100, 64, 33}, o), (Dims3{150, 96, 50}));
    o.oversampling = 2.0;
    EXPECT_EQ(paddedDimsFor({100, 64, 33}, o), (Dims3{200, 128, 70}));
    o.oversampling = 2.5;
    EXPECT_THROW(paddedDimsFor({100, 64, 33}, o), SettingsError);
    o.oversampling = 0.9;
    EXPECT_THROW(paddedDimsFor({100, 64, 33}, o), SettingsError);
    o.paddedDims = Dims3{99, 64, 33};
    EXPECT_THROW(paddedDimsFor({100, 64, 33}, o), SettingsError);
    EXPECT_EQ(spectrumBytes({128, 128, 128}), std::size_t(130) * 128 * 128 * 4);
}

TEST(Preprocess, FftMatchesDirectDftInDouble) {
    PreprocessOptions o;
    o.effort = PlannerEffort::Estimate;
    checkAgainstNaive(randomVolume({7, 5, 6}, 1), o); // odd and even, P = N
    o.oversampling = 1.5;
    checkAgainstNaive(randomVolume({6, 8, 5}, 2), o); // padded, even N with half-voxel phase
    o.paddedDims = Dims3{9, 10, 12};
    checkAgainstNaive(randomVolume({8, 7, 9}, 3), o); // even N inside odd P
    o.paddedDims.reset();
    o.oversampling = 1.0;
    checkAgainstNaive(randomVolume({37, 4, 6}, 8), o); // rows of 38 floats: two column blocks
}

TEST(Preprocess, HartleyBothMethodsMatchDirectDft) {
    for (auto method : {HartleyMethod::FromFft, HartleyMethod::Dht}) {
        PreprocessOptions o;
        o.effort = PlannerEffort::Estimate;
        o.transform = TransformKind::Fht;
        o.hartleyMethod = method;
        checkAgainstNaive(randomVolume({7, 6, 5}, 4), o);
        o.oversampling = 1.4;
        checkAgainstNaive(randomVolume({6, 8, 7}, 5), o);
        o.oversampling = 1.0;
        checkAgainstNaive(randomVolume({37, 4, 5}, 9), o); // two column blocks
    }
}

TEST(Preprocess, HartleyMethodsAgreeOnLargerVolume) {
    // FFTW_DHT + eq. 5 correction versus Re F - Im F: the same spectrum to float precision.
    const Volume v = randomVolume({40, 37, 30}, 6);
    PreprocessOptions o;
    o.effort = PlannerEffort::Estimate;
    o.transform = TransformKind::Fht;
    o.oversampling = 1.25;
    o.hartleyMethod = HartleyMethod::FromFft;
    auto a = preprocess(v, o);
    o.hartleyMethod = HartleyMethod::Dht;
    auto b = preprocess(v, o);
    ASSERT_EQ(a->padded, b->padded);
    double maxAbs = 0, maxErr = 0;
    for (std::int64_t z = 0; z < a->padded[2]; ++z)
        for (std::int64_t y = 0; y < a->padded[1]; ++y)
            for (std::int64_t x = 0; x < a->padded[0]; ++x) {
                maxAbs = std::max(maxAbs, std::abs(a->hartleyAt(x, y, z)));
                maxErr = std::max(maxErr, std::abs(a->hartleyAt(x, y, z) - b->hartleyAt(x, y, z)));
            }
    EXPECT_LT(maxErr / maxAbs, 1e-5);
}

TEST(Preprocess, MuMapping) {
    Volume v = randomVolume({5, 5, 5}, 7);
    v.voxels[0] = -1000.0f;
    v.voxels[1] = -2000.0f; // below air: clipped to 0
    v.voxels[2] = 1000.0f; // 2x water
    PreprocessOptions o;
    o.effort = PlannerEffort::Estimate;
    o.mapping = ValueMapping::Mu;
    auto s = preprocess(v, o);
    double dc = 0;
    for (float x : v.voxels) dc += std::max(0.0, 1.0 + x / 1000.0);
    EXPECT_NEAR(s->valueAt(0, 0, 0).real(), dc, 1e-5 * dc);
}

TEST(Preprocess, ProgressIsMonotoneAndComplete) {
    const Volume v = randomVolume({48, 40, 36}, 8);
    for (auto t : {TransformKind::Fft, TransformKind::Fht}) {
        PreprocessOptions o;
        o.effort = PlannerEffort::Estimate;
        o.transform = t;
        o.hartleyMethod = HartleyMethod::Dht;
        std::vector<double> seen;
        std::vector<std::string> stages;
        preprocess(v, o, [&](double f, std::string_view stage) {
            seen.push_back(f);
            if (stages.empty() || stages.back() != stage) stages.emplace_back(stage);
        });
        ASSERT_GE(seen.size(), 10u);
        for (std::size_t i = 1; i < seen.size(); ++i) EXPECT_GE(seen[i], seen[i - 1]);
        EXPECT_DOUBLE_EQ(seen.back(), 1.0);
        EXPECT_GE(stages.size(), 4u);
    }
}

TEST(Preprocess, CancelStopsAndFreesMemory) {
    const Volume v = randomVolume({96, 96, 96}, 9);
    PreprocessOptions o;
    o.effort = PlannerEffort::Estimate;
    o.oversampling = 2.0; // spectrum ~ 28 MB
    const auto before = mallinfo2().uordblks;
    CancelToken token;
    double lastSeen = 0;
    EXPECT_THROW(preprocess(
                     v, o,
                     [&](double f, std::string_view stage) {
                         lastSeen = f;
                         if (stage.find("columns") != std::string_view::npos) token.cancel();
                     },
                     &token),
                 Cancelled);
    EXPECT_LT(lastSeen, 0.95);
    const auto after = mallinfo2().uordblks;
    // The padded buffer (> 25 MB) must be gone when the exception arrives.
    EXPECT_LT(double(after) - double(before), 2.0e6);
}

TEST(Preprocess, JobRunsInBackgroundAndCancels) {
    auto v = std::make_shared<Volume>(randomVolume({64, 64, 64}, 10));
    PreprocessOptions o;
    o.effort = PlannerEffort::Estimate;
    {
        PreprocessJob job(v, o);
        auto s = job.get();
        ASSERT_TRUE(s);
        EXPECT_TRUE(job.finished());
        EXPECT_DOUBLE_EQ(job.fraction(), 1.0);
        EXPECT_EQ(s->padded, (Dims3{64, 64, 64}));
    }
    {
        o.oversampling = 2.0;
        PreprocessJob job(v, o);
        job.cancel();
        EXPECT_THROW(job.get(), Cancelled);
    }
}

TEST(Preprocess, RejectsInconsistentVolume) {
    Volume v = randomVolume({4, 4, 4}, 11);
    v.voxels.pop_back();
    EXPECT_THROW(preprocess(v, {}), SettingsError);
}

TEST(ThreadPool, ExceptionsPropagateAndThePoolStaysUsable) {
    fvr::core::ThreadPool pool(2);
    for (int i = 0; i < 5000; ++i) {
        EXPECT_THROW(pool.parallelFor(64, 1,
                                      [&](std::int64_t b, std::int64_t) {
                                          if (b == 3) throw std::runtime_error("boom");
                                      }),
                     std::runtime_error);
        std::atomic<int> n{0};
        pool.parallelFor(64, 1, [&](std::int64_t b, std::int64_t e) { n += int(e - b); });
        ASSERT_EQ(n.load(), 64);
    }
}
