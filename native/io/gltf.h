// glTF 2.0 (.gltf/.glb) loading into a Scene, with Blender's importer
// conventions (light units, Y-up kept as in the file) so a file renders the
// same in the CLI as in Blender after import.
#pragma once

#include <string>

#include "../scene/scene.h"

namespace coherent {

struct GltfLoadResult {
    bool ok = false;
    std::string error;     // one line, set when !ok: what was wrong and where
    bool had_camera = false;
    bool had_lights = false;  // punctual lights or emissive materials
};

// Appends the file's meshes, materials, lights and first camera to `scene`
// (does not call scene.finalize()). A file with no camera gets a default that
// frames the scene; one with no light at all gets a uniform white world.
// `aspect` (width/height) is used to resolve the camera's image plane.
// Never throws. When !ok the scene may hold part of the file: discard it.
// Primitives that cannot be used (not triangles, broken accessors, Draco
// compression) are skipped and listed in scene.dropped.skipped_meshes.
GltfLoadResult load_gltf(const std::string& path, Scene& scene, float aspect = 1.0f);

}  // namespace coherent
