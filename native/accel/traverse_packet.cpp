// Packet traversal of the BVH (ray_packet.h; Boulos et al. 2007,
// "Packet-based Whitted and Distribution Ray Tracing", and the masked
// early-hit traversal of Sadeghi et al. 2009, "Coherent Path Tracing").
//
// A packet of up to 256 rays walks the tree together, in chunks of 8 rays
// (one AVX2 register per quantity). The traversal stack holds (node, first
// chunk, last chunk): chunks outside [first, last] are known to miss the
// node, since they missed an ancestor whose box contains it. Whether the
// packet enters a box:
//  1. first-hit test: the first live ray (binary walk: its whole chunk) is
//     tested; if it enters, the packet descends at once, without looking at
//     the other rays;
//  2. otherwise, interval arithmetic: when all live rays share one direction
//     octant, the packet's origin and 1/d intervals bound every ray's slab
//     distances; if even the bounds cannot enter the box, the whole packet
//     skips it (one test instead of one per chunk);
//  3. otherwise the remaining chunks are tested in order; the first one that
//     enters becomes the subtree's first chunk, and if none does the box is
//     culled;
//  4. once entered, the last chunk that enters is found from the back (the
//     range of Overbeck et al. 2008, "Large Ray Packets for Real-time
//     Whitted Ray Tracing"), so the subtree ignores the chunks past it.
// Two walks use these steps: the 8-wide tree (the default, kPacketTreeWidth;
// steps 1 and 2 test all eight children of a node at once) and the binary
// tree (a node's own box tested when it is visited). Leaves test each live
// chunk against the leaf box (per-lane masks), then each triangle of the
// leaf's packs against the lanes that entered, 8 rays against one triangle.
// Children are visited near first, ordered by their box centres along the
// direction of the packet's first live ray. Packets whose rays span several
// octants are split into one sub-packet per octant (see trace()).
//
// Results are those of Bvh::intersect / Bvh::occluded per ray, bit for bit:
// the box tests are the same conservative Ize test (per lane), culling uses
// the same relative slack against each lane's closest hit, and the triangle
// test is the same watertight arithmetic (packet_kernels.h), with the same
// tie rule (lowest triangle index), which is independent of visiting order.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "bvh.h"
#include "packet_kernels.h"

