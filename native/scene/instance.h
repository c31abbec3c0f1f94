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
    // What the scene's shader programs read (SceneShading's rules), in
    // object space, 3 per triangle; empty when no program reads them.
    std::vector<std::vector<Vec2f>> uvs;  // [layer][corner], layers as SceneShading::uv_names
    std::vector<Vec3f> tangents;          // unit, orthogonal to the object-space shading normal
    std::vector<float> tangent_signs;
    Vec3f generated_scale{1.0f}, generated_offset{0.0f};  // Blender's texture space of the mesh

    size_t triangle_count() const { return slot_of.size(); }
};

constexpr uint32_t kStillInstance = 0xffffffffu;

// One placement of a prototype. `object_to_world` maps object space to the
// world; `world_to_object` is its inverse (rays are carried into object space
// with it); `normal_to_world` is the cofactor matrix times sign(det), the
// inverse transpose up to a positive scale (normals are renormalised).
// A moving instance (motion blur) has these at shutter open and its
// transform at shutter close in scene.instance_close[motion]; at time tau it
// is instance_transform_at() (the flattened motion's linear vertex paths).
struct Instance {
    uint32_t prototype = 0;
    uint32_t motion = kStillInstance;
    Transform object_to_world, world_to_object, normal_to_world;
    // Slot s of the prototype's triangles renders with material
    // scene.instance_materials[first_material + s]; slots at or past
    // material_count use the default material 0.
    uint32_t first_material = 0, material_count = 0;
    uint32_t object = 0;  // index into scene.object_names
    BBox world_bounds;    // the prototype's box, transformed (conservative; both shutter ends when moving)
};

// Inverse of the affine part of `t` (computed in double); false when the
// transform is singular or the inverse does not fit a float.
bool invert_affine(const Transform& t, Transform& inverse);
// The cofactor matrix of t's linear part times sign(det): normals map with
// it to the direction the inverse transpose gives.
Transform normal_transform(const Transform& t);

// A moving instance's object-to-world transform at shutter time tau:
// entrywise interpolation, so every object-space point moves on the line
// between its two world positions, exactly as flattened moving triangles
// do (motion_bvh.h). The one definition every kernel and shading use.
inline Transform instance_transform_at(const Transform& open, const Transform& close, float tau) {
    Transform t;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) t.m[r][c] = open.m[r][c] + tau * (close.m[r][c] - open.m[r][c]);
    return t;
}

}  // namespace coherent
