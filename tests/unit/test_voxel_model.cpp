// Voxel models (voxel_model.h): the transfer functions against the Fourier transforms of their
// interpolants, the B-spline prefilter, and FVR with each model against independent oracles: an
// exact 2D computation in double for axis views, and the spatial projector with the same model
// on the shared real CTs and MR.
#include <cmath>
#include <complex>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/errors.h>
#include <fvr/core/io/volume_io.h>
#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/render/spatial_projector.h>
#include <fvr/core/render/voxel_model.h>
#include <fvr/core/xray/patient_views.h>

#include "image_metrics.h"
#include "test_support.h"

using namespace fvr::core;
using cd = std::complex<double>;

namespace {

constexpr double kPi = std::numbers::pi;

double tent(double x) { return std::max(0.0, 1.0 - std::abs(x)); }
double cubicBSpline(double x) {
    x = std::abs(x);
    if (x < 1.0) return (4.0 - 6.0 * x * x + 3.0 * x * x * x) / 6.0;
    if (x < 2.0) return (2.0 - x) * (2.0 - x) * (2.0 - x) / 6.0;
    return 0.0;
}
/** Continuous Fourier transform of an even function supported on [-r, r] (Simpson). */
double fourierOf(double (*f)(double), double r, double nu) {
    const int n = 4000;
    const double h = 2.0 * r / n;
    double s = 0.0;
    for (int i = 0; i <= n; ++i) {
        const double x = -r + i * h;
        s += (i == 0 || i == n ? 1.0 : (i % 2 ? 4.0 : 2.0)) * f(x) * std::cos(2.0 * kPi * nu * x);
    }
    return s * h / 3.0;
}

std::vector<float> randomVoxels(const Dims3& dims, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    std::vector<float> v(std::size_t(dims[0] * dims[1] * dims[2]));
    for (float& x : v) x = u(rng);
    return v;
}

Volume randomVolume(const Dims3& dims, const Vec3& spacing, unsigned seed) {
    Volume v;
    v.dims = dims;
    v.spacing = spacing;
    v.voxels = randomVoxels(dims, seed);
    v.name = "random";
    return v;
}

/** An axis view: along +e_a, the image's right = sr e_b, its down (-up) = sd e_c. */
struct AxisView {
    int a, b, c;
    double sr, sd;
    ViewFrame frame() const {
        Vec3 dir{0, 0, 0}, up{0, 0, 0};
        dir[std::size_t(a)] = 1.0;
        up[std::size_t(c)] = -sd;
        const ViewFrame f = ViewFrame::fromDirUp(dir, up);
        EXPECT_EQ(f.r[std::size_t(b)], sr); // the frame's own right-hand rule agrees with sr
        return f;
    }
};

/**
 * The oracle for an axis view: the projection of the voxel model band-limited to the image's
 * frequencies, computed in 2D, in double, from the plain voxel sums S[xb, xc] = sum_xa v:
 * p = s_a s_b s_c / (M d)^2 sum_{m,n} S~(m, n) t(m s_b / (M d)) t(n s_c / (M d))
 *     e^{2 pi i (m (col - M/2) + n (row - M/2)) / M},
 * S~ the 2D DTFT of S about the volume's centre (coordinates signed by sr, sd), t the model's
 * transfer function, the Nyquist row and column averaged over their two aliases. No 3D spectrum,
 * no gridding.
 */
std::vector<float> axisViewOracle(const Volume& v, VoxelModel model, int M, double d,
                                  const AxisView& av = {2, 0, 1, 1, 1}) {
    const auto& Nv = v.dims;
    const auto& sv = v.spacing;
    // In the view's axes: N[0], s[0] along the image's columns (b), N[1], s[1] along its rows (c).
    const std::int64_t N[2] = {Nv[std::size_t(av.b)], Nv[std::size_t(av.c)]};
    const double s[3] = {sv[std::size_t(av.b)], sv[std::size_t(av.c)], sv[std::size_t(av.a)]};
    std::vector<double> S(std::size_t(N[0] * N[1]), 0.0);
    for (std::int64_t z = 0; z < Nv[2]; ++z)
        for (std::int64_t y = 0; y < Nv[1]; ++y)
            for (std::int64_t x = 0; x < Nv[0]; ++x) {
                const std::int64_t i[3] = {x, y, z};
                S[std::size_t(i[av.c] * N[0] + i[av.b])] += v.voxels[std::size_t(v.index(x, y, z))];
            }
    const int F = M + 1; // m = -M/2 .. M/2
    const double c0 = (N[0] - 1) / 2.0, c1 = (N[1] - 1) / 2.0;
    std::vector<cd> A(std::size_t(F * N[1]));
    for (int mi = 0; mi < F; ++mi) {
        const double f = double(mi - M / 2) * s[0] / (M * d);
        for (std::int64_t y = 0; y < N[1]; ++y) {
            cd acc = 0.0;
            for (std::int64_t x = 0; x < N[0]; ++x)
                acc += S[std::size_t(y * N[0] + x)] *
                       std::polar(1.0, -2.0 * kPi * f * av.sr * (x - c0));
            A[std::size_t(mi * N[1] + y)] = acc;
        }
    }
    std::vector<cd> X(std::size_t(F * F));
    for (int mi = 0; mi < F; ++mi)
        for (int ni = 0; ni < F; ++ni) {
            const double f = double(ni - M / 2) * s[1] / (M * d);
            cd acc = 0.0;
            for (std::int64_t y = 0; y < N[1]; ++y)
                acc += A[std::size_t(mi * N[1] + y)] *
                       std::polar(1.0, -2.0 * kPi * f * av.sd * (y - c1));
            const double tm = voxelModelTransfer(model, double(mi - M / 2) * s[0] / (M * d));
            const double tn = voxelModelTransfer(model, double(ni - M / 2) * s[1] / (M * d));
            X[std::size_t(mi * F + ni)] = acc * tm * tn;
        }
    // Fold the Nyquist aliases: index -M/2 holds the mean of -M/2 and +M/2.
    std::vector<cd> Y(std::size_t(M * M));
    for (int m = 0; m < M; ++m)
        for (int n = 0; n < M; ++n) {
            cd sum = 0.0;
            int count = 0;
            for (int a : {m, m == 0 ? M : -1})
                for (int b : {n, n == 0 ? M : -1}) {
                    if (a < 0 || b < 0) continue;
                    sum += X[std::size_t(a * F + b)];
                    ++count;
                }
            Y[std::size_t(m * M + n)] = sum / double(count);
        }
    const double scale = s[0] * s[1] * s[2] / ((M * d) * (M * d));
    std::vector<cd> B(std::size_t(M * M)); // B[col][n]
    for (int col = 0; col < M; ++col)
        for (int n = 0; n < M; ++n) {
            cd acc = 0.0;
            for (int m = 0; m < M; ++m)
                acc += Y[std::size_t(m * M + n)] *
                       std::polar(1.0, 2.0 * kPi * (m - M / 2) * (col - M / 2) / M);
            B[std::size_t(col * M + n)] = acc;
        }
    std::vector<float> img(std::size_t(M * M));
    for (int row = 0; row < M; ++row)
        for (int col = 0; col < M; ++col) {
            cd acc = 0.0;
            for (int n = 0; n < M; ++n)
                acc += B[std::size_t(col * M + n)] *
                       std::polar(1.0, 2.0 * kPi * (n - M / 2) * (row - M / 2) / M);
            img[std::size_t(row * M + col)] = float(scale * acc.real());
        }
    return img;
}

} // namespace

