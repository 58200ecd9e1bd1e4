// X-ray image formation: attenuation mappings, Beer-Lambert transmission, depth cueing
// in the frequency domain against exact depth-weighted line integrals and the depth-weighted
// spatial projector, and the slice filters against their definitions applied to the unfiltered
// CPU image (spatial Gaussian convolution; FFTW in double).
#include <cmath>
#include <complex>
#include <cstdio>
#include <numbers>
#include <random>

#include <fftw3.h>
#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/io/image_io.h>
#include <fvr/core/io/volume_io.h>
#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/render/spatial_projector.h>
#include <fvr/core/xray/phantom.h>
#include <fvr/core/xray/xray.h>

#include "image_metrics.h"
#include "phantom_fixture.h"
#include "test_support.h"

using namespace fvr::core;

namespace {

constexpr int kM = fvr::test::PhantomFixture::kM;

struct Fixture : fvr::test::PhantomFixture {
    std::vector<ViewFrame> views{ViewFrame::fromDirUp({0.35, 0.2, 0.92}, {0, -1, 0}),
                                 ViewFrame::fromDirUp({0.8, -0.45, 0.4}, {0, 0, 1}),
                                 ViewFrame::fromDirUp({0, 1, 0}, {0, 0, 1})}; // one axis view
};

const Fixture& fixture() {
    static const Fixture f;
    return f;
}

std::shared_ptr<const Spectrum> spectrumFor(TransformKind t, double over,
                                            std::optional<Kernel> deapodize,
                                            ValueMapping mapping = ValueMapping::Mu) {
    PreprocessOptions o;
    o.effort = PlannerEffort::Estimate;
    o.mapping = mapping;
    o.transform = t;
    o.oversampling = over;
    o.deapodizeFor = deapodize;
    return preprocess(fixture().volume, o);
}

/** Periodic 2D convolution of an M x M image with the sampled Gaussian of sigma pixels, in double.
 */
std::vector<double> gaussianBlurPeriodic(const std::vector<float>& img, int M, double sigmaPx) {
    const int R = int(std::ceil(8 * sigmaPx));
    std::vector<double> k(std::size_t(2 * R + 1));
    for (int i = -R; i <= R; ++i)
        k[std::size_t(i + R)] = std::exp(-0.5 * i * i / (sigmaPx * sigmaPx)) /
                                (std::sqrt(2 * std::numbers::pi) * sigmaPx);
    std::vector<double> tmp(img.size()), out(img.size());
    for (int r = 0; r < M; ++r)
        for (int c = 0; c < M; ++c) {
            double s = 0;
            for (int i = -R; i <= R; ++i)
                s += k[std::size_t(i + R)] *
                     img[std::size_t(r) * M + std::size_t(((c - i) % M + M) % M)];
            tmp[std::size_t(r) * M + c] = s;
        }
    for (int r = 0; r < M; ++r)
        for (int c = 0; c < M; ++c) {
            double s = 0;
            for (int i = -R; i <= R; ++i)
                s += k[std::size_t(i + R)] * tmp[std::size_t(((r - i) % M + M) % M) * M + c];
            out[std::size_t(r) * M + c] = s;
        }
    return out;
}

/** The filter's definition applied with FFTW in double: IDFT(H(nu) DFT(img)). */
std::vector<double> filterInDouble(const std::vector<float>& img, int M, double d,
                                   const SliceFilter& f) {
    std::vector<std::complex<double>> a(img.begin(), img.end());
    auto* p = reinterpret_cast<fftw_complex*>(a.data());
    fftw_plan fwd = fftw_plan_dft_2d(M, M, p, p, FFTW_FORWARD, FFTW_ESTIMATE);
    fftw_plan inv = fftw_plan_dft_2d(M, M, p, p, FFTW_BACKWARD, FFTW_ESTIMATE);
    fftw_execute(fwd);
    for (int r = 0; r < M; ++r)
        for (int c = 0; c < M; ++c) {
            const int n = r <= M / 2 ? r : r - M, m = c <= M / 2 ? c : c - M;
            a[std::size_t(r) * M + c] *=
                f.response(std::hypot(double(m), double(n)) / (M * d)) / (double(M) * M);
        }
    fftw_execute(inv);
    fftw_destroy_plan(fwd);
    fftw_destroy_plan(inv);
    std::vector<double> out(img.size());
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = a[i].real();
    return out;
}

double maxRelError(const std::vector<float>& got, const std::vector<double>& want) {
    double e = 0, peak = 0;
    for (std::size_t i = 0; i < want.size(); ++i) {
        e = std::max(e, std::abs(double(got[i]) - want[i]));
        peak = std::max(peak, std::abs(want[i]));
    }
    return e / peak;
}

} // namespace

