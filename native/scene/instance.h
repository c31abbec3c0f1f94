// Shared geometry: a prototype is a mesh's triangles in object space, stored
// once; an instance places a prototype in the world with an affine transform
// and its own material slots. Memory grows with unique triangles plus
// instances, never with their product (DESIGN.md, invariants).
//
// Rays meet instances through the two-level BVH of accel/instance_bvh.h: a
// top-level BVH over the instances' world boxes whose leaves carry the ray
// into object space and traverse the prototype's own BVH. A hit names the
// instance and the prototype's triangle (Hit::instance, Hit::prim); shading
// maps the point back to world space (render/instance_shading.h).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "../core/bbox.h"
#include "../core/vec.h"

namespace coherent {

// Triangles of one mesh in object space, validated like add_mesh's
// (finite, in range, non-degenerate in object space), unindexed: triangle i
// uses vertices 3i .. 3i + 2.
struct Prototype {
    std::string name;
    std::vector<Vec3f> vertices;        // 3 per triangle
    std::vector<Vec3f> normals;         // 3 per triangle (geometric normal where the mesh has none)
    std::vector<uint8_t> has_normals;   // 1 per triangle
    std::vector<uint32_t> slot_of;      // 1 per triangle: material slot, resolved per instance
    BBox bounds;                        // object space

    size_t triangle_count() const { return slot_of.size(); }
};

// One placement of a prototype. `object_to_world` maps object space to the
// world; `world_to_object` is its inverse (rays are carried into object space
// with it); `normal_to_world` is the cofactor matrix times sign(det), the
// inverse transpose up to a positive scale (normals are renormalised).
struct Instance {
    uint32_t prototype = 0;
    Transform object_to_world, world_to_object, normal_to_world;
    // Slot s of the prototype's triangles renders with material
    // scene.instance_materials[first_material + s]; slots at or past
    // material_count use the default material 0.
    uint32_t first_material = 0, material_count = 0;
    uint32_t object = 0;  // index into scene.object_names
    BBox world_bounds;    // the prototype's box, transformed (conservative)
};

}  // namespace coherent