TEST(VoxelModel, NamesAndErrors) {
    for (VoxelModel m : allVoxelModels()) EXPECT_EQ(parseVoxelModel(voxelModelName(m)), m);
    EXPECT_EQ(parseVoxelModel("band-limited"), VoxelModel::BandLimited);
    try {
        parseVoxelModel("cubic-catmull");
        FAIL() << "expected SettingsError";
    } catch (const SettingsError& e) {
        EXPECT_NE(std::string(e.what()).find("bandlimited|trilinear|bspline"), std::string::npos)
            << e.what();
        EXPECT_NE(std::string(e.what()).find("cubic-catmull"), std::string::npos) << e.what();
    }
    SpatialProjectorOptions o;
    o.voxelModel = VoxelModel::BandLimited;
    const Volume v = randomVolume({4, 4, 4}, {1, 1, 1}, 1);
    EXPECT_THROW(SpatialProjector(v, o), SettingsError);
}

TEST(VoxelModel, TransferFunctionsAreTheInterpolantsFourierTransforms) {
    for (double nu : {0.0, 0.13, 0.5, 0.77, 1.0, 1.3, 2.6, -0.4}) {
        // Trilinear: the tent's transform. B-spline: the cubic B-spline's transform over the
        // transform of its samples (the prefilter, sum_n beta3(n) e^{-2 pi i nu n}).
        EXPECT_NEAR(voxelModelTransfer(VoxelModel::Trilinear, nu), fourierOf(tent, 1.0, nu), 1e-9)
            << nu;
        const double samples = cubicBSpline(0) + 2.0 * cubicBSpline(1) * std::cos(2.0 * kPi * nu);
        EXPECT_NEAR(voxelModelTransfer(VoxelModel::BSpline, nu),
                    fourierOf(cubicBSpline, 2.0, nu) / samples, 1e-9)
            << nu;
        EXPECT_EQ(voxelModelTransfer(VoxelModel::BandLimited, nu), std::abs(nu) <= 0.5 ? 1.0 : 0.0);
        for (VoxelModel m : {VoxelModel::Trilinear, VoxelModel::BSpline}) {
            const double h = 1e-5;
            const double fd =
                (voxelModelTransfer(m, nu + h) - voxelModelTransfer(m, nu - h)) / (2 * h);
            EXPECT_NEAR(voxelModelTransferDerivative(m, nu), fd, 1e-7)
                << voxelModelName(m) << " " << nu;
        }
    }
    // The tables the CPU renderer reads, inside their range and beyond it.
    for (VoxelModel m : {VoxelModel::Trilinear, VoxelModel::BSpline}) {
        TransferTable t(m, 3.0);
        double worst = 0.0, worstD = 0.0;
        for (double nu = -4.0; nu <= 4.0; nu += 0.000731) {
            worst = std::max(worst, std::abs(t.value(nu) - voxelModelTransfer(m, nu)));
            worstD =
                std::max(worstD, std::abs(t.derivative(nu) - voxelModelTransferDerivative(m, nu)));
        }
        // Linear interpolation at h = 1/1024: h^2/8 max|t2| (a few 1e-6 for the B-spline's second
        // derivative, then float rounding), and h/2 max|t3| for the derivative.
        EXPECT_LT(worst, 5e-6) << voxelModelName(m);
        EXPECT_LT(worstD, 1e-4) << voxelModelName(m);
    }
    EXPECT_NEAR(pixelApertureResponse(0.5), 2.0 / kPi, 1e-12);
    EXPECT_EQ(voxelModelReach(VoxelModel::Trilinear), 1.0);
}

