// Breadth-first ray streams (ray_stream.h): the same closest hits, bit for
// bit, and the same occlusion as single-ray traversal, for stream sizes 0, 1,
// 7, 1000 and 100k, every batch size, serial and parallel, invalid rays
// included; counters that add up.
#include <gtest/gtest.h>

#include <tbb/task_arena.h>

#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "accel/bvh.h"
#include "accel/ray_stream.h"
#include "bvh_test_meshes.h"
#include "test_fixtures.h"
#include "scene/scene.h"

using namespace coherent;
using namespace coherent::testing_meshes;

namespace {


// Bitwise equality of two hit records (prim, t, u, v).
bool same_bits(const Hit& a, const Hit& b) {
    return a.prim == b.prim && std::memcmp(&a.t, &b.t, 4) == 0 && std::memcmp(&a.u, &b.u, 4) == 0 &&
           std::memcmp(&a.v, &b.v, 4) == 0;
}

// Streams against single rays over the same BVH.
void expect_stream_matches_single(const Bvh& bvh, const std::vector<Ray>& rays, const StreamOptions& opt,
                                  size_t* hits_out = nullptr) {
    std::vector<Hit> hits(rays.size());
    std::vector<uint8_t> occ(rays.size(), 7);  // not 0/1: the stream must write every entry
    StreamStats st;
    intersect_stream(bvh, rays.data(), rays.size(), hits.data(), &st, opt);
    EXPECT_EQ(st.rays, rays.size());
    occluded_stream(bvh, rays.data(), rays.size(), occ.data(), nullptr, opt);
    size_t hit_count = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
        Hit expected;
        const bool hit = bvh.intersect(rays[i], expected);
        if (!hit) expected = Hit{};
        ASSERT_TRUE(same_bits(hits[i], expected))
            << "ray " << i << ": stream prim " << hits[i].prim << " t " << hits[i].t << ", single prim "
            << expected.prim << " t " << expected.t;
        ASSERT_EQ(occ[i], bvh.occluded(rays[i]) ? 1 : 0) << "ray " << i;
        hit_count += hit;
    }
    if (hits_out) *hits_out = hit_count;
}

}  // namespace

TEST(RayStream, StreamSizesMatchSingleRays) {
    const auto soup = random_soup(4000, 3);
    for (int width : {2, 4, 8}) {
        BvhBuildOptions bo;
        bo.width = width;  // streams use the 8-wide layout whatever the width
        Bvh bvh;
        bvh.build(soup, bo);
        for (size_t n : {0u, 1u, 7u, 1000u}) {
            const auto rays = random_rays(n, 100 + uint32_t(n), 10.0f);
            for (size_t batch : {size_t(0), size_t(1), size_t(3), size_t(256)}) {
                StreamOptions opt;
                opt.slice_size = batch;
                expect_stream_matches_single(bvh, rays, opt);
            }
        }
    }
}

TEST(RayStream, HundredThousandRaysSerialAndParallel) {
    const auto soup = random_soup(20000, 4, 10.0f, 0.7f);
    Bvh bvh;
    bvh.build(soup);
    const auto rays = random_rays(100000, 5, 10.0f);
    for (bool parallel : {false, true})
        for (size_t batch : {size_t(4096), size_t(65536), size_t(0)}) {
            StreamOptions opt;
            opt.slice_size = batch;
            opt.parallel = parallel;
            size_t hits = 0;
            expect_stream_matches_single(bvh, rays, opt, &hits);
            EXPECT_GT(hits, 20000u);
        }
}

TEST(RayStream, MatchesBruteForceOnAdversarialRays) {
    // Rays through shared vertices and edges of a grid (ties between
    // neighbours) and axis-parallel rays with origins on node planes:
    // the brute-force oracle, with its tie rule, is the reference.
    const IndexedMesh cube = tessellated_cube(8, 1.0f, Vec3f(0, 0, 0));
    const auto soup = cube.soup();
    Bvh bvh;
    bvh.build(soup);
    std::mt19937 rng(8);
    std::uniform_int_distribution<int> cell(-1, 9);
    std::uniform_real_distribution<float> dir(-1.0f, 1.0f);
    std::uniform_int_distribution<size_t> vertex(0, cube.positions.size() - 1);
    std::vector<Ray> rays;
    for (int i = 0; i < 20000; ++i) {
        Ray r;
        r.o = Vec3f(float(cell(rng)), float(cell(rng)), float(cell(rng)));
        if (i % 2) {
            r.d = cube.positions[vertex(rng)] - r.o;
        } else {
            Vec3f d(dir(rng), dir(rng), dir(rng));
            d[i % 3] = (i / 2) % 2 ? 0.0f : -0.0f;
            r.d = d;
        }
        rays.push_back(r);
    }
    std::vector<Hit> hits(rays.size());
    std::vector<uint8_t> occ(rays.size());
    intersect_stream(bvh, rays.data(), rays.size(), hits.data());
    occluded_stream(bvh, rays.data(), rays.size(), occ.data());
    size_t hit_count = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
        const Hit expected = brute_force_closest(soup, rays[i]);
        ASSERT_TRUE(same_bits(hits[i], expected.valid() ? expected : Hit{})) << i;
        ASSERT_EQ(occ[i], expected.valid() ? 1 : 0) << i;
        hit_count += expected.valid();
    }
    EXPECT_GT(hit_count, 5000u);
}

