// Watertightness: rays aimed exactly at shared edges and vertices of closed
// meshes, near and far from the origin, must never slip through, and must
// cross a convex closed surface exactly twice.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "accel/bvh.h"
#include "bvh_test_meshes.h"

using namespace coherent;
using namespace coherent::testing_meshes;

namespace {

// Number of distinct surface crossings among all hits along a ray: hits whose
// t differ by less than `merge` belong to the same crossing (a ray through an
// edge or vertex may hit every triangle sharing it, at the same point).
int crossings(std::vector<float> ts, float merge) {
    std::sort(ts.begin(), ts.end());
    int n = 0;
    for (size_t i = 0; i < ts.size(); ++i)
        if (i == 0 || ts[i] - ts[i - 1] > merge) ++n;
    return n;
}

struct Target {
    Vec3f p;
    const char* kind;
};

// Points exactly on the mesh's vertices, and points on its edges: midpoints
// and points at random fractions (computed in float, so they are on the
// edge up to one rounding, which is exactly where leaks happen).
std::vector<Target> edge_and_vertex_targets(const IndexedMesh& m, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> frac(0.0f, 1.0f);
    std::vector<Target> out;
    for (const Vec3f& v : m.positions) out.push_back({v, "vertex"});
    for (const auto& [a, b] : m.edges()) {
        const Vec3f& pa = m.positions[a];
        const Vec3f& pb = m.positions[b];
        out.push_back({pa + (pb - pa) * 0.5f, "edge midpoint"});
        out.push_back({pa + (pb - pa) * frac(rng), "edge point"});
    }
    return out;
}

// For each target, rays from several outside origins through the target:
// the line enters the closed surface at the target, so it must hit there.
void expect_no_escapes(const IndexedMesh& mesh, const Vec3f& center, float radius, uint32_t seed) {
    const auto soup = mesh.soup();
    Bvh bvh;
    bvh.build(soup);
    std::mt19937 rng(seed);
    size_t rays = 0, escapes = 0, wrong_t = 0, bad_crossings = 0;
    for (const Target& target : edge_and_vertex_targets(mesh, seed)) {
        const Vec3f outward = normalize(target.p - center);
        for (int k = 0; k < 3; ++k) {
            // Origins outside, on the target's side, aimed through it toward
            // the interior (the direction stays within 60 degrees of -outward).
            Vec3f jitter = random_unit(rng);
            if (dot(jitter, outward) < 0.0f) jitter = -jitter;
            const Vec3f o = target.p + normalize(outward * 2.0f + jitter) * (2.0f * radius);
            Ray r;
            r.o = o;
            r.d = target.p - o;  // reaches the target at t = 1
            ++rays;
            Hit h;
            if (!bvh.intersect(r, h)) {
                ++escapes;
                ADD_FAILURE() << "escape through " << target.kind << " at offset " << center.x;
                continue;
            }
            if (!bvh.occluded(r)) ADD_FAILURE() << "occluded() disagrees with intersect()";
            // Hit at the target, up to rounding of the target and of t.
            if (std::fabs(h.t - 1.0f) > 1e-3f) ++wrong_t;
            // A line through a convex closed surface crosses it exactly twice
            // (merge hits within the float spacing at this offset).
            // (hits of one crossing differ by rounding only; the two
            // crossings are at least a fraction of the radius apart).
            if (crossings(brute_force_all(soup, r), 1e-3f) != 2) ++bad_crossings;
        }
    }
    EXPECT_EQ(escapes, 0u) << "of " << rays << " rays";
    EXPECT_EQ(wrong_t, 0u) << "of " << rays << " rays";
    EXPECT_EQ(bad_crossings, 0u) << "of " << rays << " rays";
    EXPECT_GT(rays, 1000u);
}

}  // namespace

class WatertightOffsets : public ::testing::TestWithParam<float> {};

TEST_P(WatertightOffsets, IcosphereEdgesAndVerticesNeverLeak) {
    const float offset = GetParam();
    const Vec3f center(offset, -0.5f * offset, 0.25f * offset);
    const float radius = 10.0f;
    expect_no_escapes(icosphere(3, radius, center), center, radius, 17);
}

TEST_P(WatertightOffsets, TessellatedCubeEdgesAndVerticesNeverLeak) {
    const float offset = GetParam();
    const Vec3f lo(offset, -0.5f * offset, 0.25f * offset);
    const int n = 8;
    const float step = 2.0f;
    const Vec3f center = lo + Vec3f(0.5f * n * step);
    expect_no_escapes(tessellated_cube(n, step, lo), center, 0.5f * n * step * std::sqrt(3.0f), 23);
}