// ---- Attenuation --------------------------------------------------------------------------------

TEST(XRay, AttenuationMappings) {
    EXPECT_EQ(mapValue(ValueMapping::Raw, -1000.0f), -1000.0f);
    EXPECT_FLOAT_EQ(mapValue(ValueMapping::Mu, -1000.0f), 0.0f);
    EXPECT_FLOAT_EQ(mapValue(ValueMapping::Mu, -3024.0f), 0.0f); // clipped, never negative
    EXPECT_FLOAT_EQ(mapValue(ValueMapping::Mu, 0.0f), 1.0f);
    EXPECT_FLOAT_EQ(mapValue(ValueMapping::Mu, 1000.0f), 2.0f);
    // Bone-enhanced: the water line up to the threshold, kBoneGain times steeper above, continuous.
    EXPECT_FLOAT_EQ(mapValue(ValueMapping::MuBone, -500.0f), 0.5f);
    EXPECT_FLOAT_EQ(mapValue(ValueMapping::MuBone, float(kBoneThresholdHu)),
                    float(1 + kBoneThresholdHu / 1000));
    EXPECT_FLOAT_EQ(
        mapValue(ValueMapping::MuBone, 1000.0f),
        float(1 + kBoneThresholdHu / 1000 + kBoneGain * (1000 - kBoneThresholdHu) / 1000));
    EXPECT_NEAR(mapValue(ValueMapping::MuBone, float(kBoneThresholdHu) + 0.01f),
                mapValue(ValueMapping::MuBone, float(kBoneThresholdHu)), 1e-4);
    EXPECT_FLOAT_EQ(mapValue(ValueMapping::MuBone, -2000.0f), 0.0f);
    EXPECT_EQ(parseValueMapping("mu-bone"), ValueMapping::MuBone);
    EXPECT_STREQ(valueMappingName(ValueMapping::MuBone), "mu-bone");
    EXPECT_THROW(parseValueMapping("bone"), SettingsError);
}

TEST(XRay, BoneEnhancedSpectrumIsTheTransformOfTheMappedVolume) {
    // preprocess(MuBone) must equal preprocess(Raw) of the volume mapped voxel by voxel, and the
    // rendered bone-enhanced projection must match the spatial projector with the same mapping.
    Volume mapped = fixture().volume;
    for (float& v : mapped.voxels) v = mapValue(ValueMapping::MuBone, v);
    PreprocessOptions o;
    o.effort = PlannerEffort::Estimate;
    o.mapping = ValueMapping::MuBone;
    auto a = preprocess(fixture().volume, o);
    o.mapping = ValueMapping::Raw;
    auto b = preprocess(mapped, o);
    double maxDiff = 0, peak = 0;
    for (std::size_t i = 0; i < a->floatCount(); ++i) {
        maxDiff = std::max(maxDiff, double(std::abs(a->data[i] - b->data[i])));
        peak = std::max(peak, double(std::abs(b->data[i])));
    }
    EXPECT_LT(maxDiff / peak, 1e-6);
    // Bone is enhanced, by exactly the mapped volumes' ratio in the total (the image's DC).
    double vb = 0, vm = 0;
    for (float v : fixture().volume.voxels)
        vb += mapValue(ValueMapping::MuBone, v), vm += mapValue(ValueMapping::Mu, v);
    CpuFourierRenderer rb(
        spectrumFor(TransformKind::Fft, 1.25, Kernel::KaiserBessel4, ValueMapping::MuBone));
    CpuFourierRenderer rm(spectrumFor(TransformKind::Fft, 1.25, Kernel::KaiserBessel4));
    const RenderParams p{fixture().views[0], {kM, fixture().d}, Kernel::KaiserBessel4};
    const auto bone = rb.render(p), mu = rm.render(p);
    double sb = 0, sm = 0;
    for (std::size_t i = 0; i < bone.pixels.size(); ++i) sb += bone.pixels[i], sm += mu.pixels[i];
    EXPECT_GT(vb, 1.05 * vm);
    EXPECT_NEAR(sb / sm, vb / vm, 1e-3); // deapodization moves the DC by ~4e-4
    SpatialProjector sp(fixture().volume, {0.25, ValueMapping::MuBone, 0});
    const double psnr = fvr::test::compare(bone.pixels, sp.project(p.view, p.image).pixels).psnr;
    std::printf("[xray] bone-enhanced FVR (kaiser-bessel4, deapodized, 1.25x) vs spatial "
                "projector: %.2f dB\n",
                psnr);
    EXPECT_GT(psnr, 36.0);
    EXPECT_THROW(fixture().phantom.project(p.view, p.image, ValueMapping::MuBone,
                                           fixture().volume.dims, fixture().volume.spacing),
                 SettingsError);
}

