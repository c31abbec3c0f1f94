// Running a material's shader program (program.h) at one shading point.
#pragma once

#include "../core/vec.h"
#include "../scene/material.h"

namespace coherent {

struct Prototype;
struct Scene;
struct ShaderProgram;

// The path that reached a shading point, for the Light Path node (Cycles'
// path flags and bounce counters at that point). Filled only for programs
// that read it (ShaderProgram::uses_light_path).
struct LightPathInfo {
    enum Flag : uint8_t {
        kCamera = 1, kShadow = 2, kDiffuse = 4, kGlossy = 8, kSingular = 16, kReflect = 32, kTransmit = 64
    };
    uint8_t flags = kCamera;
    float ray_length = 0.0f;
    int depth = 0, diffuse_depth = 0, glossy_depth = 0, transparent_depth = 0, transmission_depth = 0;
};

// What a program may read at a shading point.
struct ShadingGeometry {
    uint32_t tri = 0;
    float u = 0.0f, v = 0.0f;  // barycentrics of corners 1 and 2
    Vec3f p{0.0f};             // world-space position
    Vec3f n{0.0f};             // shading normal, on the side the ray came from
    Vec3f ng{0.0f};            // geometric normal, on that side
    Vec3f wo{0.0f};            // towards where the ray came from
    bool front = true;         // the ray hit the side the winding normal points to
    // On an instance (scene/instance.h; else null): the prototype, its
    // triangle (`tri` is then meaningless) and the instance's transforms at
    // the ray's time. Attributes come from the prototype, in object space.
    // Invariant: the transforms are read only where `prototype` is set
    // (batches reuse their ShadingGeometry arrays and leave them stale
    // elsewhere: render/path_state.h, fill_shading_geometry).
    const Prototype* prototype = nullptr;
    uint32_t prim = 0;
    Transform object_to_world, world_to_object;
    const LightPathInfo* path = nullptr;  // null: Light Path outputs read 0
    // Cycles' compact dP: the width the pixel's ray covers at p, the step
    // of Bump's offsets. Filled only for programs with a Bump instruction.
    float footprint = 0.0f;
};

// The closures and emission of `mat` at g: its constants with the program's
// outputs applied (mat.program must be set). `n` receives the shading normal:
// g.n unless the program computes one (Normal Map).
void evaluate_material(const Scene& scene, const Material& mat, const ShadingGeometry& g, Material& out, Vec3f& n);

// Runs a program that reads no geometry or image over `registers` (its
// constants, resized by the caller): how the compiler folds constant
// subgraphs with exactly the formulas the renderer uses.
void run_constant_program(const ShaderProgram& program, float* registers);

}  // namespace coherent