TEST(VoxelModel, BSplineCoefficientsInterpolateTheVoxelsAndTheZerosAround) {
    const Dims3 dims{9, 8, 7};
    const auto voxels = randomVoxels(dims, 3);
    const int margin = 10;
    const auto c = bsplineCoefficients(voxels, dims, margin);
    const std::int64_t L0 = dims[0] + 2 * margin, L1 = dims[1] + 2 * margin;
    auto coef = [&](std::int64_t x, std::int64_t y, std::int64_t z) {
        return double(c[std::size_t(((z + margin) * L1 + (y + margin)) * L0 + (x + margin))]);
    };
    double worst = 0.0;
    for (std::int64_t z = -4; z < dims[2] + 4; ++z)
        for (std::int64_t y = -4; y < dims[1] + 4; ++y)
            for (std::int64_t x = -4; x < dims[0] + 4; ++x) {
                // At an integer point only the taps at offsets -1, 0, 1 weigh (1/6, 4/6, 1/6).
                double val = 0.0;
                for (int k = -1; k <= 1; ++k)
                    for (int j = -1; j <= 1; ++j)
                        for (int i = -1; i <= 1; ++i)
                            val += cubicBSpline(i) * cubicBSpline(j) * cubicBSpline(k) *
                                   coef(x + i, y + j, z + k);
                const bool inside =
                    x >= 0 && y >= 0 && z >= 0 && x < dims[0] && y < dims[1] && z < dims[2];
                const double want =
                    inside ? voxels[std::size_t((z * dims[1] + y) * dims[0] + x)] : 0.0;
                worst = std::max(worst, std::abs(val - want));
            }
    EXPECT_LT(worst, 1e-5);
}