namespace coherent {

namespace {

using packet::PacketRays;

// One push per level of the binary tree (< 128 levels, see bvh_build.cpp).
constexpr int kStackSize = 192;

// Counters kept in locals during one packet, added to the caller's at the end.
struct LocalCounters {
    uint64_t node_visits = 0, box_tests = 0, triangle_tests = 0;
    uint64_t box_lanes = 0, box_lanes_active = 0, triangle_lanes = 0, triangle_lanes_active = 0;
};

// Fills `r` from the packet's active rays; returns false if none is valid.
// Invalid rays (NaN or infinite origin or direction, zero direction, NaN
// bound, tmin > tmax) are never live, like the single-ray kernel's valid_ray.
// `magnitude`: the largest absolute coordinate of the scene's bounds.
bool prepare(const RayPacket& packet, float magnitude, PacketRays& r) {
    const int size = packet.size < 0 ? 0 : (packet.size > kMaxPacketRays ? kMaxPacketRays : packet.size);
    r.chunks = (size + kPacketLanes - 1) / kPacketLanes;
    const __m256 inf = _mm256_set1_ps(kInf), abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
    auto finite = [&](__m256 x) { return _mm256_cmp_ps(_mm256_and_ps(x, abs_mask), inf, _CMP_LT_OQ); };
    const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f);
    int any_neg = 0, any_pos = 0;  // per axis bits (1 = x, 2 = y, 4 = z) over live lanes
    bool all_inv_finite = true;
    int fused_ok = 1;
    __m256 olo[3], ohi[3], ilo[3], ihi[3], tmin_lo = inf;
    for (int a = 0; a < 3; ++a) olo[a] = ilo[a] = inf, ohi[a] = ihi[a] = _mm256_set1_ps(-kInf);
    r.first_chunk = r.chunks;
    for (int c = 0; c < r.chunks; ++c) {
        const int o = c * kPacketLanes;
        const int in_use = size - o >= kPacketLanes ? kPacketLanes : size - o;
        const uint32_t active = packet.chunk_mask(c) & ((1u << in_use) - 1u);
        // Lanes past `size` may hold anything (never read as rays): only
        // the blends below let their bits through, as harmless constants.
        const __m256 ox = _mm256_load_ps(packet.ox + o), oy = _mm256_load_ps(packet.oy + o),
                     oz = _mm256_load_ps(packet.oz + o);
        const __m256 dx = _mm256_load_ps(packet.dx + o), dy = _mm256_load_ps(packet.dy + o),
                     dz = _mm256_load_ps(packet.dz + o);
        const __m256 tmin = _mm256_load_ps(packet.tmin + o), tmax = _mm256_load_ps(packet.tmax + o);
        __m256 ok = _mm256_and_ps(_mm256_and_ps(finite(ox), finite(oy)), finite(oz));
        ok = _mm256_and_ps(ok, _mm256_and_ps(_mm256_and_ps(finite(dx), finite(dy)), finite(dz)));
        const __m256 nonzero = _mm256_or_ps(
            _mm256_or_ps(_mm256_cmp_ps(dx, zero, _CMP_NEQ_OQ), _mm256_cmp_ps(dy, zero, _CMP_NEQ_OQ)),
            _mm256_cmp_ps(dz, zero, _CMP_NEQ_OQ));
        ok = _mm256_and_ps(_mm256_and_ps(ok, nonzero), _mm256_cmp_ps(tmin, tmax, _CMP_LE_OQ));
        const uint32_t live = active & static_cast<uint32_t>(_mm256_movemask_ps(ok));
        r.live[c] = r.valid[c] = live;
        if (live && r.first_chunk == r.chunks) r.first_chunk = c;

        // Dead lanes get a ray that enters nothing (and no NaN, no denormal).
        const __m256i lanes = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        const __m256 lm = _mm256_castsi256_ps(
            _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(static_cast<int>(live)), lanes), lanes));
        const __m256 ix = _mm256_blendv_ps(one, _mm256_div_ps(one, dx), lm);
        const __m256 iy = _mm256_blendv_ps(one, _mm256_div_ps(one, dy), lm);
        const __m256 iz = _mm256_blendv_ps(one, _mm256_div_ps(one, dz), lm);
        _mm256_store_ps(r.ox + o, _mm256_blendv_ps(zero, ox, lm));
        _mm256_store_ps(r.oy + o, _mm256_blendv_ps(zero, oy, lm));
        _mm256_store_ps(r.oz + o, _mm256_blendv_ps(zero, oz, lm));
        _mm256_store_ps(r.ix + o, ix);
        _mm256_store_ps(r.iy + o, iy);
        _mm256_store_ps(r.iz + o, iz);
        // Fused-form constants, exactly as the single-ray kernel's BoxRay:
        // |fl(o * inv) - o * inv| <= 2^-24 |fl(o * inv)| (1 + 2^-23); a margin
        // of 2^-22 |e| + 2^-126 survives the rounding of the addition.
        {
            const __m256 org[3] = {_mm256_blendv_ps(zero, ox, lm), _mm256_blendv_ps(zero, oy, lm),
                                   _mm256_blendv_ps(zero, oz, lm)};
            const __m256 inv[3] = {ix, iy, iz};
            float* ch[3] = {r.chx + o, r.chy + o, r.chz + o};
            float* cl[3] = {r.clx + o, r.cly + o, r.clz + o};
            for (int a = 0; a < 3; ++a) {
                const __m256 e = _mm256_mul_ps(org[a], inv[a]);
                const __m256 margin = _mm256_add_ps(_mm256_mul_ps(_mm256_and_ps(e, abs_mask), _mm256_set1_ps(0x1p-22f)),
                                                    _mm256_set1_ps(0x1p-126f));
                _mm256_store_ps(ch[a], _mm256_add_ps(e, margin));
                _mm256_store_ps(cl[a], _mm256_sub_ps(e, margin));
                // |1/d| * max(|o|, magnitude, 1) <= 2^100 (fails for an infinite 1/d).
                const __m256 m = _mm256_max_ps(_mm256_max_ps(_mm256_and_ps(org[a], abs_mask), _mm256_set1_ps(magnitude)),
                                               one);
                const __m256 reach = _mm256_mul_ps(_mm256_and_ps(inv[a], abs_mask), m);
                if ((_mm256_movemask_ps(_mm256_cmp_ps(reach, _mm256_set1_ps(0x1p100f), _CMP_LE_OQ)) & live) != live)
                    fused_ok = 0;
            }
        }
        _mm256_store_ps(r.tmin + o, _mm256_blendv_ps(zero, tmin, lm));
        const __m256 best = _mm256_blendv_ps(_mm256_set1_ps(-1.0f), tmax, lm);
        _mm256_store_ps(r.best_t + o, best);
        _mm256_store_ps(r.cull + o, packet::cull_distance(best));
        _mm256_store_ps(r.best_u + o, zero);
        _mm256_store_ps(r.best_v + o, zero);
        _mm256_store_si256(reinterpret_cast<__m256i*>(r.best_prim + o), _mm256_set1_epi32(-1));

