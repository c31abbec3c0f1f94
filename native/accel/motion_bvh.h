// Moving triangles for object motion blur (Cook et al. 1984; the DRT of
// Boulos et al. 2007 section 4): each triangle moves linearly from its
// shutter-open vertices (time 0) to its shutter-close vertices (time 1), and
// a ray carries a time in [0, 1) at which it sees the scene.
//
// Why a separate structure: most of a scene stands still. Keeping the moving
// triangles out of the main BVH leaves every fast kernel (single, wide,
// packets, streams) untouched and exact for the static part; the few moving
// triangles live here, in a binary BVH over their swept boxes (the union of
// the open and close boxes bounds a linearly moving triangle for every time,
// since each vertex stays on the segment between its two positions, inside
// both boxes' union). A ray's hit is the closer of the two structures' hits
// (ties to the lower triangle index, as everywhere).
//
// The triangle at time tau is lerp(tau, open, close) per vertex, computed by
// motion_vertex() with the same operations everywhere (intersection and
// shading), and tested with the watertight test of triangle.h, so a moving
// triangle's hit point is consistent with what shading reconstructs.
#pragma once

#include <cstdint>
#include <vector>

#include "../core/bbox.h"
#include "../core/ray.h"
#include "../core/vec.h"
#include "bvh.h"

namespace coherent {

// Vertex position at time tau: the single definition used by every kernel.
inline Vec3f motion_vertex(const Vec3f& open, const Vec3f& close, float tau) {
    return {open.x + tau * (close.x - open.x), open.y + tau * (close.y - open.y), open.z + tau * (close.z - open.z)};
}

class MotionBvh {
public:
    MotionBvh() = default;
    // Builds over the triangles `moving` (scene triangle indices), whose
    // corners are open[3t + k] and close[3t + k].
    void build(const std::vector<Vec3f>& open, const std::vector<Vec3f>& close, const std::vector<uint32_t>& moving);

    bool empty() const { return nodes_.empty(); }
    size_t triangle_count() const { return tris_.size(); }
    size_t bytes() const { return nodes_.capacity() * sizeof(Node) + tris_.capacity() * sizeof(Tri); }

    // Closest hit with t in (ray.tmin, ray.tmax] at time tau, improving on
    // `hit` (an incoming hit, e.g. from the static BVH, shortens the search
    // and wins ties at equal t only with a lower triangle index). Returns true
    // when `hit` was replaced.
    bool intersect(const Ray& ray, float tau, Hit& hit, TraversalCounters* counters = nullptr) const;
    // Any hit with t in (ray.tmin, ray.tmax] at time tau.
    bool occluded(const Ray& ray, float tau, TraversalCounters* counters = nullptr) const;

private:
    struct Node {
        BBox box;
        uint32_t index = 0;  // interior: first child (children at index, index + 1); leaf: first of tris_
        uint32_t count = 0;  // leaf: triangles; 0 = interior
    };
    struct Tri {
        Vec3f open[3], close[3];
        uint32_t prim;
    };
    template <bool kAnyHit>
    bool traverse(const Ray& ray, float tau, Hit* hit, TraversalCounters* counters) const;

    std::vector<Node> nodes_;
    std::vector<Tri> tris_;
};

}  // namespace coherent
