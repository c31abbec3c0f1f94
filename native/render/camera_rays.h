// Primary rays from the Blender-resolved camera.
//
// Image plane: (sx, sy) in [-1, 1]^2 over the full frame (y up), mapped to
// sx*half_width, sy*half_height at distance 1 (perspective) or in world units
// (orthographic). Blender's lens shift is in units of the larger image-plane
// extent: shift 1 moves the view by one full frame width (if width >= height).
// Clipping is measured along the view axis, like Blender's clip distances.
#pragma once

#include <cmath>

#include "../core/ray.h"
#include "../scene/camera.h"

namespace coherent {

struct CameraRay {
    Ray ray;           // unit direction; tmin/tmax are the clip distances converted to ray units
    float depth_scale;  // view-axis depth per unit of t (cos to the view axis)
};

template <bool kDepthOfField>
inline CameraRay generate_camera_ray(const Camera& cam, float film_x, float film_y, int width, int height,
                                     float lens_u, float lens_v) {
    const float sx = 2.0f * film_x / float(width) - 1.0f;
    const float sy = 1.0f - 2.0f * film_y / float(height);
    const float larger = 2.0f * std::max(cam.half_width, cam.half_height);
    const float px = sx * cam.half_width + cam.shift_x * larger;
    const float py = sy * cam.half_height + cam.shift_y * larger;

    CameraRay cr;
    if (cam.projection == Projection::Orthographic) {
        cr.ray.o = cam.position + cam.right * px + cam.up * py;
        cr.ray.d = cam.forward;
        cr.ray.tmin = cam.clip_start;
        cr.ray.tmax = cam.clip_end;
        cr.depth_scale = 1.0f;
        return cr;
    }

    // Direction with unit forward component: t along it is the view-axis depth.
    const Vec3f d = cam.forward + cam.right * px + cam.up * py;
    Vec3f origin = cam.position;
    Vec3f dir = d;
    if constexpr (kDepthOfField) {
        if (cam.aperture_radius > 0.0f) {
            // Thin lens: the point at focus_distance along the view axis stays sharp.
            const float a = 2.0f * lens_u - 1.0f, b = 2.0f * lens_v - 1.0f;
            float r = 0.0f, phi = 0.0f;
            if (a != 0.0f || b != 0.0f) {
                if (a * a > b * b) {
                    r = a;
                    phi = 0.25f * kPi * (b / a);
                } else {
                    r = b;
                    phi = 0.5f * kPi - 0.25f * kPi * (a / b);
                }
            }
            const Vec3f lens = cam.right * (cam.aperture_radius * r * std::cos(phi)) +
                               cam.up * (cam.aperture_radius * r * std::sin(phi));
            const Vec3f focus = cam.position + d * cam.focus_distance;
            origin = cam.position + lens;
            dir = focus - origin;
            dir = dir / dot(dir, cam.forward);  // unit forward component again
        }
    }
    const float len = length(dir);
    cr.ray.o = origin;
    cr.ray.d = dir / len;
    cr.depth_scale = 1.0f / len;  // = cos to the view axis
    cr.ray.tmin = cam.clip_start * len;
    cr.ray.tmax = cam.clip_end * len;
    return cr;
}

}  // namespace coherent
