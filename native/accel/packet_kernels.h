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

#include <cmath>
#include <cstdint>

#include "../core/bbox.h"
#include "../core/float_bounds.h"
#include "../core/simd.h"
#include "bvh.h"
#include "bvh_layout.h"
#include "ray_packet.h"
#include "triangle.h"

namespace coherent::packet {

using simd::vbool8;
using simd::vfloat4;
using simd::vfloat8;
using simd::vint8;

constexpr int kMaxChunks = kMaxPacketRays / kPacketLanes;

// cull_distance of wide_kernel.h on eight lanes (kCullSlack: float_bounds.h).
inline vfloat8 cull_distance(vfloat8 t) {
    const vfloat8 abs_t = abs(t);
    const vfloat8 slack = t + abs_t * vfloat8(kCullSlack);
    // Non-finite t (an infinite tmax) stays as it is: inf + inf * slack would
    // be fine, but -inf + inf is NaN.
    return select(abs_t == vfloat8(kInf), t, slack);
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
    vfloat4 o_lo, o_hi, inv_lo, inv_hi;  // per axis (x, y, z, unused)
    float axis_o_lo[3], axis_o_hi[3], axis_inv_lo[3], axis_inv_hi[3];  // the same, as floats
    float tmin_lo = 0.0f;
    float cull_hi = kInf;  // >= every live lane's cull distance
};

// Rays in use: packet.size clamped to [0, kMaxPacketRays].
inline int packet_size(const RayPacket& packet) {
    return packet.size < 0 ? 0 : (packet.size > kMaxPacketRays ? kMaxPacketRays : packet.size);
}

// Fills `r` from the packet's active rays (packet_prepare.cpp); returns
// false if none is valid. Invalid rays (NaN or infinite origin or direction,
// zero direction, NaN bound, tmin > tmax) are never live, like the
// single-ray kernel's valid_ray. `magnitude`: the largest absolute
// coordinate of the scene's bounds.
bool prepare(const RayPacket& packet, float magnitude, PacketRays& r);

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
    const vfloat8 ix = vfloat8::load(r.ix + o), iy = vfloat8::load(r.iy + o), iz = vfloat8::load(r.iz + o);
    vfloat8 nx, ny, nz, fx, fy, fz;
    if constexpr (kUniform) {
        nx = r.near_hi[0] ? box.hi.x : box.lo.x;
        ny = r.near_hi[1] ? box.hi.y : box.lo.y;
        nz = r.near_hi[2] ? box.hi.z : box.lo.z;
        fx = r.near_hi[0] ? box.lo.x : box.hi.x;
        fy = r.near_hi[1] ? box.lo.y : box.hi.y;
        fz = r.near_hi[2] ? box.lo.z : box.hi.z;
    } else {
        // The near plane is hi where 1/d has its sign bit set (as the
        // single-ray kernel's signbit choice: -0 counts as negative).
        const vfloat8 lx = box.lo.x, hx = box.hi.x;
        const vfloat8 ly = box.lo.y, hy = box.hi.y;
        const vfloat8 lz = box.lo.z, hz = box.hi.z;
        nx = select(signbit(ix), hx, lx); fx = select(signbit(ix), lx, hx);
        ny = select(signbit(iy), hy, ly); fy = select(signbit(iy), ly, hy);
        nz = select(signbit(iz), hz, lz); fz = select(signbit(iz), lz, hz);
    }
    vfloat8 tnx, tny, tnz, tfx, tfy, tfz;
    if constexpr (kFused) {
        tnx = fmsub(nx, ix, vfloat8::load(r.chx + o));
        tny = fmsub(ny, iy, vfloat8::load(r.chy + o));
        tnz = fmsub(nz, iz, vfloat8::load(r.chz + o));
        tfx = fmsub(fx, ix, vfloat8::load(r.clx + o));
        tfy = fmsub(fy, iy, vfloat8::load(r.cly + o));
        tfz = fmsub(fz, iz, vfloat8::load(r.clz + o));
    } else {
        const vfloat8 ox = vfloat8::load(r.ox + o), oy = vfloat8::load(r.oy + o), oz = vfloat8::load(r.oz + o);
        tnx = (nx - ox) * ix;
        tny = (ny - oy) * iy;
        tnz = (nz - oz) * iz;
        tfx = (fx - ox) * ix;
        tfy = (fy - oy) * iy;
        tfz = (fz - oz) * iz;
    }
    const vfloat8 tnear = max(tnz, max(tny, max(tnx, vfloat8::load(r.tmin + o))));
    const vfloat8 tfar = min(tfz, min(tfy, min(tfx, vfloat8::load(r.cull + o))));
    return movemask(tnear <= tfar * vfloat8(kFarScale));
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
    const vfloat4 lo(box.lo.x, box.lo.y, box.lo.z, 0.0f);
    const vfloat4 hi(box.hi.x, box.hi.y, box.hi.z, 0.0f);
    // near/far planes per axis: precomputed sign choice as a blend mask.
    const simd::vbool4 near_is_hi(r.near_hi[0], r.near_hi[1], r.near_hi[2], false);
    const vfloat4 near_plane = select(near_is_hi, hi, lo);
    const vfloat4 far_plane = select(near_is_hi, lo, hi);
    // Differences (plane - o) as intervals [plane - o_hi, plane - o_lo].
    const vfloat4 n_lo = near_plane - r.o_hi, n_hi = near_plane - r.o_lo;
    const vfloat4 f_lo = far_plane - r.o_hi, f_hi = far_plane - r.o_lo;
    // Interval products: min / max over the four corners.
    const vfloat4 near_min = min(min(n_lo * r.inv_lo, n_lo * r.inv_hi), min(n_hi * r.inv_lo, n_hi * r.inv_hi));
    const vfloat4 far_max = max(max(f_lo * r.inv_lo, f_lo * r.inv_hi), max(f_hi * r.inv_lo, f_hi * r.inv_hi));
    alignas(16) float nm[4], fm[4];
    store(nm, near_min);
    store(fm, far_max);
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
    vfloat8 tnear = r.tmin_lo, tfar = r.cull_hi;
    for (int a = 0; a < 3; ++a) {
        const vfloat8 near_plane = vfloat8::load(r.near_hi[a] ? n.hi[a] : n.lo[a]);
        const vfloat8 far_plane = vfloat8::load(r.near_hi[a] ? n.lo[a] : n.hi[a]);
        const vfloat8 olo = r.axis_o_lo[a], ohi = r.axis_o_hi[a];
        const vfloat8 ilo = r.axis_inv_lo[a], ihi = r.axis_inv_hi[a];
        const vfloat8 n_lo = near_plane - ohi, n_hi = near_plane - olo;
        const vfloat8 f_lo = far_plane - ohi, f_hi = far_plane - olo;
        const vfloat8 near_min = min(min(n_lo * ilo, n_lo * ihi), min(n_hi * ilo, n_hi * ihi));
        const vfloat8 far_max = max(max(f_lo * ilo, f_lo * ihi), max(f_hi * ilo, f_hi * ihi));
        tnear = max(near_min, tnear);
        tfar = min(far_max, tfar);
    }
    const vfloat8 margin = 4.0f * gamma_bound(3), tiny = 0x1p-126f;
    tnear = (tnear - abs(tnear) * margin) - tiny;
    tfar = (tfar + abs(tfar) * margin) + tiny;
    return ~movemask(tnear > tfar) & 0xff;
}

