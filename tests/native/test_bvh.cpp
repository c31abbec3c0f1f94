// Binary BVH: structure invariants, determinism, and closest/any hit against a
// brute-force oracle that tests every triangle.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>

#include <tbb/task_arena.h>

#include "accel/aligned_allocator.h"
#include "accel/bvh.h"
#include "bvh_test_meshes.h"

using namespace coherent;
using namespace coherent::testing_meshes;

namespace {

bool box_contains(const BBox& outer, const BBox& inner) {
    return outer.lo.x <= inner.lo.x && outer.lo.y <= inner.lo.y && outer.lo.z <= inner.lo.z &&
           outer.hi.x >= inner.hi.x && outer.hi.y >= inner.hi.y && outer.hi.z >= inner.hi.z;
}

bool box_contains_point(const BBox& b, const Vec3f& p, float tol) {
    for (int a = 0; a < 3; ++a)
        if (!(p[a] >= b.lo[a] - tol && p[a] <= b.hi[a] + tol)) return false;
    return true;
}

// With spatial splits, a triangle's references must together cover it: every
// point of the triangle lies in the box of some leaf that references it.
// Checked on the vertices, edge midpoints, centroid and random barycentric
// points (a few ulps of tolerance for the rounding of the sample points).
void check_coverage(const Bvh& bvh, const std::vector<Vec3f>& soup) {
    const auto& nodes = bvh.nodes();
    const auto& order = bvh.prim_order();
    std::vector<std::vector<uint32_t>> leaves_of(soup.size() / 3);
    for (uint32_t i = 0; i < nodes.size(); ++i)
        if (nodes[i].is_leaf())
            for (uint32_t s = nodes[i].index; s < nodes[i].index + nodes[i].count; ++s) leaves_of[order[s]].push_back(i);
    std::mt19937 rng(17);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    for (size_t t = 0; t < leaves_of.size(); ++t) {
        if (leaves_of[t].empty()) continue;  // skipped (non-finite) triangle
        const Vec3f* v = &soup[3 * t];
        const float scale = std::max({max_component(abs(v[0])), max_component(abs(v[1])), max_component(abs(v[2])), 1.0f});
        const float tol = 4e-7f * scale;
        std::vector<Vec3f> samples{v[0], v[1], v[2], (v[0] + v[1]) * 0.5f, (v[1] + v[2]) * 0.5f,
                                   (v[2] + v[0]) * 0.5f, (v[0] + v[1] + v[2]) * (1.0f / 3.0f)};
        for (int k = 0; k < 8; ++k) {
            float a = unit(rng), b = unit(rng);
            if (a + b > 1.0f) { a = 1.0f - a; b = 1.0f - b; }
            samples.push_back(v[0] * (1.0f - a - b) + v[1] * a + v[2] * b);
        }
        for (const Vec3f& p : samples) {
            bool covered = false;
            for (uint32_t leaf : leaves_of[t]) covered = covered || box_contains_point(nodes[leaf].box, p, tol);
            ASSERT_TRUE(covered) << "triangle " << t << ": a point is outside all its leaves";
        }
    }
}

// Walks the tree from the root and checks every structural invariant.
void check_structure(const Bvh& bvh, const std::vector<Vec3f>& soup, const BvhBuildOptions& opt) {
    const auto& nodes = bvh.nodes();
    const auto& order = bvh.prim_order();
    ASSERT_FALSE(nodes.empty());
    std::vector<int> seen_node(nodes.size(), 0);
    std::vector<int> seen_slot(order.size(), 0);
    const bool spatial = opt.spatial_split_budget > 0.0f;
    std::vector<uint32_t> stack{0};
    size_t leaves = 0;
    while (!stack.empty()) {
        const uint32_t i = stack.back();
        stack.pop_back();
        ASSERT_LT(i, nodes.size());
        ASSERT_EQ(seen_node[i]++, 0) << "node reached twice";
        const BvhNode& n = nodes[i];
        if (n.is_leaf()) {
            ++leaves;
            EXPECT_LE(n.count, static_cast<uint32_t>(opt.max_leaf_size));
            std::set<uint32_t> in_leaf;
            for (uint32_t s = n.index; s < n.index + n.count; ++s) {
                ASSERT_LT(s, order.size());
                seen_slot[s]++;
                const uint32_t tri = order[s];
                EXPECT_TRUE(in_leaf.insert(tri).second) << "triangle " << tri << " twice in one leaf";
                BBox tb;
                for (int k = 0; k < 3; ++k) tb.expand(soup[3 * tri + k]);
                if (spatial) {
                    // A clipped reference: the leaf box lies within the triangle's box on
                    // no axis in general, but it must at least touch it.
                    BBox overlap;
                    overlap.lo = max(n.box.lo, tb.lo);
                    overlap.hi = min(n.box.hi, tb.hi);
                    EXPECT_FALSE(overlap.empty()) << "leaf box does not touch its triangle " << tri;
                } else {
                    EXPECT_TRUE(box_contains(n.box, tb)) << "leaf box misses its triangle " << tri;
                }
            }
        } else {
            ASSERT_LT(n.index + 1, nodes.size());
            EXPECT_EQ(n.index % 2, 1u) << "sibling pairs start at odd indices";
            EXPECT_TRUE(box_contains(n.box, nodes[n.index].box));
            EXPECT_TRUE(box_contains(n.box, nodes[n.index + 1].box));
            stack.push_back(n.index);
            stack.push_back(n.index + 1);
        }
    }
    for (size_t i = 0; i < nodes.size(); ++i) EXPECT_EQ(seen_node[i], 1) << "unreachable node " << i;
    for (size_t s = 0; s < order.size(); ++s) EXPECT_EQ(seen_slot[s], 1) << "slot " << s << " not in exactly one leaf";
    std::set<uint32_t> prims(order.begin(), order.end());
    if (spatial) {
        // Every triangle at least once, and the duplicates within the budget.
        EXPECT_LE(order.size(), prims.size() + static_cast<size_t>(double(opt.spatial_split_budget) * double(prims.size())));
        check_coverage(bvh, soup);
    } else {
        EXPECT_EQ(prims.size(), order.size()) << "a triangle appears twice";
    }
    EXPECT_EQ(bvh.build_stats().references, order.size());
    EXPECT_EQ(bvh.build_stats().nodes, nodes.size());
    EXPECT_EQ(bvh.build_stats().leaves, leaves);
    EXPECT_GT(bvh.build_stats().bytes, 0u);
    EXPECT_GE(bvh.build_stats().depth, 1);
}


void expect_matches_brute_force(const Bvh& bvh, const std::vector<Vec3f>& soup, const std::vector<Ray>& rays,
                                size_t* hits_out = nullptr) {
    size_t hits = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
        const Ray& r = rays[i];
        const Hit expected = brute_force_closest(soup, r);
        Hit got;
        const bool hit = bvh.intersect(r, got);
        ASSERT_EQ(hit, expected.valid()) << "ray " << i;
        EXPECT_EQ(bvh.occluded(r), expected.valid()) << "ray " << i;
        if (!hit) {
            EXPECT_FALSE(got.valid());
            continue;
        }
        ++hits;
        EXPECT_EQ(got.prim, expected.prim) << "ray " << i;
        EXPECT_EQ(got.t, expected.t) << "ray " << i;
        EXPECT_EQ(got.u, expected.u) << "ray " << i;
        EXPECT_EQ(got.v, expected.v) << "ray " << i;
        EXPECT_GE(got.t, r.tmin);
        EXPECT_LE(got.t, r.tmax);
    }
    if (hits_out) *hits_out = hits;
}

}  // namespace

