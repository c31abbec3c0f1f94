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
//    written with the slab term first (max_ps/min_ps return the second
//    operand when either is NaN), so that slab does not restrict the
//    interval: conservative.
//  - rays whose products all stay finite use an equally conservative fused
//    form, fma(plane, 1/d, -o/d rounded outward) (see RayBoxConstants).
#pragma once

#include <immintrin.h>

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "../core/bbox.h"
#include "../core/ray.h"
#include "../core/vec.h"
#include "bvh_layout.h"
#include "triangle.h"

namespace coherent::kernel {

// gamma(n) = n eps / (1 - n eps), eps = 2^-24: the relative error bound of n
// rounded operations (pbrt-v3, section 3.9).
constexpr float gamma_bound(int n) {
    constexpr float eps = 0.5f * 1.1920928955078125e-07f;
    return (n * eps) / (1.0f - n * eps);
}
constexpr float kFarScale = 1.0f + 2.0f * gamma_bound(3);

// Boxes are culled against the closest hit so far plus this relative slack.
// A triangle's computed t carries its own rounding error and may land a few
// ulps below the (exactly conservative) entry distance of its box; without
// slack, a tie between neighbours (a ray through a shared edge) would be
// resolved by whichever leaf the traversal happened to reach first. With it,
// every triangle whose computed t is <= the best t is tested (unless its t
// error exceeds 2^-12 relative, which takes a pathologically ill-conditioned
// hit), so the tie rule (lowest triangle index) decides, independent of the
// tree and of the kernel.
constexpr float kCullSlack = 0x1p-12f;

inline float cull_distance(float t) { return std::isfinite(t) ? t + std::fabs(t) * kCullSlack : t; }

// Rays every kernel rejects up front (they hit nothing).
inline bool valid_ray(const Ray& r) {
    if (!is_finite(r.o) || !is_finite(r.d)) return false;
    if (r.d.x == 0.0f && r.d.y == 0.0f && r.d.z == 0.0f) return false;
    if (std::isnan(r.tmin) || std::isnan(r.tmax) || !(r.tmin <= r.tmax)) return false;
    return true;
}

// ---- SIMD width traits: the box test written once for 4 and 8 lanes ---------

struct Simd8 {
    using V = __m256;
    static constexpr int kWidth = 8;
    static V set1(float x) { return _mm256_set1_ps(x); }
    static V load(const float* p) { return _mm256_load_ps(p); }
    static void store(float* p, V v) { _mm256_store_ps(p, v); }
    static V fmsub(V a, V b, V c) { return _mm256_fmsub_ps(a, b, c); }
    static V sub(V a, V b) { return _mm256_sub_ps(a, b); }
    static V mul(V a, V b) { return _mm256_mul_ps(a, b); }
    static V max(V a, V b) { return _mm256_max_ps(a, b); }
    static V min(V a, V b) { return _mm256_min_ps(a, b); }
    static int le_mask(V a, V b) { return _mm256_movemask_ps(_mm256_cmp_ps(a, b, _CMP_LE_OQ)); }
    // Lanes of the eight words at p equal to `value`.
    static int equal_mask(const uint32_t* p, uint32_t value) {
        const __m256i x = _mm256_load_si256(reinterpret_cast<const __m256i*>(p));
        return _mm256_movemask_ps(
            _mm256_castsi256_ps(_mm256_cmpeq_epi32(x, _mm256_set1_epi32(static_cast<int>(value)))));
    }
};

struct Simd4 {
    using V = __m128;
    static constexpr int kWidth = 4;
    static V set1(float x) { return _mm_set1_ps(x); }
    static V load(const float* p) { return _mm_load_ps(p); }
    static void store(float* p, V v) { _mm_store_ps(p, v); }
    static V fmsub(V a, V b, V c) { return _mm_fmsub_ps(a, b, c); }
    static V sub(V a, V b) { return _mm_sub_ps(a, b); }
    static V mul(V a, V b) { return _mm_mul_ps(a, b); }
    static V max(V a, V b) { return _mm_max_ps(a, b); }
    static V min(V a, V b) { return _mm_min_ps(a, b); }
    static int le_mask(V a, V b) { return _mm_movemask_ps(_mm_cmple_ps(a, b)); }
    static int equal_mask(const uint32_t* p, uint32_t value) {
        const __m128i x = _mm_load_si128(reinterpret_cast<const __m128i*>(p));
        return _mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(x, _mm_set1_epi32(static_cast<int>(value)))));
    }
};

