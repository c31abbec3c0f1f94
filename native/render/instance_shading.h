// A hit on an instance (Hit::instance, scene/instance.h) as shading sees it:
// the point reconstructed in object space from the prototype's triangle and
// carried to the world, with an error bound that covers both directions of
// the transform, so that a ray spawned from it (offset in world space by
// that bound, ray_offset.h) starts on the right side of the surface once
// InstanceBvh carries it back into object space (pbrt-v4 sec. 6.8.6; Cycles
// offsets in world space too).
#pragma once

#include <cmath>

#include "../core/float_bounds.h"
#include "../scene/scene.h"
#include "ray_offset.h"

namespace coherent {

struct InstancedPoint {
    Vec3f p, p_error;  // world-space point and its error bound
    Vec3f ng;          // unit world-space geometric normal
    Vec3f ns;          // interpolated world-space shading normal (not unit), when has_normal
    bool has_normal;
    uint32_t material;
};

// Absolute error bound of t.point(p) for a point p known within +-e
// (pbrt-v4's Transform applied to a Point3fi).
inline Vec3f transformed_point_error(const Transform& t, const Vec3f& p, const Vec3f& e) {
    constexpr float g3 = gamma_bound(3);
    Vec3f out;
    for (int r = 0; r < 3; ++r) {
        const float* m = t.m[r];
        const float magnitude =
            std::fabs(m[0] * p.x) + std::fabs(m[1] * p.y) + std::fabs(m[2] * p.z) + std::fabs(m[3]);
        out[r] = g3 * magnitude + (1.0f + g3) * (std::fabs(m[0]) * e.x + std::fabs(m[1]) * e.y + std::fabs(m[2]) * e.z);
    }
    return out;
}

// |linear part of t| applied to e (how an object-space error grows in the world).
inline Vec3f abs_linear(const Transform& t, const Vec3f& e) {
    Vec3f out;
    for (int r = 0; r < 3; ++r)
        out[r] = std::fabs(t.m[r][0]) * e.x + std::fabs(t.m[r][1]) * e.y + std::fabs(t.m[r][2]) * e.z;
    return out;
}

// The instance's transforms at shutter time `time`: its own when it stands
// still, else computed as InstanceBvh computes them for the ray.
struct InstanceFrame {
    Transform to_world, to_object, normals;
};

inline InstanceFrame instance_frame(const Scene& scene, const Instance& inst, float time) {
    if (inst.motion == kStillInstance) return {inst.object_to_world, inst.world_to_object, inst.normal_to_world};
    InstanceFrame f;
    f.to_world = instance_transform_at(inst.object_to_world, scene.instance_close[inst.motion], time);
    invert_affine(f.to_world, f.to_object);  // succeeded: the ray found this hit through it
    f.normals = normal_transform(f.to_world);
    return f;
}

// The hit point of a ray at shutter time `time` (0 without motion blur).
inline InstancedPoint instanced_point(const Scene& scene, const Hit& hit, float time = 0.0f) {
    const Instance& inst = scene.instances[hit.instance];
    const Prototype& proto = scene.prototypes[inst.prototype];
    const Vec3f* v = &proto.vertices[3 * size_t(hit.prim)];
    const InstanceFrame frame = instance_frame(scene, inst, time);
    InstancedPoint ip;
    Vec3f obj_error;
    const Vec3f p_obj = triangle_point(v[0], v[1], v[2], hit.u, hit.v, obj_error);
    ip.p = frame.to_world.point(p_obj);
    // The world error of the point, plus what carrying a spawned origin back
    // into object space adds there (rounding of world_to_object), mapped to
    // the world: the offset must clear the surface in the space it is tested in.
    const Vec3f back = transformed_point_error(frame.to_object, ip.p, Vec3f(0.0f));
    ip.p_error = transformed_point_error(frame.to_world, p_obj, obj_error) +
                 abs_linear(frame.to_world, back) * (1.0f + 2.0f * gamma_bound(3));
    const Vec3f ng = frame.normals.vector(cross(v[1] - v[0], v[2] - v[0]));
    const float len = length(ng);
    // A transform at the edge of float range may underflow the cofactors:
    // any unit vector keeps shading finite (such a triangle is a sliver).
    ip.ng = len > 0.0f && std::isfinite(len) ? ng / len : Vec3f{0.0f, 0.0f, 1.0f};
    ip.has_normal = proto.has_normals[hit.prim] != 0;
    if (ip.has_normal) {
        const Vec3f* sn = &proto.normals[3 * size_t(hit.prim)];
        ip.ns = frame.normals.vector(sn[0] * (1.0f - hit.u - hit.v) + sn[1] * hit.u + sn[2] * hit.v);
    }
    const uint32_t slot = proto.slot_of[hit.prim];
    ip.material = slot < inst.material_count ? scene.instance_materials[inst.first_material + slot] : 0u;
    return ip;
}

}  // namespace coherent