        // Watertight constants per lane: WatertightRay's constructor
        // (triangle.h) in SIMD, the same comparisons and the same products,
        // hence the same floats as the single-ray kernel. Dead lanes get
        // d = +z (kx, ky, kz = 0, 1, 2, no shear).
        {
            const __m256 sdx = _mm256_blendv_ps(zero, dx, lm), sdy = _mm256_blendv_ps(zero, dy, lm),
                         sdz = _mm256_blendv_ps(one, dz, lm);
            const __m256 sox = _mm256_blendv_ps(zero, ox, lm), soy = _mm256_blendv_ps(zero, oy, lm),
                         soz = _mm256_blendv_ps(zero, oz, lm);
            const __m256 adx = _mm256_and_ps(sdx, abs_mask), ady = _mm256_and_ps(sdy, abs_mask),
                         adz = _mm256_and_ps(sdz, abs_mask);
            // max_dimension: ax > ay ? (ax > az ? 0 : 2) : (ay > az ? 1 : 2).
            const __m256 xy = _mm256_cmp_ps(adx, ady, _CMP_GT_OQ);
            const __m256 kz0 = _mm256_and_ps(xy, _mm256_cmp_ps(adx, adz, _CMP_GT_OQ));
            const __m256 kz1 = _mm256_andnot_ps(xy, _mm256_cmp_ps(ady, adz, _CMP_GT_OQ));
            auto pick = [&](__m256 x, __m256 y, __m256 z, __m256 is0, __m256 is1) {
                return _mm256_blendv_ps(_mm256_blendv_ps(z, y, is1), x, is0);
            };
            // kx, ky before the swap: kz 0 -> (1, 2), 1 -> (2, 0), 2 -> (0, 1);
            // swapped when d[kz] < 0.
            const __m256 dkz = pick(sdx, sdy, sdz, kz0, kz1);
            const __m256 swap = _mm256_cmp_ps(dkz, zero, _CMP_LT_OQ);
            const __m256i i0 = _mm256_setzero_si256(), i1 = _mm256_set1_epi32(1), i2 = _mm256_set1_epi32(2);
            auto ipick = [&](__m256i x, __m256i y, __m256i z, __m256 is0, __m256 is1) {
                return _mm256_castps_si256(pick(_mm256_castsi256_ps(x), _mm256_castsi256_ps(y),
                                                _mm256_castsi256_ps(z), is0, is1));
            };
            const __m256i kz = ipick(i0, i1, i2, kz0, kz1);
            const __m256i kx0 = ipick(i1, i2, i0, kz0, kz1), ky0 = ipick(i2, i0, i1, kz0, kz1);
            const __m256i kx = _mm256_castps_si256(
                _mm256_blendv_ps(_mm256_castsi256_ps(kx0), _mm256_castsi256_ps(ky0), swap));
            const __m256i ky = _mm256_castps_si256(
                _mm256_blendv_ps(_mm256_castsi256_ps(ky0), _mm256_castsi256_ps(kx0), swap));
            auto by_axis = [&](__m256 x, __m256 y, __m256 z, __m256i k) {
                return pick(x, y, z, _mm256_castsi256_ps(_mm256_cmpeq_epi32(k, i0)),
                            _mm256_castsi256_ps(_mm256_cmpeq_epi32(k, i1)));
            };
            const __m256 sz = by_axis(ix, iy, iz, kz);
            _mm256_store_si256(reinterpret_cast<__m256i*>(r.kx + o), kx);
            _mm256_store_si256(reinterpret_cast<__m256i*>(r.ky + o), ky);
            _mm256_store_si256(reinterpret_cast<__m256i*>(r.kz + o), kz);
            _mm256_store_ps(r.sz + o, sz);
            _mm256_store_ps(r.sx + o, _mm256_mul_ps(by_axis(sdx, sdy, sdz, kx), sz));
            _mm256_store_ps(r.sy + o, _mm256_mul_ps(by_axis(sdx, sdy, sdz, ky), sz));
            _mm256_store_ps(r.okx + o, by_axis(sox, soy, soz, kx));
            _mm256_store_ps(r.oky + o, by_axis(sox, soy, soz, ky));
            _mm256_store_ps(r.okz + o, by_axis(sox, soy, soz, kz));
            // One permutation for all live lanes?
            const __m256i perm = _mm256_or_si256(kx, _mm256_or_si256(_mm256_slli_epi32(ky, 2), _mm256_slli_epi32(kz, 4)));
            r.perm[c] = -1;
            if (live) {
                const int l0 = __builtin_ctz(live);
                const int p0 = r.kx[o + l0] | r.ky[o + l0] << 2 | r.kz[o + l0] << 4;
                const int same = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(perm, _mm256_set1_epi32(p0))));
                if ((same & live) == live) r.perm[c] = p0;
                if (r.first_chunk == c) r.first_dir = Vec3f(packet.dx[o + l0], packet.dy[o + l0], packet.dz[o + l0]);
            }
        }

        // Octant and interval bounds over the live lanes.
        const int neg_x = _mm256_movemask_ps(ix) & live, neg_y = _mm256_movemask_ps(iy) & live,
                  neg_z = _mm256_movemask_ps(iz) & live;
        any_neg |= (neg_x ? 1 : 0) | (neg_y ? 2 : 0) | (neg_z ? 4 : 0);
        any_pos |= ((live & ~neg_x) ? 1 : 0) | ((live & ~neg_y) ? 2 : 0) | ((live & ~neg_z) ? 4 : 0);
        const __m256 inv[3] = {ix, iy, iz}, org[3] = {ox, oy, oz};
        for (int a = 0; a < 3; ++a) {
            if ((_mm256_movemask_ps(finite(inv[a])) & live) != live) all_inv_finite = false;
            olo[a] = _mm256_min_ps(olo[a], _mm256_blendv_ps(inf, org[a], lm));
            ohi[a] = _mm256_max_ps(ohi[a], _mm256_blendv_ps(_mm256_set1_ps(-kInf), org[a], lm));
            ilo[a] = _mm256_min_ps(ilo[a], _mm256_blendv_ps(inf, inv[a], lm));
            ihi[a] = _mm256_max_ps(ihi[a], _mm256_blendv_ps(_mm256_set1_ps(-kInf), inv[a], lm));
        }
        tmin_lo = _mm256_min_ps(tmin_lo, _mm256_blendv_ps(inf, tmin, lm));
    }
    if (r.first_chunk == r.chunks) return false;

    r.fused = fused_ok != 0;
    r.uniform_signs = (any_neg & any_pos) == 0;
    for (int a = 0; a < 3; ++a) r.near_hi[a] = (any_neg >> a) & 1;
    r.interval = r.uniform_signs && all_inv_finite;
    if (r.interval) {
        auto hmin = [](__m256 x) {
            alignas(32) float v[8];
            _mm256_store_ps(v, x);
            float m = v[0];
            for (int i = 1; i < 8; ++i) m = std::min(m, v[i]);
            return m;
        };
        auto hmax = [](__m256 x) {
            alignas(32) float v[8];
            _mm256_store_ps(v, x);
            float m = v[0];
            for (int i = 1; i < 8; ++i) m = std::max(m, v[i]);
            return m;
        };
        r.o_lo = _mm_setr_ps(hmin(olo[0]), hmin(olo[1]), hmin(olo[2]), 0.0f);
        r.o_hi = _mm_setr_ps(hmax(ohi[0]), hmax(ohi[1]), hmax(ohi[2]), 0.0f);
        r.inv_lo = _mm_setr_ps(hmin(ilo[0]), hmin(ilo[1]), hmin(ilo[2]), 1.0f);
        r.inv_hi = _mm_setr_ps(hmax(ihi[0]), hmax(ihi[1]), hmax(ihi[2]), 1.0f);
        r.tmin_lo = hmin(tmin_lo);
        for (int a = 0; a < 3; ++a) {
            r.axis_o_lo[a] = hmin(olo[a]);
            r.axis_o_hi[a] = hmax(ohi[a]);
            r.axis_inv_lo[a] = hmin(ilo[a]);
            r.axis_inv_hi[a] = hmax(ihi[a]);
        }
        r.cull_hi = kInf;
    }
    return true;
}

