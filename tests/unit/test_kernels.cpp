#include <cmath>

#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/kernels.h>

using namespace fvr::core;

TEST(Kernels, TableMatchesContinuousKernel) {
    for (Kernel k : allKernels()) {
        if (k == Kernel::Nearest || k == Kernel::Sinc4) continue; // sinc is normalised, below
        KernelTable t(k);
        float w[4];
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
        float w[4];
        t.weights(0.0, w);
        if (!kernelInterpolates(k)) {
            EXPECT_NEAR(w[1], 2.0 / 3.0, 1e-6); // B-spline: 1/6, 2/3, 1/6
            continue;
        }
        for (int j = 0; j < t.taps(); ++j)
            EXPECT_NEAR(w[j], (t.firstTapOffset() + j) == 0 ? 1.0 : 0.0, 1e-7) << kernelName(k);
    }
}

TEST(Kernels, WeightsPartitionUnity) {
    for (Kernel k : allKernels()) {
        KernelTable t(k);
        float w[4];
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
    EXPECT_THROW(parseKernel("lanczos"), SettingsError);
}
