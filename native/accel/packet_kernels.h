// The 8-lane building blocks of packet traversal (traverse_packet.cpp): a
// packet's rays prepared once in SoA order (PacketRays), the ray-box test of
// one chunk of 8 rays against one binary node, the interval-arithmetic
// (frustum) test of a whole packet, and the watertight test of one triangle
// against one chunk (private to the accel layer).
//
// Invariant: for every lane, the box test is the single-ray kernel's exact
// (Ize) form, and the triangle test performs the operations of
// intersect_triangle_watertight (triangle.h) in the same order on the same
// floats, so t, u, v are bit-identical to Bvh::intersect(); lanes where an
// edge function rounds to exactly 0 go through that scalar function (its
// double-precision recomputation), as traverse_single.cpp does.
#pragma once

#include <immintrin.h>

#include <cmath>
#include <cstdint>

#include "../core/bbox.h"
#include "bvh.h"
#include "bvh_layout.h"
#include "ray_packet.h"
#include "triangle.h"

namespace coherent::packet {

constexpr int kMaxChunks = kMaxPacketRays / kPacketLanes;

// gamma(n) = n eps / (1 - n eps), eps = 2^-24 (pbrt-v3, section 3.9); the
// same far-distance scaling as the single-ray kernel (traverse_single.cpp).
constexpr float gamma_bound(int n) {
    constexpr float eps = 0.5f * 1.1920928955078125e-07f;
    return (n * eps) / (1.0f - n * eps);
}
constexpr float kFarScale = 1.0f + 2.0f * gamma_bound(3);
// The single-ray kernel's relative cull slack (see kCullSlack there): boxes
// are culled against best t * (1 + 2^-12), so that every triangle whose
// computed t ties with the best is tested and ties go to the lowest index
// whatever the visiting order.
constexpr float kCullSlack = 0x1p-12f;

inline __m256 cull_distance(__m256 t) {
    const __m256 abs_t = _mm256_andnot_ps(_mm256_set1_ps(-0.0f), t);
    const __m256 slack = _mm256_add_ps(t, _mm256_mul_ps(abs_t, _mm256_set1_ps(kCullSlack)));
    // Non-finite t (an infinite tmax) stays as it is: inf + inf * slack would
    // be fine, but -inf + inf is NaN.
    return _mm256_blendv_ps(slack, t, _mm256_cmp_ps(abs_t, _mm256_set1_ps(kInf), _CMP_EQ_OQ));
}

// A packet's rays, prepared for traversal: lane i of chunk c is array index
// 8c + i. Lanes that are inactive or invalid are never live and their values
// are never used as rays (they hold harmless finite numbers).
struct alignas(32) PacketRays {
    int chunks = 0;
    // Live lanes per chunk: active, valid and (any-hit) not yet occluded.
    uint32_t live[kMaxChunks] = {};
    // Lanes that entered as active and valid (the records written back).
    uint32_t valid[kMaxChunks] = {};
    // Per chunk: the watertight permutation shared by all its valid lanes
    // (kx | ky << 2 | kz << 4), or -1 when the lanes differ.
    int perm[kMaxChunks] = {};

    alignas(32) float ox[kMaxPacketRays], oy[kMaxPacketRays], oz[kMaxPacketRays];
    alignas(32) float ix[kMaxPacketRays], iy[kMaxPacketRays], iz[kMaxPacketRays];  // 1 / d
    // Fused box test (see box_test): o / d rounded up (near planes) and down
    // (far planes), per axis.
    alignas(32) float chx[kMaxPacketRays], chy[kMaxPacketRays], chz[kMaxPacketRays];
    alignas(32) float clx[kMaxPacketRays], cly[kMaxPacketRays], clz[kMaxPacketRays];
    alignas(32) float tmin[kMaxPacketRays];
    // Closest hit so far (t starts at tmax) and the box cull distance derived from it.
    alignas(32) float best_t[kMaxPacketRays], cull[kMaxPacketRays];
    alignas(32) float best_u[kMaxPacketRays], best_v[kMaxPacketRays];
    alignas(32) uint32_t best_prim[kMaxPacketRays];
    // Watertight constants (triangle.h) per lane: permutation, shear and the
    // origin in the permuted axes.
    alignas(32) int32_t kx[kMaxPacketRays], ky[kMaxPacketRays], kz[kMaxPacketRays];
    alignas(32) float sx[kMaxPacketRays], sy[kMaxPacketRays], sz[kMaxPacketRays];
    alignas(32) float okx[kMaxPacketRays], oky[kMaxPacketRays], okz[kMaxPacketRays];
    // Every live lane may use the fused box test.
    bool fused = false;
    // Direction of the first live ray: orders the children (near first).
    Vec3f first_dir;
    int first_chunk = 0;