// The largest cull distance over live lanes (the interval test's far bound).
float max_cull(const PacketRays& r) {
    __m256 m = _mm256_set1_ps(-kInf);
    const __m256i lanes = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    for (int c = 0; c < r.chunks; ++c) {
        if (!r.live[c]) continue;
        const __m256 lm = _mm256_castsi256_ps(
            _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(static_cast<int>(r.live[c])), lanes), lanes));
        m = _mm256_max_ps(m, _mm256_blendv_ps(_mm256_set1_ps(-kInf), _mm256_load_ps(r.cull + c * kPacketLanes), lm));
    }
    alignas(32) float v[8];
    _mm256_store_ps(v, m);
    float out = v[0];
    for (int i = 1; i < 8; ++i) out = std::max(out, v[i]);
    return out;
}

// The trees a packet can walk (the Bvh's private arrays).
struct TreeView {
    const BvhNode* nodes;        // binary tree
    const WideNode8* wide;       // its 8-wide collapse (root first)
    const TrianglePack4* packs;  // leaf triangles
    const uint32_t* binary_pack; // first pack of each binary leaf
};

// Which tree the packet kernels walk: 8 (the wide collapse, one node visit
// tests up to eight child boxes, fewer and denser cache lines) or 2 (the
// binary tree). Same hits either way; 8 measured faster on every scene
// (docs/results/packet_traversal.md).
constexpr int kPacketTreeWidth = 8;

// The per-node and per-leaf steps shared by both walks.
template <bool kAnyHit, bool kCount, bool kUniform, bool kFused>
struct Walker {
    PacketRays& r;
    LocalCounters& k;
    uint32_t* ray_visits;
    int live_chunks = 0;  // any-hit: the packet ends when this reaches 0

    Walker(PacketRays& rays, LocalCounters& counters, uint32_t* visits) : r(rays), k(counters), ray_visits(visits) {
        for (int c = 0; c < r.chunks; ++c) live_chunks += r.live[c] != 0;
    }

    // Box test of chunk c against `b`: the live lanes that enter.
    __attribute__((always_inline)) int box(const BBox& b, int c) {
        const int m = packet::box_test<kUniform, kFused>(b, r, c) & static_cast<int>(r.live[c]);
        if constexpr (kCount) {
            const int n = __builtin_popcount(r.live[c]);
            k.box_tests += n;
            k.box_lanes += kPacketLanes;
            k.box_lanes_active += n;
        }
        return m;
    }

    // Drops retired chunks from the ends of [f, l]; false if none is left.
    __attribute__((always_inline)) bool trim(int& f, int& l) const {
        while (f <= l && !r.live[f]) ++f;
        while (l > f && !r.live[l]) --l;
        return f <= l;
    }

    void count_visit(int f, int l) {
        if constexpr (kCount) {
            ++k.node_visits;
            if (ray_visits)
                for (int c = f; c <= l; ++c)
                    for (uint32_t m = r.live[c]; m; m &= m - 1) ++ray_visits[c * kPacketLanes + __builtin_ctz(m)];
        }
    }