// ---- Beer-Lambert -------------------------------------------------------------------------------

TEST(XRay, WaterAttenuationFollowsNist) {
    EXPECT_NEAR(waterAttenuationPerMm(40), 0.02683, 1e-9);
    EXPECT_NEAR(waterAttenuationPerMm(60), 0.02059, 1e-9);
    EXPECT_NEAR(waterAttenuationPerMm(80), 0.01837, 1e-9);
    EXPECT_NEAR(waterAttenuationPerMm(100), 0.01707, 1e-9);
    // Between table points: log-log interpolation, monotone (70 keV is about 0.0194 / mm).
    EXPECT_NEAR(waterAttenuationPerMm(70), 0.0194, 0.0002);
    double prev = 1;
    for (double e = 20; e <= 150; e += 2.5) {
        const double mu = waterAttenuationPerMm(e);
        EXPECT_LT(mu, prev) << e;
        prev = mu;
    }
    EXPECT_THROW(waterAttenuationPerMm(10), SettingsError);
    EXPECT_THROW(waterAttenuationPerMm(200), SettingsError);
}

TEST(XRay, BeerLambertIsExpOfTheLineIntegral) {
    CpuFourierRenderer r(spectrumFor(TransformKind::Fft, 1.25, Kernel::KaiserBessel4));
    const auto img = r.render({fixture().views[1], {kM, fixture().d}, Kernel::KaiserBessel4});
    const Transmission t{waterAttenuationPerMm(70), 1.7};
    auto I = img.pixels;
    applyTransmission(I, t);
    for (std::size_t i = 0; i < I.size(); i += 97)
        EXPECT_NEAR(I[i], 1.7 * std::exp(-t.muWaterPerMm * std::max(0.0f, img.pixels[i])),
                    1e-6 * 1.7);
    // No pixel transmits more than the beam, also where ringing leaves a negative integral.
    EXPECT_LE(*std::max_element(I.begin(), I.end()), 1.7f);
    EXPECT_DOUBLE_EQ(t.intensity(-5.0), 1.7);
    EXPECT_DOUBLE_EQ(t.logExposure(-5.0), t.logExposure(0.0));
    // A thick path transmits less: the pixel with the largest integral has the lowest intensity.
    const auto maxIt = std::max_element(img.pixels.begin(), img.pixels.end());
    EXPECT_EQ(std::min_element(I.begin(), I.end()) - I.begin(), maxIt - img.pixels.begin());
    EXPECT_THROW(applyTransmission(I, {0.0, 1.0}), SettingsError);
    EXPECT_THROW(applyTransmission(I, {0.02, -1.0}), SettingsError);

    // Display: the window applies to the log exposure min(0, log10(signal)), as film blackening;
    // the film look (invert) shows bone white and air black.
    for (double L : {0.0, 10.0, 120.0, 400.0})
        EXPECT_NEAR(t.logExposure(L), std::min(0.0, std::log10(t.intensity(L))), 1e-12) << L;
    EXPECT_TRUE(std::isfinite(t.logExposure(1e6))); // no underflow through thick paths
    DisplayWindow film{-3.0, 0.0, true, t};
    EXPECT_NEAR(film.map(0.0), 0.0, 1e-12); // 1.7 x exp(0) saturates the film: black
    const double bone = film.map(300.0);
    EXPECT_NEAR(bone, 1.0 - (t.logExposure(300.0) + 3.0) / 3.0, 1e-12);
    EXPECT_GT(bone, 0.5);
    DisplayWindow fluoro{-3.0, 0.0, false, t};
    EXPECT_NEAR(fluoro.map(300.0), 1.0 - bone, 1e-12);
    // More exposure darkens the film (lower brightness for the same path); a higher energy
    // attenuates less, so the same path also comes out darker.
    DisplayWindow more = film;
    more.transmission.exposure = 4.0;
    EXPECT_LT(more.map(300.0), bone);
    DisplayWindow harder = film;
    harder.transmission.muWaterPerMm = waterAttenuationPerMm(120);
    EXPECT_LT(harder.map(300.0), bone);
    auto logE = img.pixels;
    applyLogExposure(logE, t);
    EXPECT_NEAR(logE[1234], t.logExposure(img.pixels[1234]), 1e-6);
}