// Node and triangle arrays start on their cache-line alignment, and those of
// 2 MiB and more (a large scene's) on a huge-page boundary, so the kernel can
// back them with transparent huge pages.
TEST(Bvh, AlignedArraysOfTwoMegabytesStartOnAHugePage) {
    std::vector<float, AlignedAllocator<float, 64>> small(1000, 1.0f), large(size_t(1) << 20, 2.0f);
    EXPECT_EQ(reinterpret_cast<uintptr_t>(small.data()) % 64, 0u);
    EXPECT_EQ(reinterpret_cast<uintptr_t>(large.data()) % (size_t(2) << 20), 0u);
    EXPECT_EQ(small.back() + large.back(), 3.0f);
}

TEST(Bvh, EmptyInputHitsNothing) {
    Bvh bvh;
    bvh.build(std::vector<Vec3f>{});
    EXPECT_TRUE(bvh.empty());
    Ray r;
    r.d = Vec3f(0, 0, 1);
    Hit h;
    EXPECT_FALSE(bvh.intersect(r, h));
    EXPECT_FALSE(bvh.occluded(r));
    Bvh unbuilt;
    EXPECT_FALSE(unbuilt.intersect(r, h));
}

TEST(Bvh, SmallSoupsMatchBruteForce) {
    for (size_t n : {1u, 2u, 3u, 5u, 17u, 64u}) {
        const auto soup = random_soup(n, 7 + static_cast<uint32_t>(n), 2.0f, 1.5f);
        Bvh bvh;
        bvh.build(soup);
        check_structure(bvh, soup, {});
        expect_matches_brute_force(bvh, soup, random_rays(2000, 11, 2.0f));
    }
}

