// Transparent surfaces, as Cycles 3.4 renders them.
//
// A Transparent closure (Transparent BSDF, Principled Alpha < 1, glTF
// alphaMode) lets light through unchanged in direction, weighted by its
// colour. Cycles treats it as a lobe of the BSDF that is chosen stochastically
// like any other (so at a Principled with alpha a the path passes through with
// probability about 1 - a), and a pass-through is not a bounce: it counts
// against transparent_max_bounces only, keeps the ray's type (a camera ray
// stays a camera ray, for alpha and light visibility) and its MIS state. Here
// the pass-through keeps the very ray and moves its tmin to the hit (the
// interval is half-open, triangle.h), so the origin that MIS and light pdfs
// measure from stays the last scattering vertex.
//
// Shadow rays see transparency deterministically (Cycles' transparent
// shadows): the product of the transparent weights of the surfaces between
// the point and the light, opaque once a non-transparent surface or more than
// the remaining transparent bounces are crossed. In scenes with transparent
// surfaces the state machine resolves each shadow ray itself with the
// single-ray kernels (path_state.h, trace_transparent_shadow: one any-hit
// test, then closest hits only if that one is occluded) and queues none for
// the driver, so every traversal gives the same answer; those rays are not
// in the drivers' ray statistics.
//
// A Holdout closure scatters nothing; while the path is still the camera's
// (no bounce yet, pass-throughs allowed) its weight times the throughput is
// taken off the pixel's alpha, and a full holdout ends the path.
//
// All of this is compiled in only where SceneFeatures::transparent /
// ::holdout say a used material has such a closure.
#pragma once

#include "../core/ray.h"
#include "../scene/material.h"

namespace coherent {

// Cycles' average(): how a colour weight counts against the scalar alpha.
inline float average(const Vec3f& c) { return (c.x + c.y + c.z) * (1.0f / 3.0f); }

// The summed colour of the Transparent closures of an evaluated material.
inline Vec3f material_transparency(const Material& m) {
    Vec3f t(0.0f);
    for (int c = 0; c < m.closure_count && c < 4; ++c) {
        const Closure& cl = m.closures[size_t(c)];
        if (cl.kind == ClosureKind::Transparent && m.weights[size_t(c)] > 0.0f) t += cl.base_color * m.weights[size_t(c)];
    }
    return t;
}

// The summed weight of the Holdout closures of an evaluated material.
inline float material_holdout(const Material& m) {
    float h = 0.0f;
    for (int c = 0; c < m.closure_count && c < 4; ++c)
        if (m.closures[size_t(c)].kind == ClosureKind::Holdout && m.weights[size_t(c)] > 0.0f)
            h += m.weights[size_t(c)];
    return h;
}

// How much of a shadow ray's light arrives through transparent surfaces:
// walks r's closest hits front to back. closest(ray, t_hit) finds the next
// hit of `ray` (false: none); transparency_at(ray) gives the transparent
// colour of the surface just found (black: opaque). At most `max_hits`
// transparent surfaces are crossed; one more blocks the ray.
template <class Closest, class TransparencyAt>
inline Vec3f shadow_transmittance(Ray r, int max_hits, Closest&& closest, TransparencyAt&& transparency_at) {
    Vec3f t(1.0f);
    for (int hits = 0;; ++hits) {
        float t_hit = 0.0f;
        if (!closest(r, t_hit)) return t;
        if (hits >= max_hits) return Vec3f(0.0f);
        t *= transparency_at(r);
        if (is_black(t)) return Vec3f(0.0f);
        r.tmin = t_hit;  // past this surface (tmin is exclusive)
    }
}

}  // namespace coherent
