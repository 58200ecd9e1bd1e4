#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/render/voxel_model.h>

#include "image_metrics.h"

using namespace fvr::core;

namespace {

Volume randomVolume(Dims3 dims, unsigned seed, Vec3 spacing) {
    Volume v;
    v.dims = dims;
    v.spacing = spacing;
    v.voxels.resize(std::size_t(v.voxelCount()));
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 100.0f);
    for (float& x : v.voxels) x = u(rng);
    return v;
}

/** A smooth blob volume (band-limited enough that interpolation errors stay small). */
Volume blobVolume(Dims3 dims, Vec3 spacing, Vec3 centreVox) {
    Volume v;
    v.dims = dims;
    v.spacing = spacing;
    v.voxels.resize(std::size_t(v.voxelCount()));
    for (std::int64_t z = 0; z < dims[2]; ++z)
        for (std::int64_t y = 0; y < dims[1]; ++y)
            for (std::int64_t x = 0; x < dims[0]; ++x) {
                const double dx = (x - centreVox[0]) / 3.0, dy = (y - centreVox[1]) / 2.5,
                             dz = (z - centreVox[2]) / 3.5;
                const double dx2 = (x - centreVox[0] - 4) / 2.0, dy2 = (y - centreVox[1] + 3) / 2.0;
                v.voxels[v.index(x, y, z)] =
                    float(100.0 * std::exp(-0.5 * (dx * dx + dy * dy + dz * dz)) +
                          60.0 * std::exp(-0.5 * (dx2 * dx2 + dy2 * dy2 + dz * dz)));
            }
    return v;
}

/** Plain voxel sum along the axis of D for pixels that fall on voxel centres; 0 elsewhere. */
std::vector<double> voxelSumOracle(const Volume& v, const ViewFrame& f, int M, double d) {
    std::vector<double> out(std::size_t(M) * M, 0.0);
    int axis = 0;
    for (int a = 0; a < 3; ++a)
        if (std::abs(f.d[a]) > 0.5) axis = a;
    for (int row = 0; row < M; ++row)
        for (int col = 0; col < M; ++col) {
            double idx[3];
            bool inside = true;
            for (int a = 0; a < 3; ++a) {
                idx[a] = (v.dims[a] - 1) / 2.0 +
                         ((col - M / 2) * d * f.r[a] - (row - M / 2) * d * f.u[a]) / v.spacing[a];
                if (a == axis) continue;
                const double r = std::round(idx[a]);
                EXPECT_NEAR(idx[a], r, 1e-9) << "test geometry must put pixels on voxel centres";
                if (r < 0 || r >= v.dims[a]) inside = false;
                idx[a] = r;
            }
            if (!inside) continue;
            double sum = 0;
            for (std::int64_t i = 0; i < v.dims[axis]; ++i) {
                std::int64_t p[3] = {std::int64_t(idx[0]), std::int64_t(idx[1]),
                                     std::int64_t(idx[2])};
                p[axis] = i;
                sum += v.at(p[0], p[1], p[2]);
            }
            out[std::size_t(row) * M + col] = sum * v.spacing[axis];
        }
    return out;
}

std::shared_ptr<const Spectrum> spectrumOf(const Volume& v, TransformKind t,
                                           double oversampling = 1.0,
                                           std::optional<Dims3> padded = {}) {
    PreprocessOptions o;
    o.effort = PlannerEffort::Estimate;
    o.transform = t;
    o.oversampling = oversampling;
    o.paddedDims = padded;
    return preprocess(v, o);
}

} // namespace

