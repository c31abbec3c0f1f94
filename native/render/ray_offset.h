// Spawning rays from surfaces without self-intersection at any scene scale
// (pbrt-v4, "Robust spawned ray origins", sec. 6.8.6): the hit point is
// reconstructed from barycentrics, its floating-point error is bounded
// conservatively, and the origin is pushed along the geometric normal just
// past that bound, then rounded away from the surface by one ulp. The bound is
// relative to the magnitude of the vertex coordinates, so the offset shrinks
// and grows with the scene instead of being a fixed epsilon.
#pragma once

#include <cmath>
#include <cstring>

#include "../core/float_bounds.h"
#include "../core/vec.h"

namespace coherent {

constexpr float kMachineEps = 0x1p-24f;

// Point on triangle (p0, p1, p2) at barycentrics (u, v) with an absolute
// error bound that also covers the intersector.
//
// Two error sources matter: (1) the reconstructed point itself (pbrt-v4's
// gamma(7) bound on barycentric interpolation, doubled for w = 1 - u - v);
// (2) the watertight intersector computes t from vertex positions relative to
// the ray origin, so a ray leaving a large triangle can re-hit it at a small
// positive t even from a point exactly on its plane (measured: t = 1.6e-7 on
// a 20 m quad through z = 0, whose point error is exactly 0). That error is
// proportional to the triangle's extent around p, so it is added as
// 32 eps * max |p_i - p| in every axis. Both terms scale with the geometry.
inline Vec3f triangle_point(const Vec3f& p0, const Vec3f& p1, const Vec3f& p2, float u, float v, Vec3f& error) {
    const float w = 1.0f - u - v;
    const Vec3f p = p0 * w + p1 * u + p2 * v;
    const float extent = max_component(max(max(abs(p0 - p), abs(p1 - p)), abs(p2 - p)));
    error = (abs(p0 * w) + abs(p1 * u) + abs(p2 * v)) * (2.0f * gamma_bound(7)) + Vec3f(32.0f * kMachineEps * extent);
    return p;
}

inline float next_float_up(float f) {
    if (std::isinf(f) && f > 0.0f) return f;
    if (f == -0.0f) f = 0.0f;
    uint32_t ui;
    std::memcpy(&ui, &f, 4);
    ui = f >= 0.0f ? ui + 1 : ui - 1;
    std::memcpy(&f, &ui, 4);
    return f;
}
inline float next_float_down(float f) {
    if (std::isinf(f) && f < 0.0f) return f;
    if (f == 0.0f) f = -0.0f;
    uint32_t ui;
    std::memcpy(&ui, &f, 4);
    ui = f > 0.0f ? ui - 1 : ui + 1;
    std::memcpy(&f, &ui, 4);
    return f;
}

// Origin for a ray leaving point p (error bound `error`, unit geometric
// normal n) in direction w.
inline Vec3f offset_ray_origin(const Vec3f& p, const Vec3f& error, const Vec3f& n, const Vec3f& w) {
    const float d = dot(abs(n), error);
    Vec3f offset = n * d;
    if (dot(w, n) < 0.0f) offset = -offset;
    Vec3f po = p + offset;
    for (int i = 0; i < 3; ++i) {
        if (offset[i] > 0.0f) po[i] = next_float_up(po[i]);
        else if (offset[i] < 0.0f) po[i] = next_float_down(po[i]);
    }
    return po;
}

}  // namespace coherent
