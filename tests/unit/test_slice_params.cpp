// The rules both renderers share: the slice parameters against a hand-worked case and
// the slice filter's per-frame table against the filter's definition in double.
#include <cmath>
#include <limits>
#include <numbers>

#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/render/slice_filter.h>
#include <fvr/core/render/slice_params.h>

using namespace fvr::core;

namespace {

Spectrum handWorkedSpectrum() {
    Spectrum s; // no data: sliceParams reads the geometry only
    s.volumeDims = {4, 5, 6};
    s.padded = {8, 10, 12};
    s.spacing = {1.0, 2.0, 3.0};
    return s;
}

RenderParams handWorkedParams() {
    RenderParams p; // default view: d = (0, 0, 1), u = (0, -1, 0), r = (1, 0, 0)
    p.image = {16, 0.5}; // M d = 8 mm
    return p;
}

} // namespace

TEST(SliceParams, HandWorkedCase) {
    const SliceParams sp = sliceParams(handWorkedSpectrum(), handWorkedParams());
    // Per spectrum index along each axis: s_a P_a / (M d) = 8/8, 20/8, 36/8.
    EXPECT_DOUBLE_EQ(sp.A[0], 1.0);
    EXPECT_DOUBLE_EQ(sp.A[1], 0.0);
    EXPECT_DOUBLE_EQ(sp.A[2], 0.0);
    EXPECT_DOUBLE_EQ(sp.B[0], 0.0);
    EXPECT_DOUBLE_EQ(sp.B[1], 2.5); // -u_y = +1
    EXPECT_DOUBLE_EQ(sp.B[2], 0.0);
    EXPECT_DOUBLE_EQ(sp.scale, 6.0 / 64.0); // s_x s_y s_z / (M d)^2
    for (int a = 0; a < 3; ++a) {
        EXPECT_EQ(sp.padded[a], 8 + 2 * a);
        EXPECT_DOUBLE_EQ(sp.invP[a], 1.0 / double(8 + 2 * a));
        EXPECT_DOUBLE_EQ(sp.half[a], 4.0 + a);
        EXPECT_DOUBLE_EQ(sp.E[a], 0.0);
    }
    EXPECT_TRUE(sp.banded);
    EXPECT_TRUE(sp.anti[0]);
    EXPECT_FALSE(sp.anti[1]);
    EXPECT_TRUE(sp.anti[2]);
    EXPECT_EQ(sp.taps, 2);
    EXPECT_FALSE(sp.depth);
    EXPECT_DOUBLE_EQ(sp.depthA, 1.0);
    // (M/2 + 1)(|A_a| + |B_a|) / P_a: 9/8 along x, 9 x 2.5/10 along y.
    EXPECT_DOUBLE_EQ(sp.maxCyclesPerVoxel, 2.25);
}

TEST(SliceParams, DepthCueAndCompactModels) {
    RenderParams p = handWorkedParams();
    p.depthCue = 0.5;
    p.voxelModel = VoxelModel::Trilinear;
    const SliceParams sp = sliceParams(handWorkedSpectrum(), p);
    // R = sqrt(4^2 + 10^2 + 18^2) / 2 mm; a = 1 - S/2, b = -S / (2R); E_z = b/(2 pi) d_z s_z P_z.
    const double R = 0.5 * std::sqrt(440.0);
    EXPECT_TRUE(sp.depth);
    EXPECT_EQ(sp.taps, 3); // linear with depth cueing: the central difference needs 3 taps
    EXPECT_DOUBLE_EQ(sp.depthA, 0.75);
    EXPECT_DOUBLE_EQ(sp.E[0], 0.0);
    EXPECT_DOUBLE_EQ(sp.E[1], 0.0);
    EXPECT_NEAR(sp.E[2], -0.25 / R / (2.0 * std::numbers::pi) * 36.0, 1e-15);
    EXPECT_FALSE(sp.banded);
    for (int a = 0; a < 3; ++a) EXPECT_EQ(sp.half[a], std::numeric_limits<double>::infinity());
}

TEST(SliceParams, TapsAndKernelCheck) {
    EXPECT_EQ(sliceTaps(Kernel::Nearest, false), 1);
    EXPECT_EQ(sliceTaps(Kernel::Linear, false), 2);
    EXPECT_EQ(sliceTaps(Kernel::Linear, true), 3);
    EXPECT_EQ(sliceTaps(Kernel::CatmullRom, true), 4);
    EXPECT_EQ(sliceTaps(Kernel::KaiserBessel6, true), 6);
    Spectrum s = handWorkedSpectrum();
    EXPECT_NO_THROW(checkKernelMatchesSpectrum(s, Kernel::Linear));
    s.deapodizedFor = Kernel::KaiserBessel4;
    EXPECT_NO_THROW(checkKernelMatchesSpectrum(s, Kernel::KaiserBessel4));
    EXPECT_THROW(checkKernelMatchesSpectrum(s, Kernel::Linear), SettingsError);
}

TEST(SliceFilterTable, MatchesTheFilterDefinitionInDouble) {
    const int M = 64;
    const double d = 0.7;
    for (bool aperture : {false, true})
        for (const SliceFilter& f : {SliceFilter{1.2, 3.0, 0.2}, SliceFilter{0.0, 1.0, 0.3},
                                     SliceFilter{2.0, 0.8, 0.0}, SliceFilter{}}) {
            const SliceFilterTable t(f, aperture, M, d);
            EXPECT_EQ(t.on, f.active() || aperture);
            for (int n = -M / 2; n < M / 2; ++n)
                for (int m = -M / 2; m < M / 2; ++m) {
                    double want = f.response(std::hypot(double(m), double(n)) / (M * d));
                    if (aperture)
                        want *= pixelApertureResponse(double(m) / M) *
                                pixelApertureResponse(double(n) / M);
                    ASSERT_NEAR(t(m, n), want, 2e-6 * std::max(1.0, std::abs(want)))
                        << m << "," << n << " aperture " << aperture << " sharpen "
                        << f.sharpenAmount;
                }
        }
}

TEST(SliceFilterTable, GainIsOneWithoutFilter) {
    EXPECT_EQ(sliceFilterGain(0.0, 0.3, 0.0), 1.0);
    EXPECT_EQ(sliceFilterGain(2.0f, 1.0f, 0.0f), 1.0f);
    // -3 dB at the cutoff: q = 1 gives 1 / sqrt(2).
    EXPECT_DOUBLE_EQ(sliceFilterGain(0.0, 1.0, 1.0), 1.0 / std::sqrt(2.0));
}
