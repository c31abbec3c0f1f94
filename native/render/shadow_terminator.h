// Cycles' shadow terminator geometry offset (Object > Shading > Shadow
// Terminator > Geometry Offset, 0.1 by default; Hanika 2021, "Hacking the
// Shadow Terminator", Ray Tracing Gems II, ch. 4). A smooth-shaded mesh is
// flat triangles whose interpolated normals describe a curved surface. Where
// light grazes it, shadow rays leaving the flat triangles are blocked by
// their neighbours (a jagged, faceted terminator), or pass below them. Cycles
// 3.4 starts such shadow rays from the curved surface instead: the point
// lifted along the interpolated normal by a parabola through the vertex
// normals. This follows kernel/light/sample.h (shadow_ray_offset and
// shadow_ray_smooth_surface_offset) of Cycles 3.4; without it our shadow
// edges differ from Cycles' on curved, sunlit geometry (Sponza's arches and
// curtains, the scanned statues), an error that more samples do not reduce.
#pragma once

#include <algorithm>
#include <cmath>

#include "../core/vec.h"

namespace coherent {

// The lift of the point with barycentric weights (b0, b1, b2) on vertices
// V[0..2] with vertex normals N[0..2] (world space) towards the smooth surface
// they describe, for a shadow ray on the side of unit normal `ng` (the
// geometric normal facing the light's side of the surface). Cycles'
// shadow_ray_smooth_surface_offset, its u and v being b0 and b1.
inline Vec3f smooth_surface_lift(const Vec3f V[3], const Vec3f N[3], float b0, float b1, float b2, const Vec3f& ng) {
    const float u = b0, v = b1;
    const Vec3f P = V[0] * b0 + V[1] * b1 + V[2] * b2;
    const Vec3f n = N[0] * b0 + N[1] * b1 + N[2] * b2;  // unnormalised, as Cycles
    // Parabolic approximation.
    const float a = dot(N[2] - N[0], V[0] - V[2]);
    const float b = dot(N[2] - N[1], V[1] - V[2]);
    const float c = dot(N[1] - N[0], V[1] - V[0]);
    float h = a * u * (u - 1.0f) + (a + b + c) * u * v + b * v * (v - 1.0f);
    // Bounded by each vertex's tangent plane (the local linear envelope).
    if (dot(n, ng) > 0.0f) {
        float h0 = std::max(std::max(dot(V[1] - V[0], N[0]), dot(V[2] - V[0], N[0])), 0.0f);
        float h1 = std::max(std::max(dot(V[0] - V[1], N[1]), dot(V[2] - V[1], N[1])), 0.0f);
        float h2 = std::max(std::max(dot(V[0] - V[2], N[2]), dot(V[1] - V[2], N[2])), 0.0f);
        h0 = std::max(dot(V[0] - P, N[0]) + h0, 0.0f);
        h1 = std::max(dot(V[1] - P, N[1]) + h1, 0.0f);
        h2 = std::max(dot(V[2] - P, N[2]) + h2, 0.0f);
        h = std::max(std::min(std::min(h0, h1), h2), h * 0.5f);
    } else {  // the interpolated normal faces away from ng
        float h0 = std::max(std::max(dot(V[0] - V[1], N[0]), dot(V[0] - V[2], N[0])), 0.0f);
        float h1 = std::max(std::max(dot(V[1] - V[0], N[1]), dot(V[1] - V[2], N[1])), 0.0f);
        float h2 = std::max(std::max(dot(V[2] - V[0], N[2]), dot(V[2] - V[1], N[2])), 0.0f);
        h0 = std::max(dot(P - V[0], N[0]) + h0, 0.0f);
        h1 = std::max(dot(P - V[1], N[1]) + h1, 0.0f);
        h2 = std::max(dot(P - V[2], N[2]) + h2, 0.0f);
        h = std::min(-std::min(std::min(h0, h1), h2), h * 0.5f);
    }
    return n * h;
}

// How much of the lift a shadow ray towards unit direction l gets, from the
// shading point's unit smooth normal ns and geometric normal ng (both on the
// side the path arrived from) and the object's offset `cutoff`: 1 where the
// light grazes or lies below the geometric surface, fading to 0 where it is
// `cutoff` (as a cosine) above both normals. `ng_light` gets the geometric
// normal on the light's side; `ng_dot_l` its cosine with l (Cycles' NgL).
inline float terminator_amount(float cutoff, const Vec3f& ns, const Vec3f& ng, const Vec3f& l, Vec3f& ng_light,
                               float& ng_dot_l) {
    float nl = dot(ns, l);
    const bool transmit = nl < 0.0f;
    nl = std::abs(nl);
    ng_light = transmit ? -ng : ng;
    ng_dot_l = dot(ng_light, l);
    const float amount = nl < cutoff ? 2.0f - (ng_dot_l + nl) / cutoff : 1.0f - ng_dot_l / cutoff;
    return std::clamp(amount, 0.0f, 1.0f);
}

}  // namespace coherent
