// The one scene representation: flat, validated, world-space triangle arrays
// plus materials, lights, camera and world. Front ends (Blender export, glTF
// loader, tests) fill it through add_mesh(), which validates every input.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "../core/bbox.h"
#include "../core/vec.h"
#include "camera.h"
#include "features.h"
#include "instance.h"
#include "light.h"
#include "material.h"
#include "shading_attributes.h"
#include "world.h"

namespace coherent {

// What validation removed, per reason. Reported to the user as one warning.
struct DropReport {
    size_t nonfinite_vertices = 0;     // triangles dropped because a vertex was NaN/Inf
    size_t out_of_range_indices = 0;   // triangles dropped for an index >= vertex count
    size_t degenerate_triangles = 0;   // triangles dropped for zero area
    size_t bad_material_ids = 0;       // material id out of range, replaced by default material
    std::vector<std::string> skipped_meshes;  // meshes rejected as a whole, with the reason
    std::vector<std::string> meshes_with_drops;  // names of meshes that lost triangles or had bad material ids

    size_t total_triangles() const { return nonfinite_vertices + out_of_range_indices + degenerate_triangles; }
    bool empty() const { return total_triangles() == 0 && bad_material_ids == 0 && skipped_meshes.empty(); }
    // One human-readable line, empty when nothing was dropped.
    std::string summary() const;
};

// Input to add_mesh: borrowed, row-major arrays (numpy-compatible).
struct MeshInput {
    std::string name;
    const float* positions = nullptr;     // vertex_count x 3, object space
    size_t vertex_count = 0;
    const uint32_t* indices = nullptr;    // triangle_count x 3
    size_t triangle_count = 0;
    const float* normals = nullptr;       // optional: per-corner normals, triangle_count x 3 x 3 (object space)
    const uint32_t* material_ids = nullptr;  // optional: triangle_count entries, index into `material_slots`
    std::vector<uint32_t> material_slots;    // scene material index per slot; empty => default material 0
    Transform object_to_world;
    // Object motion blur (optional): the mesh at shutter close. Positions
    // (vertex_count x 3, object space; null = the same as `positions`) and
    // transform; the mesh moves linearly from (positions, object_to_world)
    // at shutter open to these. Normals follow the close transform.
    const float* positions_close = nullptr;
    bool moves = false;  // true when positions_close or object_to_world_close applies
    Transform object_to_world_close;
    MeshShadingInput shading;  // UVs, tangents, texture space: read only where Scene::shading wants them
    // Vector pass (optional): object_to_world one frame earlier and one frame
    // later, two transforms (DataPassInputs::object_frame_motion).
    const Transform* frame_transforms = nullptr;
};

// Vector pass (film/passes.h): where a point seen at this frame was one
// frame earlier and will be one frame later, as world-to-world transforms.
struct FrameMotion {
    Transform to_previous, to_next;
};

// The camera's frame (Camera's position and axes) one frame away; the lens
// is always Scene::camera's, as in Cycles' motion pass.
struct CameraFrame {
    Vec3f position{0.0f}, right{1.0f, 0.0f, 0.0f}, up{0.0f, 1.0f, 0.0f}, forward{0.0f, 0.0f, -1.0f};
};

// What Cycles' data passes (film/passes.h) read besides the geometry:
// pass_index per object (parallel to Scene::object_names) and per material
// (parallel to Scene::materials), missing entries 0; the World's mist
// (falloff exponent 2 quadratic, 1 linear, 0.5 inverse quadratic) and AO
// distance (<= 0: the ao_distance setting's resolved length).
struct DataPassInputs {
    std::vector<float> object_pass_index, material_pass_index;
    float mist_start = 5.0f, mist_depth = 25.0f, mist_falloff = 2.0f;
    float ao_distance = 0.0f;
    // Cryptomatte names per object (empty entries or vectors: the object's
    // name): the object as Blender names it (an instance's own object) and
    // its asset (the top-level parent).
    std::vector<std::string> crypto_object_names, crypto_asset_names;
    // Vector pass: per object (parallel to object_names, for world-space
    // triangles) and per instance (parallel to instances), identity where
    // still; a list is empty while nothing in it moves, and may end early.
    std::vector<FrameMotion> object_frame_motion, instance_frame_motion;
    // The camera one frame earlier and later (camera_moves false: standing still).
    bool camera_moves = false;
    CameraFrame camera_previous, camera_next;
};

// Sets list[index] (growing the list with identities) to the motion of an
// object placed by `now` whose placements one frame away are frames[0]
// (previous) and frames[1] (next). A singular `now` leaves it still.
void set_frame_motion(std::vector<FrameMotion>& list, size_t index, const Transform& now, const Transform* frames);

// Cycles' default Shadow Terminator Geometry Offset of an object.
constexpr float kDefaultTerminatorOffset = 0.1f;

struct Scene {
    // --- geometry (world space), triangle i uses vertices 3i, 3i+1, 3i+2 ---
    std::vector<Vec3f> vertices;        // 3 per triangle (unindexed: simplest for BVH leaves and for validation)
    std::vector<Vec3f> normals;         // 3 per triangle shading normals; geometric normal used if size() == 0 for all
    std::vector<uint8_t> has_normals;   // 1 per triangle: 1 if `normals` holds real shading normals
    std::vector<uint32_t> material_of;  // 1 per triangle
    std::vector<uint32_t> object_of;    // 1 per triangle: index into object_names
    std::vector<std::string> object_names;
    // Cycles' Shadow Terminator > Geometry Offset per object (parallel to
    // object_names; render/shadow_terminator.h); empty: Cycles' default for all.
    std::vector<float> object_terminator_offset;
    float terminator_offset(uint32_t tri) const {
        if (object_terminator_offset.empty() || tri >= object_of.size()) return kDefaultTerminatorOffset;
        return object_terminator_offset[object_of[tri]];
    }
    // Object motion blur: every triangle's corners (and shading normals) at
    // shutter close, parallel to `vertices` / `normals`; empty when nothing
    // moves. `vertices` are the positions at shutter open; a triangle moves
    // linearly between the two over the shutter (ray time 0 to 1).
    std::vector<Vec3f> motion_vertices;
    std::vector<Vec3f> motion_normals;