// ---- Depth cueing -------------------------------------------------------------------------------

TEST(XRay, DepthCueWeights) {
    const auto w = depthCueWeights(0.6, {100, 100, 50}, {1, 1, 2});
    EXPECT_NEAR(w.radiusMm, 0.5 * std::sqrt(3 * 100.0 * 100.0), 1e-9);
    EXPECT_NEAR(w.a + w.b * -w.radiusMm, 1.0, 1e-12); // front of the bounding sphere
    EXPECT_NEAR(w.a + w.b * w.radiusMm, 0.4, 1e-12); // back
    EXPECT_THROW(depthCueWeights(1.5, {8, 8, 8}, {1, 1, 1}), SettingsError);
    const auto none = depthCueWeights(0.0, {8, 8, 8}, {1, 1, 1});
    EXPECT_EQ(none.a, 1.0);
    EXPECT_EQ(none.b, 0.0);
}

TEST(XRay, DepthWeightedOraclesAgree) {
    // The analytic depth-weighted chords and the depth-weighted spatial ray integration are
    // independent computations of the same images.
    const Fixture& f = fixture();
    SpatialProjectorOptions so{0.25, ValueMapping::Mu, 0};
    so.depthCue = 0.8;
    SpatialProjector sp(f.volume, so);
    for (const auto& v : f.views) {
        const auto truth =
            f.phantom.project(v, {kM, f.d}, ValueMapping::Mu, f.volume.dims, f.volume.spacing, 0.8);
        const auto plain =
            f.phantom.project(v, {kM, f.d}, ValueMapping::Mu, f.volume.dims, f.volume.spacing);
        const double psnr = fvr::test::compare(sp.project(v, {kM, f.d}).pixels, truth.pixels).psnr;
        std::printf("[xray] depth-weighted spatial projector vs analytic: %.2f dB\n", psnr);
        EXPECT_GT(psnr, 33.0);
        // The weight changes the image (this test could not pass with the weight ignored).
        EXPECT_LT(fvr::test::compare(plain.pixels, truth.pixels).psnr, 25.0);
    }
}

TEST(XRay, DepthCuedFvrMatchesDepthWeightedIntegrals) {
    const Fixture& f = fixture();
    struct Case {
        TransformKind t;
        double over;
        Kernel k;
        bool deapodize;
        double floor;
    };
    // Floors a little below the measured values (printed).
    const Case cases[] = {{TransformKind::Fft, 1.25, Kernel::KaiserBessel4, true, 36.0},
                          {TransformKind::Fht, 1.25, Kernel::KaiserBessel4, true, 36.0},
                          {TransformKind::Fft, 2.0, Kernel::CatmullRom, false, 30.0},
                          {TransformKind::Fft, 2.0, Kernel::Linear, false, 24.0}};
    for (const Case& c : cases) {
        CpuFourierRenderer r(
            spectrumFor(c.t, c.over, c.deapodize ? std::optional<Kernel>(c.k) : std::nullopt));
        double cued = 0, uncued = 0;
        for (const auto& v : f.views) {
            const auto truth = f.phantom.project(v, {kM, f.d}, ValueMapping::Mu, f.volume.dims,
                                                 f.volume.spacing, 0.8);
            RenderParams p{v, {kM, f.d}, c.k};
            uncued += fvr::test::compare(r.render(p).pixels, truth.pixels).psnr / 3;
            p.depthCue = 0.8;
            cued += fvr::test::compare(r.render(p).pixels, truth.pixels).psnr / 3;
        }
        std::printf("[xray] depth cue 0.8 %s %s oversampling %.2f%s: %.2f dB (without the depth "
                    "term %.2f dB)\n",
                    transformName(c.t), kernelName(c.k), c.over, c.deapodize ? " deapodized" : "",
                    cued, uncued);
        EXPECT_GT(cued, c.floor) << kernelName(c.k);
        EXPECT_GT(cued, uncued + 8.0) << kernelName(c.k);
    }
}

