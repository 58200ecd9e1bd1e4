// The Vec3 helper set (vec3.h) on hand-worked cases.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include <fvr/core/vec3.h>

using namespace fvr::core;

namespace {

void expectVec(const Vec3& got, const Vec3& want) {
    for (int i = 0; i < 3; ++i) EXPECT_DOUBLE_EQ(got[i], want[i]) << "component " << i;
}

} // namespace

TEST(Vec3, AddSubScale) {
    expectVec(add({1, 2, 3}, {4, -5, 0.5}), {5, -3, 3.5});
    expectVec(sub({1, 2, 3}, {4, -5, 0.5}), {-3, 7, 2.5});
    expectVec(scale({1, -2, 3}, -2.0), {-2, 4, -6});
    expectVec(scale({1, -2, 3}, 0.0), {0, 0, 0});
}

TEST(Vec3, Dot) {
    EXPECT_DOUBLE_EQ(dot({1, 2, 3}, {4, -5, 6}), 4 - 10 + 18); // 12
    EXPECT_DOUBLE_EQ(dot({1, 0, 0}, {0, 1, 0}), 0.0);
    EXPECT_DOUBLE_EQ(dot({2, 3, 6}, {2, 3, 6}), 49.0);
}

TEST(Vec3, CrossIsRightHanded) {
    expectVec(cross({1, 0, 0}, {0, 1, 0}), {0, 0, 1});
    expectVec(cross({0, 1, 0}, {0, 0, 1}), {1, 0, 0});
    expectVec(cross({0, 0, 1}, {1, 0, 0}), {0, 1, 0});
    expectVec(cross({0, 1, 0}, {1, 0, 0}), {0, 0, -1});
    // (1,2,3) x (4,5,6) = (2*6 - 3*5, 3*4 - 1*6, 1*5 - 2*4) = (-3, 6, -3)
    expectVec(cross({1, 2, 3}, {4, 5, 6}), {-3, 6, -3});
    expectVec(cross({1, 2, 3}, {2, 4, 6}), {0, 0, 0}); // parallel
}

TEST(Vec3, Norm) {
    EXPECT_DOUBLE_EQ(norm({3, 4, 0}), 5.0);
    EXPECT_DOUBLE_EQ(norm({2, -3, 6}), 7.0);
    EXPECT_DOUBLE_EQ(norm({0, 0, 0}), 0.0);
}

TEST(Vec3, Normalized) {
    const auto a = normalized({0, 3, 4});
    ASSERT_TRUE(a);
    expectVec(*a, {0, 0.6, 0.8});
    const auto b = normalized({-2, 0, 0});
    ASSERT_TRUE(b);
    expectVec(*b, {-1, 0, 0});
    EXPECT_FALSE(normalized({0, 0, 0}));
    EXPECT_FALSE(normalized({1e-13, 0, 0})); // below the default 1e-12
    EXPECT_TRUE(normalized({1e-13, 0, 0}, 1e-14)); // but above a smaller bound
    EXPECT_FALSE(normalized({1, 0, 0}, 1.0)); // the bound is exclusive
    const double inf = std::numeric_limits<double>::infinity();
    EXPECT_FALSE(normalized({inf, 0, 0}));
    EXPECT_FALSE(normalized({std::nan(""), 1, 0}));
}
