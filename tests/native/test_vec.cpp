#include <gtest/gtest.h>

#include "core/vec.h"

using namespace coherent;

TEST(Vec, BasisIsOrthonormal) {
    for (Vec3f n : {Vec3f(0, 0, 1), Vec3f(0, 0, -1), normalize(Vec3f(1, 2, 3)), normalize(Vec3f(-1e-6f, 1, 0))}) {
        Vec3f t, b;
        make_basis(n, t, b);
        EXPECT_NEAR(dot(t, n), 0.0f, 1e-6f);
        EXPECT_NEAR(dot(b, n), 0.0f, 1e-6f);
        EXPECT_NEAR(dot(t, b), 0.0f, 1e-6f);
        EXPECT_NEAR(length(t), 1.0f, 1e-6f);
        EXPECT_NEAR(length(b), 1.0f, 1e-6f);
    }
}