// Both builders: spatial splits (the default) and the plain binned SAH.
BvhBuildOptions with_budget(float budget) {
    BvhBuildOptions opt;
    opt.spatial_split_budget = budget;
    return opt;
}

TEST(Bvh, RandomSoupMatchesBruteForce) {
    const auto soup = random_soup(20000, 1234, 10.0f, 1.0f);
    for (float budget : {0.0f, 0.3f}) {
        Bvh bvh;
        bvh.build(soup, with_budget(budget));
        check_structure(bvh, soup, with_budget(budget));
        size_t hits = 0;
        expect_matches_brute_force(bvh, soup, random_rays(3000, 99, 10.0f), &hits);
        EXPECT_GT(hits, 1000u) << "the ray set should exercise hits, not only misses";
    }
}

// Long thin triangles crossing each other (like sponza's): where spatial
// splits pay off, so the builder really cuts references here. Cut references
// must stay conservative, far from the origin too.
std::vector<Vec3f> sliver_soup(size_t n, uint32_t seed, const Vec3f& offset) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> pos(-10.0f, 10.0f);
    std::vector<Vec3f> soup;
    for (size_t i = 0; i < n; ++i) {
        const Vec3f a(pos(rng), pos(rng), pos(rng)), b(pos(rng), pos(rng), pos(rng));
        const Vec3f side = random_unit(rng) * 0.05f;
        soup.push_back(a + offset);
        soup.push_back(b + offset);
        soup.push_back(a + side + offset);
    }
    return soup;
}

TEST(Bvh, SpatialSplitsCutReferencesAndMatchBruteForce) {
    for (const Vec3f offset : {Vec3f(0, 0, 0), Vec3f(1e4f, -3e3f, 5e3f)}) {
        const auto soup = sliver_soup(3000, 61, offset);
        for (float budget : {0.1f, 0.3f, 1.0f}) {
            Bvh bvh;
            bvh.build(soup, with_budget(budget));
            check_structure(bvh, soup, with_budget(budget));
            // A small budget may not afford any cut near the root, where each
            // plane crosses most slivers; a larger one must be used.
            if (budget >= 0.3f) {
                EXPECT_GT(bvh.prim_order().size(), soup.size() / 3) << "no spatial split was made";
            }
            // Random rays, and rays aimed at random points of random triangles
            // (each must hit at least that triangle's plane point).
            auto rays = random_rays(2000, 62, 10.0f);
            for (Ray& r : rays) r.o = r.o + offset;
            std::mt19937 rng(63);
            std::uniform_real_distribution<float> unit(0.0f, 1.0f);
            for (int i = 0; i < 2000; ++i) {
                const size_t t = rng() % (soup.size() / 3);
                float u = unit(rng), v = unit(rng);
                if (u + v > 1.0f) { u = 1.0f - u; v = 1.0f - v; }
                const Vec3f* tv = &soup[3 * t];
                const Vec3f target = tv[0] * (1.0f - u - v) + tv[1] * u + tv[2] * v;
                Ray r;
                r.o = target + random_unit(rng) * 30.0f;
                r.d = target - r.o;
                rays.push_back(r);
            }
            size_t hits = 0;
            expect_matches_brute_force(bvh, soup, rays, &hits);
            EXPECT_GT(hits, 2000u);
        }
    }
}

