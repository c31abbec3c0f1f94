// Camera as Blender describes it, resolved to world space by the front end.
#pragma once

#include "../core/vec.h"

namespace coherent {

enum class Projection : uint8_t { Perspective, Orthographic };

struct Camera {
    Projection projection = Projection::Perspective;
    // World-space frame: right, up and forward (view direction) are orthonormal.
    Vec3f position{0.0f, 0.0f, 5.0f};
    Vec3f right{1.0f, 0.0f, 0.0f};
    Vec3f up{0.0f, 1.0f, 0.0f};
    Vec3f forward{0.0f, 0.0f, -1.0f};

    // Half extents of the image plane at distance 1 (perspective) or in world
    // units (orthographic), already resolved from lens/sensor fit/aspect.
    float half_width = 0.41421356f;   // tan(45deg/2) for a 45 degree horizontal FOV
    float half_height = 0.41421356f;
    // Lens shift in units of the larger image-plane extent (Blender shift_x/y).
    float shift_x = 0.0f, shift_y = 0.0f;
    float clip_start = 1e-3f, clip_end = 1e30f;

    // Depth of field: thin lens, disabled when aperture_radius == 0.
    float aperture_radius = 0.0f;
    float focus_distance = 10.0f;
};

}  // namespace coherent
