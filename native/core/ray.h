// Rays and hit records shared by every traversal kernel.
#pragma once

#include <cstdint>

#include "vec.h"

namespace coherent {

// A ray is the half-open segment o + t*d for t in [tmin, tmax].
// Invariant: d need not be normalised; t is measured in units of |d|.
struct Ray {
    Vec3f o;
    float tmin = 0.0f;
    Vec3f d;
    float tmax = kInf;
};

constexpr uint32_t kInvalidPrim = 0xffffffffu;

// Closest hit. u, v are the barycentrics of vertex 1 and 2 of triangle `prim`
// (vertex 0 weight is 1-u-v). prim == kInvalidPrim means no hit.
// `instance` is kInvalidPrim for a hit on the scene's own (world-space)
// triangles; otherwise the hit is on triangle `prim` of that instance's
// prototype (scene.h, instance_bvh.h), with t in world-ray units.
struct Hit {
    float t = kInf;
    float u = 0.0f, v = 0.0f;
    uint32_t prim = kInvalidPrim;
    uint32_t instance = kInvalidPrim;

    bool valid() const { return prim != kInvalidPrim; }
};

}  // namespace coherent
