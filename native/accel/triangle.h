// Watertight ray/triangle intersection (Woop, Benthin, Wald 2013,
// "Watertight Ray/Triangle Intersection", JCGT 2(1)).
//
// The ray is transformed once into a space where it starts at the origin and
// points along +z (a permutation plus a shear/scale, `WatertightRay`). Each
// triangle is then tested with three 2D edge functions U, V, W. Two triangles
// that share an edge evaluate that edge's function on bit-identical inputs
// (same vertices, same ray constants) up to a sign, so a ray through the edge
// sees U == 0 on both or on neither side: it can never slip between them.
// Edge functions that round to exactly 0 are recomputed in double precision,
// where the products of two floats are exact, which removes the remaining
// case where a 0 came from cancellation rather than from the geometry.
//
// Invariant: the test is a pure function of (ray, v0, v1, v2); every
// traversal kernel calls it with the same arguments, so the kernels agree
// bit for bit on t, u and v.
#pragma once

#include <cmath>
#include <cstdint>

#include "../core/ray.h"
#include "../core/vec.h"

namespace coherent {

// Per-ray constants of the watertight test.
struct WatertightRay {
    Vec3f o;
    int kx = 0, ky = 1, kz = 2;  // permutation: kz is the dominant direction axis
    float sx = 0.0f, sy = 0.0f, sz = 1.0f;  // shear (sx, sy) and scale (sz)

    WatertightRay() = default;
    // Precondition: d is finite and non-zero (checked by the kernels).
    WatertightRay(const Vec3f& origin, const Vec3f& d) : WatertightRay(origin, d, 1.0f / d[max_dimension(abs(d))], true) {}
    // The same constants from a precomputed 1 / d[kz] (bit-identical, since
    // division is correctly rounded): for kernels that already have 1/d.
    WatertightRay(const Vec3f& origin, const Vec3f& d, const Vec3f& inv)
        : WatertightRay(origin, d, inv[max_dimension(abs(d))], true) {}

private:
    WatertightRay(const Vec3f& origin, const Vec3f& d, float inv_dz, bool) : o(origin) {
        const Vec3f ad = abs(d);
        kz = max_dimension(ad);
        kx = kz == 2 ? 0 : kz + 1;
        ky = kx == 2 ? 0 : kx + 1;
        // Keep the winding consistent when the dominant axis points backwards;
        // we accept both faces, but the paper's convention keeps det's sign
        // meaningful for callers that want it.
        if (d[kz] < 0.0f) {
            const int tmp = kx;
            kx = ky;
            ky = tmp;
        }
        // One reciprocal, then products: any per-ray shear constants keep the
        // test watertight (every triangle sees the same ones), and the
        // traversal kernels reuse the slab test's 1/d for sz.
        sz = inv_dz;
        sx = d[kx] * sz;
        sy = d[ky] * sz;
    }
};

// Result of one triangle test (t in ray units, u/v barycentrics of v1/v2).
struct TriangleHit {
    float t, u, v;
};

// Returns true and fills `out` when the ray hits triangle (v0, v1, v2) at a
// parameter t in (tmin, tmax]. Both faces are hit; degenerate triangles never.
inline bool intersect_triangle_watertight(const WatertightRay& r, const Vec3f& v0, const Vec3f& v1,
                                          const Vec3f& v2, float tmin, float tmax, TriangleHit& out) {
    const Vec3f a = v0 - r.o;
    const Vec3f b = v1 - r.o;
    const Vec3f c = v2 - r.o;

    const float ax = a[r.kx] - r.sx * a[r.kz];
    const float ay = a[r.ky] - r.sy * a[r.kz];
    const float bx = b[r.kx] - r.sx * b[r.kz];
    const float by = b[r.ky] - r.sy * b[r.kz];
    const float cx = c[r.kx] - r.sx * c[r.kz];
    const float cy = c[r.ky] - r.sy * c[r.kz];

    // Scaled barycentric coordinates: U weights v0, V weights v1, W weights v2.
    float u = cx * by - cy * bx;
    float v = ax * cy - ay * cx;
    float w = bx * ay - by * ax;

    // An exact 0 may be cancellation: products of floats are exact in double.
    if (u == 0.0f || v == 0.0f || w == 0.0f) {
        u = static_cast<float>(static_cast<double>(cx) * by - static_cast<double>(cy) * bx);
        v = static_cast<float>(static_cast<double>(ax) * cy - static_cast<double>(ay) * cx);
        w = static_cast<float>(static_cast<double>(bx) * ay - static_cast<double>(by) * ax);
    }

    // Inside iff all three have the same sign (zeros count as either sign:
    // a ray through an edge or vertex hits every triangle sharing it).
    if ((u < 0.0f || v < 0.0f || w < 0.0f) && (u > 0.0f || v > 0.0f || w > 0.0f)) return false;

    const float det = u + v + w;
    if (det == 0.0f) return false;  // ray parallel to the plane, or degenerate triangle

    const float az = r.sz * a[r.kz];
    const float bz = r.sz * b[r.kz];
    const float cz = r.sz * c[r.kz];
    const float tscaled = u * az + v * bz + w * cz;

    // The range test is made on t itself, not on the scaled values before the
    // division: the result must be a pure function of the triangle and the
    // ray, independent of the current tmax, so that every traversal order
    // (and every kernel) picks the same hit among exact ties.
    const float rcp = 1.0f / det;
    const float t = tscaled * rcp;
    // Half-open interval (tmin, tmax], as ray.h describes and as Embree does:
    // a hit exactly at tmin (an origin lying on a surface, t == 0) is a
    // self-intersection, not an occluder.
    if (!(t > tmin && t <= tmax)) return false;
    out.t = t;
    out.u = v * rcp;
    out.v = w * rcp;
    return true;
}

}  // namespace coherent
