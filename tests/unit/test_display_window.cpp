// The film window: the one rule for the display window of a projection, with and
// without Beer-Lambert transmission.
#include <algorithm>
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include <fvr/core/xray/display_window.h>

using namespace fvr::core;

namespace {
std::vector<float> ramp() {
    std::vector<float> v(1001);
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = float(i) * 0.5f; // 0 .. 500 mm of water
    return v;
}
} // namespace

TEST(FilmWindow, LineIntegralsWithoutTransmission) {
    const std::vector<float> L = ramp();
    EXPECT_EQ(windowedValues(L, {}), L);
    const DisplayWindow w = filmWindow(L, {}, true);
    const DisplayWindow a = autoWindow(L);
    EXPECT_EQ(w.low, a.low);
    EXPECT_EQ(w.high, a.high);
    EXPECT_TRUE(w.invert);
    EXPECT_FALSE(w.transmission.active());
    EXPECT_DOUBLE_EQ(w.low, 2.5); // the 0.5 percentile of 0, 0.5, ..., 500: index 5
    EXPECT_DOUBLE_EQ(w.high, 497.5); // the 99.5 percentile: index 995
}

TEST(FilmWindow, LogExposureWithTransmission) {
    const std::vector<float> L = ramp();
    const Transmission t{0.02, 2.0};
    const std::vector<float> logE = windowedValues(L, t);
    ASSERT_EQ(logE.size(), L.size());
    for (std::size_t i = 0; i < L.size(); ++i) EXPECT_FLOAT_EQ(logE[i], float(t.logExposure(L[i])));
    // log10(2) - 0.02 L / ln 10 saturates at 0 below L = 15 mm: the window is the percentiles of
    // the log exposure (decreasing in L), and maps line integrals through it.
    const DisplayWindow w = filmWindow(L, t, true);
    EXPECT_TRUE(w.invert);
    EXPECT_EQ(w.transmission.muWaterPerMm, 0.02);
    EXPECT_EQ(w.transmission.exposure, 2.0);
    EXPECT_NEAR(w.low, t.logExposure(497.5), 1e-6);
    EXPECT_DOUBLE_EQ(w.high, 0.0);
    EXPECT_NEAR(w.map(497.5), 1.0, 1e-6); // thick: low exposure, inverted to white (bone white)
    EXPECT_NEAR(w.map(0.0), 0.0, 1e-12); // air: full exposure, black
    const DisplayWindow fluoro = filmWindow(L, t, false);
    EXPECT_NEAR(fluoro.map(0.0), 1.0, 1e-12);
}