INSTANTIATE_TEST_SUITE_P(Offsets, WatertightOffsets, ::testing::Values(0.0f, 1e3f, 1e4f, 1e5f));

TEST(Watertight, AxisAlignedRaysThroughGridVertices) {
    // Rays parallel to an axis (two exactly zero direction components, of
    // either sign of zero) through every grid vertex and edge midpoint of a
    // cube face, at several offsets: all must hit at the exact distance.
    for (float offset : {0.0f, 1e3f, 1e5f}) {
        const int n = 6;
        const float step = 1.0f;
        const Vec3f lo(offset, offset, offset);
        const auto soup = tessellated_cube(n, step, lo).soup();
        Bvh bvh;
        bvh.build(soup);
        size_t rays = 0;
        for (int axis = 0; axis < 3; ++axis)
            for (int sign : {1, -1})
                for (int i = 0; i <= 2 * n; ++i)
                    for (int j = 0; j <= 2 * n; ++j) {
                        const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
                        Ray r;
                        Vec3f o = lo;
                        o[a1] += 0.5f * i * step;  // grid vertices and edge midpoints, exact in float
                        o[a2] += 0.5f * j * step;
                        o[axis] += sign > 0 ? -3.0f : n * step + 3.0f;
                        r.o = o;
                        Vec3f d(sign > 0 ? 0.0f : -0.0f);
                        if ((i + j) % 2) d = Vec3f(0.0f, -0.0f, 0.0f);
                        d[axis] = static_cast<float>(sign);
                        r.d = d;
                        ++rays;
                        Hit h;
                        ASSERT_TRUE(bvh.intersect(r, h)) << "axis " << axis << " sign " << sign << " i " << i
                                                         << " j " << j << " offset " << offset;
                        EXPECT_EQ(h.t, 3.0f);
                        EXPECT_TRUE(bvh.occluded(r));
                        // Just short of the face: no hit.
                        r.tmax = 2.999f;
                        EXPECT_FALSE(bvh.intersect(r, h));
                        EXPECT_FALSE(bvh.occluded(r));
                    }
        EXPECT_EQ(rays, 3u * 2u * (2 * n + 1) * (2 * n + 1));
    }
}

TEST(Watertight, RaysWithOneZeroComponent) {
    // d.x == +0 or -0 exactly, diagonal in y/z, through edges of a cube whose
    // faces lie exactly on the slab planes of the ray's origin: exercises the
    // 0 * inf case of the slab test.
    const auto mesh = tessellated_cube(4, 1.0f, Vec3f(0, 0, 0));
    const auto soup = mesh.soup();
    Bvh bvh;
    bvh.build(soup);
    size_t hits = 0, rays = 0;
    for (float zero : {0.0f, -0.0f})
        for (int i = 0; i <= 8; ++i) {
            Ray r;
            r.o = Vec3f(0.5f * i, -1.0f, -1.0f);  // x on the cube's face planes for i = 0 and 8
            r.d = Vec3f(zero, 1.0f, 1.0f);
            ++rays;
            Hit h;
            const bool hit = bvh.intersect(r, h);
            const Hit expected = brute_force_closest(soup, r);
            ASSERT_EQ(hit, expected.valid()) << i;
            EXPECT_EQ(bvh.occluded(r), hit);
            if (!hit) continue;
            ++hits;
            EXPECT_EQ(h.t, expected.t);
            EXPECT_EQ(h.t, 1.0f);  // enters through the edge y = z = 0
        }
    EXPECT_EQ(hits, rays) << "every ray passes through the cube's edge y = z = 0";
}

TEST(Watertight, RandomRaysThroughClosedMeshNeverEscape) {
    // Rays between random interior points and random exterior points: the
    // segment from inside to outside must hit, from both ends.
    for (float offset : {0.0f, 1e4f}) {
        const Vec3f center(offset, offset, -offset);
        const auto soup = icosphere(3, 5.0f, center).soup();
        Bvh bvh;
        bvh.build(soup);
        std::mt19937 rng(3);
        std::uniform_real_distribution<float> unit(0.0f, 1.0f);
        for (int i = 0; i < 20000; ++i) {
            const Vec3f inside = center + random_unit(rng) * (4.0f * unit(rng));
            const Vec3f outside = center + random_unit(rng) * 20.0f;
            Ray r;
            r.o = inside;
            r.d = outside - inside;
            ASSERT_TRUE(bvh.occluded(r)) << i;
            r.o = outside;
            r.d = inside - outside;
            Hit h;
            ASSERT_TRUE(bvh.intersect(r, h)) << i;
            EXPECT_LT(h.t, 1.0f);
        }
    }
}
