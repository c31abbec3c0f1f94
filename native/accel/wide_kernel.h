// Building blocks shared by the traversal kernels of every width
// (traverse_single.cpp: single rays over the binary, 4-wide and 8-wide trees;
// ray_stream.cpp: breadth-first ray streams over the 8-wide tree). Private to
// the accel layer.
//
// Why one header: the kernels must agree bit for bit on every hit. They do
// because they share the one triangle test below (the watertight test of
// triangle.h on four triangles at once, same operations in the same order),
// the one tie rule (Closest) and the one culling rule (cull_distance); box
// tests only have to be conservative, and all of them are (Ize 2013).
//
// Box test (Ize 2013, "Robust BVH Ray Traversal"), W children at once:
//  - slab distances are (plane - origin) * (1 / d), whose rounding error is
//    bounded by gamma(3); the far distance is enlarged by (1 + 2 gamma(3)) so
//    rounding never culls a box the ray enters;
//  - a zero direction component gives an infinite reciprocal of the right
//    sign. The only undefined product, 0 * inf, occurs for an origin exactly on
//    a slab plane of a parallel ray; it yields NaN, and the min/max chains are
//    written with the slab term first (min/max return the second
//    operand when either is NaN), so that slab does not restrict the
//    interval: conservative.
//  - rays whose products all stay finite use an equally conservative fused
//    form, fma(plane, 1/d, -o/d rounded outward) (see RayBoxConstants).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "../core/bbox.h"
#include "../core/float_bounds.h"
#include "../core/inline.h"
#include "../core/ray.h"
#include "../core/simd.h"
#include "../core/vec.h"
#include "bvh_layout.h"
#include "triangle.h"

namespace coherent::kernel {

using simd::vfloat;
using simd::vfloat4;
using simd::vint;

// Boxes are culled against the closest hit so far plus a relative slack
// (kCullSlack, float_bounds.h, says why).
inline float cull_distance(float t) { return std::isfinite(t) ? t + std::fabs(t) * kCullSlack : t; }

// Rays every kernel rejects up front (they hit nothing).
inline bool valid_ray(const Ray& r) {
    if (!is_finite(r.o) || !is_finite(r.d)) return false;
    if (r.d.x == 0.0f && r.d.y == 0.0f && r.d.z == 0.0f) return false;
    if (std::isnan(r.tmin) || std::isnan(r.tmax) || !(r.tmin <= r.tmax)) return false;
    return true;
}

// What the wide kernel needs to know of a node type: its SIMD width (the box
// test is written once for 4 and 8 lanes), where its planes are and how
// they decode, and which slots hold children.
template <class Node>
struct NodeTraits;

// Float nodes (WideNode8, WideNode4): planes are stored as they are; empty
// slots have empty boxes, which no ray enters. (A node type whose planes are
// decoded, e.g. quantized, would provide its own planes() and valid_mask().)
template <class Node, int W>
struct FloatNodeTraits {
    static constexpr int kWidth = W;
    using V = vfloat<W>;
    static constexpr uint32_t kLo = offsetof(Node, lo), kHi = offsetof(Node, hi);
    static constexpr uint32_t kAxis = sizeof(float) * W;  // bytes between axes
    static V planes(const Node& n, uint32_t offset, int /*axis*/) {
        return V::load(reinterpret_cast<const float*>(reinterpret_cast<const char*>(&n) + offset));
    }
    static int valid_mask(const Node&) { return (1 << W) - 1; }
    static int interior_mask(const Node& n) { return movemask(vint<W>::load(n.count) == vint<W>(0)); }
    static int used_slots(const Node& n) {
        return W - popcount(vint<W>::load(n.ref) == vint<W>(static_cast<int32_t>(kEmptyChild)));
    }
};
template <>
struct NodeTraits<WideNode8> : FloatNodeTraits<WideNode8, 8> {};
template <>
struct NodeTraits<WideNode4> : FloatNodeTraits<WideNode4, 4> {};


// ---- per-ray constants of the box test ---------------------------------------

// Scalar per-ray constants of the slab test, computed once per ray and
// splatted into SIMD registers by BoxRay (ray streams keep one per ray).
//
// Two forms of the same conservative test:
//  - exact (Ize): (plane - o) * (1/d), valid for every ray, including zero
//    direction components (infinite 1/d) and any magnitude;
//  - fused: fma(plane, 1/d, -c), one instruction per plane (as in Embree's
//    fast path), where c is o * (1/d) rounded *outward*: c_hi >= o/d for near
//    planes and c_lo <= o/d for far planes. Then the only rounding left is the
//    fma's own (relative, like Ize's), so the near distance never exceeds
//    the exact one by more than 1 ulp and the far distance never falls short
//    of it by more than 1 ulp, which the (1 + 2 gamma(3)) far scaling covers.
//    The widening by c's error is |o/d| * 2^-22 in t, i.e. boxes grow by a
//    few ulps of the origin's coordinates: a rare extra visit, never a miss.
//    Used only where every product stays finite: all 1/d finite and
//    |1/d| * max(|o|, scene magnitude) <= 2^100, so no plane of the scene
//    (or the origin) overflows.
//
// 52 bytes, unaligned on purpose: ray streams keep one per ray next to the
// ray's interval and early-out distance, all in one cache line.
struct RayBoxConstants {
    float o[3];    // origin
    float inv[3];  // 1/d (+-inf for +-0)
    float ch[3];   // fused form: o/d rounded up (near planes)
    float cl[3];   // fused form: o/d rounded down (far planes)
    bool fused = false;
    // Which plane is near per axis: lo for 1/d >= 0, hi for 1/d < 0 (sign
    // bit, so -0 counts as < 0).
    bool near_is_hi[3] = {false, false, false};