// With d = s and the padded grid equal to the image grid across the view, slice samples fall on
// spectrum grid points: every interpolating kernel must give the discrete projection exactly.
TEST(CpuRenderer, AxisAlignedViewsReproduceVoxelSums) {
    const int M = 64;
    struct Case {
        Dims3 dims;
        Vec3 spacing;
        Vec3 dir, up;
        Dims3 padded;
    };
    const Case cases[] = {
        {{31, 45, 29}, {0.8, 0.8, 1.7}, {0, 0, 1}, {0, -1, 0}, {M, M, 29}}, // plain slice sum
        {{33, 27, 41}, {1.2, 1.1, 1.1}, {1, 0, 0}, {0, -1, 0}, {33, M, M}}, // lateral
        {{25, 21, 35}, {0.9, 1.3, 0.9}, {0, -1, 0}, {0, 0, 1}, {M, 21, M}}, // along -y
    };
    for (const Case& c : cases) {
        const Volume v = randomVolume(c.dims, 17, c.spacing);
        const ViewFrame f = ViewFrame::fromDirUp(c.dir, c.up);
        double d = 0;
        for (int a = 0; a < 3; ++a)
            if (std::abs(f.r[a]) > 0.5) d = c.spacing[a];
        const auto oracle = voxelSumOracle(v, f, M, d);
        double peak = 0;
        for (double x : oracle) peak = std::max(peak, std::abs(x));
        for (auto t : {TransformKind::Fft, TransformKind::Fht}) {
            CpuFourierRenderer r(spectrumOf(v, t, 1.0, c.padded), 2);
            for (Kernel k : allKernels()) {
                if (!kernelInterpolates(k)) continue;
                const auto img = r.render({f, {M, d}, k});
                double maxErr = 0;
                for (std::size_t i = 0; i < oracle.size(); ++i)
                    maxErr = std::max(maxErr, std::abs(img.pixels[i] - oracle[i]));
                EXPECT_LT(maxErr / peak, 2e-5)
                    << kernelName(k) << " " << transformName(t) << " dir " << c.dir[0] << ","
                    << c.dir[1] << "," << c.dir[2];
            }
        }
    }
}

TEST(CpuRenderer, FftAndFhtGiveTheSameProjection) {
    const Volume v = blobVolume({40, 36, 30}, {1.0, 1.2, 1.5}, {18, 20, 14});
    const auto sf = spectrumOf(v, TransformKind::Fft, 1.3);
    const auto sh = spectrumOf(v, TransformKind::Fht, 1.3);
    CpuFourierRenderer rf(sf, 2), rh(sh, 2);
    const ViewFrame views[] = {ViewFrame::fromDirUp({0.3, 0.5, 0.8}, {0, -1, 0}),
                               ViewFrame::fromDirUp({1, 0.2, -0.1}, {0, 0, 1}),
                               ViewFrame::fromDirUp({0, 0, 1}, {0, -1, 0})};
    for (const auto& f : views)
        for (Kernel k : allKernels())
            for (int M : {64, 128}) {
                const double d = defaultPixelSize(v.dims, v.spacing, M);
                const auto a = rf.render({f, {M, d}, k});
                const auto b = rh.render({f, {M, d}, k});
                const auto m = fvr::test::compare(b.pixels, a.pixels);
                EXPECT_LT(m.maxAbsError / m.peak, 2e-5) << kernelName(k) << " M " << M;
            }
}

