// Breadth-first ray streams (the "dynamic ray scheduling" of paper 003,
// papers/INDEX.md, on the CPU): instead of one ray walking the tree, a whole
// slice of rays enters the root together; each wide node tests every ray of
// its queue against its children ("talk first, think later": one node's
// boxes stay in cache while all its rays are tested) and appends each ray to
// the queue of every child it enters; leaves intersect their whole queue. An
// early-out array holds each ray's closest hit so far (paper 003: "minimum
// distance array"), and a queued ray whose entry distance into a node
// exceeds it is dropped there.
//
// Results are those of Bvh::intersect / Bvh::occluded for the same rays, bit
// for bit (t, u, v, prim; the same tie rule: lowest triangle index at equal
// t): the kernels share the triangle test, the culling rule and the tie rule
// (wide_kernel.h), and the box tests are conservative.
//
// Streams run on the BVH's 8-wide traversal layout, whatever
// BvhBuildOptions::width single rays use (every Bvh keeps it).
#pragma once

#include <cstddef>
#include <cstdint>

#include "../core/ray.h"

namespace coherent {

class Bvh;

struct StreamOptions {
    // Rays traced together (one set of queues). The stream is cut into
    // slices of this many consecutive rays; slices are the unit of parallel
    // work, so each task owns its queues and no lock is taken. 0 means one
    // slice of all the rays.
    size_t slice_size = 4096;
    // Trace slices on the TBB pool (the caller's arena); false: on the
    // calling thread only.
    bool parallel = true;
};

constexpr int kStreamMaxLevels = 64;

// Work counters of stream traversal (summed over slices).
//  - node_visits: (node, queue) visits, interior wide nodes and leaves;
//  - ray_node_visits: queue entries processed at those visits (a ray tested
//    against a node's children or a leaf's triangles): rays per node visit
//    = ray_node_visits / node_visits, the amortisation streams buy;
//  - culled: queue entries dropped by the early-out array (their entry
//    distance exceeded the ray's closest hit found since they were queued);
//  - box_tests / triangle_tests: ray-box tests of non-empty child slots and
//    ray-triangle tests (real triangles, not padding lanes);
//  - level_visits[d] / level_rays[d]: nodes visited and queue entries
//    processed at depth d (root 0), clamped to the last level.
struct StreamStats {
    uint64_t rays = 0;  // rays given (valid or not)
    uint64_t slices = 0;
    uint64_t node_visits = 0;
    uint64_t ray_node_visits = 0;
    uint64_t culled = 0;
    uint64_t box_tests = 0;
    uint64_t triangle_tests = 0;
    uint64_t max_queue = 0;  // longest queue at any visit
    uint64_t level_visits[kStreamMaxLevels] = {};
    uint64_t level_rays[kStreamMaxLevels] = {};

    double rays_per_visit() const { return node_visits ? double(ray_node_visits) / double(node_visits) : 0.0; }
    double box_tests_per_ray() const { return rays ? double(box_tests) / double(rays) : 0.0; }
    double triangle_tests_per_ray() const { return rays ? double(triangle_tests) / double(rays) : 0.0; }
    int levels() const {
        int l = kStreamMaxLevels;
        while (l > 0 && level_visits[l - 1] == 0) --l;
        return l;
    }
    StreamStats& operator+=(const StreamStats& o) {
        rays += o.rays; slices += o.slices; node_visits += o.node_visits; ray_node_visits += o.ray_node_visits;
        culled += o.culled; box_tests += o.box_tests; triangle_tests += o.triangle_tests;
        max_queue = max_queue > o.max_queue ? max_queue : o.max_queue;
        for (int l = 0; l < kStreamMaxLevels; ++l) {
            level_visits[l] += o.level_visits[l];
            level_rays[l] += o.level_rays[l];
        }
        return *this;
    }
};

// Closest hits of rays[0, n): hits[i] receives ray i's closest hit, or Hit{}
// (prim == kInvalidPrim) when it hits nothing; invalid rays (NaN, zero or
// non-finite direction, tmin > tmax) hit nothing. `stats`, if given, is
// overwritten. `rays` and `hits` must not overlap.
void intersect_stream(const Bvh& bvh, const Ray* rays, size_t n, Hit* hits, StreamStats* stats = nullptr,
                      const StreamOptions& options = {});

// Any hit (shadow rays): occluded[i] = 1 if ray i hits anything with t in
// (tmin, tmax], else 0.
void occluded_stream(const Bvh& bvh, const Ray* rays, size_t n, uint8_t* occluded, StreamStats* stats = nullptr,
                     const StreamOptions& options = {});

}  // namespace coherent
