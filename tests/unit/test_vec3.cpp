// Vec3 (vec3.h: GLM's double vector) and the operations the code uses on it, on hand-worked
// cases: the conventions (a right-handed cross product, zero-initialised braces) and normalized().
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include <fvr/core/vec3.h>

using namespace fvr::core;

namespace {

void expectVec(const Vec3& got, const Vec3& want) {
    for (int i = 0; i < 3; ++i) EXPECT_DOUBLE_EQ(got[i], want[i]) << "component " << i;
}

} // namespace

TEST(Vec3, BracesZeroAndComponents) {
    const Vec3 zero{};
    expectVec(zero, {0, 0, 0});
    const Vec3 v{1, -2, 3.5};
    EXPECT_EQ(v.x, 1.0);
    EXPECT_EQ(v[1], -2.0);
    EXPECT_EQ(v.z, 3.5);
    EXPECT_EQ(Vec3(1, 2, 3), (Vec3{1, 2, 3}));
    EXPECT_NE(Vec3(1, 2, 3), (Vec3{1, 2, 4}));
}

TEST(Vec3, AddSubScale) {
    expectVec(Vec3{1, 2, 3} + Vec3{4, -5, 0.5}, {5, -3, 3.5});
    expectVec(Vec3{1, 2, 3} - Vec3{4, -5, 0.5}, {-3, 7, 2.5});
    expectVec(Vec3{1, -2, 3} * -2.0, {-2, 4, -6});
    expectVec(Vec3{1, -2, 3} * 0.0, {0, 0, 0});
}

TEST(Vec3, Dot) {
    EXPECT_DOUBLE_EQ(glm::dot(Vec3{1, 2, 3}, Vec3{4, -5, 6}), 4 - 10 + 18); // 12
    EXPECT_DOUBLE_EQ(glm::dot(Vec3{1, 0, 0}, Vec3{0, 1, 0}), 0.0);
    EXPECT_DOUBLE_EQ(glm::dot(Vec3{2, 3, 6}, Vec3{2, 3, 6}), 49.0);
}

TEST(Vec3, CrossIsRightHanded) {
    auto cross = [](const Vec3& a, const Vec3& b) { return glm::cross(a, b); };
    expectVec(cross({1, 0, 0}, {0, 1, 0}), {0, 0, 1});
    expectVec(cross({0, 1, 0}, {0, 0, 1}), {1, 0, 0});
    expectVec(cross({0, 0, 1}, {1, 0, 0}), {0, 1, 0});
    expectVec(cross({0, 1, 0}, {1, 0, 0}), {0, 0, -1});
    // (1,2,3) x (4,5,6) = (2*6 - 3*5, 3*4 - 1*6, 1*5 - 2*4) = (-3, 6, -3)
    expectVec(cross({1, 2, 3}, {4, 5, 6}), {-3, 6, -3});
    expectVec(cross({1, 2, 3}, {2, 4, 6}), {0, 0, 0}); // parallel
}

TEST(Vec3, Length) {
    EXPECT_DOUBLE_EQ(glm::length(Vec3{3, 4, 0}), 5.0);
    EXPECT_DOUBLE_EQ(glm::length(Vec3{2, -3, 6}), 7.0);
    EXPECT_DOUBLE_EQ(glm::length(Vec3{0, 0, 0}), 0.0);
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