TEST(Bvh, SpatialSplitsLowerTheSahCostOnSlivers) {
    // The point of spatial splits: fewer box and triangle tests on overlapping
    // slivers for the same rays.
    const auto soup = sliver_soup(5000, 71, Vec3f(0, 0, 0));
    Bvh plain, split;
    plain.build(soup, with_budget(0.0f));
    split.build(soup, with_budget(0.3f));
    TraversalCounters a, b;
    for (const Ray& r : random_rays(3000, 72, 10.0f)) {
        Hit h;
        plain.intersect(r, h, &a);
        split.intersect(r, h, &b);
    }
    EXPECT_LT(b.box_tests + 4 * b.triangle_tests, a.box_tests + 4 * a.triangle_tests);
}

// A finely tessellated closed surface (a scanned mesh's shape): its
// triangles are thin next to every node where Stich's overlap test alone
// would search, so the default thickness test skips the spatial-split
// search there and the tree keeps one reference per triangle, while the
// slivers above still get cut. Both trees stay exact.
TEST(Bvh, ThinOverlapsSkipTheSpatialSplitSearch) {
    const auto sphere = icosphere(5, 3.0f, Vec3f(0.5f, -0.25f, 1.0f)).soup();
    BvhBuildOptions stich_only = with_budget(0.3f);
    stich_only.spatial_split_min_thickness = 0.0f;
    const BvhBuildOptions defaults = with_budget(0.3f);
    ASSERT_GT(defaults.spatial_split_min_thickness, 0.0f);
    Bvh searched, skipped;
    searched.build(sphere, stich_only);
    skipped.build(sphere, defaults);
    EXPECT_GT(searched.prim_order().size(), sphere.size() / 3) << "Stich's test alone should cut some references";
    EXPECT_EQ(skipped.prim_order().size(), sphere.size() / 3);
    for (const Bvh* bvh : {&searched, &skipped}) {
        size_t hits = 0;
        expect_matches_brute_force(*bvh, sphere, random_rays(1000, 81, 3.0f), &hits);
        EXPECT_GT(hits, 100u);
    }
}

// The 8-wide collapse: the SAH-optimal one (default) and the greedy one must
// give the same hits (both bit-identical to brute force), and the optimal one
// must not cost more by its own objective, the summed area of the wide nodes
// (the greedy collapse is one of the collapses it minimises over), nor, by
// more than noise, in node visits measured on rays.
TEST(Bvh, OptimalCollapseMatchesBruteForceAndVisitsNoMoreNodes) {
    const auto random = random_soup(8000, 81, 10.0f, 1.0f);
    const auto slivers = sliver_soup(3000, 82, Vec3f(0, 0, 0));
    const auto sphere = icosphere(4, 3.0f, Vec3f(0.5f, -0.25f, 1.0f)).soup();
    for (const auto* soup : {&random, &slivers, &sphere}) {
        for (float budget : {0.0f, 0.3f}) {
            BvhBuildOptions greedy_opt = with_budget(budget), optimal_opt = with_budget(budget);
            greedy_opt.optimal_collapse = false;
            optimal_opt.optimal_collapse = true;
            Bvh greedy, optimal;
            greedy.build(*soup, greedy_opt);
            optimal.build(*soup, optimal_opt);
            // The collapse changes only the traversal layout, never the binary tree.
            ASSERT_EQ(greedy.nodes().size(), optimal.nodes().size());
            ASSERT_EQ(greedy.prim_order(), optimal.prim_order());
            ASSERT_GT(optimal.build_stats().wide_nodes, 0u);
            EXPECT_LE(optimal.build_stats().wide_node_visit_estimate,
                      greedy.build_stats().wide_node_visit_estimate * (1.0 + 1e-5));

            const auto rays = random_rays(3000, 83, soup == &sphere ? 3.0f : 10.0f);
            size_t hits = 0;
            expect_matches_brute_force(optimal, *soup, rays, &hits);
            EXPECT_GT(hits, 300u);
            TraversalCounters cg, co;
            for (const Ray& r : rays) {
                Hit hg, ho;
                const bool g = greedy.intersect(r, hg, &cg);
                const bool o = optimal.intersect(r, ho, &co);
                ASSERT_EQ(g, o);
                if (g) {
                    EXPECT_EQ(hg.prim, ho.prim);
                    EXPECT_EQ(hg.t, ho.t);
                    EXPECT_EQ(hg.u, ho.u);
                    EXPECT_EQ(hg.v, ho.v);
                }
            }
            // Same leaves, so the same triangle work up to visiting order.
            EXPECT_LE(double(co.node_visits), 1.02 * double(cg.node_visits));
        }
    }
}

