// Deapodization: the kernels' Fourier transforms, the per-axis factors, what preprocess() does
// with them and how the renderer guards the kernel. Accuracy numbers: test_accuracy.cpp.
#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/render/kernels.h>
#include <fvr/core/render/preprocess.h>

using namespace fvr::core;

namespace {

/** Integral of kernelValue(k, x) cos(2 pi u x) dx by a fine midpoint rule (independent of the
 *  library's Simpson integration). */
double integrateFourier(Kernel k, double u, double sigma) {
    const double r = kernelTaps(k) / 2.0;
    const int n = 20000;
    const double h = 2 * r / n;
    double s = 0;
    for (int i = 0; i < n; ++i) {
        const double x = -r + (i + 0.5) * h;
        s += kernelValue(k, x, sigma) * std::cos(2 * std::numbers::pi * u * x);
    }
    return s * h;
}

} // namespace

TEST(Deapodization, FourierTransformsMatchNumericIntegrals) {
    for (Kernel k : allKernels())
        for (double sigma : {1.0, 1.5, 2.0}) {
            const double norm = integrateFourier(k, 0.0, sigma);
            EXPECT_NEAR(kernelFourier(k, 0.0, sigma), 1.0, 1e-12) << kernelName(k);
            for (double u : {0.05, 0.17, 0.25, 0.33, 0.5, 0.8, 1.0, 1.3}) {
                const double expected = integrateFourier(k, u, sigma) / norm;
                EXPECT_NEAR(kernelFourier(k, u, sigma), expected, 2e-6)
                    << kernelName(k) << " sigma " << sigma << " u " << u;
            }
        }
}

TEST(Deapodization, KaiserBesselHasUnitIntegral) {
    for (Kernel k : {Kernel::KaiserBessel4, Kernel::KaiserBessel6})
        for (double sigma : {1.0, 1.25, 2.0})
            EXPECT_NEAR(integrateFourier(k, 0.0, sigma), 1.0, 1e-6);
}

TEST(Deapodization, FactorsSitAtCentredVoxelPositions) {
    // Odd n: voxel n/2 is the centre (factor 1) at padded index 0; even n: half-voxel offsets.
    const auto odd = deapodizationFactors(Kernel::Linear, 5, 10, 2.0);
    ASSERT_EQ(odd.size(), 10u);
    EXPECT_FLOAT_EQ(odd[0], 1.0f);
    for (int x = 0; x < 5; ++x) {
        const int j = (x - 2 + 10) % 10;
        const double s =
            std::sin(std::numbers::pi * (x - 2) / 10.0) / (std::numbers::pi * (x - 2) / 10.0);
        EXPECT_NEAR(odd[j], x == 2 ? 1.0 : 1.0 / (s * s), 1e-6) << x;
    }
    for (int j : {3, 4, 5, 6, 7}) EXPECT_EQ(odd[j], 1.0f); // padding: no voxel
    const auto even = deapodizationFactors(Kernel::Nearest, 4, 8, 2.0);
    // voxel 2 sits at padded index 0, at offset +0.5 from the centre 1.5.
    const double u = 0.5 / 8.0;
    EXPECT_NEAR(even[0], 1.0 / (std::sin(std::numbers::pi * u) / (std::numbers::pi * u)), 1e-6);
    EXPECT_NEAR(even[7], even[0], 1e-7); // voxel 1 at -0.5: symmetric
}

TEST(Deapodization, PreprocessDividesByTheSeparableTransform) {
    Volume v;
    v.dims = {9, 8, 7};
    v.spacing = {1, 1, 1};
    v.voxels.assign(std::size_t(v.voxelCount()), 0.0f);
    v.voxels[std::size_t(v.index(1, 6, 2))] = 3.0f;
    PreprocessOptions o;
    o.effort = PlannerEffort::Estimate;
    o.oversampling = 1.5;
    o.deapodizeFor = Kernel::KaiserBessel4;
    const auto s = preprocess(v, o);
    ASSERT_TRUE(s->deapodizedFor.has_value());
    EXPECT_EQ(*s->deapodizedFor, Kernel::KaiserBessel4);
    const double sigma = kernelOversampling(v.dims, s->padded);
    // DC = the sum of the voxels, each divided by the product of the per-axis transforms.
    const double expected =
        3.0 / (kernelFourier(Kernel::KaiserBessel4, (1 - 4.0) / s->padded[0], sigma) *
               kernelFourier(Kernel::KaiserBessel4, (6 - 3.5) / s->padded[1], sigma) *
               kernelFourier(Kernel::KaiserBessel4, (2 - 3.0) / s->padded[2], sigma));
    EXPECT_NEAR(s->valueAt(0, 0, 0).real(), expected, 1e-5 * expected);
    // Without deapodization: the plain sum, and nothing recorded.
    o.deapodizeFor.reset();
    const auto plain = preprocess(v, o);
    EXPECT_FALSE(plain->deapodizedFor.has_value());
    EXPECT_NEAR(plain->valueAt(0, 0, 0).real(), 3.0, 1e-6);
}

TEST(Deapodization, RendererRefusesAnotherKernel) {
    Volume v;
    v.dims = {8, 8, 8};
    v.spacing = {1, 1, 1};
    v.voxels.assign(512, 1.0f);
    PreprocessOptions o;
    o.effort = PlannerEffort::Estimate;
    o.deapodizeFor = Kernel::KaiserBessel6;
    CpuFourierRenderer r(preprocess(v, o), 1);
    const ImageGeometry g{32, defaultPixelSize(v.dims, v.spacing, 32)};
    EXPECT_THROW(r.render({ViewFrame{}, g, Kernel::Linear}), SettingsError);
    EXPECT_NO_THROW(r.render({ViewFrame{}, g, Kernel::KaiserBessel6}));
}