// An axis view against the exact 2D oracle: every model, the FFT and the FHT path, an even and an
// odd voxel count across the image (the period signs), pixels of s, s/2, s/3 and s/9 (the compact
// models read the spectrum up to 1.5 and 4.5 cycles per voxel: the CPU's fast row walk reaches 4
// periods, the samples beyond take its general path). With voxel-aligned pixels (d = s) the
// band-limited model gives the plain voxel sums; the trilinear model gives them bilinearly
// interpolated and band-limited to the image (what a trilinear ray caster samples, less the
// aliases beyond the image's Nyquist frequency, which FVR never sees).
TEST(VoxelModel, AxisViewEqualsTheExactProjectionOfEachModel) {
    const Volume v = randomVolume({30, 25, 12}, {2.0, 2.0, 3.0}, 7);
    const int M = 64;
    // Along z (the slices' plain sum), x (image right -y, down -z) and y (right x, down -z): every
    // axis's period signs and transfer function in the image plane once.
    const AxisView axisViews[] = {{2, 0, 1, 1, 1}, {0, 1, 2, -1, -1}, {1, 0, 2, 1, -1}};
    for (const AxisView& av : axisViews)
        for (auto t : {TransformKind::Fft, TransformKind::Fht}) {
            const ViewFrame view = av.frame();
            PreprocessOptions o;
            o.effort = PlannerEffort::Estimate;
            o.transform = t;
            o.oversampling = 2.0;
            o.deapodizeFor = Kernel::KaiserBessel6;
            CpuFourierRenderer r(preprocess(v, o));
            for (VoxelModel model : allVoxelModels())
                for (int K : {1, 2, 3, 9}) {
                    if (model == VoxelModel::BandLimited && K > 1)
                        continue; // its band edge falls on samples
                    const double d = 2.0 / K;
                    RenderParams p{view, {M, d}, Kernel::KaiserBessel6};
                    p.voxelModel = model;
                    const auto got = r.render(p);
                    const auto want = axisViewOracle(v, model, M, d, av);
                    const double psnr = fvr::test::compare(got.pixels, want).psnr;
                    std::printf("[voxel model] view along axis %d vs exact 2D oracle: %s %-11s d = "
                                "2 mm/%d  %.1f dB\n",
                                av.a, transformName(t), voxelModelName(model), K, psnr);
                    EXPECT_GT(psnr, 75.0) << "axis " << av.a << " " << transformName(t) << " "
                                          << voxelModelName(model) << " K " << K;
                }
        }
}

// The oracle's conventions (centre, orientation, scale) on a case worked out by hand: pixels on
// the voxel centres (odd counts, d = s), the band-limited model, where the projection at a voxel
// centre is exactly s_z times the plain voxel sum, and 0 at the centres of the zero padding.
TEST(VoxelModel, AxisViewOracleGivesThePlainVoxelSumsOnVoxelCentres) {
    const Volume v = randomVolume({31, 25, 12}, {2.0, 2.0, 3.0}, 8);
    const int M = 64;
    const auto img = axisViewOracle(v, VoxelModel::BandLimited, M, 2.0);
    double worst = 0.0, peak = 0.0;
    for (int row = 0; row < M; ++row)
        for (int col = 0; col < M; ++col) {
            const std::int64_t x = col - M / 2 + 15, y = row - M / 2 + 12;
            double want = 0.0;
            if (x >= 0 && x < 31 && y >= 0 && y < 25)
                for (std::int64_t z = 0; z < 12; ++z)
                    want += 3.0 * v.voxels[std::size_t(v.index(x, y, z))];
            worst = std::max(worst, std::abs(img[std::size_t(row * M + col)] - want));
            peak = std::max(peak, want);
        }
    EXPECT_LT(worst, 1e-5 * peak);
}