    // Non-empty child slots of a wide node.
    static int used(const WideNode8& n) {
        const __m256i refs = _mm256_load_si256(reinterpret_cast<const __m256i*>(n.ref));
        return ~_mm256_movemask_ps(_mm256_castsi256_ps(
                   _mm256_cmpeq_epi32(refs, _mm256_set1_epi32(static_cast<int>(kEmptyChild))))) &
               0xff;
    }

    // Does the packet (chunks [f, l]) enter box `b`? Steps 1-4 of the file
    // comment; on entry, [f, l] narrows to the first and last chunks that
    // enter. kInterval false: the interval test was already made.
    template <bool kInterval = true>
    __attribute__((always_inline)) bool enter(const BBox& b, int& f, int& l) {
        if (!box(b, f)) {
            if (f == l) return false;  // one chunk: nothing else to test
            if (kInterval && r.interval) {
                if constexpr (kCount) ++k.box_tests;
                if (packet::interval_misses(b, r)) return false;
            }
            int c = f + 1;
            for (; c <= l; ++c)
                if (r.live[c] && box(b, c)) break;
            if (c > l) return false;
            f = c;
        }
        narrow_last(b, f, l);
        return true;
    }
    __attribute__((always_inline)) bool enter_after_interval(const BBox& b, int& f, int& l) {
        return enter<false>(b, f, l);
    }

    // Range: the last chunk that enters, from the back (Overbeck et al.
    // 2008's ranged traversal), so that the subtree's leaves and scans skip
    // the chunks past it. (Not for two chunks: the extra test would cost
    // what it saves.) Precondition: chunk f enters.
    __attribute__((always_inline)) void narrow_last(const BBox& b, int f, int& l) {
        if (l - f >= 2)
            while (l > f && !(r.live[l] && box(b, l))) --l;
    }

    // The first-hit test of Boulos et al. at a wide node: the first live ray
    // of chunk f against all eight children at once (the single-ray
    // kernel's exact box test). Returns the children it enters.
    __attribute__((always_inline)) int first_ray_children(const WideNode8& n, int f) {
        const int i = f * kPacketLanes + __builtin_ctz(r.live[f]);
        const float inv[3] = {r.ix[i], r.iy[i], r.iz[i]};
        const float org[3] = {r.ox[i], r.oy[i], r.oz[i]};
        __m256 tnear = _mm256_set1_ps(r.tmin[i]), tfar = _mm256_set1_ps(r.cull[i]);
        for (int a = 0; a < 3; ++a) {
            const bool neg = std::signbit(inv[a]);
            const __m256 o = _mm256_set1_ps(org[a]), iv = _mm256_set1_ps(inv[a]);
            const __m256 tn = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(neg ? n.hi[a] : n.lo[a]), o), iv);
            const __m256 tf = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(neg ? n.lo[a] : n.hi[a]), o), iv);
            // Slab term first: a NaN slab (0 * inf) leaves the interval as it is.
            tnear = _mm256_max_ps(tn, tnear);
            tfar = _mm256_min_ps(tf, tfar);
        }
        const int m = _mm256_movemask_ps(
            _mm256_cmp_ps(tnear, _mm256_mul_ps(tfar, _mm256_set1_ps(packet::kFarScale)), _CMP_LE_OQ));
        if constexpr (kCount) {
            int used = 0;
            for (int c = 0; c < kWideWidth; ++c) used += n.ref[c] != kEmptyChild;
            k.box_tests += used;
            k.box_lanes += kPacketLanes;
            k.box_lanes_active += used;
        }
        return m;
    }

    // Tests the leaf (box `b`, `count` triangles in packs from `leaf_packs`)
    // against chunks [f, l]. Returns true when an any-hit packet is done.
    __attribute__((always_inline)) bool leaf(const BBox& b, const TrianglePack4* leaf_packs, uint32_t count, int f,
                                             int l) {
        bool moved = false;
        for (int c = f; c <= l; ++c) {
            if (!r.live[c]) continue;
            int m = box(b, c);
            if (!m) continue;
            int changed = 0;
            for (uint32_t left = count, p = 0; left > 0 && m; ++p) {
                const int lanes = left >= 4 ? 4 : static_cast<int>(left);
                for (int t = 0; t < lanes && m; ++t) {
                    if constexpr (kCount) {
                        const int a = __builtin_popcount(m);
                        k.triangle_tests += a;
                        k.triangle_lanes += kPacketLanes;
                        k.triangle_lanes_active += a;
                    }
                    const int hit = packet::triangle_test<kAnyHit>(leaf_packs[p], t, r, c, m);
                    if constexpr (kAnyHit) {
                        if (hit) {
                            r.live[c] &= ~static_cast<uint32_t>(hit);
                            m &= ~hit;
                        }
                    } else {
                        changed |= hit;
                    }
                }
                left -= lanes;
            }
            if constexpr (kAnyHit) {
                if (!r.live[c] && --live_chunks == 0) return true;
            } else if (changed) {
                const int o = c * kPacketLanes;
                _mm256_store_ps(r.cull + o, packet::cull_distance(_mm256_load_ps(r.best_t + o)));
                moved = true;
            }
        }
        if (!kAnyHit && moved && r.interval) r.cull_hi = max_cull(r);
        return false;
    }
};

int last_live_chunk(const PacketRays& r) {
    int l = r.chunks - 1;
    while (l > r.first_chunk && !r.live[l]) --l;
    return l;
}

