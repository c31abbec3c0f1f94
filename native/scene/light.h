// Analytic lights, in Blender/Cycles units so a scene looks the same in both.
#pragma once

#include <cstdint>

#include "../core/vec.h"

namespace coherent {

enum class LightType : uint8_t { Point, Spot, Sun, Area };
enum class AreaShape : uint8_t { Square, Rectangle, Disk, Ellipse };

struct Light {
    LightType type = LightType::Point;
    // Colour x power as the user typed it: Watts for point/spot/area,
    // W/m^2 (irradiance) for sun. Converted to radiance by the renderer.
    Vec3f color{1.0f, 1.0f, 1.0f};
    float power = 10.0f;

    Vec3f position{0.0f, 0.0f, 0.0f};
    // Direction the light points to (spot axis, sun travel direction, area normal).
    Vec3f direction{0.0f, 0.0f, -1.0f};
    // Area lights: unit tangent axes spanning the emitter plane.
    Vec3f axis_u{1.0f, 0.0f, 0.0f};
    Vec3f axis_v{0.0f, 1.0f, 0.0f};

    float radius = 0.0f;        // point/spot soft radius (Blender shadow_soft_size)
    float spot_size = 0.785f;   // full cone angle, radians
    float spot_blend = 0.15f;   // [0,1]
    float sun_angle = 0.0f;     // angular diameter, radians
    AreaShape shape = AreaShape::Square;
    float size_u = 1.0f;        // area light extent along axis_u (diameter for disk/ellipse)
    float size_v = 1.0f;        // along axis_v (ignored for Square and Disk)
};

}  // namespace coherent
