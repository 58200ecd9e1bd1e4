#include <cmath>

#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/render/kernels.h>

using namespace fvr::core;

TEST(Kernels, TableMatchesContinuousKernel) {
    for (Kernel k : allKernels()) {
        if (k == Kernel::Nearest || k == Kernel::Sinc4) continue; // sinc is normalised, below
        KernelTable t(k);
        float w[KernelTable::kMaxTaps];
        for (double frac : {0.0, 0.1234, 0.5, 0.77, 0.999}) {
            t.weights(frac, w);
            for (int j = 0; j < t.taps(); ++j)
                EXPECT_NEAR(w[j], kernelValue(k, frac - (t.firstTapOffset() + j)), 2e-6)
                    << kernelName(k) << " frac " << frac << " tap " << j;
        }
    }
}

TEST(Kernels, InterpolatingKernelsAreExactAtGridPoints) {
    for (Kernel k : allKernels()) {
        KernelTable t(k);
        float w[KernelTable::kMaxTaps];
        t.weights(0.0, w);
        if (k == Kernel::BSpline) {
            EXPECT_NEAR(w[1], 2.0 / 3.0, 1e-6); // B-spline: 1/6, 2/3, 1/6
            continue;
        }
        if (!kernelInterpolates(k)) continue; // Kaiser-Bessel: see below
        for (int j = 0; j < t.taps(); ++j)
            EXPECT_NEAR(w[j], (t.firstTapOffset() + j) == 0 ? 1.0 : 0.0, 1e-7) << kernelName(k);
    }
}

TEST(Kernels, WeightsPartitionUnity) {
    for (Kernel k : allKernels()) {
        if (k == Kernel::KaiserBessel4 || k == Kernel::KaiserBessel6) continue; // below
        KernelTable t(k);
        float w[KernelTable::kMaxTaps];
        for (int i = 0; i < 100; ++i) {
            t.weights(i / 100.0, w);
            double s = 0;
            for (int j = 0; j < t.taps(); ++j) s += w[j];
            EXPECT_NEAR(s, 1.0, 1e-6) << kernelName(k) << " at " << i / 100.0;
        }
    }
}

TEST(Kernels, SincIsBlackmanWindowed) {
    // At x = 1.5: sinc(1.5) = -2/(3 pi), window 0.42 + 0.5 cos(0.75 pi) + 0.08 cos(1.5 pi).
    const double expected = -2.0 / (3.0 * M_PI) * (0.42 + 0.5 * std::cos(0.75 * M_PI));
    EXPECT_NEAR(kernelValue(Kernel::Sinc4, 1.5), expected, 1e-12);
    EXPECT_EQ(kernelValue(Kernel::Sinc4, 2.0), 0.0);
    EXPECT_NEAR(kernelValue(Kernel::Sinc4, 1.0), 0.0, 1e-15);
}

TEST(Kernels, ParseNames) {
    for (Kernel k : allKernels()) EXPECT_EQ(parseKernel(kernelName(k)), k);
    EXPECT_EQ(parseKernel("kaiser-bessel"), Kernel::KaiserBessel4);
    EXPECT_EQ(kaiserBesselKernel(4), Kernel::KaiserBessel4);
    EXPECT_EQ(kaiserBesselKernel(6), Kernel::KaiserBessel6);
    EXPECT_THROW(kaiserBesselKernel(5), SettingsError);
    EXPECT_THROW(parseKernel("lanczos"), SettingsError);
}

TEST(Kernels, KaiserBesselBetaFollowsBeatty) {
    // beta = pi sqrt((W/sigma)^2 (sigma - 1/2)^2 - 0.8)
    EXPECT_NEAR(kaiserBesselBeta(4, 2.0), M_PI * std::sqrt(8.2), 1e-12);
    EXPECT_NEAR(kaiserBesselBeta(6, 2.0), M_PI * std::sqrt(19.45), 1e-12);
    EXPECT_NEAR(kaiserBesselBeta(4, 1.0), M_PI * std::sqrt(3.2), 1e-12);
    EXPECT_NEAR(kaiserBesselBeta(4, 1.25), M_PI * std::sqrt(4.96), 1e-12);
    EXPECT_EQ(kernelTaps(Kernel::KaiserBessel4), 4);
    EXPECT_EQ(kernelTaps(Kernel::KaiserBessel6), 6);
    EXPECT_EQ(KernelTable(Kernel::KaiserBessel6).firstTapOffset(), -2);
    EXPECT_NEAR(kernelOversampling({64, 64, 50}, {128, 128, 75}), 1.5, 1e-12);
}

TEST(Kernels, KaiserBesselTablesDependOnOversampling) {
    for (Kernel k : {Kernel::KaiserBessel4, Kernel::KaiserBessel6})
        for (double sigma : {1.0, 1.25, 1.5, 2.0}) {
            KernelTable t(k, sigma);
            EXPECT_EQ(t.oversampling(), sigma);
            float w[KernelTable::kMaxTaps];
            for (double frac : {0.0, 0.3, 0.5, 0.91}) {
                t.weights(frac, w);
                double sum = 0;
                for (int j = 0; j < t.taps(); ++j) {
                    EXPECT_NEAR(w[j], kernelValue(k, frac - (t.firstTapOffset() + j), sigma), 2e-6);
                    sum += w[j];
                }
                // Unit integral, so the weights sum to 1 up to the kernel's aliases (which shrink
                // as the oversampling grows): within 3% at sigma 1, 1% at 1.25, 1e-3 at sigma 2.
                EXPECT_NEAR(sum, 1.0, sigma >= 2.0 ? 1e-3 : (sigma >= 1.25 ? 1e-2 : 3e-2))
                    << kernelName(k) << " sigma " << sigma;
            }
        }
    KernelTable a(Kernel::KaiserBessel4, 1.0), b(Kernel::KaiserBessel4, 2.0);
    EXPECT_NE(a.table(), b.table());
}
