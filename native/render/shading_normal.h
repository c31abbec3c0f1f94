// The shading normal a BSDF may use, as Cycles 3.4 makes it valid
// (ensure_valid_reflection(), applied to every closure's normal): an
// interpolated normal is kept unless the viewer's mirror direction about it
// would fall below the geometric surface; then it is rotated towards the
// geometric normal, in the plane the two span, just far enough that the
// mirror direction rises above it by a small threshold. The rotation is
// continuous, so a smooth surface seen at grazing angles shades smoothly;
// replacing such a normal by the geometric one (what we did before) left a
// visibly different, straight-edged patch on every curved silhouette
// triangle (Sponza's columns: half of our bias against Cycles,
// docs/results/efficiency_gap.md).
#pragma once

#include <algorithm>
#include <cmath>

#include "../core/vec.h"

namespace coherent {

// ng: unit geometric normal on the viewer's side; wo: unit direction to the
// viewer; n: unit shading normal on ng's side. Returns a unit normal.
inline Vec3f valid_reflection_normal(const Vec3f& ng, const Vec3f& wo, const Vec3f& n) {
    // A normal on the far side of the surface (a mesh whose normals disagree
    // with its winding, e.g. a glTF with inward normals) has no valid
    // rotation in the plane below; the geometric normal shades it.
    if (!(dot(n, ng) > 0.0f)) return ng;
    // Reflections may always be at least as shallow as the incoming ray.
    const float threshold = std::min(0.9f * dot(ng, wo), 0.01f);
    const Vec3f r = n * (2.0f * dot(n, wo)) - wo;
    if (dot(ng, r) >= threshold) return n;

    // Frame: z = ng, x = n's part orthogonal to ng. The new normal n' lies in
    // the x-z plane; solve 2 (n'.x wo.x + n'.z wo.z) n'.z - wo.z = threshold
    // with n'.x = sqrt(1 - n'.z^2): n'.z^2 = (c +- b) / (2 a) below.
    const Vec3f x_axis = n - ng * dot(n, ng);
    const float x_len = length(x_axis);
    if (!(x_len > 0.0f)) return ng;
    const Vec3f x = x_axis / x_len;
    const float ix = dot(wo, x), iz = dot(wo, ng);
    const float a = ix * ix + iz * iz;
    const float b = std::sqrt(std::max(0.0f, ix * ix * (a - threshold * threshold)));
    const float c = iz * threshold + a;
    const float z2[2] = {0.5f * (b + c) / a, 0.5f * (c - b) / a};
    bool ok[2];
    for (int k = 0; k < 2; ++k) ok[k] = z2[k] > 1e-5f && z2[k] <= 1.0f + 1e-5f;
    float nz2;
    if (ok[0] && ok[1]) {
        // Both solve the quadratic; keep those whose mirror direction is
        // really above the surface, and of two the shallower (closer to n).
        float refl[2];
        for (int k = 0; k < 2; ++k) {
            const float nx = std::sqrt(std::max(0.0f, 1.0f - z2[k])), nz = std::sqrt(std::max(0.0f, z2[k]));
            refl[k] = 2.0f * (nx * ix + nz * iz) * nz - iz;
        }
        const bool up0 = refl[0] >= 1e-5f, up1 = refl[1] >= 1e-5f;
        nz2 = up0 && up1 ? (refl[0] < refl[1] ? z2[0] : z2[1]) : (refl[0] > refl[1] ? z2[0] : z2[1]);
    } else if (ok[0] || ok[1]) {
        nz2 = ok[0] ? z2[0] : z2[1];
    } else {
        return ng;
    }
    return x * std::sqrt(std::max(0.0f, 1.0f - nz2)) + ng * std::sqrt(std::max(0.0f, nz2));
}

}  // namespace coherent
