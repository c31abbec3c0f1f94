#include "gltf_blender.h"

#include <algorithm>
#include <cmath>

namespace coherent::gltf {
namespace {

Vec3f normalize_or(const Vec3f& v, const Vec3f& fallback) {
    const float len = length(v);
    return (std::isfinite(len) && len > 1e-20f) ? v / len : fallback;
}

// Any unit vector not parallel to `n`.
Vec3f perpendicular_to(const Vec3f& n) {
    Vec3f t, b;
    make_basis(n, t, b);
    return b;
}

}  // namespace

void set_camera_frame(const Transform& world, Camera& camera) {
    camera.position = world.point(Vec3f(0.0f));
    const Vec3f forward = normalize_or(world.vector({0.0f, 0.0f, -1.0f}), {0.0f, 0.0f, -1.0f});
    // Gram-Schmidt: keep forward exact, make up perpendicular to it.
    Vec3f up = world.vector({0.0f, 1.0f, 0.0f});
    up = up - forward * dot(up, forward);
    up = normalize_or(up, perpendicular_to(forward));
    camera.forward = forward;
    camera.up = up;
    camera.right = cross(forward, up);  // (0,0,-1) x (0,1,0) = (1,0,0)
}

void resolve_perspective(float yfov, float aspect, Camera& camera) {
    camera.projection = Projection::Perspective;
    camera.half_height = std::tan(0.5f * yfov);
    camera.half_width = camera.half_height * aspect;
}

void resolve_orthographic(float xmag, float ymag, float aspect, Camera& camera) {
    camera.projection = Projection::Orthographic;
    // ortho_scale spans the larger image dimension (sensor fit AUTO).
    const float half_scale = std::max(std::fabs(xmag), std::fabs(ymag));
    if (aspect >= 1.0f) {
        camera.half_width = half_scale;
        camera.half_height = half_scale / aspect;
    } else {
        camera.half_height = half_scale;
        camera.half_width = half_scale * aspect;
    }
}

Camera framing_camera(const BBox& bounds, float aspect) {
    Camera camera;
    const float half_fov = 0.5f * 40.0f * kPi / 180.0f;
    const float t = std::tan(half_fov);
    if (aspect >= 1.0f) {
        camera.half_height = t;
        camera.half_width = t * aspect;
    } else {
        camera.half_width = t;
        camera.half_height = t / aspect;
    }
    if (bounds.empty()) return camera;

    const Vec3f center = bounds.center();
    const float radius = std::max(0.5f * length(bounds.extent()), 1e-6f);
    // The sphere fits when its tangent cone's half angle is the half FOV.
    const float distance = radius / std::sin(half_fov);
    const Vec3f from = normalize(Vec3f(0.3f, 0.4f, 1.0f));
    camera.position = center + from * distance;
    camera.forward = -from;
    camera.up = normalize(Vec3f(0.0f, 1.0f, 0.0f) - camera.forward * dot(Vec3f(0.0f, 1.0f, 0.0f), camera.forward));
    camera.right = cross(camera.forward, camera.up);
    // Every point of the scene lies within distance + radius of the camera.
    camera.clip_start = 1e-3f * distance;
    camera.clip_end = 2.0f * (distance + radius);
    return camera;
}

Light blender_light(const PunctualLight& in, const Transform& world) {
    Light light;
    light.position = world.point(Vec3f(0.0f));
    light.direction = normalize_or(world.vector({0.0f, 0.0f, -1.0f}), {0.0f, 0.0f, -1.0f});
    light.color = in.has_color ? max(in.color, Vec3f(0.0f)) : Vec3f(1.0f);
    light.radius = kBlenderDefaultSoftSize;
    light.sun_angle = kBlenderDefaultSunAngle;
    const float intensity = std::max(in.intensity, 0.0f);

    switch (in.type) {
        case PunctualLight::Type::Directional:
            light.type = LightType::Sun;
            light.power = in.has_intensity ? intensity / kWattsToLumens : kBlenderDefaultEnergy;
            break;
        case PunctualLight::Type::Point:
            light.type = LightType::Point;
            light.power = in.has_intensity ? intensity / kWattsToLumens * 4.0f * kPi : kBlenderDefaultEnergy;
            break;
        case PunctualLight::Type::Spot: {
            light.type = LightType::Spot;
            light.power = in.has_intensity ? intensity / kWattsToLumens * 4.0f * kPi : kBlenderDefaultEnergy;
            const float outer = in.has_outer_cone ? in.outer_cone : kPi / 4.0f;
            float blend = 1.0f;
            if (in.has_inner_cone && outer > 0.0f) blend = 1.0f - in.inner_cone / outer;
            // Blender's property ranges clamp what the importer assigns.
            light.spot_size = std::clamp(2.0f * outer, kPi / 180.0f, kPi);
            light.spot_blend = std::clamp(blend, 0.0f, 1.0f);
            break;
        }
    }
    return light;
}

}  // namespace coherent::gltf