    RayBoxConstants() = default;
    // `o4`, `inv4`: the origin and 1 / d (lanes x, y, z; lane 3 unused).
    // `magnitude`: the largest absolute coordinate of the scene's bounds.
    RayBoxConstants(vfloat4 o4, vfloat4 inv4, float magnitude) {
        alignas(16) float lanes[4][4];
        store(lanes[0], o4);
        store(lanes[1], inv4);
        // |fl(o * inv) - o * inv| <= 2^-24 |fl(o * inv)| (1 + 2^-23); a margin
        // of 2^-22 |e| survives the rounding of the addition (+ 2^-126 for an
        // e so small that o * inv rounds with an absolute error).
        const vfloat4 e = o4 * inv4;
        const vfloat4 margin = abs(e) * vfloat4(0x1p-22f) + vfloat4(0x1p-126f);
        store(lanes[2], e + margin);
        store(lanes[3], e - margin);
        for (int a = 0; a < 3; ++a) {
            o[a] = lanes[0][a];
            inv[a] = lanes[1][a];
            ch[a] = lanes[2][a];
            cl[a] = lanes[3][a];
        }
        // |1/d| * max(|o|, magnitude, 1) <= 2^100 on x, y and z (an infinite
        // 1/d, or an overflowing product, fails the comparison).
        const vfloat4 m = max(max(abs(o4), vfloat4(magnitude)), vfloat4(1.0f));
        const vfloat4 reach = abs(inv4) * m;
        fused = (movemask(reach <= vfloat4(0x1p100f)) & 7) == 7;
        for (int a = 0; a < 3; ++a) near_is_hi[a] = std::signbit(inv[a]);
    }
    // From a ray (1/d by one correctly rounded division per lane, like the
    // scalar one, so every kernel derives the same WatertightRay from it).
    static RayBoxConstants from_ray(const Ray& ray, float magnitude) {
        const vfloat4 inv4 = vfloat4(1.0f) / vfloat4(ray.d.x, ray.d.y, ray.d.z, 1.0f);
        return RayBoxConstants(vfloat4(ray.o.x, ray.o.y, ray.o.z, 0.0f), inv4, magnitude);
    }
    Vec3f inverse_direction() const { return {inv[0], inv[1], inv[2]}; }
};

// Splatted constants of the W-box slab test for one node type.
template <class Node>
struct BoxRay {
    using V = typename NodeTraits<Node>::V;
    V ox, oy, oz;     // splatted origin
    V ix, iy, iz;     // splatted 1/d
    V chx, chy, chz;  // fused form, near planes
    V clx, cly, clz;  // fused form, far planes
    bool fused = false;
    // Byte offsets of the near and far plane arrays in a Node.
    uint32_t nx, ny, nz, fx, fy, fz;

