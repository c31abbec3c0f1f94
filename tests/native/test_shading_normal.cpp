// valid_reflection_normal (render/shading_normal.h), Cycles 3.4's
// ensure_valid_reflection, checked against what it promises rather than
// against a copy of its formula:
// - a shading normal whose mirror direction of the viewer is already above
//   the surface (by the threshold) is returned unchanged;
// - otherwise the result is a unit vector in the plane of the normal and the
//   geometric normal whose mirror direction is above the surface, lifted no
//   higher than the threshold, and almost always exactly to it (the smallest
//   rotation that makes it valid);
// - it changes continuously with the input normal (no jump to ng).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "render/shading_normal.h"
#include "test_seed.h"

namespace coherent {
namespace {

Vec3f mirror(const Vec3f& n, const Vec3f& wo) { return n * (2.0f * dot(n, wo)) - wo; }

float threshold(const Vec3f& ng, const Vec3f& wo) { return std::min(0.9f * dot(ng, wo), 0.01f); }

TEST(ShadingNormal, AValidNormalIsKept) {
    const Vec3f ng(0, 0, 1), wo = normalize(Vec3f(0.3f, 0.1f, 1.0f));
    const Vec3f n = normalize(Vec3f(-0.2f, 0.1f, 1.0f));
    const Vec3f got = valid_reflection_normal(ng, wo, n);
    EXPECT_EQ(got.x, n.x);
    EXPECT_EQ(got.y, n.y);
    EXPECT_EQ(got.z, n.z);
}

TEST(ShadingNormal, AnInvalidNormalIsBentJustEnough) {
    std::mt19937 gen(test::test_seed(7));
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    const Vec3f ng(0, 0, 1);
    int bent = 0, on_threshold = 0;
    for (int i = 0; i < 20000; ++i) {
        // Grazing viewers and strongly tilted normals, all on ng's side.
        const Vec3f wo = normalize(Vec3f(u(gen), u(gen), 0.02f + 0.3f * std::fabs(u(gen))));
        const Vec3f n = normalize(Vec3f(u(gen), u(gen), 0.05f + std::fabs(u(gen))));
        const float t = threshold(ng, wo);
        if (dot(ng, mirror(n, wo)) >= t) continue;
        const Vec3f got = valid_reflection_normal(ng, wo, n);
        ++bent;
        ASSERT_NEAR(length(got), 1.0f, 1e-4f);
        // In the plane of n and ng.
        EXPECT_NEAR(dot(got, normalize(cross(n, ng))), 0.0f, 1e-4f);
        // Its mirror direction is above the surface and lifted no higher than
        // the threshold: the rotation is the smallest that makes it valid
        // (or the normal gave up and became ng, where no rotation works).
        if (got.z < 1.0f - 1e-6f) {
            const float lifted = dot(ng, mirror(got, wo));
            EXPECT_GT(lifted, 0.0f) << i;
            EXPECT_LE(lifted, t + 2e-3f) << i;
            EXPECT_GT(dot(got, wo), 0.0f);
            on_threshold += std::fabs(lifted - t) < 2e-3f ? 1 : 0;
        }
    }
    EXPECT_GT(bent, 2000);
    EXPECT_GT(on_threshold, bent * 99 / 100);  // the quadratic's other root is rare
}

// Normals that disagree with the winding (the generated Cornell box's glass
// sphere has them) shade with the geometric normal: bending such a normal
// would send glass paths the wrong way (Whitted chains broke at its first hit).
TEST(ShadingNormal, ANormalBelowTheSurfaceGivesTheGeometricNormal) {
    const Vec3f ng(0, 0, 1), wo = normalize(Vec3f(0.2f, 0.1f, 1.0f));
    for (const Vec3f& n : {Vec3f(0, 0, -1), normalize(Vec3f(0.9f, 0.1f, -0.2f)), Vec3f(1, 0, 0)}) {
        const Vec3f got = valid_reflection_normal(ng, wo, n);
        EXPECT_EQ(got.x, ng.x);
        EXPECT_EQ(got.y, ng.y);
        EXPECT_EQ(got.z, ng.z);
    }
}

TEST(ShadingNormal, ChangesContinuouslyWithTheNormal) {
    const Vec3f ng(0, 0, 1), wo = normalize(Vec3f(1.0f, 0.0f, 0.15f));
    // Sweep the shading normal away from the viewer, through the point where
    // the mirror direction drops below the surface: no jump anywhere.
    Vec3f prev = valid_reflection_normal(ng, wo, ng);
    for (int i = 1; i <= 2000; ++i) {
        const float a = 1.2f * float(i) / 2000.0f;
        const Vec3f n(-std::sin(a), 0.0f, std::cos(a));
        const Vec3f got = valid_reflection_normal(ng, wo, n);
        EXPECT_LT(length(got - prev), 5e-3f) << "at tilt " << a;
        prev = got;
    }
}

}  // namespace
}  // namespace coherent