// Vertex k of triangle `tri` of `p` minus chunk c's origins, in each lane's
// permuted axes (triangle.h's kx, ky, kz), before the shear.
__attribute__((always_inline)) inline void permuted_vertices(const TrianglePack4& p, int tri, const PacketRays& r,
                                                             int c, vfloat8 px[3], vfloat8 py[3], vfloat8 pz[3]) {
    const int o = c * kPacketLanes;
    const vfloat8 okx = vfloat8::load(r.okx + o), oky = vfloat8::load(r.oky + o), okz = vfloat8::load(r.okz + o);
    const int perm = r.perm[c];
    if (perm >= 0) {
        // One permutation for the chunk: the permuted coordinates are plain broadcasts.
        const int kx = perm & 3, ky = (perm >> 2) & 3, kz = perm >> 4;
        for (int k = 0; k < 3; ++k) {
            px[k] = vfloat8(p.v[k][kx][tri]) - okx;
            py[k] = vfloat8(p.v[k][ky][tri]) - oky;
            pz[k] = vfloat8(p.v[k][kz][tri]) - okz;
        }
    } else {
        // Per-lane permutation: pick each lane's axis out of (x, y, z) with an
        // in-lane variable permute (the same float as the broadcast above).
        const vint8 kx = vint8::load(r.kx + o), ky = vint8::load(r.ky + o), kz = vint8::load(r.kz + o);
        for (int k = 0; k < 3; ++k) {
            const vfloat4 v4(p.v[k][0][tri], p.v[k][1][tri], p.v[k][2][tri], 0.0f);
            const vfloat8 v8(v4, v4);
            px[k] = permute_in_lanes(v8, kx) - okx;
            py[k] = permute_in_lanes(v8, ky) - oky;
            pz[k] = permute_in_lanes(v8, kz) - okz;
        }
    }
}