// The 4- and 6-tap rows of the FFT slice run in x86-64-v3 code (AVX2, FMA) where the CPU has it,
// in baseline SSE2 code elsewhere or with FVR_CPU_SIMD=baseline: the same sums, rounded once per
// multiply-add, so the images agree to float rounding. On an AVX2 machine they must also differ
// somewhere (the dispatch really runs the other code). Both against the independent checks: the
// other tests run the default code; FftAndFhtGiveTheSameProjection holds it against the Hartley
// path, which has no wide rows.
TEST(CpuRenderer, WideSimdRowsAgreeWithTheBaselineRows) {
    const Volume v = randomVolume({27, 22, 19}, 5, {1.0, 1.2, 1.7});
    const auto s = spectrumOf(v, TransformKind::Fft, 1.25);
    CpuFourierRenderer r(s, 2);
    const ViewFrame views[] = {ViewFrame::fromDirUp({0.3, 0.5, 0.8}, {0, -1, 0}),
                               ViewFrame::fromDirUp({-1, 0.2, -0.1}, {0, 0, 1})};
    std::size_t differing = 0;
    for (const auto& f : views)
        for (Kernel k : {Kernel::KaiserBessel4, Kernel::KaiserBessel6, Kernel::CatmullRom})
            for (VoxelModel model : {VoxelModel::BandLimited, VoxelModel::Trilinear})
                for (double pixel : {1.0, 0.4}) {
                    RenderParams p{f, {64, pixel}, k};
                    p.voxelModel = model;
                    p.filter.sharpenAmount = pixel < 1.0 ? 0.5 : 0.0;
                    const auto wide = r.render(p);
                    ::setenv("FVR_CPU_SIMD", "baseline", 1);
                    const auto base = r.render(p);
                    ::unsetenv("FVR_CPU_SIMD");
                    const auto m = fvr::test::compare(wide.pixels, base.pixels);
                    EXPECT_LT(m.maxAbsError / m.peak, 2e-6)
                        << kernelName(k) << " " << voxelModelName(model) << " pixel " << pixel;
                    for (std::size_t i = 0; i < wide.pixels.size(); ++i)
                        differing += wide.pixels[i] != base.pixels[i];
                }
#if defined(__x86_64__)
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) {
        EXPECT_GT(differing, 0u) << "the AVX2 rows never ran";
    }
#endif
    std::printf("[simd] %zu pixels differ in the last bits between the wide and baseline rows\n",
                differing);
}

TEST(CpuRenderer, TranslatedVolumeGivesTranslatedProjection) {
    const Vec3 s{1.0, 1.0, 1.0};
    const Volume a = blobVolume({48, 48, 48}, s, {22, 24, 23});
    const Volume b =
        blobVolume({48, 48, 48}, s, {22 + 3, 24 - 2, 23 + 5}); // shifted (3,-2,5) voxels
    const int M = 128;
    const double d = 1.0;
    // D in the x-z plane: a y shift moves the image by whole rows, the other axes mix into D.
    const ViewFrame f = ViewFrame::fromDirUp({0.6, 0, 0.8}, {0, -1, 0});
    for (auto t : {TransformKind::Fft, TransformKind::Fht}) {
        CpuFourierRenderer ra(spectrumOf(a, t, 2.0), 2), rb(spectrumOf(b, t, 2.0), 2);
        for (Kernel k : {Kernel::Linear, Kernel::CatmullRom, Kernel::Sinc4}) {
            const auto pa = ra.render({f, {M, d}, k});
            const auto pb = rb.render({f, {M, d}, k});
            // Shift in the image: along R by (3,-2,5).R voxels, along rows by -2 (y down = rows).
            const double shiftCols =
                (3 * f.r[0] - 2 * f.r[1] + 5 * f.r[2]) / d; // (0.8*3 - 0.6*5) = -0.6
            ASSERT_NEAR(shiftCols, 3 * 0.8 - 5 * 0.6, 1e-9);
            // Compare rows only: b(col, row) = a(col - shiftCols, row + 2), interpolated along
            // cols.
            double err2 = 0, ref2 = 0;
            for (int row = 10; row < M - 10; ++row)
                for (int col = 10; col < M - 10; ++col) {
                    const double x = col - shiftCols;
                    const int x0 = int(std::floor(x));
                    const double t0 = x - x0;
                    const double av = (1 - t0) * pa.at(x0, row + 2) + t0 * pa.at(x0 + 1, row + 2);
                    err2 += (pb.at(col, row) - av) * (pb.at(col, row) - av);
                    ref2 += av * av;
                }
            EXPECT_LT(std::sqrt(err2 / ref2), 0.02) << kernelName(k) << " " << transformName(t);
        }
    }
}