TEST(Bvh, IcosphereAndGridMatchBruteForce) {
    // Closed meshes with shared edges: ties between neighbours are common.
    const auto sphere = icosphere(4, 3.0f, Vec3f(0.5f, -0.25f, 1.0f)).soup();
    const auto cube = tessellated_cube(16, 0.25f, Vec3f(-2.0f, -2.0f, -2.0f)).soup();
    for (const auto* soup : {&sphere, &cube})
        for (float budget : {0.0f, 0.3f}) {
            Bvh bvh;
            bvh.build(*soup, with_budget(budget));
            check_structure(bvh, *soup, with_budget(budget));
            size_t hits = 0;
            expect_matches_brute_force(bvh, *soup, random_rays(4000, 5, 3.0f), &hits);
            EXPECT_GT(hits, 500u);
        }
}

TEST(Bvh, LeafSizeOptionIsRespected) {
    const auto soup = random_soup(5000, 3);
    for (int leaf : {1, 2, 8}) {
        BvhBuildOptions opt;
        opt.max_leaf_size = leaf;
        opt.bins = 8;
        Bvh bvh;
        bvh.build(soup, opt);
        check_structure(bvh, soup, opt);
        expect_matches_brute_force(bvh, soup, random_rays(500, 4, 10.0f));
    }
}

TEST(Bvh, CoincidentCentroidsUseMedianSplit) {
    // 200 triangles with the same centroid (the origin), rotated about random
    // axes: SAH cannot separate them, the median fallback must. Their planes
    // all differ, so exact ties (which may legitimately resolve differently
    // within rounding, see SharedEdgeTies) are measure-zero.
    std::mt19937 rng(5);
    std::vector<Vec3f> soup;
    for (int i = 0; i < 200; ++i) {
        Vec3f a = random_unit(rng), t, b;
        make_basis(a, t, b);
        const float s = 1.0f + 0.01f * i;
        const Vec3f p0 = t * s, p1 = (t * -0.5f + b * 0.866f) * s;
        soup.push_back(p0);
        soup.push_back(p1);
        soup.push_back(-(p0 + p1));  // centroid exactly 0 up to rounding
    }
    Bvh bvh;
    bvh.build(soup);
    check_structure(bvh, soup, {});
    size_t hits = 0;
    expect_matches_brute_force(bvh, soup, random_rays(2000, 8, 2.0f), &hits);
    EXPECT_GT(hits, 200u);
}

TEST(Bvh, CoplanarOverlapsAgreeWithinRounding) {
    // Overlapping coplanar triangles: every hit is a tie up to the rounding of
    // each triangle's t, and the BVH may legitimately cull a box whose entry
    // distance lies above a neighbour's rounded t. The hit must still be a
    // real hit of the ray at the brute-force distance within a few ulps.
    std::vector<Vec3f> soup;
    for (int i = 0; i < 200; ++i) {
        const float s = 1.0f + 0.01f * i;
        soup.push_back(Vec3f(-s, -1, 0));
        soup.push_back(Vec3f(s, -1, 0));
        soup.push_back(Vec3f(0, 2, 0));
    }
    Bvh bvh;
    bvh.build(soup);
    check_structure(bvh, soup, {});
    size_t hits = 0;
    for (const Ray& r : random_rays(2000, 8, 2.0f)) {
        const Hit expected = brute_force_closest(soup, r);
        Hit got;
        ASSERT_EQ(bvh.intersect(r, got), expected.valid());
        EXPECT_EQ(bvh.occluded(r), expected.valid());
        if (!expected.valid()) continue;
        ++hits;
        EXPECT_NEAR(got.t, expected.t, 1e-5f * (1.0f + expected.t));
        // The reported triangle really is hit at the reported t.
        const std::vector<Vec3f> one(soup.begin() + 3 * got.prim, soup.begin() + 3 * got.prim + 3);
        const Hit check = brute_force_closest(one, r);
        ASSERT_TRUE(check.valid());
        EXPECT_EQ(check.t, got.t);
    }
    EXPECT_GT(hits, 100u);
}

