// Tree width (BvhBuildOptions::width = 2, 4, 8): the binary, 4-wide and
// 8-wide single-ray kernels must return bit-identical closest hits (t, u, v,
// prim) and the same occlusion for every ray, equal to the brute-force
// oracle, on random and adversarial rays, after refits, and on closed meshes.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "accel/bvh.h"
#include "bvh_test_meshes.h"

using namespace coherent;
using namespace coherent::testing_meshes;

namespace {

constexpr int kWidths[] = {2, 4, 8};

BvhBuildOptions with_width(int width, float spatial_budget = BvhBuildOptions{}.spatial_split_budget) {
    BvhBuildOptions opt;
    opt.width = width;
    opt.spatial_split_budget = spatial_budget;
    return opt;
}

// The traversal layouts under test.
struct Layout {
    int width;
};
constexpr Layout kLayouts[] = {{2}, {4}, {8}};
constexpr int kLayoutCount = 3;


// Rays that stress the box tests and the tie rule: zero direction components
// with origins exactly on the integer node planes of a grid mesh, tiny
// components (|1/d| up to 2^100), and rays aimed exactly at shared vertices
// and edge midpoints (ties between neighbouring triangles).
std::vector<Ray> adversarial_rays(const IndexedMesh& mesh, size_t n, uint32_t seed, float lo, float hi) {
    std::mt19937 rng(seed);
    std::uniform_int_distribution<int> cell(static_cast<int>(lo) - 1, static_cast<int>(hi) + 1);
    std::uniform_real_distribution<float> dir(-1.0f, 1.0f);
    std::uniform_int_distribution<size_t> vertex(0, mesh.positions.size() - 1);
    const auto edges = mesh.edges();
    std::uniform_int_distribution<size_t> edge(0, edges.size() - 1);
    std::vector<Ray> rays;
    for (size_t i = 0; i < n; ++i) {
        Ray r;
        r.o = Vec3f(float(cell(rng)), float(cell(rng)), float(cell(rng)));
        switch (i % 4) {
            case 0: {  // zero components (+0 / -0)
                Vec3f d(dir(rng), dir(rng), dir(rng));
                d[i % 3] = (i / 4) % 2 ? 0.0f : -0.0f;
                if ((i / 8) % 2) d[(i + 1) % 3] = 0.0f;
                r.d = d;
                break;
            }
            case 1: {  // tiny components
                Vec3f d(dir(rng), dir(rng), dir(rng));
                d[i % 3] = std::ldexp((i / 4) % 2 ? 1.0f : -1.0f, -20 - int(i / 8 % 6) * 16);
                r.d = d;
                break;
            }
            case 2:  // exactly at a shared vertex
                r.d = mesh.positions[vertex(rng)] - r.o;
                break;
            default: {  // at an edge midpoint
                const auto& e = edges[edge(rng)];
                r.d = (mesh.positions[e.first] + mesh.positions[e.second]) * 0.5f - r.o;
                break;
            }
        }
        rays.push_back(r);
    }
    return rays;
}

struct Result {
    bool hit = false, occluded = false;
    Hit h;
};

Result trace(const Bvh& bvh, const Ray& r) {
    Result out;
    out.hit = bvh.intersect(r, out.h);
    out.occluded = bvh.occluded(r);
    return out;
}

// Every width against the brute-force oracle (bitwise on t, u, v, prim) and
// against each other (occlusion equal to "has a closest hit").
void expect_widths_agree(const std::vector<Vec3f>& soup, const std::vector<Ray>& rays, float spatial_budget,
                         size_t* hits_out = nullptr) {
    Bvh bvh[kLayoutCount];
    for (int w = 0; w < kLayoutCount; ++w) {
        bvh[w].build(soup, with_width(kLayouts[w].width, spatial_budget));
        ASSERT_EQ(bvh[w].width(), kLayouts[w].width);
    }
    size_t hits = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
        const Hit expected = brute_force_closest(soup, rays[i]);
        hits += expected.valid();
        for (int w = 0; w < kLayoutCount; ++w) {
            const Result got = trace(bvh[w], rays[i]);
            ASSERT_EQ(got.hit, expected.valid()) << "layout " << w << " ray " << i;
            ASSERT_EQ(got.occluded, expected.valid()) << "layout " << w << " ray " << i;
            if (!got.hit) continue;
            // Bitwise: EXPECT_EQ on floats compares exactly.
            EXPECT_EQ(got.h.prim, expected.prim) << "layout " << w << " ray " << i;
            EXPECT_EQ(got.h.t, expected.t) << "layout " << w << " ray " << i;
            EXPECT_EQ(got.h.u, expected.u) << "layout " << w << " ray " << i;
            EXPECT_EQ(got.h.v, expected.v) << "layout " << w << " ray " << i;
        }
    }
    if (hits_out) *hits_out = hits;
}

}  // namespace

