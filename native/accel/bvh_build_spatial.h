// Spatial-split BVH builder (private to the accel layer): SBVH, Stich,
// Friedrich, Dietrich 2009, "Spatial Splits in Bounding Volume Hierarchies".
//
// Produces the same portable binary tree as the binned SAH builder
// (bvh_build.cpp), except that a triangle may be referenced by several leaves:
// a spatial split cuts the triangles that straddle its plane, and each side
// keeps a reference to the part of the triangle on its side. Every leaf box
// bounds (conservatively) the part of each of its triangles that lies in the
// leaf's region, and the union of a triangle's references covers the whole
// triangle, so every ray/triangle hit lies in some leaf box of that triangle.
#pragma once

#include <cstdint>
#include <vector>

#include "bvh.h"

namespace coherent {

// Builds over the triangles `tris` (indices into triangle_vertices, 3
// vertices per triangle, all finite). Fills `nodes` (root first, siblings
// adjacent, as BvhNode describes) and `prim_order` (leaf slot -> triangle;
// may repeat a triangle across leaves, never within one leaf) and the depth,
// leaf count and reference count of `stats`.
// Deterministic: the output does not depend on the number of threads.
void build_spatial_bvh(const Vec3f* triangle_vertices, const std::vector<uint32_t>& tris,
                       const BvhBuildOptions& opt, std::vector<BvhNode>& nodes, std::vector<uint32_t>& prim_order,
                       BvhBuildStats& stats);

}  // namespace coherent