    // Interval arithmetic (Boulos et al. 2007, Wald et al. 2007): usable only
    // when every live ray's 1/d has the same sign per axis (one octant) and is
    // finite. `near_hi[a]` says whether axis a's near plane is the box's hi.
    bool uniform_signs = false;
    int near_hi[3] = {0, 0, 0};
    bool interval = false;
    __m128 o_lo, o_hi, inv_lo, inv_hi;  // per axis (x, y, z, unused)
    float axis_o_lo[3], axis_o_hi[3], axis_inv_lo[3], axis_inv_hi[3];  // the same, as floats
    float tmin_lo = 0.0f;
    float cull_hi = kInf;  // >= every live lane's cull distance
};

// Per-chunk box test of one node, in either of the single-ray kernel's two
// conservative forms (traverse_single.cpp, BoxRay):
//  - exact (Ize): (plane - o) * (1 / d), for every ray;
//  - fused (kFused): fma(plane, 1/d, -o/d rounded outward), where every
//    product stays finite (PacketRays::fused).
// Slab terms come first in the min/max chains (a NaN slab, from 0 * inf,
// does not restrict), far distance scaled by (1 + 2 gamma(3)).
// kUniform: every live lane has the same direction signs (near planes chosen
// once per node); otherwise per-lane blends on the sign of 1/d.
// Returns the lanes (of all eight) whose interval is not empty.
template <bool kUniform, bool kFused>
__attribute__((always_inline)) inline int box_test(const BBox& box, const PacketRays& r, int c) {
    const int o = c * kPacketLanes;
    const __m256 ix = _mm256_load_ps(r.ix + o), iy = _mm256_load_ps(r.iy + o), iz = _mm256_load_ps(r.iz + o);
    __m256 nx, ny, nz, fx, fy, fz;
    if constexpr (kUniform) {
        nx = _mm256_set1_ps(r.near_hi[0] ? box.hi.x : box.lo.x);
        ny = _mm256_set1_ps(r.near_hi[1] ? box.hi.y : box.lo.y);
        nz = _mm256_set1_ps(r.near_hi[2] ? box.hi.z : box.lo.z);
        fx = _mm256_set1_ps(r.near_hi[0] ? box.lo.x : box.hi.x);
        fy = _mm256_set1_ps(r.near_hi[1] ? box.lo.y : box.hi.y);
        fz = _mm256_set1_ps(r.near_hi[2] ? box.lo.z : box.hi.z);
    } else {
        // The near plane is hi where 1/d has its sign bit set (as the
        // single-ray kernel's signbit choice: -0 counts as negative).
        const __m256 lx = _mm256_set1_ps(box.lo.x), hx = _mm256_set1_ps(box.hi.x);
        const __m256 ly = _mm256_set1_ps(box.lo.y), hy = _mm256_set1_ps(box.hi.y);
        const __m256 lz = _mm256_set1_ps(box.lo.z), hz = _mm256_set1_ps(box.hi.z);
        nx = _mm256_blendv_ps(lx, hx, ix); fx = _mm256_blendv_ps(hx, lx, ix);
        ny = _mm256_blendv_ps(ly, hy, iy); fy = _mm256_blendv_ps(hy, ly, iy);
        nz = _mm256_blendv_ps(lz, hz, iz); fz = _mm256_blendv_ps(hz, lz, iz);
    }
    __m256 tnx, tny, tnz, tfx, tfy, tfz;
    if constexpr (kFused) {
        tnx = _mm256_fmsub_ps(nx, ix, _mm256_load_ps(r.chx + o));
        tny = _mm256_fmsub_ps(ny, iy, _mm256_load_ps(r.chy + o));
        tnz = _mm256_fmsub_ps(nz, iz, _mm256_load_ps(r.chz + o));
        tfx = _mm256_fmsub_ps(fx, ix, _mm256_load_ps(r.clx + o));
        tfy = _mm256_fmsub_ps(fy, iy, _mm256_load_ps(r.cly + o));
        tfz = _mm256_fmsub_ps(fz, iz, _mm256_load_ps(r.clz + o));
    } else {
        const __m256 ox = _mm256_load_ps(r.ox + o), oy = _mm256_load_ps(r.oy + o), oz = _mm256_load_ps(r.oz + o);
        tnx = _mm256_mul_ps(_mm256_sub_ps(nx, ox), ix);
        tny = _mm256_mul_ps(_mm256_sub_ps(ny, oy), iy);
        tnz = _mm256_mul_ps(_mm256_sub_ps(nz, oz), iz);
        tfx = _mm256_mul_ps(_mm256_sub_ps(fx, ox), ix);
        tfy = _mm256_mul_ps(_mm256_sub_ps(fy, oy), iy);
        tfz = _mm256_mul_ps(_mm256_sub_ps(fz, oz), iz);
    }
    const __m256 tnear = _mm256_max_ps(tnz, _mm256_max_ps(tny, _mm256_max_ps(tnx, _mm256_load_ps(r.tmin + o))));
    const __m256 tfar = _mm256_min_ps(tfz, _mm256_min_ps(tfy, _mm256_min_ps(tfx, _mm256_load_ps(r.cull + o))));
    return _mm256_movemask_ps(_mm256_cmp_ps(tnear, _mm256_mul_ps(tfar, _mm256_set1_ps(kFarScale)), _CMP_LE_OQ));
}

// Interval-arithmetic test of the whole packet against a box (valid only
// when r.interval): every live ray's slab distances lie in the products of
// the packet's (plane - origin) intervals with its 1/d intervals, so if the
// smallest possible entry exceeds the largest possible exit, no ray of the
// packet enters the box.
// The bounds are computed in float and then widened by a relative 4 gamma(3)
// (each bound is a product of a rounded difference and a rounded reciprocal,
// <= gamma(3) from the exact value), so the test never culls a box that any
// ray enters in exact arithmetic. NaN (never expected: all terms finite)
// compares false and culls nothing.
__attribute__((always_inline)) inline bool interval_misses(const BBox& box, const PacketRays& r) {
    const __m128 lo = _mm_setr_ps(box.lo.x, box.lo.y, box.lo.z, 0.0f);
    const __m128 hi = _mm_setr_ps(box.hi.x, box.hi.y, box.hi.z, 0.0f);
    // near/far planes per axis: precomputed sign choice as a blend mask.
    const __m128 sel = _mm_castsi128_ps(_mm_setr_epi32(r.near_hi[0] ? -1 : 0, r.near_hi[1] ? -1 : 0,
                                                       r.near_hi[2] ? -1 : 0, 0));
    const __m128 near_plane = _mm_blendv_ps(lo, hi, sel);
    const __m128 far_plane = _mm_blendv_ps(hi, lo, sel);
    // Differences (plane - o) as intervals [plane - o_hi, plane - o_lo].
    const __m128 n_lo = _mm_sub_ps(near_plane, r.o_hi), n_hi = _mm_sub_ps(near_plane, r.o_lo);
    const __m128 f_lo = _mm_sub_ps(far_plane, r.o_hi), f_hi = _mm_sub_ps(far_plane, r.o_lo);
    // Interval products: min / max over the four corners.
    const __m128 a = _mm_mul_ps(n_lo, r.inv_lo), b = _mm_mul_ps(n_lo, r.inv_hi);
    const __m128 c = _mm_mul_ps(n_hi, r.inv_lo), d = _mm_mul_ps(n_hi, r.inv_hi);
    const __m128 near_min = _mm_min_ps(_mm_min_ps(a, b), _mm_min_ps(c, d));
    const __m128 e = _mm_mul_ps(f_lo, r.inv_lo), f = _mm_mul_ps(f_lo, r.inv_hi);
    const __m128 g = _mm_mul_ps(f_hi, r.inv_lo), h = _mm_mul_ps(f_hi, r.inv_hi);
    const __m128 far_max = _mm_max_ps(_mm_max_ps(e, f), _mm_max_ps(g, h));
    alignas(16) float nm[4], fm[4];
    _mm_store_ps(nm, near_min);
    _mm_store_ps(fm, far_max);
    float tnear = std::max(r.tmin_lo, std::max(nm[0], std::max(nm[1], nm[2])));
    float tfar = std::min(r.cull_hi, std::min(fm[0], std::min(fm[1], fm[2])));
    constexpr float kMargin = 4.0f * gamma_bound(3);
    tnear = tnear - std::fabs(tnear) * kMargin - 0x1p-126f;
    tfar = tfar + std::fabs(tfar) * kMargin + 0x1p-126f;
    return tnear > tfar;
}

// interval_misses for the eight children of a wide node at once: returns
// the children that the packet may enter (bit c set), i.e. those whose
// interval bounds are not disjoint. Same bounds, same margins, same
// conservativeness; empty slots (infinite planes) come out either way and
// are skipped by the caller.
__attribute__((always_inline)) inline int interval_children(const WideNode8& n, const PacketRays& r) {
    __m256 tnear = _mm256_set1_ps(r.tmin_lo), tfar = _mm256_set1_ps(r.cull_hi);
    for (int a = 0; a < 3; ++a) {
        const __m256 near_plane = _mm256_load_ps(r.near_hi[a] ? n.hi[a] : n.lo[a]);
        const __m256 far_plane = _mm256_load_ps(r.near_hi[a] ? n.lo[a] : n.hi[a]);
        const __m256 olo = _mm256_set1_ps(r.axis_o_lo[a]), ohi = _mm256_set1_ps(r.axis_o_hi[a]);
        const __m256 ilo = _mm256_set1_ps(r.axis_inv_lo[a]), ihi = _mm256_set1_ps(r.axis_inv_hi[a]);
        const __m256 n_lo = _mm256_sub_ps(near_plane, ohi), n_hi = _mm256_sub_ps(near_plane, olo);
        const __m256 f_lo = _mm256_sub_ps(far_plane, ohi), f_hi = _mm256_sub_ps(far_plane, olo);
        const __m256 near_min =
            _mm256_min_ps(_mm256_min_ps(_mm256_mul_ps(n_lo, ilo), _mm256_mul_ps(n_lo, ihi)),
                          _mm256_min_ps(_mm256_mul_ps(n_hi, ilo), _mm256_mul_ps(n_hi, ihi)));
        const __m256 far_max =
            _mm256_max_ps(_mm256_max_ps(_mm256_mul_ps(f_lo, ilo), _mm256_mul_ps(f_lo, ihi)),
                          _mm256_max_ps(_mm256_mul_ps(f_hi, ilo), _mm256_mul_ps(f_hi, ihi)));
        tnear = _mm256_max_ps(near_min, tnear);
        tfar = _mm256_min_ps(far_max, tfar);
    }
    const __m256 abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
    const __m256 margin = _mm256_set1_ps(4.0f * gamma_bound(3)), tiny = _mm256_set1_ps(0x1p-126f);
    tnear = _mm256_sub_ps(_mm256_sub_ps(tnear, _mm256_mul_ps(_mm256_and_ps(tnear, abs_mask), margin)), tiny);
    tfar = _mm256_add_ps(_mm256_add_ps(tfar, _mm256_mul_ps(_mm256_and_ps(tfar, abs_mask), margin)), tiny);
    return ~_mm256_movemask_ps(_mm256_cmp_ps(tnear, tfar, _CMP_GT_OQ)) & 0xff;
}

// One triangle against the `mask` lanes of chunk c; the watertight test of
// triangle.h per lane. Closest hit (kAnyHit false): offers each hit to the
// lane's record with the single-ray tie rule and returns the lanes whose
// record changed. Any hit: returns the lanes that hit (records untouched).
// The triangle is lane `tri` of pack `p`.
template <bool kAnyHit>
__attribute__((always_inline)) inline int triangle_test(const TrianglePack4& p, int tri, PacketRays& r, int c, int mask) {
    const uint32_t prim = p.prim[tri];
    const int o = c * kPacketLanes;
    const __m256 okx = _mm256_load_ps(r.okx + o), oky = _mm256_load_ps(r.oky + o), okz = _mm256_load_ps(r.okz + o);
    const __m256 sx = _mm256_load_ps(r.sx + o), sy = _mm256_load_ps(r.sy + o);
    __m256 px[3], py[3], pz[3];  // vertex - origin in the permuted axes, before the shear
    const int perm = r.perm[c];
    if (perm >= 0) {
        // One permutation for the chunk: the permuted coordinates are plain broadcasts.
        const int kx = perm & 3, ky = (perm >> 2) & 3, kz = perm >> 4;
        for (int k = 0; k < 3; ++k) {
            px[k] = _mm256_sub_ps(_mm256_set1_ps(p.v[k][kx][tri]), okx);
            py[k] = _mm256_sub_ps(_mm256_set1_ps(p.v[k][ky][tri]), oky);
            pz[k] = _mm256_sub_ps(_mm256_set1_ps(p.v[k][kz][tri]), okz);
        }
    } else {
        // Per-lane permutation: pick each lane's axis out of (x, y, z) with an
        // in-lane variable permute (the same float as the broadcast above).
        const __m256i kx = _mm256_load_si256(reinterpret_cast<const __m256i*>(r.kx + o));
        const __m256i ky = _mm256_load_si256(reinterpret_cast<const __m256i*>(r.ky + o));
        const __m256i kz = _mm256_load_si256(reinterpret_cast<const __m256i*>(r.kz + o));
        for (int k = 0; k < 3; ++k) {
            const __m128 v4 = _mm_setr_ps(p.v[k][0][tri], p.v[k][1][tri], p.v[k][2][tri], 0.0f);
            const __m256 v8 = _mm256_set_m128(v4, v4);
            px[k] = _mm256_sub_ps(_mm256_permutevar_ps(v8, kx), okx);
            py[k] = _mm256_sub_ps(_mm256_permutevar_ps(v8, ky), oky);
            pz[k] = _mm256_sub_ps(_mm256_permutevar_ps(v8, kz), okz);
        }
    }
    // Shear: x = a[kx] - sx * a[kz] (multiply, then subtract: no contraction).
    const __m256 ax = _mm256_sub_ps(px[0], _mm256_mul_ps(sx, pz[0]));
    const __m256 ay = _mm256_sub_ps(py[0], _mm256_mul_ps(sy, pz[0]));
    const __m256 bx = _mm256_sub_ps(px[1], _mm256_mul_ps(sx, pz[1]));
    const __m256 by = _mm256_sub_ps(py[1], _mm256_mul_ps(sy, pz[1]));
    const __m256 cx = _mm256_sub_ps(px[2], _mm256_mul_ps(sx, pz[2]));
    const __m256 cy = _mm256_sub_ps(py[2], _mm256_mul_ps(sy, pz[2]));
    const __m256 u = _mm256_sub_ps(_mm256_mul_ps(cx, by), _mm256_mul_ps(cy, bx));
    const __m256 v = _mm256_sub_ps(_mm256_mul_ps(ax, cy), _mm256_mul_ps(ay, cx));
    const __m256 w = _mm256_sub_ps(_mm256_mul_ps(bx, ay), _mm256_mul_ps(by, ax));

    const __m256 zero = _mm256_setzero_ps();
    const int exact_zero = _mm256_movemask_ps(_mm256_or_ps(
                               _mm256_or_ps(_mm256_cmp_ps(u, zero, _CMP_EQ_OQ), _mm256_cmp_ps(v, zero, _CMP_EQ_OQ)),
                               _mm256_cmp_ps(w, zero, _CMP_EQ_OQ))) &
                           mask;
    const __m256 neg = _mm256_or_ps(
        _mm256_or_ps(_mm256_cmp_ps(u, zero, _CMP_LT_OQ), _mm256_cmp_ps(v, zero, _CMP_LT_OQ)),
        _mm256_cmp_ps(w, zero, _CMP_LT_OQ));
    const __m256 pos = _mm256_or_ps(
        _mm256_or_ps(_mm256_cmp_ps(u, zero, _CMP_GT_OQ), _mm256_cmp_ps(v, zero, _CMP_GT_OQ)),
        _mm256_cmp_ps(w, zero, _CMP_GT_OQ));
    // Outside iff some edge function is negative and another positive.
    const int inside = ~_mm256_movemask_ps(_mm256_and_ps(neg, pos)) & mask & ~exact_zero;

    int result = 0;
    if (inside) {
        const __m256 sz = _mm256_load_ps(r.sz + o);
        const __m256 det = _mm256_add_ps(_mm256_add_ps(u, v), w);
        const __m256 tscaled = _mm256_add_ps(
            _mm256_add_ps(_mm256_mul_ps(u, _mm256_mul_ps(sz, pz[0])), _mm256_mul_ps(v, _mm256_mul_ps(sz, pz[1]))),
            _mm256_mul_ps(w, _mm256_mul_ps(sz, pz[2])));
        const __m256 rcp = _mm256_div_ps(_mm256_set1_ps(1.0f), det);
        const __m256 t = _mm256_mul_ps(tscaled, rcp);
        const __m256 best_t = _mm256_load_ps(r.best_t + o);
        const __m256 in_range = _mm256_and_ps(
            _mm256_and_ps(_mm256_cmp_ps(det, zero, _CMP_NEQ_UQ), _mm256_cmp_ps(t, _mm256_load_ps(r.tmin + o), _CMP_GT_OQ)),
            _mm256_cmp_ps(t, best_t, _CMP_LE_OQ));
        int hits = _mm256_movemask_ps(in_range) & inside;
        if (hits) {
            if constexpr (kAnyHit) {
                result = hits;
            } else {
                // Offer: closer, or as close with a lower triangle index.
                const __m256i best_prim = _mm256_load_si256(reinterpret_cast<const __m256i*>(r.best_prim + o));
                const __m256i p = _mm256_set1_epi32(static_cast<int>(prim));
                const __m256i lower = _mm256_andnot_si256(_mm256_cmpeq_epi32(p, best_prim),
                                                          _mm256_cmpeq_epi32(_mm256_min_epu32(p, best_prim), p));
                const __m256 better = _mm256_or_ps(_mm256_cmp_ps(t, best_t, _CMP_LT_OQ),
                                                   _mm256_and_ps(_mm256_cmp_ps(t, best_t, _CMP_EQ_OQ),
                                                                 _mm256_castsi256_ps(lower)));
                hits &= _mm256_movemask_ps(better);
                if (hits) {
                    const __m256i lanes = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
                    const __m256i sel = _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(hits), lanes), lanes);
                    const __m256 s = _mm256_castsi256_ps(sel);
                    _mm256_store_ps(r.best_t + o, _mm256_blendv_ps(best_t, t, s));
                    _mm256_store_ps(r.best_u + o, _mm256_blendv_ps(_mm256_load_ps(r.best_u + o), _mm256_mul_ps(v, rcp), s));
                    _mm256_store_ps(r.best_v + o, _mm256_blendv_ps(_mm256_load_ps(r.best_v + o), _mm256_mul_ps(w, rcp), s));
                    _mm256_store_si256(reinterpret_cast<__m256i*>(r.best_prim + o),
                                       _mm256_blendv_epi8(best_prim, p, sel));
                    result = hits;
                }
            }
        }
    }
    // Rare: an edge function rounded to exactly 0; the scalar test redoes it
    // (in double) with the same per-ray constants.
    for (int z = exact_zero; z; z &= z - 1) {
        const int l = o + __builtin_ctz(z);
        WatertightRay wr;
        wr.o = Vec3f(r.ox[l], r.oy[l], r.oz[l]);
        wr.kx = r.kx[l]; wr.ky = r.ky[l]; wr.kz = r.kz[l];
        wr.sx = r.sx[l]; wr.sy = r.sy[l]; wr.sz = r.sz[l];
        const Vec3f v0(p.v[0][0][tri], p.v[0][1][tri], p.v[0][2][tri]);
        const Vec3f v1(p.v[1][0][tri], p.v[1][1][tri], p.v[1][2][tri]);
        const Vec3f v2(p.v[2][0][tri], p.v[2][1][tri], p.v[2][2][tri]);
        TriangleHit th;
        if (!intersect_triangle_watertight(wr, v0, v1, v2, r.tmin[l], r.best_t[l], th)) continue;
        if constexpr (kAnyHit) {
            result |= 1 << (l - o);
        } else if (th.t < r.best_t[l] || (th.t == r.best_t[l] && prim < r.best_prim[l])) {
            r.best_t[l] = th.t; r.best_u[l] = th.u; r.best_v[l] = th.v; r.best_prim[l] = prim;
            result |= 1 << (l - o);
        }
    }
    return result;
}

}  // namespace coherent::packet