TEST(CpuRenderer, IntegerTranslationIsExactOnAxis) {
    const Vec3 s{1.0, 1.0, 2.0};
    // Blobs stay > 6 sigma inside the volume in x and y; z is not shifted (same cut of the tails).
    const Volume a = blobVolume({41, 41, 21}, s, {18, 20, 10});
    const Volume b = blobVolume({41, 41, 21}, s, {18 + 4, 20 - 3, 10});
    const int M = 64;
    const ViewFrame f = ViewFrame::fromDirUp({0, 0, 1}, {0, -1, 0});
    CpuFourierRenderer ra(spectrumOf(a, TransformKind::Fft, 1, Dims3{M, M, 21}), 2);
    CpuFourierRenderer rb(spectrumOf(b, TransformKind::Fft, 1, Dims3{M, M, 21}), 2);
    // d = s and P = M across the view: samples on grid points, so the shift is exact.
    const auto pa = ra.render({f, {M, 1.0}, Kernel::Linear});
    const auto pb = rb.render({f, {M, 1.0}, Kernel::Linear});
    double maxErr = 0, peak = 0;
    for (int row = 0; row < M; ++row)
        for (int col = 0; col < M; ++col) {
            const int sc = col - 4, sr = row + 3;
            const double ref = (sc >= 0 && sc < M && sr >= 0 && sr < M) ? pa.at(sc, sr) : 0.0;
            maxErr = std::max(maxErr, std::abs(pb.at(col, row) - ref));
            peak = std::max(peak, std::abs(ref));
        }
    EXPECT_LT(maxErr / peak, 2e-5);
}

TEST(CpuRenderer, OutputScaleIsPhysicalLineIntegral) {
    // A Gaussian of peak A and sigma (mm) along z integrates to A sigma sqrt(2 pi) through its
    // centre, whatever the kernel; the image integral equals the volume integral. d = s keeps the
    // kernel's ghost copies (at the padded period P s) away from the centre after the image's
    // own wrap-around at M d.
    Volume v;
    v.dims = {33, 33, 25};
    v.spacing = {1.5, 1.5, 2.5};
    const double sigma = 7.5, A = 100.0;
    v.voxels.resize(std::size_t(v.voxelCount()));
    double volumeIntegral = 0;
    for (std::int64_t z = 0; z < 25; ++z)
        for (std::int64_t y = 0; y < 33; ++y)
            for (std::int64_t x = 0; x < 33; ++x) {
                const double px = (x - 16) * 1.5, py = (y - 16) * 1.5, pz = (z - 12) * 2.5;
                const float val =
                    float(A * std::exp(-(px * px + py * py + pz * pz) / (2 * sigma * sigma)));
                v.voxels[v.index(x, y, z)] = val;
                volumeIntegral += val * 1.5 * 1.5 * 2.5;
            }
    const ViewFrame f = ViewFrame::fromDirUp({0, 0, 1}, {0, -1, 0});
    for (auto t : {TransformKind::Fft, TransformKind::Fht}) {
        CpuFourierRenderer r(spectrumOf(v, t, 2.0), 2);
        for (Kernel k : {Kernel::Linear, Kernel::CatmullRom, Kernel::Sinc4}) {
            const auto img = r.render({f, {128, 1.5}, k});
            EXPECT_NEAR(img.at(64, 64), A * sigma * std::sqrt(2 * M_PI), 0.01 * A * sigma * 2.5);
            double total = 0;
            for (float p : img.pixels) total += p;
            EXPECT_NEAR(total * 1.5 * 1.5, volumeIntegral, 1e-4 * volumeIntegral);
        }
    }
}

TEST(CpuRenderer, RejectsBadGeometry) {
    Volume v;
    v.dims = {8, 8, 8};
    v.voxels.assign(512, 1.0f);
    CpuFourierRenderer r(spectrumOf(v, TransformKind::Fft), 1);
    const ViewFrame f;
    EXPECT_THROW(r.render({f, {15, 1.0}, Kernel::Linear}), SettingsError);
    EXPECT_THROW(r.render({f, {64, 1.0, 4097}, Kernel::Linear}), SettingsError);
    EXPECT_THROW(r.render({f, {128, 0.0}, Kernel::Linear}), SettingsError);
    EXPECT_THROW(ViewFrame::fromDirUp({0, 0, 1}, {0, 0, 2}), SettingsError);
    EXPECT_THROW(ViewFrame::fromDirUp({0, 0, 0}, {0, 1, 0}), SettingsError);
}
