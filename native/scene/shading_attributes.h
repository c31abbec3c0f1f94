// Per-corner and per-object data that shader programs read (native/shader),
// kept beside the triangles and filled only when some material's program
// needs it: a scene without textures stores no UVs, one without normal maps
// no tangents (SceneShading::wants_*, set by the front end before add_mesh).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "../core/vec.h"

namespace coherent {

class TextureStore;

// What add_mesh reads for shading, all optional (null = not provided).
struct MeshShadingInput {
    // One per SceneShading::uv_names entry: triangle_count x 3 x 2 per-corner UVs, or null.
    std::vector<const float*> uvs;
    // One per SceneShading::color_names entry: triangle_count x 3 x 4 per-corner linear RGBA, or null.
    std::vector<const float*> colors;
    // triangle_count x 3 x 4: object-space tangent (xyz) and bitangent sign (w), per corner.
    const float* tangents = nullptr;
    // Blender's texture space: generated = object position * scale + offset.
    Vec3f generated_scale{1.0f}, generated_offset{0.0f};
};

// Where object-space texture coordinates come from, per object (Scene::object_of).
struct ObjectShading {
    Transform world_to_object;
    Vec3f generated_scale{1.0f}, generated_offset{0.0f};
};

struct SceneShading {
    // Set before meshes are added: what programs read.
    std::vector<std::string> uv_names;  // UV layers programs address by index ("" = the active render UV map)
    std::vector<std::string> color_names;  // colour attributes programs address by index
    bool wants_tangents = false;
    bool wants_objects = false;

    // Filled by add_mesh, parallel to Scene::vertices (3 per triangle):
    std::vector<std::vector<Vec2f>> uvs;  // [layer][corner]; a mesh without the layer gets (0, 0)
    std::vector<std::vector<float>> colors;  // [attribute][4 * corner + channel]; missing: 0
    std::vector<Vec3f> tangents;          // world space, unit; empty unless wants_tangents
    std::vector<float> tangent_signs;     // bitangent = sign * cross(normal, tangent), mirroring included
    std::vector<ObjectShading> objects;   // per object; empty unless wants_objects

    // Images the programs look up (null until the first image is added).
    std::shared_ptr<TextureStore> textures;
};

struct MeshInput;
// Appends triangle t's corners (in `corner` order) to the shading attributes;
// `normals` are its world-space shading normals in that order.
void append_shading_corners(SceneShading& shading, const MeshInput& mesh, size_t t, const int corner[3],
                            const Vec3f normals[3]);
// Records the object-space data of a mesh that became an object.
void append_object_shading(SceneShading& shading, const MeshInput& mesh);

}  // namespace coherent