TEST(XRay, DepthCueIsLinearInStrengthAndFftEqualsFht) {
    const Fixture& f = fixture();
    CpuFourierRenderer fft(spectrumFor(TransformKind::Fft, 1.25, std::nullopt));
    CpuFourierRenderer fht(spectrumFor(TransformKind::Fht, 1.25, std::nullopt));
    for (Kernel k : {Kernel::Linear, Kernel::BSpline, Kernel::CatmullRom, Kernel::Sinc4,
                     Kernel::KaiserBessel6}) {
        RenderParams p{f.views[1], {kM, f.d}, k};
        const auto i0 = fft.render(p);
        p.depthCue = 1.0;
        const auto i1 = fft.render(p);
        const auto h1 = fht.render(p);
        p.depthCue = 0.3;
        const auto i3 = fft.render(p);
        std::vector<float> lin(i0.pixels.size());
        for (std::size_t i = 0; i < lin.size(); ++i)
            lin[i] = i0.pixels[i] + 0.3f * (i1.pixels[i] - i0.pixels[i]);
        EXPECT_GT(fvr::test::compare(i3.pixels, lin).psnr, 100.0) << kernelName(k);
        EXPECT_GT(fvr::test::compare(h1.pixels, i1.pixels).psnr, 100.0) << kernelName(k);
    }
    EXPECT_THROW(fft.render({f.views[0], {kM, f.d}, Kernel::Nearest, 0.5}), SettingsError);
    EXPECT_THROW(fft.render({f.views[0], {kM, f.d}, Kernel::Linear, -0.1}), SettingsError);
}

// ---- Slice filters ------------------------------------------------------------------------------

TEST(XRay, SliceFilterResponse) {
    SliceFilter f;
    EXPECT_FALSE(f.active());
    EXPECT_EQ(f.response(3.0), 1.0);
    f.sharpenAmount = 2.0;
    f.sharpenSigmaMm = 1.5;
    EXPECT_NEAR(f.response(0.0), 1.0, 1e-15); // the mean is kept
    EXPECT_NEAR(f.response(10.0), 3.0, 1e-9); // high frequencies gain 1 + a
    f = {};
    f.bandLimitLpMm = 0.5;
    EXPECT_NEAR(f.response(0.5), 1.0 / std::sqrt(2.0), 1e-12); // -3 dB at the cutoff
    EXPECT_LT(f.response(0.75), 0.04);
    EXPECT_LT(f.response(1.0), 0.004);
    EXPECT_GT(f.response(0.3), 0.999);
    EXPECT_THROW(validateSliceFilter({-1.0, 1.0, 0.0}), SettingsError);
    EXPECT_THROW(validateSliceFilter({1.0, 0.0, 0.0}), SettingsError);
    EXPECT_THROW(validateSliceFilter({0.0, 1.0, -2.0}), SettingsError);
}

TEST(XRay, UnsharpMaskMatchesSpatialDefinition) {
    // Image + a (image - Gaussian blur of the image), the blur computed in the image domain.
    const Fixture& f = fixture();
    for (TransformKind t : {TransformKind::Fft, TransformKind::Fht}) {
        CpuFourierRenderer r(spectrumFor(t, 1.25, Kernel::KaiserBessel4));
        RenderParams p{f.views[0], {kM, f.d}, Kernel::KaiserBessel4};
        const auto plain = r.render(p);
        p.filter.sharpenAmount = 1.5;
        p.filter.sharpenSigmaMm = 2.5 * f.d; // 2.5 pixels
        const auto sharp = r.render(p);
        const auto blur = gaussianBlurPeriodic(plain.pixels, kM, 2.5);
        std::vector<double> want(blur.size());
        for (std::size_t i = 0; i < want.size(); ++i)
            want[i] = plain.pixels[i] + 1.5 * (plain.pixels[i] - blur[i]);
        const double err = maxRelError(sharp.pixels, want);
        std::printf("[xray] unsharp mask (%s) vs spatial definition: max rel error %.2e\n",
                    transformName(t), err);
        EXPECT_LT(err, 1e-4);
        EXPECT_GT(maxRelError(plain.pixels, want), 1e-2); // the filter does something
    }
}

