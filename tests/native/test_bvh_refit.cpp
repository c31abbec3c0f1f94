// Bvh::refit: after moving triangles (same indices, new positions) the
// refit tree must give exactly the brute-force closest hits over the moved
// triangles, for both builders (binned SAH and spatial splits, whose clipped
// reference boxes become full triangle boxes), and a refit over unchanged
// vertices must not change any hit.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>

#include "accel/bvh.h"
#include "bvh_test_meshes.h"
#include "scene/scene.h"

using namespace coherent;
using namespace coherent::testing_meshes;

namespace {

std::vector<Ray> refit_rays(size_t n, uint32_t seed, float extent) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> pos(-1.5f * extent, 1.5f * extent);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    std::vector<Ray> rays(n);
    for (auto& r : rays) {
        r.o = Vec3f(pos(rng), pos(rng), pos(rng));
        r.d = random_unit(rng) * (0.5f + unit(rng));
        r.tmin = 0.0f;
        r.tmax = unit(rng) < 0.3f ? 5.0f + 30.0f * unit(rng) : kInf;
    }
    return rays;
}

// Rays aimed at random triangles' centroids: most of them hit something, so
// a box that failed to follow its triangles would show as a missed hit.
std::vector<Ray> aimed_rays(const std::vector<Vec3f>& soup, size_t n, uint32_t seed, float extent) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> pos(-1.5f * extent, 1.5f * extent);
    std::uniform_int_distribution<size_t> pick(0, soup.size() / 3 - 1);
    std::vector<Ray> rays(n);
    for (auto& r : rays) {
        const size_t t = pick(rng);
        const Vec3f c = (soup[3 * t] + soup[3 * t + 1] + soup[3 * t + 2]) * (1.0f / 3.0f);
        r.o = Vec3f(pos(rng), pos(rng), pos(rng));
        r.d = c - r.o;
        r.tmin = 0.0f;
        r.tmax = kInf;
    }
    return rays;
}

// Moves triangles [first, first + count) by a rotation about z plus a translation.
void move_triangles(std::vector<Vec3f>& soup, size_t first, size_t count, float angle, const Vec3f& offset) {
    const float c = std::cos(angle), s = std::sin(angle);
    for (size_t i = 3 * first; i < 3 * (first + count); ++i) {
        const Vec3f p = soup[i];
        soup[i] = Vec3f(c * p.x - s * p.y, s * p.x + c * p.y, p.z) + offset;
    }
}

// Returns the number of hits.
size_t expect_matches_brute_force(const Bvh& bvh, const std::vector<Vec3f>& soup, const std::vector<Ray>& rays) {
    size_t hits = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
        const Hit expected = brute_force_closest(soup, rays[i]);
        Hit got;
        const bool hit = bvh.intersect(rays[i], got);
        EXPECT_EQ(hit, expected.valid()) << "ray " << i;
        EXPECT_EQ(bvh.occluded(rays[i]), expected.valid()) << "ray " << i;
        if (!hit || !expected.valid()) continue;
        ++hits;
        EXPECT_EQ(got.prim, expected.prim) << "ray " << i;
        EXPECT_EQ(got.t, expected.t) << "ray " << i;
        EXPECT_EQ(got.u, expected.u) << "ray " << i;
        EXPECT_EQ(got.v, expected.v) << "ray " << i;
    }
    return hits;
}

bool contains(const BBox& outer, const BBox& inner) {
    for (int a = 0; a < 3; ++a)
        if (!(outer.lo[a] <= inner.lo[a] && outer.hi[a] >= inner.hi[a])) return false;
    return true;
}

class BvhRefit : public ::testing::TestWithParam<bool> {  // param: spatial splits
protected:
    BvhBuildOptions options() const {
        BvhBuildOptions opt;
        opt.spatial_split_budget = GetParam() ? 0.3f : 0.0f;
        return opt;
    }
};

}  // namespace