// Real data: each compact model against the spatial projector (ray casting) with the same model,
// the workstation's default kernel (Kaiser-Bessel 4, oversampling 1.25, deapodized), M = 256 at
// the default pixel size, clip on; the band-limited model against trilinear ray casting for
// contrast. Floors sit ~1.5 dB below the measured values (docs/dev/accuracy.md, "Voxel models").
namespace {

struct RealCase {
    const char* path; // under ../shared/data
    ValueMapping mapping;
    double floors[2][4]; // [trilinear, bspline][AP, LEFT, oblique 1, oblique 2], dB
    double minTrilinear; // most negative trilinear pixel (fraction of the maximum), clamp off
    double bandLimitedBelow; // the band-limited model's most negative pixel on AP is below this
    // How much closer than the band-limited model the trilinear one comes to trilinear ray
    // casting per view (dB; NaN: not asserted, where pixels coarser than the voxels let the
    // point-sampled ray caster alias and the band-limited image scores as well).
    double gainOverBandLimited[4];
};

constexpr double kNotAsserted = std::numeric_limits<double>::quiet_NaN();

Volume loadReal(const char* rel) {
    const auto path = fvr::test::sharedData() / rel;
    if (std::filesystem::is_directory(path)) return std::move(loadDicomFolder(path).volume);
    return loadVolume(path);
}

void checkRealData(const RealCase& rc) {
    const Volume v = loadReal(rc.path);
    const int M = 256;
    const double d = defaultPixelSize(v.dims, v.spacing, M);
    const std::vector<std::pair<const char*, ViewFrame>> views{
        {"AP", patientViewFrame(v, PatientView::AP)},
        {"LEFT", patientViewFrame(v, PatientView::Left)},
        {"oblique .7,.6,.3", ViewFrame::fromDirUp({0.7, 0.6, 0.3}, {0, 0, 1})},
        {"oblique .5,-.4,.77", ViewFrame::fromDirUp({0.5, -0.4, 0.77}, {0, -1, 0})}};
    PreprocessOptions o;
    o.effort = PlannerEffort::Estimate;
    o.mapping = rc.mapping;
    o.oversampling = 1.25;
    o.deapodizeFor = Kernel::KaiserBessel4;
    CpuFourierRenderer r(preprocess(v, o));
    const VoxelModel models[2] = {VoxelModel::Trilinear, VoxelModel::BSpline};
    for (int mi = 0; mi < 2; ++mi) {
        SpatialProjectorOptions so;
        so.mapping = rc.mapping;
        so.voxelModel = models[mi];
        SpatialProjector sp(v, so);
        for (std::size_t i = 0; i < views.size(); ++i) {
            const auto ref = sp.project(views[i].second, {M, d});
            RenderParams p{views[i].second, {M, d}, Kernel::KaiserBessel4};
            p.clipToVolume = true;
            p.voxelModel = models[mi];
            const auto img = r.render(p);
            const double psnr = fvr::test::compare(img.pixels, ref.pixels).psnr;
            const double lowest = mostNegativeFraction(img.pixels);
            std::printf(
                "[voxel model] %s %-18s %-9s vs %-9s ray casting %6.2f dB, most negative %.3f %%\n",
                rc.path, views[i].first, voxelModelName(models[mi]), voxelModelName(models[mi]),
                psnr, 100 * lowest);
            EXPECT_GT(psnr, rc.floors[mi][i])
                << rc.path << " " << views[i].first << " " << voxelModelName(models[mi]);
            if (mi != 0) continue;
            EXPECT_GT(lowest, rc.minTrilinear) << rc.path << " " << views[i].first;
            // The clamp for a non-negative volume: nothing below 0, and never further from the
            // ray caster (its line integrals are >= 0).
            p.nonNegative = true;
            const auto clamped = r.render(p);
            EXPECT_EQ(mostNegativeFraction(clamped.pixels), 0.0);
            // The band-limited model against the same trilinear ray caster: lower, and ringing.
            p.nonNegative = false;
            p.voxelModel = VoxelModel::BandLimited;
            const auto band = r.render(p);
            const double bandPsnr = fvr::test::compare(band.pixels, ref.pixels).psnr;
            std::printf("[voxel model] %s %-18s %-9s vs trilinear ray casting %6.2f dB, most "
                        "negative %.3f %%\n",
                        rc.path, views[i].first, "bandlimited", bandPsnr,
                        100 * mostNegativeFraction(band.pixels));
            if (i == 0) {
                EXPECT_LT(mostNegativeFraction(band.pixels), rc.bandLimitedBelow) << rc.path;
            }
            if (!std::isnan(rc.gainOverBandLimited[i])) {
                EXPECT_GT(psnr, bandPsnr + rc.gainOverBandLimited[i])
                    << rc.path << " " << views[i].first;
            }
        }
    }
}

} // namespace

TEST(VoxelModel, BodyCtMatchesRayCastingWithTheSameModel) {
    FVR_REQUIRE_DATA("volumes/body_ct_hu_3mm/example_ct.mhd");
    checkRealData({"volumes/body_ct_hu_3mm/example_ct.mhd",
                   ValueMapping::Mu,
                   {{48, 50, 55, 59}, {49.5, 52, 55, 59}},
                   -0.003,
                   -0.10,
                   {8, 8, 2, 4}}); // measured gains 10.1, 10.3, 3.1, 5.3 dB
}