// What the wide kernel needs to know of a node type: its SIMD width, where
// its planes are and how they decode, and which slots hold children.
template <class Node>
struct NodeTraits;

// Float nodes (WideNode8, WideNode4): planes are stored as they are; empty
// slots have empty boxes, which no ray enters. (A node type whose planes are
// decoded, e.g. quantized, would provide its own planes() and valid_mask().)
template <class Node, class Simd>
struct FloatNodeTraits {
    using S = Simd;
    static constexpr uint32_t kLo = offsetof(Node, lo), kHi = offsetof(Node, hi);
    static constexpr uint32_t kAxis = sizeof(float) * S::kWidth;  // bytes between axes
    static typename S::V planes(const Node& n, uint32_t offset, int /*axis*/) {
        return S::load(reinterpret_cast<const float*>(reinterpret_cast<const char*>(&n) + offset));
    }
    static int valid_mask(const Node&) { return (1 << S::kWidth) - 1; }
    static int interior_mask(const Node& n) { return S::equal_mask(n.count, 0); }
    static int used_slots(const Node& n) { return S::kWidth - __builtin_popcount(S::equal_mask(n.ref, kEmptyChild)); }
};
template <>
struct NodeTraits<WideNode8> : FloatNodeTraits<WideNode8, Simd8> {};
template <>
struct NodeTraits<WideNode4> : FloatNodeTraits<WideNode4, Simd4> {};


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
    RayBoxConstants(__m128 o4, __m128 inv4, float magnitude) {
        alignas(16) float lanes[4][4];
        _mm_store_ps(lanes[0], o4);
        _mm_store_ps(lanes[1], inv4);
        const __m128 sign = _mm_set1_ps(-0.0f);
        // |fl(o * inv) - o * inv| <= 2^-24 |fl(o * inv)| (1 + 2^-23); a margin
        // of 2^-22 |e| survives the rounding of the addition (+ 2^-126 for an
        // e so small that o * inv rounds with an absolute error).
        const __m128 e = _mm_mul_ps(o4, inv4);
        const __m128 margin =
            _mm_add_ps(_mm_mul_ps(_mm_andnot_ps(sign, e), _mm_set1_ps(0x1p-22f)), _mm_set1_ps(0x1p-126f));
        _mm_store_ps(lanes[2], _mm_add_ps(e, margin));
        _mm_store_ps(lanes[3], _mm_sub_ps(e, margin));
        for (int a = 0; a < 3; ++a) {
            o[a] = lanes[0][a];
            inv[a] = lanes[1][a];
            ch[a] = lanes[2][a];
            cl[a] = lanes[3][a];
        }
        // |1/d| * max(|o|, magnitude, 1) <= 2^100 on x, y and z (an infinite
        // 1/d, or an overflowing product, fails the comparison).
        const __m128 m = _mm_max_ps(_mm_max_ps(_mm_andnot_ps(sign, o4), _mm_set1_ps(magnitude)), _mm_set1_ps(1.0f));
        const __m128 reach = _mm_mul_ps(_mm_andnot_ps(sign, inv4), m);
        fused = (_mm_movemask_ps(_mm_cmple_ps(reach, _mm_set1_ps(0x1p100f))) & 7) == 7;
        for (int a = 0; a < 3; ++a) near_is_hi[a] = std::signbit(inv[a]);
    }
    // From a ray (1/d by one correctly rounded division per lane, like the
    // scalar one, so every kernel derives the same WatertightRay from it).
    static RayBoxConstants from_ray(const Ray& ray, float magnitude) {
        const __m128 inv4 = _mm_div_ps(_mm_set1_ps(1.0f), _mm_setr_ps(ray.d.x, ray.d.y, ray.d.z, 1.0f));
        return RayBoxConstants(_mm_setr_ps(ray.o.x, ray.o.y, ray.o.z, 0.0f), inv4, magnitude);
    }
    Vec3f inverse_direction() const { return {inv[0], inv[1], inv[2]}; }
};