// Walk of the binary tree: each node's box is tested when the node is
// visited. Chunks outside [first, last] are known to miss the node (they
// missed an ancestor, whose box contains the node's).
template <bool kAnyHit, bool kCount, bool kUniform, bool kFused>
void traverse_binary(const TreeView& tree, PacketRays& r, LocalCounters& k, uint32_t* ray_visits) {
    struct Entry {
        uint32_t node;
        int first, last;
    };
    Walker<kAnyHit, kCount, kUniform, kFused> w(r, k, ray_visits);
    Entry stack[kStackSize];
    int sp = 0;
    Entry cur{0, r.first_chunk, last_live_chunk(r)};
    while (true) {
        int f = cur.first, l = cur.last;
        if (w.trim(f, l)) {
            const BvhNode& n = tree.nodes[cur.node];
            w.count_visit(f, l);
            if (n.is_leaf()) {
                const TrianglePack4* leaf_packs = tree.packs + tree.binary_pack[cur.node];
                // The packs are read after the leaf's box test: start their
                // (likely) cache misses now.
                for (int line = 0; line < 3; ++line)
                    _mm_prefetch(reinterpret_cast<const char*>(leaf_packs) + 64 * line, _MM_HINT_T0);
                if (w.leaf(n.box, leaf_packs, n.count, f, l)) return;
            } else {
                // Both children (read by the ordering below) while the box is tested.
                _mm_prefetch(reinterpret_cast<const char*>(tree.nodes + n.index), _MM_HINT_T0);
                _mm_prefetch(reinterpret_cast<const char*>(tree.nodes + n.index + 1), _MM_HINT_T0);
                if (w.enter(n.box, f, l)) {
                    // Near child first: the one whose centre lies further
                    // back along the first live ray's direction.
                    const BvhNode& left = tree.nodes[n.index];
                    const BvhNode& right = tree.nodes[n.index + 1];
                    const Vec3f delta = (right.box.lo + right.box.hi) - (left.box.lo + left.box.hi);
                    const bool left_first = dot(delta, r.first_dir) >= 0.0f;
                    stack[sp++] = {left_first ? n.index + 1 : n.index, f, l};
                    cur = {left_first ? n.index : n.index + 1, f, l};
                    continue;
                }
            }
        }
        if (sp == 0) return;
        cur = stack[--sp];
    }
}

inline BBox child_box(const WideNode8& n, int c) {
    BBox b;
    b.lo = Vec3f(n.lo[0][c], n.lo[1][c], n.lo[2][c]);
    b.hi = Vec3f(n.hi[0][c], n.hi[1][c], n.hi[2][c]);
    return b;
}

// Walk of the 8-wide tree: a visited node tests the first live ray against
// its eight children at once (the first-hit test); each child that ray
// misses goes through steps 1-4 (the rest of its chunk, interval
// arithmetic, the other chunks); the node pushes the children that the packet enters,
// farthest first (by box centre along the first live ray's direction), each
// with its own chunk range. Leaf children are tested when popped.
template <bool kAnyHit, bool kCount, bool kUniform, bool kFused>
void traverse_wide(const TreeView& tree, PacketRays& r, LocalCounters& k, uint32_t* ray_visits) {
    // A child: wide node `ref` (count 0) or a leaf of `count` triangles in
    // packs from `ref`, with its box and the chunks that entered it.
    struct Entry {
        uint32_t ref, count;
        int first, last;
        const WideNode8* parent;
        int slot;
    };
    Walker<kAnyHit, kCount, kUniform, kFused> w(r, k, ray_visits);
    Entry stack[7 * 128 + kWideWidth];
    int sp = 0;
    Entry cur{0, 0, r.first_chunk, last_live_chunk(r), nullptr, 0};
    while (true) {
        int f = cur.first, l = cur.last;
        if (w.trim(f, l)) {
            w.count_visit(f, l);
            if (cur.count != 0) {
                if (w.leaf(child_box(*cur.parent, cur.slot), tree.packs + cur.ref, cur.count, f, l)) return;
            } else {
                const WideNode8& n = tree.wide[cur.ref];
                Entry entered[kWideWidth];
                float key[kWideWidth];
                int ne = 0;
                // (Even for a one-chunk packet, the first ray's and the
                // interval tests beat one chunk test per child: measured
                // 15.9 vs 13.5 Mrays/s on 4x2 dragon primary packets.)
                const int first_hits = w.first_ray_children(n, f);
                // Interval arithmetic on the children the first ray missed,
                // all at once; the survivors go through the chunk tests.
                int maybe = 0xff;
                if (r.interval && (first_hits & w.used(n)) != w.used(n)) {
                    maybe = first_hits | packet::interval_children(n, r);
                    if constexpr (kCount) k.box_tests += __builtin_popcount(w.used(n) & ~first_hits);
                }
                for (int c = 0; c < kWideWidth; ++c) {
                    if (n.ref[c] == kEmptyChild || !((maybe >> c) & 1)) continue;
                    const BBox b = child_box(n, c);
                    int cf = f, cl = l;
                    if ((first_hits >> c) & 1) {
                        w.narrow_last(b, cf, cl);
                    } else if (!w.enter_after_interval(b, cf, cl)) {
                        continue;
                    }
                    if (n.count[c] != 0)
                        for (int line = 0; line < 3; ++line)
                            _mm_prefetch(reinterpret_cast<const char*>(tree.packs + n.ref[c]) + 64 * line, _MM_HINT_T0);
                    else
                        for (int line = 0; line < 4; ++line)
                            _mm_prefetch(reinterpret_cast<const char*>(tree.wide + n.ref[c]) + 64 * line, _MM_HINT_T0);
                    // Insert by decreasing distance of the centre along the
                    // first ray (farthest pushed first, popped last).
                    const float d = dot(b.lo + b.hi, r.first_dir);
                    int j = ne++;
                    while (j > 0 && key[j - 1] < d) {
                        key[j] = key[j - 1];
                        entered[j] = entered[j - 1];
                        --j;
                    }
                    key[j] = d;
                    entered[j] = Entry{n.ref[c], n.count[c], cf, cl, &n, c};
                }
                if (ne > 0) {
                    for (int j = 0; j < ne - 1; ++j) stack[sp++] = entered[j];
                    cur = entered[ne - 1];
                    continue;
                }
            }
        }
        if (sp == 0) return;
        cur = stack[--sp];
    }
}

