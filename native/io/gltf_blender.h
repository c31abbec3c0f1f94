// How Blender 3.4's glTF importer (io_scene_gltf2, default "Standard" lighting
// mode) turns glTF cameras and KHR_lights_punctual lights into Blender data,
// reproduced so that a file rendered by the CLI matches the same file
// imported into Blender and rendered there.
//
// Sources: io_scene_gltf2/blender/imp/gltf2_blender_camera.py and
// gltf2_blender_light.py, and the values Blender itself reports after an
// import (checked with `blender -b` on test files):
//  - perspective: angle_y = yfov with sensor_fit VERTICAL, so the vertical
//    field of view is yfov whatever the render aspect; aspectRatio is ignored.
//  - orthographic: ortho_scale = 2 max(xmag, ymag), sensor_fit AUTO, so the
//    scale spans the larger image dimension.
//  - point/spot: W = cd / 683 * 4 pi; sun: W/m^2 = lux / 683.
//  - spot: spot_size = 2 outer, spot_blend = 1 - inner / outer.
//  - a missing intensity leaves Blender's default energy of 10, a missing
//    colour leaves white; the importer never touches shadow_soft_size (0.25)
//    or the sun angle (0.526 degrees).
#pragma once

#include "../core/bbox.h"
#include "../core/vec.h"
#include "../scene/camera.h"
#include "../scene/light.h"

namespace coherent::gltf {

constexpr float kWattsToLumens = 683.0f;          // PBR_WATTS_TO_LUMENS
constexpr float kBlenderDefaultEnergy = 10.0f;     // bpy.data.lights.new() energy
constexpr float kBlenderDefaultSoftSize = 0.25f;   // shadow_soft_size
constexpr float kBlenderDefaultSunAngle = 0.526f * kPi / 180.0f;

// Sets position and the orthonormal right/up/forward frame from a node's
// world matrix (glTF cameras look down -Z with +Y up). Scale and shear are
// removed as Blender does for camera objects.
void set_camera_frame(const Transform& world, Camera& camera);

// Resolves the image-plane half extents for a render of aspect width/height.
void resolve_perspective(float yfov, float aspect, Camera& camera);
void resolve_orthographic(float xmag, float ymag, float aspect, Camera& camera);

// The camera used when a file has none: looks at the centre of `bounds` from
// the direction (0.3, 0.4, 1) (up +Y), with a 40 degree field of view across
// the smaller image dimension and the bounding sphere just inside the view.
Camera framing_camera(const BBox& bounds, float aspect);

// A KHR_lights_punctual light with presence flags, because Blender's result
// depends on whether a property was written or left to the glTF default.
struct PunctualLight {
    enum class Type { Point, Spot, Directional } type = Type::Point;
    bool has_color = false;
    Vec3f color{1.0f, 1.0f, 1.0f};
    bool has_intensity = false;
    float intensity = 1.0f;
    bool has_inner_cone = false, has_outer_cone = false;
    float inner_cone = 0.0f, outer_cone = kPi / 4.0f;
};

// The light Blender creates for `light` on a node with world matrix `world`.
Light blender_light(const PunctualLight& light, const Transform& world);

}  // namespace coherent::gltf