// Splatted constants of the W-box slab test for one node type.
template <class Node>
struct BoxRay {
    using S = typename NodeTraits<Node>::S;
    using V = typename S::V;
    V ox, oy, oz;     // splatted origin
    V ix, iy, iz;     // splatted 1/d
    V chx, chy, chz;  // fused form, near planes
    V clx, cly, clz;  // fused form, far planes
    bool fused = false;
    // Byte offsets of the near and far plane arrays in a Node.
    uint32_t nx, ny, nz, fx, fy, fz;

    explicit BoxRay(const RayBoxConstants& k) {
        ox = S::set1(k.o[0]); oy = S::set1(k.o[1]); oz = S::set1(k.o[2]);
        ix = S::set1(k.inv[0]); iy = S::set1(k.inv[1]); iz = S::set1(k.inv[2]);
        chx = S::set1(k.ch[0]); chy = S::set1(k.ch[1]); chz = S::set1(k.ch[2]);
        clx = S::set1(k.cl[0]); cly = S::set1(k.cl[1]); clz = S::set1(k.cl[2]);
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
                          typename NodeTraits<Node>::S::V& entry) {
    using S = typename NodeTraits<Node>::S;
    typename S::V tnx, tny, tnz, tfx, tfy, tfz;
    if constexpr (kFused) {
        tnx = S::fmsub(NodeTraits<Node>::planes(n, r.nx, 0), r.ix, r.chx);
        tny = S::fmsub(NodeTraits<Node>::planes(n, r.ny, 1), r.iy, r.chy);
        tnz = S::fmsub(NodeTraits<Node>::planes(n, r.nz, 2), r.iz, r.chz);
        tfx = S::fmsub(NodeTraits<Node>::planes(n, r.fx, 0), r.ix, r.clx);
        tfy = S::fmsub(NodeTraits<Node>::planes(n, r.fy, 1), r.iy, r.cly);
        tfz = S::fmsub(NodeTraits<Node>::planes(n, r.fz, 2), r.iz, r.clz);
    } else {
        tnx = S::mul(S::sub(NodeTraits<Node>::planes(n, r.nx, 0), r.ox), r.ix);
        tny = S::mul(S::sub(NodeTraits<Node>::planes(n, r.ny, 1), r.oy), r.iy);
        tnz = S::mul(S::sub(NodeTraits<Node>::planes(n, r.nz, 2), r.oz), r.iz);
        tfx = S::mul(S::sub(NodeTraits<Node>::planes(n, r.fx, 0), r.ox), r.ix);
        tfy = S::mul(S::sub(NodeTraits<Node>::planes(n, r.fy, 1), r.oy), r.iy);
        tfz = S::mul(S::sub(NodeTraits<Node>::planes(n, r.fz, 2), r.oz), r.iz);
    }
    // Slab term first: max_ps/min_ps return the second operand when either
    // is NaN, so a NaN slab leaves the accumulator unchanged.
    const auto tnear = S::max(tnz, S::max(tny, S::max(tnx, S::set1(tmin))));
    const auto tfar = S::min(tfz, S::min(tfy, S::min(tfx, S::set1(tmax))));
    // Ize's (1 + 2 gamma(3)) on the far distance; scaling after the min is the
    // same as scaling each slab (rounding is monotonic) and also widens tmax a
    // hair, which only costs a rare extra visit.
    entry = tnear;
    return S::le_mask(tnear, S::mul(tfar, S::set1(kFarScale))) & NodeTraits<Node>::valid_mask(n);
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
    __m128 okx, oky, okz;  // origin in the permuted axes
    __m128 sx, sy, sz;
    explicit TriRay(const WatertightRay& wr) : w(wr) {
        okx = _mm_set1_ps(w.o[w.kx]);
        oky = _mm_set1_ps(w.o[w.ky]);
        okz = _mm_set1_ps(w.o[w.kz]);
        sx = _mm_set1_ps(w.sx);
        sy = _mm_set1_ps(w.sy);
        sz = _mm_set1_ps(w.sz);
    }
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
    auto shear = [&](int vtx, __m128& x, __m128& y, __m128& z) {
        const __m128 dx = _mm_sub_ps(_mm_load_ps(p.v[vtx][kx]), r.okx);
        const __m128 dy = _mm_sub_ps(_mm_load_ps(p.v[vtx][ky]), r.oky);
        z = _mm_sub_ps(_mm_load_ps(p.v[vtx][kz]), r.okz);
        x = _mm_sub_ps(dx, _mm_mul_ps(r.sx, z));
        y = _mm_sub_ps(dy, _mm_mul_ps(r.sy, z));
    };
    __m128 ax, ay, az, bx, by, bz, cx, cy, cz;
    shear(0, ax, ay, az);
    shear(1, bx, by, bz);
    shear(2, cx, cy, cz);
    const __m128 u = _mm_sub_ps(_mm_mul_ps(cx, by), _mm_mul_ps(cy, bx));
    const __m128 v = _mm_sub_ps(_mm_mul_ps(ax, cy), _mm_mul_ps(ay, cx));
    const __m128 w = _mm_sub_ps(_mm_mul_ps(bx, ay), _mm_mul_ps(by, ax));

    const int lane_mask = (1 << lanes) - 1;
    const __m128 zero = _mm_setzero_ps();
    const int exact_zero =
        _mm_movemask_ps(_mm_or_ps(_mm_or_ps(_mm_cmpeq_ps(u, zero), _mm_cmpeq_ps(v, zero)), _mm_cmpeq_ps(w, zero))) &
        lane_mask;

    const __m128 neg = _mm_or_ps(_mm_or_ps(_mm_cmplt_ps(u, zero), _mm_cmplt_ps(v, zero)), _mm_cmplt_ps(w, zero));
    const __m128 pos = _mm_or_ps(_mm_or_ps(_mm_cmpgt_ps(u, zero), _mm_cmpgt_ps(v, zero)), _mm_cmpgt_ps(w, zero));
    const __m128 inside = _mm_andnot_ps(_mm_and_ps(neg, pos), _mm_castsi128_ps(_mm_set1_epi32(-1)));
    // Most tests end here: the ray passes outside every triangle of the pack.
    if (((_mm_movemask_ps(inside) & lane_mask) | exact_zero) == 0) return false;
    const __m128 det = _mm_add_ps(_mm_add_ps(u, v), w);
    const __m128 tscaled = _mm_add_ps(
        _mm_add_ps(_mm_mul_ps(u, _mm_mul_ps(r.sz, az)), _mm_mul_ps(v, _mm_mul_ps(r.sz, bz))),
        _mm_mul_ps(w, _mm_mul_ps(r.sz, cz)));
    const __m128 rcp = _mm_div_ps(_mm_set1_ps(1.0f), det);
    const __m128 t = _mm_mul_ps(tscaled, rcp);
    __m128 ok = _mm_and_ps(inside, _mm_cmpneq_ps(det, zero));
    ok = _mm_and_ps(ok, _mm_and_ps(_mm_cmpgt_ps(t, _mm_set1_ps(tmin)), _mm_cmple_ps(t, _mm_set1_ps(best.t))));
    int hits = _mm_movemask_ps(ok) & lane_mask & ~exact_zero;

    bool found = false;
    if (hits) {
        if constexpr (kAnyHit) return true;
        alignas(16) float ts[4], us[4], vs[4];
        _mm_store_ps(ts, t);
        _mm_store_ps(us, _mm_mul_ps(v, rcp));
        _mm_store_ps(vs, _mm_mul_ps(w, rcp));
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
__attribute__((always_inline)) inline bool intersect_leaf(const TrianglePack4* packs, uint32_t first_pack,
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
