// Traversal robustness: rays that stress the slab test's special cases
// (zero direction components with the origin exactly on node planes, which
// produce 0 * inf = NaN inside the box test), extreme direction magnitudes,
// and degenerate intervals. The oracle is the brute-force closest hit.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "accel/bvh.h"
#include "bvh_test_meshes.h"

using namespace coherent;
using namespace coherent::testing_meshes;

namespace {

void expect_same(const Bvh& bvh, const std::vector<Vec3f>& soup, const Ray& r, const char* what) {
    const Hit expected = brute_force_closest(soup, r);
    Hit got;
    ASSERT_EQ(bvh.intersect(r, got), expected.valid()) << what;
    EXPECT_EQ(bvh.occluded(r), expected.valid()) << what;
    if (expected.valid()) {
        EXPECT_EQ(got.prim, expected.prim) << what;
        EXPECT_EQ(got.t, expected.t) << what;
    }
}

}  // namespace

TEST(TraversalRobustness, ZeroComponentsWithOriginOnNodePlanes) {
    // Integer grid geometry: node boxes have integer planes, and so do the
    // origins below, so (plane - origin) is exactly 0 for many slabs while the
    // matching direction component is +0 or -0.
    const auto soup = tessellated_cube(8, 1.0f, Vec3f(0, 0, 0)).soup();
    Bvh bvh;
    bvh.build(soup);
    std::mt19937 rng(1);
    std::uniform_int_distribution<int> cell(-1, 9);
    std::uniform_real_distribution<float> dir(-1.0f, 1.0f);
    size_t hits = 0;
    for (int i = 0; i < 20000; ++i) {
        Ray r;
        r.o = Vec3f(float(cell(rng)), float(cell(rng)), float(cell(rng)));
        Vec3f d(dir(rng), dir(rng), dir(rng));
        const int zeros = 1 + i % 2;  // one or two zero components
        for (int k = 0; k < zeros; ++k) d[(i / 2 + k) % 3] = (i / 4) % 2 ? 0.0f : -0.0f;
        r.d = d;
        expect_same(bvh, soup, r, "zero component");
        hits += brute_force_closest(soup, r).valid();
    }
    EXPECT_GT(hits, 5000u);
}

TEST(TraversalRobustness, RayInsideTheFacePlane) {
    // A ray travelling inside the plane z = 0 of a face: coplanar triangles
    // have det == 0 and are never hit, the rest of the cube still is.
    const auto soup = tessellated_cube(4, 1.0f, Vec3f(0, 0, 0)).soup();
    Bvh bvh;
    bvh.build(soup);
    for (float y : {0.0f, 0.5f, 1.0f, 2.0f, 4.0f}) {
        Ray r;
        r.o = Vec3f(-1.0f, y, 0.0f);
        r.d = Vec3f(1.0f, 0.0f, 0.0f);
        expect_same(bvh, soup, r, "in plane");
        r.d = Vec3f(1.0f, 0.0f, -0.0f);
        expect_same(bvh, soup, r, "in plane, -0");
    }
}

TEST(TraversalRobustness, ExtremeDirectionMagnitudes) {
    const auto soup = icosphere(3, 2.0f, Vec3f(0.5f, 0.25f, -0.5f)).soup();
    Bvh bvh;
    bvh.build(soup);
    std::mt19937 rng(4);
    size_t hits = 0;
    for (float scale : {1e-30f, 1e-12f, 1e-3f, 1e3f, 1e12f, 1e30f}) {
        for (int i = 0; i < 500; ++i) {
            Ray r;
            r.o = random_unit(rng) * 6.0f;
            r.d = (random_unit(rng) * 1.5f - r.o) * scale;
            if (!is_finite(r.d)) continue;
            expect_same(bvh, soup, r, "scaled direction");
            hits += brute_force_closest(soup, r).valid();
        }
    }
    EXPECT_GT(hits, 1000u);
}