TEST(XRay, BandLimitAndCombinedFilterMatchDefinitionInDouble) {
    const Fixture& f = fixture();
    for (TransformKind t : {TransformKind::Fft, TransformKind::Fht}) {
        CpuFourierRenderer r(spectrumFor(t, 1.0, std::nullopt));
        for (const SliceFilter& filter :
             {SliceFilter{0.0, 1.0, 0.1}, SliceFilter{0.8, 3.0, 0.15}}) {
            RenderParams p{f.views[2], {kM, f.d}, Kernel::CatmullRom};
            const auto plain = r.render(p);
            p.filter = filter;
            const auto got = r.render(p);
            const auto want = filterInDouble(plain.pixels, kM, f.d, filter);
            const double err = maxRelError(got.pixels, want);
            std::printf(
                "[xray] filter a=%.1f sigma=%.1f mm cutoff=%.2f lp/mm (%s): max rel error %.2e\n",
                filter.sharpenAmount, filter.sharpenSigmaMm, filter.bandLimitLpMm, transformName(t),
                err);
            EXPECT_LT(err, 1e-4);
            EXPECT_GT(maxRelError(plain.pixels, want), 1e-2);
        }
    }
}

// The oracle on real data: depth-cued FVR against the depth-weighted spatial ray
// integration of the same voxels (body CT in HU, 122x101x112 at 3 mm, mu values).
TEST(XRay, DepthCuedFvrMatchesDepthWeightedRayCastingOnRealCt) {
    const auto path = fvr::test::sharedData() / "volumes/body_ct_hu_3mm/example_ct.mhd";
    FVR_REQUIRE_DATA("volumes/body_ct_hu_3mm/example_ct.mhd");
    const Volume v = loadVolume(path);
    const int M = 256;
    const double d = defaultPixelSize(v.dims, v.spacing, M);
    SpatialProjectorOptions so{0.25, ValueMapping::Mu, 0};
    so.depthCue = 0.7;
    SpatialProjector sp(v, so);
    PreprocessOptions o;
    o.effort = PlannerEffort::Estimate;
    o.mapping = ValueMapping::Mu;
    o.oversampling = 1.25;
    o.deapodizeFor = Kernel::KaiserBessel4;
    CpuFourierRenderer r(preprocess(v, o));
    for (const ViewFrame& view : {ViewFrame::fromDirUp({0, 1, 0}, {0, 0, 1}),
                                  ViewFrame::fromDirUp({0.7, 0.6, 0.3}, {0, 0, 1})}) {
        const auto ref = sp.project(view, {M, d});
        RenderParams p{view, {M, d}, Kernel::KaiserBessel4};
        const double uncued = fvr::test::compare(r.render(p).pixels, ref.pixels).psnr;
        p.depthCue = 0.7;
        const double cued = fvr::test::compare(r.render(p).pixels, ref.pixels).psnr;
        std::printf("[xray] body CT, depth cue 0.7, KB4 deapodized 1.25x vs depth-weighted ray "
                    "casting: %.2f dB "
                    "(without the depth term %.2f dB)\n",
                    cued, uncued);
        EXPECT_GT(cued, 36.0); // measured 38.2 (axis view) and 53.8 dB (oblique)
        EXPECT_GT(cued, uncued + 10.0);
        // The trilinear voxel model (the depth term then also differentiates its transfer
        // function), against the same trilinear ray caster: like with like.
        p.voxelModel = VoxelModel::Trilinear;
        p.clipToVolume = true;
        const double model = fvr::test::compare(r.render(p).pixels, ref.pixels).psnr;
        p.depthCue = 0.0;
        const double modelUncued = fvr::test::compare(r.render(p).pixels, ref.pixels).psnr;
        std::printf("[xray] body CT, depth cue 0.7, trilinear voxel model vs depth-weighted ray "
                    "casting: %.2f dB "
                    "(without the depth term %.2f dB)\n",
                    model, modelUncued);
        EXPECT_GT(model, cued + 3.0); // measured +10.5 dB (axis view), +3.5 dB (oblique)
        EXPECT_GT(model, modelUncued + 10.0);
    }
}