TEST(RayStream, InvalidRaysHitNothing) {
    const auto soup = tessellated_cube(2, 1.0f, Vec3f(0, 0, 0)).soup();
    Bvh bvh;
    bvh.build(soup);
    const float nan = std::nanf("");
    std::vector<Ray> rays;
    auto add = [&](Vec3f o, Vec3f d, float tmin, float tmax) {
        Ray r;
        r.o = o;
        r.d = d;
        r.tmin = tmin;
        r.tmax = tmax;
        rays.push_back(r);
    };
    const Vec3f o(0.5f, 0.5f, -1.0f), d(0, 0, 1);
    add(o, d, 0.0f, kInf);                           // valid: hits z = 0 at t = 1
    add(Vec3f(nan, 0.5f, -1.0f), d, 0.0f, kInf);     // NaN origin
    add(o, Vec3f(0, nan, 1), 0.0f, kInf);            // NaN direction
    add(o, Vec3f(0, 0, 0), 0.0f, kInf);              // zero direction
    add(o, Vec3f(0, 0, kInf), 0.0f, kInf);           // infinite direction
    add(o, d, 2.0f, 1.0f);                           // tmin > tmax
    add(o, d, nan, kInf);                            // NaN tmin
    add(o, d, 0.0f, nan);                            // NaN tmax
    add(o, d, 0.0f, kInf);                           // valid again, after the invalid ones
    std::vector<Hit> hits(rays.size());
    std::vector<uint8_t> occ(rays.size());
    StreamStats st;
    intersect_stream(bvh, rays.data(), rays.size(), hits.data(), &st);
    occluded_stream(bvh, rays.data(), rays.size(), occ.data());
    for (size_t i = 0; i < rays.size(); ++i) {
        const bool valid = i == 0 || i + 1 == rays.size();
        EXPECT_EQ(hits[i].valid(), valid) << i;
        EXPECT_EQ(occ[i], valid ? 1 : 0) << i;
        if (valid) {
            EXPECT_EQ(hits[i].t, 1.0f);
        }
    }
    // Invalid rays never enter the root queue.
    EXPECT_EQ(st.level_rays[0], 2u);
    // An empty BVH: nothing hits.
    Bvh empty;
    empty.build(std::vector<Vec3f>{});
    intersect_stream(empty, rays.data(), rays.size(), hits.data());
    occluded_stream(empty, rays.data(), rays.size(), occ.data());
    for (size_t i = 0; i < rays.size(); ++i) {
        EXPECT_FALSE(hits[i].valid());
        EXPECT_EQ(occ[i], 0);
    }
}

TEST(RayStream, CountersAddUp) {
    const auto soup = random_soup(5000, 9);
    Bvh bvh;
    bvh.build(soup);
    const auto rays = random_rays(5000, 10, 10.0f);
    std::vector<Hit> hits(rays.size());
    StreamOptions opt;
    opt.slice_size = 1000;
    opt.parallel = false;
    StreamStats st;
    intersect_stream(bvh, rays.data(), rays.size(), hits.data(), &st, opt);
    EXPECT_EQ(st.rays, 5000u);
    EXPECT_EQ(st.slices, 5u);
    // Every batch enters the root once with all its (valid) rays.
    EXPECT_EQ(st.level_visits[0], 5u);
    EXPECT_EQ(st.level_rays[0], 5000u);
    EXPECT_LE(st.max_queue, 1000u);
    uint64_t visits = 0, processed = 0;
    for (int l = 0; l < kStreamMaxLevels; ++l) {
        visits += st.level_visits[l];
        processed += st.level_rays[l];
    }
    EXPECT_EQ(visits, st.node_visits);
    EXPECT_EQ(processed, st.ray_node_visits);
    EXPECT_GT(st.levels(), 2);
    EXPECT_GT(st.rays_per_visit(), 1.0);
    EXPECT_GT(st.triangle_tests, 0u);
    // Batches are traced independently and deterministically, so a parallel
    // run counts exactly the work of a serial one.
    StreamStats par;
    opt.parallel = true;
    intersect_stream(bvh, rays.data(), rays.size(), hits.data(), &par, opt);
    EXPECT_EQ(par.node_visits, st.node_visits);
    EXPECT_EQ(par.box_tests, st.box_tests);
    EXPECT_EQ(par.triangle_tests, st.triangle_tests);
    EXPECT_EQ(par.culled, st.culled);
}

TEST(RayStream, GeneratedCornellBoxMatchesSingleRays) {
    Scene scene;
    ASSERT_TRUE(test::load_fixture("cornell_box.glb", scene));
    scene.finalize();
    Bvh bvh;
    bvh.build(scene);
    const BBox b = scene.bounds();
    const Vec3f c = b.center();
    const float radius = length(b.extent());
    std::mt19937 rng(31);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    std::vector<Ray> rays(50000);
    for (Ray& ray : rays) {
        ray.o = c + random_unit(rng) * radius;
        ray.d = b.lo + b.extent() * Vec3f(unit(rng), unit(rng), unit(rng)) - ray.o;
    }
    size_t hits = 0;
    expect_stream_matches_single(bvh, rays, StreamOptions{}, &hits);
    EXPECT_GT(hits, 10000u);
}