TEST(TraversalRobustness, DegenerateIntervals) {
    const auto soup = tessellated_cube(2, 1.0f, Vec3f(0, 0, 0)).soup();
    Bvh bvh;
    bvh.build(soup);
    Ray r;
    r.o = Vec3f(0.5f, 0.5f, -1.0f);
    r.d = Vec3f(0.0f, 0.0f, 1.0f);
    // The interval is half-open, (tmin, tmax]: a surface exactly at tmax is
    // hit, one exactly at tmin is not (that is a self-intersection).
    r.tmin = 0.0f;
    r.tmax = 1.0f;
    Hit h;
    EXPECT_TRUE(bvh.intersect(r, h));
    EXPECT_EQ(h.t, 1.0f);
    EXPECT_TRUE(bvh.occluded(r));
    r.tmin = 1.0f;
    r.tmax = 10.0f;
    EXPECT_TRUE(bvh.intersect(r, h));
    EXPECT_EQ(h.t, 3.0f) << "the far face, not the one at tmin";
    r.tmin = r.tmax = 1.0f;  // empty interval
    EXPECT_FALSE(bvh.intersect(r, h));
    EXPECT_FALSE(bvh.occluded(r));
    r.tmin = r.tmax = 0.999f;
    EXPECT_FALSE(bvh.intersect(r, h));
    EXPECT_FALSE(bvh.occluded(r));
    // Negative tmin finds the surface behind the origin.
    r.o = Vec3f(0.5f, 0.5f, 3.0f);
    r.tmin = -10.0f;
    r.tmax = 0.0f;
    EXPECT_TRUE(bvh.intersect(r, h));
    EXPECT_EQ(h.t, -3.0f);
    // An origin lying exactly on a face, tmin = 0: the face itself is not
    // hit (t = 0), whichever way the ray points; the opposite face is.
    r.o = Vec3f(0.5f, 0.5f, 0.0f);
    r.tmin = 0.0f;
    r.tmax = kInf;
    r.d = Vec3f(0.0f, 0.0f, 1.0f);
    EXPECT_TRUE(bvh.intersect(r, h));
    EXPECT_EQ(h.t, 2.0f);
    r.d = Vec3f(0.0f, 0.0f, -1.0f);
    EXPECT_FALSE(bvh.intersect(r, h));
    EXPECT_FALSE(bvh.occluded(r));
    // Infinite tmin or -inf tmax: nothing, without NaN trouble.
    r.tmin = kInf;
    r.tmax = kInf;
    EXPECT_FALSE(bvh.intersect(r, h));
    r.tmin = -kInf;
    r.tmax = -kInf;
    EXPECT_FALSE(bvh.intersect(r, h));
}

TEST(TraversalRobustness, TinyDirectionComponentsWithOriginOnNodePlanes) {
    // Nearly axis-parallel rays: |1/d| up to 1e30 in one axis, origins exactly
    // on integer node planes, the grid near the origin and far from it. Small
    // |1/d| x magnitude takes the fused slab test (fma with an outward-rounded
    // o/d), large takes the exact one; both must be conservative, so the hits
    // equal the brute-force ones, including rays through shared edges.
    for (const float offset : {0.0f, 1024.0f, 65536.0f}) {
        const auto soup = tessellated_cube(8, 1.0f, Vec3f(offset, offset, offset)).soup();
        Bvh bvh;
        bvh.build(soup);
        std::mt19937 rng(7);
        std::uniform_int_distribution<int> cell(-1, 9);
        std::uniform_real_distribution<float> dir(-1.0f, 1.0f);
        size_t hits = 0;
        for (int i = 0; i < 12000; ++i) {
            Ray r;
            r.o = Vec3f(offset + float(cell(rng)), offset + float(cell(rng)), offset + float(cell(rng)));
            Vec3f d(dir(rng), dir(rng), dir(rng));
            const float tiny = std::ldexp(1.0f, -20 - (i % 6) * 16);  // 2^-20 ... 2^-100
            d[i % 3] = (i / 3) % 2 ? tiny : -tiny;
            r.d = d;
            expect_same(bvh, soup, r, "tiny component");
            hits += brute_force_closest(soup, r).valid();
        }
        EXPECT_GT(hits, 3000u);
    }
}