TEST_P(BvhRefit, MovedTrianglesMatchBruteForce) {
    // Two "objects": a random soup and a tessellated cube.
    std::vector<Vec3f> soup = random_soup(3000, 11, 10.0f, 1.0f);
    const size_t first_cube = soup.size() / 3;
    const std::vector<Vec3f> cube = tessellated_cube(12, 0.5f, Vec3f(-3, -3, -3)).soup();
    soup.insert(soup.end(), cube.begin(), cube.end());
    const size_t cube_count = cube.size() / 3;

    Bvh bvh;
    bvh.build(soup, options());
    if (GetParam()) {
        EXPECT_GT(bvh.build_stats().references, soup.size() / 3) << "expected some spatial-split duplicates";
    }
    const BvhBuildStats built = bvh.build_stats();

    // Move the cube far (outside the old root box) and rotate part of the soup.
    move_triangles(soup, first_cube, cube_count, 0.7f, Vec3f(25.0f, -4.0f, 8.0f));
    move_triangles(soup, 100, 500, -0.3f, Vec3f(0.0f, 3.0f, -2.0f));
    bvh.refit(soup);

    // Structure kept: same nodes, references and wide nodes.
    EXPECT_EQ(bvh.nodes().size(), built.nodes);
    EXPECT_EQ(bvh.prim_order().size(), built.references);
    EXPECT_EQ(bvh.build_stats().wide_nodes, built.wide_nodes);
    // Every box bounds what lies below it (an independent check of pass 1).
    const auto& nodes = bvh.nodes();
    for (const BvhNode& n : nodes) {
        if (n.is_leaf()) {
            for (uint32_t s = n.index; s < n.index + n.count; ++s) {
                const uint32_t t = bvh.prim_order()[s];
                BBox tb;
                for (int k = 0; k < 3; ++k) tb.expand(soup[3 * size_t(t) + k]);
                EXPECT_TRUE(contains(n.box, tb)) << "triangle " << t;
            }
        } else {
            EXPECT_TRUE(contains(n.box, nodes[n.index].box));
            EXPECT_TRUE(contains(n.box, nodes[n.index + 1].box));
        }
    }
    BBox all;
    for (const Vec3f& v : soup) all.expand(v);
    EXPECT_TRUE(contains(bvh.bounds(), all));
    EXPECT_TRUE(contains(all, bvh.bounds()));

    size_t hits = expect_matches_brute_force(bvh, soup, refit_rays(4000, 5, 30.0f));
    hits += expect_matches_brute_force(bvh, soup, aimed_rays(soup, 3000, 6, 30.0f));
    EXPECT_GT(hits, 2500u);

    // Moving back and refitting again gives exactly the original hits too.
    move_triangles(soup, first_cube, cube_count, 0.0f, Vec3f(-25.0f, 4.0f, -8.0f));
    bvh.refit(soup);
    expect_matches_brute_force(bvh, soup, aimed_rays(soup, 1000, 7, 30.0f));
}

TEST_P(BvhRefit, RefitWithoutChangeKeepsEveryHit) {
    std::vector<Vec3f> soup = random_soup(4000, 21, 10.0f, 1.5f);
    Bvh bvh;
    bvh.build(soup, options());
    const std::vector<Ray> rays = refit_rays(5000, 8, 10.0f);
    std::vector<Hit> before(rays.size());
    std::vector<bool> hit_before(rays.size());
    for (size_t i = 0; i < rays.size(); ++i) hit_before[i] = bvh.intersect(rays[i], before[i]);
    bvh.refit(soup);
    size_t hits = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
        Hit h;
        ASSERT_EQ(bvh.intersect(rays[i], h), hit_before[i]) << "ray " << i;
        if (!hit_before[i]) continue;
        ++hits;
        EXPECT_EQ(h.prim, before[i].prim);
        EXPECT_EQ(h.t, before[i].t);
        EXPECT_EQ(h.u, before[i].u);
        EXPECT_EQ(h.v, before[i].v);
    }
    EXPECT_GT(hits, 500u);
}

INSTANTIATE_TEST_SUITE_P(Builders, BvhRefit, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool>& info) {
                             return info.param ? std::string("SpatialSplits") : std::string("BinnedSah");
                         });

TEST(BvhRefitErrors, RejectsTooFewTriangles) {
    std::vector<Vec3f> soup = random_soup(100, 3);
    Bvh bvh;
    bvh.build(soup);
    soup.resize(3 * 50);
    EXPECT_THROW(bvh.refit(soup), std::invalid_argument);
}

TEST(BvhRefitErrors, EmptyAndSingleLeafTrees) {
    Bvh empty;
    empty.build(std::vector<Vec3f>{});
    EXPECT_NO_THROW(empty.refit(std::vector<Vec3f>{}));
    EXPECT_TRUE(empty.empty());

    std::vector<Vec3f> one = random_soup(1, 4);
    Bvh bvh;
    bvh.build(one);
    move_triangles(one, 0, 1, 0.5f, Vec3f(100.0f, 0.0f, 0.0f));
    bvh.refit(one);
    expect_matches_brute_force(bvh, one, aimed_rays(one, 50, 9, 120.0f));
    EXPECT_TRUE(contains(bvh.bounds(), BBox{min(min(one[0], one[1]), one[2]), max(max(one[0], one[1]), one[2])}));
}
