// Uniform sampling of the solid angle a triangle subtends (Arvo 1995,
// "Stratified Sampling of Spherical Triangles"), as Cycles 3.4 samples
// emissive triangles near the shading point. Area sampling there has pdf
// d^2 / (A cos) in solid angle, which varies wildly over a light seen close
// up or at a grazing angle; this pdf is the constant 1 / solid angle, so the
// only variation left in a constant emitter's estimate is the receiver's
// cosine. The mapping is area-preserving, so low-discrepancy (u1, u2) stay
// well distributed over the spherical triangle.
//
// Float precision: the solid angle is exact to a few ulps, but the mapping
// subtracts cosines near 1 for small spherical triangles; the caller keeps
// this for solid angles above kMinSolidAngle and samples by area below it.
#pragma once

#include <algorithm>
#include <cmath>

#include "../core/vec.h"

namespace coherent {

struct SphericalTriangle {
    Vec3f a, b, c;            // unit directions from the viewpoint to the vertices
    float solid_angle = 0.0f;
    // Below this (steradians) the mapping loses precision in float: a triangle
    // of angular size ~0.03 rad, where 1 - cos is ~5e-4 and keeps 1e-4 relative.
    static constexpr float kMinSolidAngle = 1e-3f;
};

// The triangle v0 v1 v2 seen from p. False when p lies on a vertex.
inline bool make_spherical_triangle(const Vec3f& p, const Vec3f& v0, const Vec3f& v1, const Vec3f& v2,
                                    SphericalTriangle& st) {
    const Vec3f da = v0 - p, db = v1 - p, dc = v2 - p;
    const float la = length(da), lb = length(db), lc = length(dc);
    if (!(la > 0.0f) || !(lb > 0.0f) || !(lc > 0.0f)) return false;
    st.a = da / la;
    st.b = db / lb;
    st.c = dc / lc;
    // Van Oosterom & Strackee (1983): tan(omega / 2) = |a.(b x c)| / (1 + a.b + b.c + c.a).
    const float triple = std::fabs(dot(st.a, cross(st.b, st.c)));
    st.solid_angle = 2.0f * std::atan2(triple, 1.0f + dot(st.a, st.b) + dot(st.b, st.c) + dot(st.c, st.a));
    return std::isfinite(st.solid_angle);
}

// A unit direction uniformly distributed in solid angle over st, for
// (u1, u2) in [0, 1)^2. Arvo's two steps: u1 picks the sub-triangle A B C'
// with area u1 * solid_angle, by placing C' on the arc A C; u2 then picks a
// point on the arc B C' so that the area swept is uniform.
inline Vec3f sample_spherical_triangle(const SphericalTriangle& st, float u1, float u2) {
    const Vec3f& A = st.a;
    const Vec3f& B = st.b;
    const Vec3f& C = st.c;
    const float cos_a = dot(B, C), cos_b = dot(A, C), cos_c = dot(A, B);  // arc lengths opposite A, B, C
    // The spherical angle at A: cos = (cos a - cos b cos c) / (sin b sin c),
    // sin = |A.(B x C)| / (sin b sin c).
    const float sin_b_sin_c = std::sqrt(std::max(0.0f, (1.0f - cos_b * cos_b) * (1.0f - cos_c * cos_c)));
    if (!(sin_b_sin_c > 0.0f)) return A;
    const float cos_alpha = std::clamp((cos_a - cos_b * cos_c) / sin_b_sin_c, -1.0f, 1.0f);
    const float sin_alpha = std::min(std::fabs(dot(A, cross(B, C))) / sin_b_sin_c, 1.0f);

    const float area = u1 * st.solid_angle;  // of the sub-triangle A B C'
    const float sin_area = std::sin(area), cos_area = std::cos(area);
    const float s = sin_area * cos_alpha - cos_area * sin_alpha;  // sin(area - alpha)
    const float t = cos_area * cos_alpha + sin_area * sin_alpha;  // cos(area - alpha)
    const float u = t - cos_alpha;
    const float v = s + sin_alpha * cos_c;
    const float denom = (v * s + u * t) * sin_alpha;
    // q = cos of the arc A C'.
    const float q = denom != 0.0f ? std::clamp(((v * t - u * s) * cos_alpha - v) / denom, -1.0f, 1.0f) : 1.0f;
    const Vec3f c_perp = C - A * cos_b;  // C's component orthogonal to A
    const float c_perp_len = length(c_perp);
    if (!(c_perp_len > 0.0f)) return A;
    const Vec3f c_sub = A * q + c_perp * (std::sqrt(std::max(0.0f, 1.0f - q * q)) / c_perp_len);

    const float z = 1.0f - u2 * (1.0f - dot(c_sub, B));  // cos of the arc from B to the sample
    const Vec3f w_perp = c_sub - B * dot(c_sub, B);
    const float w_perp_len = length(w_perp);
    if (!(w_perp_len > 0.0f)) return B;
    return normalize(B * z + w_perp * (std::sqrt(std::max(0.0f, 1.0f - z * z)) / w_perp_len));
}

}  // namespace coherent