// The second half of the watertight test for the `inside` lanes of chunk c
// (edge functions u, v, w; pz: the permuted vertices' z before scaling):
// t, the range test against (tmin, best t], then (closest hit) the offer to
// each lane's record. Returns what triangle_test returns for those lanes.
template <bool kAnyHit>
__attribute__((always_inline)) inline int offer_hits(uint32_t prim, vfloat8 u, vfloat8 v, vfloat8 w,
                                                     const vfloat8 pz[3], PacketRays& r, int c, int inside) {
    const int o = c * kPacketLanes;
    const vfloat8 sz = vfloat8::load(r.sz + o);
    const vfloat8 det = (u + v) + w;
    const vfloat8 tscaled = (u * (sz * pz[0]) + v * (sz * pz[1])) + w * (sz * pz[2]);
    const vfloat8 rcp = vfloat8(1.0f) / det;
    const vfloat8 t = tscaled * rcp;
    const vfloat8 best_t = vfloat8::load(r.best_t + o);
    const vbool8 in_range = ((det != vfloat8::zero()) & (t > vfloat8::load(r.tmin + o))) & (t <= best_t);
    int hits = movemask(in_range) & inside;
    if (!hits) return 0;
    if constexpr (kAnyHit) return hits;
    // Offer: closer, or as close with a lower triangle index.
    const vint8 best_prim = vint8::load(r.best_prim + o);
    const vint8 p = static_cast<int>(prim);
    const vbool8 lower = andnot(min_u32(p, best_prim) == p, p == best_prim);
    const vbool8 better = (t < best_t) | ((t == best_t) & lower);
    hits &= movemask(better);
    if (!hits) return 0;
    const vbool8 s = vbool8::from_bits(hits);
    store(r.best_t + o, select(s, t, best_t));
    store(r.best_u + o, select(s, v * rcp, vfloat8::load(r.best_u + o)));
    store(r.best_v + o, select(s, w * rcp, vfloat8::load(r.best_v + o)));
    store(r.best_prim + o, select(s, p, best_prim));
    return hits;
}

// Rare: lanes (`exact_zero`) where an edge function rounded to exactly 0; the
// scalar test redoes them (in double) with the same per-ray constants.
template <bool kAnyHit>
inline int retest_exact_zeros(const TrianglePack4& p, int tri, PacketRays& r, int c, int exact_zero) {
    const uint32_t prim = p.prim[tri];
    const int o = c * kPacketLanes;
    int result = 0;
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

// One triangle against the `mask` lanes of chunk c; the watertight test of
// triangle.h per lane. Closest hit (kAnyHit false): offers each hit to the
// lane's record with the single-ray tie rule and returns the lanes whose
// record changed. Any hit: returns the lanes that hit (records untouched).
// The triangle is lane `tri` of pack `p`.
template <bool kAnyHit>
__attribute__((always_inline)) inline int triangle_test(const TrianglePack4& p, int tri, PacketRays& r, int c,
                                                        int mask) {
    const int o = c * kPacketLanes;
    vfloat8 px[3], py[3], pz[3];
    permuted_vertices(p, tri, r, c, px, py, pz);
    // Shear: x = a[kx] - sx * a[kz] (multiply, then subtract: no contraction).
    const vfloat8 sx = vfloat8::load(r.sx + o), sy = vfloat8::load(r.sy + o);
    const vfloat8 ax = px[0] - sx * pz[0], ay = py[0] - sy * pz[0];
    const vfloat8 bx = px[1] - sx * pz[1], by = py[1] - sy * pz[1];
    const vfloat8 cx = px[2] - sx * pz[2], cy = py[2] - sy * pz[2];
    const vfloat8 u = cx * by - cy * bx;
    const vfloat8 v = ax * cy - ay * cx;
    const vfloat8 w = bx * ay - by * ax;

    const vfloat8 zero = vfloat8::zero();
    const int exact_zero = movemask(((u == zero) | (v == zero)) | (w == zero)) & mask;
    const vbool8 neg = ((u < zero) | (v < zero)) | (w < zero);
    const vbool8 pos = ((u > zero) | (v > zero)) | (w > zero);
    // Outside iff some edge function is negative and another positive.
    const int inside = ~movemask(neg & pos) & mask & ~exact_zero;

    int result = inside ? offer_hits<kAnyHit>(p.prim[tri], u, v, w, pz, r, c, inside) : 0;
    if (exact_zero) result |= retest_exact_zeros<kAnyHit>(p, tri, r, c, exact_zero);
    return result;
}

}  // namespace coherent::packet