    // --- shared geometry (instance.h): prototypes in object space, placed by instances ---
    std::vector<Prototype> prototypes;
    std::vector<Instance> instances;
    std::vector<uint32_t> instance_materials;  // per instance, its slots' scene materials (Instance::first_material)
    std::vector<Transform> instance_close;     // moving instances' transforms at shutter close (Instance::motion)

    std::vector<Material> materials;    // materials[0] always exists (default grey diffuse)
    std::vector<Light> lights;
    Vec3f world_color{0.0f, 0.0f, 0.0f};  // constant environment radiance, or world_map's strength
    EnvironmentMap world_map;              // when not empty, world radiance(d) = world_color x world_map(d)
    Camera camera;
    // What shader programs read (UVs, tangents, object spaces) and their images.
    SceneShading shading;

    DataPassInputs data_passes;

    DropReport dropped;

    Scene();

    size_t triangle_count() const { return material_of.size(); }
    BBox bounds() const;

    // Validates and appends a mesh in world space. Never throws for bad data:
    // bad triangles are dropped and counted in `dropped`; a mesh with nothing
    // usable is listed in dropped.skipped_meshes. Returns triangles added.
    size_t add_mesh(const MeshInput& mesh);
    uint32_t add_material(const Material& m);  // returns its index

    // Shared geometry (instancing.cpp). add_prototype validates a mesh's
    // triangles as add_mesh does, but in object space (object_to_world and
    // motion are ignored), and stores them once; material ids are kept as
    // slots, resolved per instance. Returns the prototype's index, or
    // kNoPrototype when no triangle is usable (listed in dropped).
    static constexpr uint32_t kNoPrototype = 0xffffffffu;
    uint32_t add_prototype(const MeshInput& mesh);
    // Places prototype `prototype` once per transform, each with the same
    // material slots (scene material per slot) and object name. With
    // `close_transforms` (motion blur; null = none), instance i moves from
    // transforms[i] at shutter open to close_transforms[i] at close. An
    // instance whose transform is not invertible (or not finite; for a
    // moving one at either end or mid-shutter) is skipped and reported in dropped. Instances of an emissive material are flattened
    // into world-space triangles instead (add_mesh), so that next-event
    // estimation samples them. Throws std::invalid_argument for an unknown
    // prototype or material. Returns the instances placed (either way).
    // `frame_transforms` (Vector pass; null = none): two per instance, its
    // placement one frame earlier and one later (MeshInput::frame_transforms).
    size_t add_instances(uint32_t prototype, const Transform* transforms, size_t count,
                         const std::vector<uint32_t>& material_slots, const std::string& name,
                         const Transform* close_transforms = nullptr, const Transform* frame_transforms = nullptr);
    bool has_moving_instances() const { return !instance_close.empty(); }
    // Triangles rendered through instances (each instance counts its prototype's).
    size_t instanced_triangle_count() const;

    // Computed by finalize(); valid until the scene changes.
    SceneFeatures features;
    // Emissive triangles, for next-event estimation (static ones: a moving
    // emitter is reached by BSDF sampling only).
    std::vector<uint32_t> emissive_triangles;
    // Per-triangle world-space geometric normal (unit, from the winding), filled by finalize().
    std::vector<Vec3f> geometric_normals;
    // Triangles whose close corners differ from their open ones (motion blur).
    std::vector<uint32_t> moving_triangles;
    bool is_moving(uint32_t tri) const { return !moving_flag.empty() && moving_flag[tri] != 0; }
    std::vector<uint8_t> moving_flag;  // 1 per triangle when any moves, else empty
    void finalize();
};

}  // namespace coherent