TEST(VoxelModel, PhilipsCtMatchesRayCastingWithTheSameModel) {
    FVR_REQUIRE_DATA("dicom/ct_phantom_philips_512x512x140");
    checkRealData({"dicom/ct_phantom_philips_512x512x140",
                   ValueMapping::Mu,
                   {{53.5, 47, 60.5, 60}, {52, 46, 59, 59}},
                   -0.005,
                   -0.005,
                   {kNotAsserted, kNotAsserted, 1.5, 0.5}}); // gains -1.3, -0.3, 2.5, 1.1 dB
}

TEST(VoxelModel, MrHeadMatchesRayCastingWithTheSameModel) {
    FVR_REQUIRE_DATA("dicom/mr_head_coronal_256x256x100");
    checkRealData({"dicom/mr_head_coronal_256x256x100",
                   ValueMapping::Raw,
                   {{50, 52.5, 54, 55}, {48.5, 52.5, 51.5, 52}},
                   -0.006,
                   -0.005,
                   {0.5, 5, 5, 4}}); // gains 1.0, 6.2, 6.0, 5.2 dB
}

// Depth cueing with a compact model differentiates the model's spectrum T G, so its slice value
// carries E.grad T as well. That term vanishes for cubic voxels (T is then nearly radial and its
// gradient lies in the slice), so an anisotropic volume of white noise (strong high frequencies)
// and an oblique view: against the depth-weighted trilinear ray caster. Without the E.grad T term
// the first view measured 66.3 dB instead of 74.2.
TEST(VoxelModel, DepthCueDifferentiatesTheModelsTransferFunction) {
    const Volume v = randomVolume({40, 36, 14}, {1.0, 1.0, 3.0}, 3);
    PreprocessOptions o;
    o.effort = PlannerEffort::Estimate;
    o.oversampling = 2.0;
    o.deapodizeFor = Kernel::KaiserBessel6;
    CpuFourierRenderer r(preprocess(v, o));
    SpatialProjectorOptions so;
    so.depthCue = 0.8;
    SpatialProjector sp(v, so);
    const ViewFrame view = ViewFrame::fromDirUp({0.5, 0.3, 0.8}, {0, -1, 0});
    const ImageGeometry g{128, 0.5};
    RenderParams p{view, g, Kernel::KaiserBessel6};
    p.voxelModel = VoxelModel::Trilinear;
    p.depthCue = 0.8;
    p.clipToVolume = true;
    const double psnr = fvr::test::compare(r.render(p).pixels, sp.project(view, g).pixels).psnr;
    std::printf("[voxel model] depth cue 0.8, anisotropic noise, trilinear vs depth-weighted ray "
                "casting: %.2f dB\n",
                psnr);
    EXPECT_GT(psnr, 71.0);
}

// The FFT and the FHT path compute the same image for every voxel model, with depth cueing too
// (different storage, different derivative formula: a G + i E.grad(T G) against
// a T H(k) + T E.grad H(-k) - H(-k) E.grad T). Even and odd voxel counts, oblique view, fine
// pixels so that most samples lie beyond the band.
TEST(VoxelModel, FftEqualsFhtForEveryModelWithDepthCue) {
    for (const Dims3& dims : {Dims3{24, 19, 16}, Dims3{21, 25, 15}}) {
        const Volume v = randomVolume(dims, {1.0, 1.5, 2.0}, 11);
        std::shared_ptr<const Spectrum> spectra[2];
        for (int i = 0; i < 2; ++i) {
            PreprocessOptions o;
            o.effort = PlannerEffort::Estimate;
            o.transform = i ? TransformKind::Fht : TransformKind::Fft;
            o.oversampling = 1.25;
            spectra[i] = preprocess(v, o);
        }
        CpuFourierRenderer fft(spectra[0], 1), fht(spectra[1], 1);
        const ViewFrame view = ViewFrame::fromDirUp({0.45, -0.3, 0.84}, {0, -1, 0});
        for (VoxelModel model : allVoxelModels())
            for (Kernel k : {Kernel::Linear, Kernel::CatmullRom})
                for (double depth : {0.0, 0.7}) {
                    RenderParams p{view, {64, 0.5}, k};
                    p.voxelModel = model;
                    p.depthCue = depth;
                    const double psnr =
                        fvr::test::compare(fht.render(p).pixels, fft.render(p).pixels).psnr;
                    EXPECT_GT(psnr, 110.0) << dims[0] << " " << voxelModelName(model) << " "
                                           << kernelName(k) << " depth " << depth;
                }
    }
}