// Clip to the volume: pixels whose ray misses the volume (grown by a voxel) are 0, as in the true
// projection, so the kernel's ghost copies and ringing outside the volume's shadow disappear.
TEST(XRay, ClipToVolumeRemovesGhostsOutsideTheShadow) {
    const Fixture& f = fixture();
    // A wide field (pixel size 1.5 x the default) puts the first ghost copies inside the image.
    const double d = 1.5 * f.d;
    CpuFourierRenderer r(spectrumFor(TransformKind::Fft, 1.0, std::nullopt));
    for (const auto& v : f.views) {
        const auto truth =
            f.phantom.project(v, {kM, d}, ValueMapping::Mu, f.volume.dims, f.volume.spacing);
        RenderParams p{v, {kM, d}, Kernel::Linear};
        const auto plain = r.render(p);
        p.clipToVolume = true;
        const auto clipped = r.render(p);
        const Vec3 half =
            supportHalfExtents(f.volume.dims, f.volume.spacing, voxelModelReach(p.voxelModel));
        int outside = 0;
        double ghost = 0;
        for (int row = 0; row < kM; ++row)
            for (int col = 0; col < kM; ++col) {
                const std::size_t i = std::size_t(row) * kM + col;
                if (rayMissesVolume(v, half, kM, d, col, row)) {
                    ++outside;
                    EXPECT_EQ(clipped.pixels[i], 0.0f);
                    EXPECT_EQ(truth.pixels[i], 0.0f); // the oracle agrees: nothing out there
                    ghost = std::max(ghost, double(std::abs(plain.pixels[i])));
                } else {
                    EXPECT_EQ(clipped.pixels[i], plain.pixels[i]);
                }
            }
        const double before = fvr::test::compare(plain.pixels, truth.pixels).psnr;
        const double after = fvr::test::compare(clipped.pixels, truth.pixels).psnr;
        std::printf("[xray] clip to volume (linear, 1x, wide field): %d pixels outside, largest "
                    "ghost %.1f mm; "
                    "PSNR %.2f -> %.2f dB\n",
                    outside, ghost, before, after);
        EXPECT_GT(outside, kM * kM / 10);
        EXPECT_GT(after, before + 0.1); // measured +0.5, +0.2, +1.2 dB
        EXPECT_GT(ghost, 5.0); // ghosts of 12-30 mm (peak ~500 mm) were there
    }
}

TEST(XRay, ShadowColumnsAreExactlyThePixelsWhoseRaysHit) {
    // The per-row run the clip uses equals the per-pixel test, for oblique, axis and edge-on
    // views, thin and flat volumes, fields narrower and wider than the volume.
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::vector<ViewFrame> views{ViewFrame::fromDirUp({0, 0, 1}, {0, -1, 0}),
                                 ViewFrame::fromDirUp({1, 0, 0}, {0, 0, 1}),
                                 ViewFrame::fromDirUp({1, 1, 0}, {0, 0, 1})};
    for (int i = 0; i < 20; ++i)
        views.push_back(ViewFrame::fromDirUp({u(rng), u(rng), u(rng) + 0.01}, {0, 0, 1}));
    const std::pair<Dims3, Vec3> volumes[] = {
        {{64, 64, 64}, {4, 4, 4}}, {{512, 512, 40}, {0.5, 0.5, 3}}, {{10, 200, 30}, {1, 1, 2}}};
    for (const auto& [dims, spacing] : volumes)
        for (const ViewFrame& view : views)
            for (double scale : {0.5, 1.0, 1.7}) {
                const int M = 64;
                const double d = scale * defaultPixelSize(dims, spacing, M);
                const Vec3 half = supportHalfExtents(dims, spacing, scale < 1.0 ? 1.0 : 1.5);
                for (int row = 0; row < M; ++row) {
                    const ColumnRange r = volumeShadowColumns(view, half, M, d, row);
                    for (int col = 0; col < M; ++col)
                        ASSERT_EQ(rayMissesVolume(view, half, M, d, col, row),
                                  !(col >= r.first && col <= r.last))
                            << "row " << row << " col " << col << " range " << r.first << ".."
                            << r.last;
                }
            }
}