TEST(Bvh, BuildIsDeterministicAcrossThreadCounts) {
    auto soup = random_soup(150000, 42);  // large enough for parallel binning and subtrees
    const auto slivers = sliver_soup(20000, 43, Vec3f(0, 0, 0));  // spatial splits at the top levels
    soup.insert(soup.end(), slivers.begin(), slivers.end());
    for (float budget : {0.0f, 0.3f}) {
    Bvh a, b;
    tbb::task_arena one(1);
    one.execute([&] { a.build(soup, with_budget(budget)); });
    b.build(soup, with_budget(budget));
    ASSERT_EQ(a.nodes().size(), b.nodes().size());
    for (size_t i = 0; i < a.nodes().size(); ++i) {
        const BvhNode &x = a.nodes()[i], &y = b.nodes()[i];
        ASSERT_TRUE(x.index == y.index && x.count == y.count && x.box.lo.x == y.box.lo.x && x.box.hi.z == y.box.hi.z)
            << "node " << i;
    }
    EXPECT_EQ(a.prim_order(), b.prim_order());
    check_structure(b, soup, with_budget(budget));
    expect_matches_brute_force(b, soup, random_rays(200, 77, 10.0f));
    }
}

TEST(Bvh, NonFiniteTrianglesAreSkipped) {
    auto soup = random_soup(100, 9);
    soup[3 * 10 + 1] = Vec3f(NAN, 0, 0);
    soup[3 * 20 + 2] = Vec3f(0, INFINITY, 0);
    Bvh bvh;
    bvh.build(soup);
    const std::set<uint32_t> prims(bvh.prim_order().begin(), bvh.prim_order().end());
    EXPECT_EQ(prims.size(), 98u);
    for (uint32_t p : prims) EXPECT_TRUE(p != 10 && p != 20);
    EXPECT_TRUE(is_finite(bvh.bounds().lo) && is_finite(bvh.bounds().hi));
    expect_matches_brute_force(bvh, soup, random_rays(1000, 10, 10.0f));
}

TEST(Bvh, BarycentricsReconstructTheHitPoint) {
    const auto soup = random_soup(2000, 21, 5.0f, 1.0f);
    Bvh bvh;
    bvh.build(soup);
    size_t hits = 0;
    for (const Ray& r : random_rays(3000, 22, 5.0f)) {
        Hit h;
        if (!bvh.intersect(r, h)) continue;
        ++hits;
        EXPECT_GE(h.u, 0.0f);
        EXPECT_GE(h.v, 0.0f);
        EXPECT_LE(h.u + h.v, 1.0f + 1e-6f);
        const Vec3f* v = &soup[3 * h.prim];
        const Vec3f p = v[0] * (1.0f - h.u - h.v) + v[1] * h.u + v[2] * h.v;
        const Vec3f q = r.o + r.d * h.t;
        EXPECT_LT(length(p - q), 1e-4f * (1.0f + length(q))) << "prim " << h.prim;
    }
    EXPECT_GT(hits, 300u);
}