TEST(WideBvh, InvalidWidthThrows) {
    const auto soup = random_soup(10, 1);
    Bvh bvh;
    for (int w : {0, 1, 3, 5, 16, -8}) EXPECT_THROW(bvh.build(soup, with_width(w)), std::invalid_argument) << w;
    for (int w : kWidths) EXPECT_NO_THROW(bvh.build(soup, with_width(w)));
}

TEST(WideBvh, EmptyAndTinyInputs) {
    for (int w : kWidths) {
        Bvh bvh;
        bvh.build(std::vector<Vec3f>{}, with_width(w));
        Ray r;
        r.d = Vec3f(0, 0, 1);
        Hit h;
        EXPECT_FALSE(bvh.intersect(r, h));
        EXPECT_FALSE(bvh.occluded(r));
    }
    for (size_t n : {1u, 2u, 3u, 5u, 9u, 33u})
        expect_widths_agree(random_soup(n, 40 + uint32_t(n), 2.0f, 1.5f), random_rays(1500, 3, 2.0f), 0.3f);
}

TEST(WideBvh, RandomSoupAllWidthsMatchBruteForce) {
    const auto soup = random_soup(3000, 5);
    for (float budget : {0.0f, 0.3f}) {
        size_t hits = 0;
        expect_widths_agree(soup, random_rays(3000, 6, 10.0f), budget, &hits);
        EXPECT_GT(hits, 300u);
    }
}

TEST(WideBvh, AdversarialRaysAllWidthsMatchBruteForce) {
    // Near the origin and far from it (1e6: the float ulp is 0.0625).
    for (const float offset : {0.0f, 1024.0f, 1048576.0f}) {
        const IndexedMesh cube = tessellated_cube(8, 1.0f, Vec3f(offset, offset, offset));
        std::vector<Ray> rays = adversarial_rays(cube, 8000, 9, offset, offset + 8.0f);
        size_t hits = 0;
        expect_widths_agree(cube.soup(), rays, 0.3f, &hits);
        EXPECT_GT(hits, 2000u) << offset;
    }
    const IndexedMesh sphere = icosphere(3, 3.0f, Vec3f(0.25f, -0.5f, 0.75f));
    size_t hits = 0;
    expect_widths_agree(sphere.soup(), adversarial_rays(sphere, 6000, 10, -4.0f, 4.0f), 0.3f, &hits);
    EXPECT_GT(hits, 2000u);
}

TEST(WideBvh, WiderTreesVisitFewerNodes) {
    // The point of the collapse: a ray visits fewer (wider) nodes. The binary
    // kernel counts binary nodes, the wide ones wide nodes (+ leaves).
    const auto soup = random_soup(20000, 12, 10.0f, 0.5f);
    const auto rays = random_rays(4000, 13, 10.0f);
    uint64_t visits[3] = {};
    for (int w = 0; w < 3; ++w) {
        Bvh bvh;
        bvh.build(soup, with_width(kWidths[w]));
        TraversalCounters c;
        for (const Ray& r : rays) {
            Hit h;
            bvh.intersect(r, h, &c);
        }
        EXPECT_EQ(c.rays, rays.size());
        EXPECT_GT(c.triangle_tests, 0u);
        visits[w] = c.node_visits;
        // The 8-wide tree is always built (streams run on it), the 4-wide one
        // only for width 4, where it needs more nodes.
        if (kWidths[w] == 4) {
            EXPECT_GT(bvh.build_stats().wide4_nodes, bvh.build_stats().wide_nodes);
        } else {
            EXPECT_EQ(bvh.build_stats().wide4_nodes, 0u);
        }
    }
    EXPECT_GT(visits[0], visits[1]);
    EXPECT_GT(visits[1], visits[2]);
}