template <bool kAnyHit, bool kCount, bool kUniform, bool kFused>
void traverse(const TreeView& tree, PacketRays& r, LocalCounters& k, uint32_t* ray_visits) {
    if constexpr (kPacketTreeWidth == 8) traverse_wide<kAnyHit, kCount, kUniform, kFused>(tree, r, k, ray_visits);
    else traverse_binary<kAnyHit, kCount, kUniform, kFused>(tree, r, k, ray_visits);
}

template <bool kAnyHit, bool kCount>
void dispatch(const TreeView& tree, PacketRays& r, LocalCounters& k, uint32_t* ray_visits) {
    if (r.fused) {
        if (r.uniform_signs) traverse<kAnyHit, kCount, true, true>(tree, r, k, ray_visits);
        else traverse<kAnyHit, kCount, false, true>(tree, r, k, ray_visits);
    } else {
        if (r.uniform_signs) traverse<kAnyHit, kCount, true, false>(tree, r, k, ray_visits);
        else traverse<kAnyHit, kCount, false, false>(tree, r, k, ray_visits);
    }
}

int count_active(const RayPacket& packet) {
    const int size = packet.size < 0 ? 0 : (packet.size > kMaxPacketRays ? kMaxPacketRays : packet.size);
    int n = 0;
    for (int i = 0; i < size; ++i) n += packet.is_active(i);
    return n;
}

void add(PacketCounters& out, const LocalCounters& k) {
    out.node_visits += k.node_visits;
    out.box_tests += k.box_tests;
    out.triangle_tests += k.triangle_tests;
    out.box_lanes += k.box_lanes;
    out.box_lanes_active += k.box_lanes_active;
    out.triangle_lanes += k.triangle_lanes;
    out.triangle_lanes_active += k.triangle_lanes_active;
}

}  // namespace

namespace {

// Octant of every active ray's direction (bit 0: x < 0, 1: y < 0, 2: z < 0,
// by sign bit); returns the set of octants present (bit per octant). Most
// packets are single-octant: that is settled chunk by chunk first.
uint32_t octants(const RayPacket& packet, uint8_t* octant) {
    const int size = packet.size < 0 ? 0 : (packet.size > kMaxPacketRays ? kMaxPacketRays : packet.size);
    {
        uint32_t neg[3] = {0, 0, 0}, pos[3] = {0, 0, 0};
        for (int c = 0; c * kPacketLanes < size; ++c) {
            const int o = c * kPacketLanes;
            const int in_use = size - o >= kPacketLanes ? kPacketLanes : size - o;
            const uint32_t active = packet.chunk_mask(c) & ((1u << in_use) - 1u);
            const float* d[3] = {packet.dx + o, packet.dy + o, packet.dz + o};
            for (int a = 0; a < 3; ++a) {
                const uint32_t m = static_cast<uint32_t>(_mm256_movemask_ps(_mm256_load_ps(d[a]))) & active;
                neg[a] |= m;
                pos[a] |= active & ~m;
            }
        }
        if (!((neg[0] && pos[0]) || (neg[1] && pos[1]) || (neg[2] && pos[2]))) return 1u;  // one octant (or none)
    }
    uint32_t present = 0;
    for (int i = 0; i < size; ++i) {
        if (!packet.is_active(i)) continue;
        const int o = int(std::signbit(packet.dx[i])) | int(std::signbit(packet.dy[i])) << 1 |
                      int(std::signbit(packet.dz[i])) << 2;
        octant[i] = static_cast<uint8_t>(o);
        present |= 1u << o;
    }
    return present;
}

// Traces one packet whose rays are handed to `emit(source lane, PacketRays,
// lane in r)` afterwards. A packet whose rays span several direction
// octants (and more than one chunk) is traced as one sub-packet per octant,
// rays compacted in their original order: each sub-packet is then
// single-octant, so the interval test and one near-plane choice per node
// apply, and its chunks hold rays that go the same way.
// `emit_all(r)` does the same for a packet traced whole (lane i = lane i).
template <bool kAnyHit, typename Emit, typename EmitAll>
void trace(const RayPacket& packet, const TreeView& tree, float magnitude, PacketCounters* counters, Emit emit,
           EmitAll emit_all) {
    LocalCounters k;
    auto run = [&](const RayPacket& p, PacketRays& r, uint32_t* visits) {
        if (!prepare(p, magnitude, r)) return false;
        if (counters) dispatch<kAnyHit, true>(tree, r, k, visits);
        else dispatch<kAnyHit, false>(tree, r, k, nullptr);
        return true;
    };
    uint8_t octant[kMaxPacketRays];
    const uint32_t present = packet.size > kPacketLanes ? octants(packet, octant) : 1u;
    PacketRays r;
    if ((present & (present - 1)) == 0) {
        if (run(packet, r, counters ? counters->ray_node_visits : nullptr)) emit_all(r);
    } else {
        RayPacket sub;
        int source[kMaxPacketRays];
        uint32_t sub_visits[kMaxPacketRays];
        uint32_t* visits = counters ? counters->ray_node_visits : nullptr;
        for (uint32_t left = present; left; left &= left - 1) {
            const int o = __builtin_ctz(left);
            sub.clear();
            for (int i = 0; i < packet.size; ++i)
                if (packet.is_active(i) && octant[i] == o) {
                    source[sub.size] = i;
                    sub.push(packet.ray(i));
                }
            if (visits) std::fill(sub_visits, sub_visits + sub.size, 0u);
            if (!run(sub, r, visits ? sub_visits : nullptr)) continue;
            for (int j = 0; j < sub.size; ++j) {
                if ((r.valid[j / kPacketLanes] >> (j % kPacketLanes)) & 1u) emit(source[j], r, j);
                if (visits) visits[source[j]] += sub_visits[j];
            }
        }
    }
    if (counters) add(*counters, k);
}

}  // namespace