TEST(Bvh, InvalidRaysHitNothing) {
    const auto soup = icosphere(2, 1.0f, Vec3f(0, 0, 0)).soup();
    Bvh bvh;
    bvh.build(soup);
    const Vec3f o(0, 0, -5), d(0, 0, 1);
    std::vector<Ray> bad;
    auto make = [](Vec3f o_, Vec3f d_, float tmin, float tmax) {
        Ray r;
        r.o = o_; r.d = d_; r.tmin = tmin; r.tmax = tmax;
        return r;
    };
    bad.push_back(make(Vec3f(NAN, 0, -5), d, 0, kInf));
    bad.push_back(make(o, Vec3f(0, NAN, 1), 0, kInf));
    bad.push_back(make(o, d, NAN, kInf));
    bad.push_back(make(o, d, 0, NAN));
    bad.push_back(make(o, d, 7.0f, 3.0f));        // tmin > tmax
    bad.push_back(make(o, Vec3f(0, 0, 0), 0, kInf));
    bad.push_back(make(o, Vec3f(-0.0f, 0.0f, -0.0f), 0, kInf));
    bad.push_back(make(o, Vec3f(0, 0, INFINITY), 0, kInf));
    bad.push_back(make(Vec3f(0, 0, -INFINITY), d, 0, kInf));
    bad.push_back(make(o, d, 0, 3.0f));            // valid, but ends before the sphere
    bad.push_back(make(o, d, 6.5f, kInf));         // valid, starts past the sphere
    TraversalCounters c;
    for (const Ray& r : bad) {
        Hit h;
        EXPECT_FALSE(bvh.intersect(r, h, &c));
        EXPECT_FALSE(h.valid());
        EXPECT_FALSE(bvh.occluded(r, &c));
    }
    EXPECT_EQ(c.rays, 2 * bad.size());
    // Control: the same ray without the defect hits.
    Hit h;
    EXPECT_TRUE(bvh.intersect(make(o, d, 0, kInf), h));
    EXPECT_NEAR(h.t, 4.0f, 0.05f);
}

TEST(Bvh, CountersAreFilled) {
    const auto soup = random_soup(10000, 31);
    Bvh bvh;
    bvh.build(soup);
    const auto rays = random_rays(1000, 32, 10.0f);
    TraversalCounters c;
    size_t hits = 0;
    for (const Ray& r : rays) {
        Hit h;
        hits += bvh.intersect(r, h, &c);
    }
    EXPECT_EQ(c.rays, rays.size());
    EXPECT_GT(c.node_visits, c.rays);
    EXPECT_GE(c.box_tests, 2 * c.rays);  // at least the root pair per ray
    EXPECT_GE(c.triangle_tests, hits);
    // A BVH must be far cheaper than brute force.
    EXPECT_LT(c.triangle_tests, rays.size() * soup.size() / 3 / 50);
    TraversalCounters o;
    for (const Ray& r : rays) bvh.occluded(r, &o);
    EXPECT_EQ(o.rays, rays.size());
    EXPECT_LE(o.triangle_tests, c.triangle_tests) << "any-hit never does more work than closest-hit";
}

// ---- the BVH over a real Scene ------------------------------------------------

#include "scene/scene.h"
#include "test_fixtures.h"

// The generated Cornell box: axis-aligned walls, rotated blocks and a
// smooth-shaded sphere, loaded through glTF like any user scene.
TEST(BvhScene, GeneratedCornellBoxMatchesBruteForce) {
    Scene scene;
    ASSERT_TRUE(test::load_fixture("cornell_box.glb", scene));
    scene.finalize();
    ASSERT_EQ(scene.triangle_count(), 564u);  // make_gltf.py: 6 quads, 2 boxes, a 12x24 UV sphere

    Bvh bvh;
    bvh.build(scene);
    const std::set<uint32_t> prims(bvh.prim_order().begin(), bvh.prim_order().end());
    EXPECT_EQ(prims.size(), scene.vertices.size() / 3);
    check_structure(bvh, scene.vertices, {});

    const int n = 400;
    const std::vector<Ray> rays = rays_into_box(scene.bounds(), n, 2024);
    size_t hits = 0;
    for (int i = 0; i < n; ++i) {
        const Ray& ray = rays[size_t(i)];
        const Hit expected = brute_force_closest(scene.vertices, ray);
        Hit got;
        ASSERT_EQ(bvh.intersect(ray, got), expected.valid()) << i;
        EXPECT_EQ(bvh.occluded(ray), expected.valid()) << i;
        if (!expected.valid()) continue;
        ++hits;
        EXPECT_EQ(got.prim, expected.prim) << i;
        EXPECT_EQ(got.t, expected.t) << i;
    }
    EXPECT_GT(hits, static_cast<size_t>(n / 10));
}