TEST(WideBvh, RefitKeepsEveryWidthExact) {
    IndexedMesh mesh = icosphere(3, 2.0f, Vec3f(0, 0, 0));
    const auto rays = random_rays(3000, 21, 2.0f);
    for (const Layout& layout : kLayouts) {
        const int w = layout.width;
        Bvh bvh;
        bvh.build(mesh.soup(), with_width(w));
        // Move every vertex (a squash, a shear and a translation): the refit
        // tree must stay exact for the new positions.
        IndexedMesh moved = mesh;
        for (Vec3f& p : moved.positions) p = Vec3f(1.5f * p.x + 0.3f * p.y, 0.5f * p.y, p.z + 1.0f);
        const auto soup = moved.soup();
        bvh.refit(soup);
        size_t hits = 0;
        for (size_t i = 0; i < rays.size(); ++i) {
            const Hit expected = brute_force_closest(soup, rays[i]);
            hits += expected.valid();
            const Result got = trace(bvh, rays[i]);
            ASSERT_EQ(got.hit, expected.valid()) << "width " << w << " ray " << i;
            ASSERT_EQ(got.occluded, expected.valid()) << "width " << w << " ray " << i;
            if (!got.hit) continue;
            EXPECT_EQ(got.h.prim, expected.prim) << "width " << w << " ray " << i;
            EXPECT_EQ(got.h.t, expected.t) << "width " << w << " ray " << i;
        }
        EXPECT_GT(hits, 300u);
    }
}

// Closed meshes (a smooth sphere and a tessellated cube beside it, 6.6k
// triangles): every width gives bit-identical hits for rays from outside and
// for secondary rays leaving the hit points. Closed surfaces only: where two
// faces overlap in one plane (a box standing on a floor, as in the generated
// Cornell box) a secondary ray starting 1e-7 from both can see either at
// t ~ 1e-7, where the triangle test's rounding exceeds the cull slack.
TEST(WideBvhScene, ClosedMeshesAllWidthsBitIdentical) {
    std::vector<Vec3f> soup = icosphere(4, 1.0f, Vec3f(0, 0, 0)).soup();
    const std::vector<Vec3f> cube = tessellated_cube(12, 0.125f, Vec3f(1.25f, -0.5f, -0.75f)).soup();
    soup.insert(soup.end(), cube.begin(), cube.end());

    Bvh bvh[kLayoutCount];
    for (int w = 0; w < kLayoutCount; ++w)
        bvh[w].build(soup, with_width(kLayouts[w].width));
    // Rays from a sphere around the model toward random points of its box,
    // and secondary rays leaving the hit points (origins on the surface).
    BBox b;
    for (const Vec3f& v : soup) b.expand(v);
    const Vec3f c = b.center();
    const float radius = length(b.extent());
    std::mt19937 rng(77);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    std::vector<Ray> rays;
    for (int i = 0; i < 20000; ++i) {
        Ray ray;
        ray.o = c + random_unit(rng) * radius;
        ray.d = b.lo + b.extent() * Vec3f(unit(rng), unit(rng), unit(rng)) - ray.o;
        rays.push_back(ray);
    }
    size_t hits = 0, secondary = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
        Result ref = trace(bvh[2], rays[i]);  // 8-wide
        for (int w : {0, 1}) {
            const Result got = trace(bvh[w], rays[i]);
            ASSERT_EQ(got.hit, ref.hit) << "layout " << w << " ray " << i;
            ASSERT_EQ(got.occluded, ref.occluded) << "layout " << w << " ray " << i;
            if (!ref.hit) continue;
            EXPECT_EQ(got.h.prim, ref.h.prim) << i;
            EXPECT_EQ(got.h.t, ref.h.t) << i;
            EXPECT_EQ(got.h.u, ref.h.u) << i;
            EXPECT_EQ(got.h.v, ref.h.v) << i;
        }
        if (!ref.hit) continue;
        ++hits;
        // A secondary ray from the hit point, no offset: t = 0 self-hits are
        // excluded by the half-open interval; the widths must agree on what
        // else it sees.
        if (rays.size() < 40000) {
            Ray s;
            s.o = rays[i].o + rays[i].d * ref.h.t;
            s.d = random_unit(rng);
            rays.push_back(s);
            ++secondary;
        }
    }
    EXPECT_GT(hits, 5000u);
    EXPECT_GT(secondary, 5000u);
}