void Bvh::intersect(const RayPacket& packet, HitPacket& hits, PacketCounters* counters) const {
    if (counters) {
        ++counters->packets;
        counters->rays += static_cast<uint64_t>(count_active(packet));
    }
    if (nodes_.empty() || packs_.empty() || wide_.empty()) return;
    const BBox& root = nodes_[0].box;
    const float magnitude = std::max(max_component(abs(root.lo)), max_component(abs(root.hi)));
    const TreeView tree{nodes_.data(), wide_.data(), packs_.data(), binary_pack_.data()};
    // Valid lanes with a triangle get their record; the others stay untouched.
    auto one = [&](int i, const PacketRays& r, int j) {
        if (r.best_prim[j] == kInvalidPrim) return;
        hits.t[i] = r.best_t[j];
        hits.u[i] = r.best_u[j];
        hits.v[i] = r.best_v[j];
        hits.prim[i] = r.best_prim[j];
    };
    auto all = [&](const PacketRays& r) {
        const __m256i lanes = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        for (int c = 0; c < r.chunks; ++c) {
            if (!r.valid[c]) continue;
            const int o = c * kPacketLanes;
            const __m256i prim = _mm256_load_si256(reinterpret_cast<const __m256i*>(r.best_prim + o));
            const __m256i valid = _mm256_cmpeq_epi32(
                _mm256_and_si256(_mm256_set1_epi32(static_cast<int>(r.valid[c])), lanes), lanes);
            const __m256i hit = _mm256_andnot_si256(_mm256_cmpeq_epi32(prim, _mm256_set1_epi32(-1)), valid);
            if (_mm256_testz_si256(hit, hit)) continue;
            _mm256_maskstore_ps(hits.t + o, hit, _mm256_load_ps(r.best_t + o));
            _mm256_maskstore_ps(hits.u + o, hit, _mm256_load_ps(r.best_u + o));
            _mm256_maskstore_ps(hits.v + o, hit, _mm256_load_ps(r.best_v + o));
            _mm256_maskstore_epi32(reinterpret_cast<int*>(hits.prim + o), hit, prim);
        }
    };
    trace<false>(packet, tree, magnitude, counters, one, all);
}

void Bvh::occluded(const RayPacket& packet, OcclusionMask& occluded_out, PacketCounters* counters) const {
    if (counters) {
        ++counters->packets;
        counters->rays += static_cast<uint64_t>(count_active(packet));
    }
    if (nodes_.empty() || packs_.empty() || wide_.empty()) return;
    const BBox& root = nodes_[0].box;
    const float magnitude = std::max(max_component(abs(root.lo)), max_component(abs(root.hi)));
    const TreeView tree{nodes_.data(), wide_.data(), packs_.data(), binary_pack_.data()};
    // Valid lanes retire from `live` exactly when they are occluded.
    auto one = [&](int i, const PacketRays& r, int j) {
        if (!((r.live[j / kPacketLanes] >> (j % kPacketLanes)) & 1u)) occluded_out.set(i);
    };
    auto all = [&](const PacketRays& r) {
        for (int c = 0; c < r.chunks; ++c) {
            const uint32_t occ = r.valid[c] & ~r.live[c];
            if (occ) occluded_out.bits[c >> 2] |= occ << (8 * (c & 3));
        }
    };
    trace<true>(packet, tree, magnitude, counters, one, all);
}

}  // namespace coherent