    explicit BoxRay(const RayBoxConstants& k) {
        ox = k.o[0]; oy = k.o[1]; oz = k.o[2];
        ix = k.inv[0]; iy = k.inv[1]; iz = k.inv[2];
        chx = k.ch[0]; chy = k.ch[1]; chz = k.ch[2];
        clx = k.cl[0]; cly = k.cl[1]; clz = k.cl[2];
        fused = k.fused;
        constexpr uint32_t lo = NodeTraits<Node>::kLo, hi = NodeTraits<Node>::kHi;
        constexpr uint32_t axis = NodeTraits<Node>::kAxis;
        nx = (k.near_is_hi[0] ? hi : lo) + 0 * axis;
        ny = (k.near_is_hi[1] ? hi : lo) + 1 * axis;
        nz = (k.near_is_hi[2] ? hi : lo) + 2 * axis;
        fx = (k.near_is_hi[0] ? lo : hi) + 0 * axis;
        fy = (k.near_is_hi[1] ? lo : hi) + 1 * axis;
        fz = (k.near_is_hi[2] ? lo : hi) + 2 * axis;
    }
};


// Tests the W children of `n`; returns the hit mask and their entry distances.
template <bool kFused, class Node>
inline int intersect_node(const Node& n, const BoxRay<Node>& r, float tmin, float tmax,
                          typename NodeTraits<Node>::V& entry) {
    using T = NodeTraits<Node>;
    using V = typename T::V;
    V tnx, tny, tnz, tfx, tfy, tfz;
    if constexpr (kFused) {
        tnx = fmsub(T::planes(n, r.nx, 0), r.ix, r.chx);
        tny = fmsub(T::planes(n, r.ny, 1), r.iy, r.chy);
        tnz = fmsub(T::planes(n, r.nz, 2), r.iz, r.chz);
        tfx = fmsub(T::planes(n, r.fx, 0), r.ix, r.clx);
        tfy = fmsub(T::planes(n, r.fy, 1), r.iy, r.cly);
        tfz = fmsub(T::planes(n, r.fz, 2), r.iz, r.clz);
    } else {
        tnx = (T::planes(n, r.nx, 0) - r.ox) * r.ix;
        tny = (T::planes(n, r.ny, 1) - r.oy) * r.iy;
        tnz = (T::planes(n, r.nz, 2) - r.oz) * r.iz;
        tfx = (T::planes(n, r.fx, 0) - r.ox) * r.ix;
        tfy = (T::planes(n, r.fy, 1) - r.oy) * r.iy;
        tfz = (T::planes(n, r.fz, 2) - r.oz) * r.iz;
    }
    // Slab term first: min/max return the second operand when either is
    // NaN, so a NaN slab leaves the accumulator unchanged.
    const V tnear = max(tnz, max(tny, max(tnx, V(tmin))));
    const V tfar = min(tfz, min(tfy, min(tfx, V(tmax))));
    // Ize's (1 + 2 gamma(3)) on the far distance; scaling after the min is the
    // same as scaling each slab (rounding is monotonic) and also widens tmax a
    // hair, which only costs a rare extra visit.
    entry = tnear;
    return movemask(tnear <= tfar * V(kFarScale)) & T::valid_mask(n);
}

// The same exact (Ize) test for one box of the binary tree: scalar, with the
// NaN rule made explicit (a comparison with NaN is false, so the accumulator
// is kept). Returns whether the ray's [tmin, tmax] overlaps the box; `entry`
// receives the entry distance.
inline bool intersect_box(const BBox& b, const RayBoxConstants& k, float tmin, float tmax, float& entry) {
    float tn = tmin, tf = tmax;
    for (int a = 0; a < 3; ++a) {
        const float near_plane = k.near_is_hi[a] ? b.hi[a] : b.lo[a];
        const float far_plane = k.near_is_hi[a] ? b.lo[a] : b.hi[a];
        const float sn = (near_plane - k.o[a]) * k.inv[a];
        const float sf = (far_plane - k.o[a]) * k.inv[a];
        tn = sn > tn ? sn : tn;
        tf = sf < tf ? sf : tf;
    }
    entry = tn;
    return tn <= tf * kFarScale;
}

// ---- triangles ---------------------------------------------------------------

// Per-ray constants of the 4-wide watertight triangle test.
struct TriRay {
    WatertightRay w;
    vfloat4 okx, oky, okz;  // origin in the permuted axes
    vfloat4 sx, sy, sz;
    explicit TriRay(const WatertightRay& wr)
        : w(wr), okx(w.o[w.kx]), oky(w.o[w.ky]), okz(w.o[w.kz]), sx(w.sx), sy(w.sy), sz(w.sz) {}
    TriRay(const Ray& r, const Vec3f& inv) : TriRay(WatertightRay(r.o, r.d, inv)) {}
};

struct Closest {
    float t;
    float u = 0.0f, v = 0.0f;
    uint32_t prim = kInvalidPrim;
    // Ties (a ray through a shared edge) go to the lowest scene triangle
    // index, so the result does not depend on the tree or the visiting order.
    void offer(float t_, float u_, float v_, uint32_t prim_) {
        if (t_ < t || (t_ == t && prim_ < prim)) {
            t = t_; u = u_; v = v_; prim = prim_;
        }
    }
};

inline Vec3f pack_vertex(const TrianglePack4& p, int vtx, int lane) {
    return {p.v[vtx][0][lane], p.v[vtx][1][lane], p.v[vtx][2][lane]};
}

// Tests the first `lanes` triangles of `p`. Any hit: returns true on the first
// hit. Closest hit: offers every hit to `best` and returns whether any was found.
template <bool kAnyHit>
inline bool intersect_pack(const TrianglePack4& p, int lanes, const TriRay& r, float tmin, Closest& best) {
    const int kx = r.w.kx, ky = r.w.ky, kz = r.w.kz;
    // Vertex vtx minus the origin in the permuted axes, sheared.
    auto shear = [&](int vtx, vfloat4& x, vfloat4& y, vfloat4& z) {
        const vfloat4 dx = vfloat4::load(p.v[vtx][kx]) - r.okx;
        const vfloat4 dy = vfloat4::load(p.v[vtx][ky]) - r.oky;
        z = vfloat4::load(p.v[vtx][kz]) - r.okz;
        x = dx - r.sx * z;
        y = dy - r.sy * z;
    };
    vfloat4 ax, ay, az, bx, by, bz, cx, cy, cz;
    shear(0, ax, ay, az);
    shear(1, bx, by, bz);
    shear(2, cx, cy, cz);
    const vfloat4 u = cx * by - cy * bx;
    const vfloat4 v = ax * cy - ay * cx;
    const vfloat4 w = bx * ay - by * ax;

    const int lane_mask = (1 << lanes) - 1;
    const vfloat4 zero = vfloat4::zero();
    const int exact_zero = movemask(((u == zero) | (v == zero)) | (w == zero)) & lane_mask;
    const simd::vbool4 neg = ((u < zero) | (v < zero)) | (w < zero);
    const simd::vbool4 pos = ((u > zero) | (v > zero)) | (w > zero);
    const simd::vbool4 inside = ~(neg & pos);
    // Most tests end here: the ray passes outside every triangle of the pack.
    if (((movemask(inside) & lane_mask) | exact_zero) == 0) return false;
    const vfloat4 det = (u + v) + w;
    const vfloat4 tscaled = (u * (r.sz * az) + v * (r.sz * bz)) + w * (r.sz * cz);
    const vfloat4 rcp = vfloat4(1.0f) / det;
    const vfloat4 t = tscaled * rcp;
    const simd::vbool4 ok = (inside & (det != zero)) & ((t > vfloat4(tmin)) & (t <= vfloat4(best.t)));
    int hits = movemask(ok) & lane_mask & ~exact_zero;

    bool found = false;
    if (hits) {
        if constexpr (kAnyHit) return true;
        alignas(16) float ts[4], us[4], vs[4];
        store(ts, t);
        store(us, v * rcp);
        store(vs, w * rcp);
        found = true;
        for (; hits; hits &= hits - 1) {
            const int l = __builtin_ctz(hits);
            best.offer(ts[l], us[l], vs[l], p.prim[l]);
        }
    }
    // Rare: an edge function rounded to exactly 0; the scalar test redoes it in double.
    for (int z = exact_zero; z; z &= z - 1) {
        const int l = __builtin_ctz(z);
        TriangleHit th;
        if (intersect_triangle_watertight(r.w, pack_vertex(p, 0, l), pack_vertex(p, 1, l), pack_vertex(p, 2, l),
                                          tmin, best.t, th)) {
            if constexpr (kAnyHit) return true;
            best.offer(th.t, th.u, th.v, p.prim[l]);
            found = true;
        }
    }
    return found;
}

// Tests a leaf's packs. Any hit: true on the first hit. Closest hit: true
// when `best` improved. (Forced inline: an out-of-line leaf test and loop
// cost ~10% on primary rays, and GCC left the any-hit instance out of line;
// see docs/results/traversal_foundation.md.)
template <bool kAnyHit>
COHERENT_ALWAYS_INLINE bool intersect_leaf(const TrianglePack4* packs, uint32_t first_pack,
                                                          uint32_t count, const TriRay& r, float tmin,
                                                          Closest& best) {
    bool found = false;
    for (uint32_t k = 0; count > 0; ++k) {
        const int lanes = count >= 4 ? 4 : static_cast<int>(count);
        found |= intersect_pack<kAnyHit>(packs[first_pack + k], lanes, r, tmin, best);
        if (kAnyHit && found) return true;
        count -= lanes;
    }
    return found;
}

}  // namespace coherent::kernel
