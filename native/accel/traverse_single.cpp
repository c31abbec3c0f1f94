// Single-ray traversal of the BVH over its 8-wide traversal layout
// (bvh_layout.h): closest hit (children visited nearest first) and any hit
// (early exit).
//
// Box test (Ize 2013, "Robust BVH Ray Traversal"), eight children at once:
//  - slab distances are (plane - origin) * (1 / d), whose rounding error is
//    bounded by gamma(3); the far distance is enlarged by (1 + 2 gamma(3)) so
//    rounding never culls a box the ray enters;
//  - a zero direction component gives an infinite reciprocal of the right
//    sign. The only undefined product, 0 * inf, occurs for an origin exactly on
//    a slab plane of a parallel ray; it yields NaN, and the min/max chains are
//    written with the slab term first (_mm256_max_ps/_mm256_min_ps return the
//    second operand when either is NaN), so that slab does not restrict the
//    interval: conservative.
//  - rays whose products all stay finite use an equally conservative fused
//    form, fma(plane, 1/d, -o/d rounded outward) (see BoxRay).
// Triangle test: the watertight test of triangle.h on four triangles at once,
// with the same operations in the same order, hence bit-identical results;
// lanes that need the double-precision fallback go through the scalar code.
// Hits count for t in (tmin, tmax]. Invalid rays (NaN, zero or infinite
// direction, tmin > tmax) hit nothing.
#include <immintrin.h>

#include <cmath>
#include <cstddef>

#include "bvh.h"
#include "triangle.h"

namespace coherent {

namespace {

// Each visited wide node pushes at most 7 children, and the wide tree is no
// deeper than the binary one (< 128 levels, see bvh_build.cpp).
constexpr int kStackSize = 7 * 128;

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

bool valid_ray(const Ray& r) {
    if (!is_finite(r.o) || !is_finite(r.d)) return false;
    if (r.d.x == 0.0f && r.d.y == 0.0f && r.d.z == 0.0f) return false;
    if (std::isnan(r.tmin) || std::isnan(r.tmax) || !(r.tmin <= r.tmax)) return false;
    return true;
}

// Per-ray constants of the eight-box slab test.
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
struct BoxRay {
    __m256 ox, oy, oz;  // splatted origin
    __m256 ix, iy, iz;  // splatted 1/d (+-inf for +-0)
    __m256 chx, chy, chz;  // fused form: o/d rounded up (near planes)
    __m256 clx, cly, clz;  // fused form: o/d rounded down (far planes)
    bool fused = false;
    // Byte offsets of the near and far plane arrays in a WideNode8: the near
    // plane is lo for 1/d >= 0 and hi for 1/d < 0 (sign bit, so -0 counts as <0).
    uint32_t nx, ny, nz, fx, fy, fz;

    // `o4`, `inv4`: the origin and 1 / d (lanes x, y, z; lane 3 unused).
    // `magnitude`: the largest absolute coordinate of the scene's bounds.
    BoxRay(__m128 o4, __m128 inv4, float magnitude) {
        alignas(16) float o[4], inv[4], ch[4], cl[4];
        _mm_store_ps(o, o4);
        _mm_store_ps(inv, inv4);
        ox = _mm256_set1_ps(o[0]); oy = _mm256_set1_ps(o[1]); oz = _mm256_set1_ps(o[2]);
        ix = _mm256_set1_ps(inv[0]); iy = _mm256_set1_ps(inv[1]); iz = _mm256_set1_ps(inv[2]);
        const __m128 sign = _mm_set1_ps(-0.0f);
        // |fl(o * inv) - o * inv| <= 2^-24 |fl(o * inv)| (1 + 2^-23); a margin
        // of 2^-22 |e| survives the rounding of the addition (+ 2^-126 for an
        // e so small that o * inv rounds with an absolute error).
        const __m128 e = _mm_mul_ps(o4, inv4);
        const __m128 margin =
            _mm_add_ps(_mm_mul_ps(_mm_andnot_ps(sign, e), _mm_set1_ps(0x1p-22f)), _mm_set1_ps(0x1p-126f));
        _mm_store_ps(ch, _mm_add_ps(e, margin));
        _mm_store_ps(cl, _mm_sub_ps(e, margin));
        // |1/d| * max(|o|, magnitude, 1) <= 2^100 on x, y and z (an infinite
        // 1/d, or an overflowing product, fails the comparison).
        const __m128 m = _mm_max_ps(_mm_max_ps(_mm_andnot_ps(sign, o4), _mm_set1_ps(magnitude)), _mm_set1_ps(1.0f));
        const __m128 reach = _mm_mul_ps(_mm_andnot_ps(sign, inv4), m);
        fused = (_mm_movemask_ps(_mm_cmple_ps(reach, _mm_set1_ps(0x1p100f))) & 7) == 7;
        chx = _mm256_set1_ps(ch[0]); chy = _mm256_set1_ps(ch[1]); chz = _mm256_set1_ps(ch[2]);
        clx = _mm256_set1_ps(cl[0]); cly = _mm256_set1_ps(cl[1]); clz = _mm256_set1_ps(cl[2]);
        const Vec3f inv3(inv[0], inv[1], inv[2]);
        constexpr uint32_t lo = offsetof(WideNode8, lo), hi = offsetof(WideNode8, hi);
        constexpr uint32_t axis = sizeof(float) * kWideWidth;
        nx = (std::signbit(inv3.x) ? hi : lo) + 0 * axis;
        ny = (std::signbit(inv3.y) ? hi : lo) + 1 * axis;
        nz = (std::signbit(inv3.z) ? hi : lo) + 2 * axis;
        fx = (std::signbit(inv3.x) ? lo : hi) + 0 * axis;
        fy = (std::signbit(inv3.y) ? lo : hi) + 1 * axis;
        fz = (std::signbit(inv3.z) ? lo : hi) + 2 * axis;
    }
};

inline __m256 load_planes(const WideNode8& n, uint32_t offset) {
    return _mm256_load_ps(reinterpret_cast<const float*>(reinterpret_cast<const char*>(&n) + offset));
}

// Tests the eight children of `n`; returns the hit mask and their entry distances.
template <bool kFused>
inline int intersect_wide(const WideNode8& n, const BoxRay& r, float tmin, float tmax, __m256& entry) {
    __m256 tnx, tny, tnz, tfx, tfy, tfz;
    if constexpr (kFused) {
        tnx = _mm256_fmsub_ps(load_planes(n, r.nx), r.ix, r.chx);
        tny = _mm256_fmsub_ps(load_planes(n, r.ny), r.iy, r.chy);
        tnz = _mm256_fmsub_ps(load_planes(n, r.nz), r.iz, r.chz);
        tfx = _mm256_fmsub_ps(load_planes(n, r.fx), r.ix, r.clx);
        tfy = _mm256_fmsub_ps(load_planes(n, r.fy), r.iy, r.cly);
        tfz = _mm256_fmsub_ps(load_planes(n, r.fz), r.iz, r.clz);
    } else {
        tnx = _mm256_mul_ps(_mm256_sub_ps(load_planes(n, r.nx), r.ox), r.ix);
        tny = _mm256_mul_ps(_mm256_sub_ps(load_planes(n, r.ny), r.oy), r.iy);
        tnz = _mm256_mul_ps(_mm256_sub_ps(load_planes(n, r.nz), r.oz), r.iz);
        tfx = _mm256_mul_ps(_mm256_sub_ps(load_planes(n, r.fx), r.ox), r.ix);
        tfy = _mm256_mul_ps(_mm256_sub_ps(load_planes(n, r.fy), r.oy), r.iy);
        tfz = _mm256_mul_ps(_mm256_sub_ps(load_planes(n, r.fz), r.oz), r.iz);
    }
    // Slab term first: _mm256_max_ps/_mm256_min_ps return the second operand
    // when either is NaN, so a NaN slab leaves the accumulator unchanged.
    const __m256 tnear = _mm256_max_ps(tnz, _mm256_max_ps(tny, _mm256_max_ps(tnx, _mm256_set1_ps(tmin))));
    const __m256 tfar = _mm256_min_ps(tfz, _mm256_min_ps(tfy, _mm256_min_ps(tfx, _mm256_set1_ps(tmax))));
    // Ize's (1 + 2 gamma(3)) on the far distance; scaling after the min is the
    // same as scaling each slab (rounding is monotonic) and also widens tmax a
    // hair, which only costs a rare extra visit.
    entry = tnear;
    return _mm256_movemask_ps(_mm256_cmp_ps(tnear, _mm256_mul_ps(tfar, _mm256_set1_ps(kFarScale)), _CMP_LE_OQ));
}

// Per-ray constants of the 4-wide watertight triangle test.
struct TriRay {
    WatertightRay w;
    __m128 okx, oky, okz;  // origin in the permuted axes
    __m128 sx, sy, sz;
    TriRay(const Ray& r, const Vec3f& inv) : w(r.o, r.d, inv) {
        okx = _mm_set1_ps(r.o[w.kx]);
        oky = _mm_set1_ps(r.o[w.ky]);
        okz = _mm_set1_ps(r.o[w.kz]);
        sx = _mm_set1_ps(w.sx);
        sy = _mm_set1_ps(w.sy);
        sz = _mm_set1_ps(w.sz);
    }
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

// A stack entry is a child: an interior node (count 0) or a leaf.
struct Entry {
    uint32_t ref, count;
    float t;
};

// The traversal loop, for one form of the box test (see BoxRay). `best.t`
// starts at the ray's tmax and shrinks to the closest hit so far (inclusive).
// Forced inline into Bvh::traverse: a call per ray costs primary rays.
template <bool kAnyHit, bool kCount, bool kFused>
__attribute__((always_inline)) inline bool traverse_wide(const WideNode8* nodes, const TrianglePack4* packs,
                                                         const BoxRay& box_ray, const TriRay& tri_ray, float tmin,
                                                         Closest& best, TraversalCounters* counters) {
    // Boxes farther than this cannot hold a closer hit; recomputed only when
    // a leaf moved best.t (any-hit queries never change it).
    float cull = cull_distance(best.t);
    Entry stack[kStackSize];
    int sp = 0;
    Entry current{0, 0, tmin};  // the root node, whose own box is the union of its children's

    // Tests a leaf; true answers an any-hit query.
    auto leaf = [&](uint32_t first_pack, uint32_t count) {
        if constexpr (kCount) {
            ++counters->node_visits;
            counters->triangle_tests += count;
        }
        if (intersect_leaf<kAnyHit>(packs, first_pack, count, tri_ray, tmin, best)) {
            if constexpr (kAnyHit) return true;
            cull = cull_distance(best.t);
        }
        return false;
    };

    while (true) {
        if (current.count != 0) {
            if (leaf(current.ref, current.count)) return true;  // any-hit only
        } else {
            const WideNode8& n = nodes[current.ref];
            // The child references (the node's fourth cache line) are read
            // only after the box test; asking for them now overlaps that
            // miss with the box planes' instead of serialising the two.
            _mm_prefetch(reinterpret_cast<const char*>(n.ref), _MM_HINT_T0);
            __m256 entry_v;
            int mask = intersect_wide<kFused>(n, box_ray, tmin, cull, entry_v);
            if constexpr (kCount) {
                ++counters->node_visits;
                const __m256i refs = _mm256_load_si256(reinterpret_cast<const __m256i*>(n.ref));
                const int empty = _mm256_movemask_ps(
                    _mm256_castsi256_ps(_mm256_cmpeq_epi32(refs, _mm256_set1_epi32(static_cast<int>(kEmptyChild)))));
                counters->box_tests += static_cast<uint64_t>(kWideWidth - __builtin_popcount(empty));
            }
            if (mask != 0) {
                if constexpr (kAnyHit) {
                    // Any hit: the entry distances do not matter (nothing
                    // is culled by distance below tmax, which the box test
                    // already applied), so they are not kept.
                    if ((mask & (mask - 1)) == 0) {
                        const int c = __builtin_ctz(mask);
                        current = {n.ref[c], n.count[c], tmin};
                        continue;
                    }
                    const int base = sp;
                    // Interior children have count 0 (so do empty slots, but
                    // their empty boxes are never in `mask`).
                    const __m256i counts = _mm256_load_si256(reinterpret_cast<const __m256i*>(n.count));
                    const int interior = mask & _mm256_movemask_ps(_mm256_castsi256_ps(
                                                    _mm256_cmpeq_epi32(counts, _mm256_setzero_si256())));
                    // Push interior children first (in any order) and start
                    // loading the one popped next, so that its cache misses
                    // overlap the leaf tests below.
                    for (int m = interior; m; m &= m - 1) stack[sp++] = {n.ref[__builtin_ctz(m)], 0, tmin};
                    if (sp > base) {
                        const char* next = reinterpret_cast<const char*>(&nodes[stack[sp - 1].ref]);
                        for (int line = 0; line < 4; ++line) _mm_prefetch(next + 64 * line, _MM_HINT_T0);
                    }
                    // Then test the leaf children (a hit ends the query).
                    for (int m = mask & ~interior; m; m &= m - 1) {
                        const int c = __builtin_ctz(m);
                        if (leaf(n.ref[c], n.count[c])) return true;
                    }
                    if (sp > base) {
                        current = stack[--sp];
                        continue;
                    }
                } else {
                    alignas(32) float entry[kWideWidth];
                    _mm256_store_ps(entry, entry_v);
                    if ((mask & (mask - 1)) == 0) {
                        // One child: no stack traffic.
                        const int c = __builtin_ctz(mask);
                        current = {n.ref[c], n.count[c], entry[c]};
                        continue;
                    }
                    const int base = sp;
                    // Closest hit: push farthest first so the nearest is popped first.
                    for (; mask; mask &= mask - 1) {
                        const int c = __builtin_ctz(mask);
                        const Entry e{n.ref[c], n.count[c], entry[c]};
                        int j = sp;
                        while (j > base && stack[j - 1].t < e.t) {
                            stack[j] = stack[j - 1];
                            --j;
                        }
                        stack[j] = e;
                        ++sp;
                    }
                    current = stack[--sp];
                    continue;
                }
            }
        }
        // Pop the next subtree that can still hold a closer hit.
        while (true) {
            if (sp == 0) return false;
            current = stack[--sp];
            if (kAnyHit || current.t <= cull) break;
        }
    }
}

}  // namespace

template <bool kAnyHit, bool kCount>
bool Bvh::traverse(const Ray& ray, Hit* hit, TraversalCounters* counters) const {
    if constexpr (kCount) ++counters->rays;
    if (wide_.empty() || !valid_ray(ray)) return false;

    const BBox& root = nodes_[0].box;
    // 1/d once, for both tests (one vector division, correctly rounded per lane
    // like the scalar one).
    const __m128 inv4 = _mm_div_ps(_mm_set1_ps(1.0f), _mm_setr_ps(ray.d.x, ray.d.y, ray.d.z, 1.0f));
    alignas(16) float inv_lanes[4];
    _mm_store_ps(inv_lanes, inv4);
    const Vec3f inv(inv_lanes[0], inv_lanes[1], inv_lanes[2]);
    const BoxRay box_ray(_mm_setr_ps(ray.o.x, ray.o.y, ray.o.z, 0.0f), inv4,
                         std::max(max_component(abs(root.lo)), max_component(abs(root.hi))));
    const TriRay tri_ray(ray, inv);
    Closest best;
    best.t = ray.tmax;
    const bool any = box_ray.fused
                         ? traverse_wide<kAnyHit, kCount, true>(wide_.data(), packs_.data(), box_ray, tri_ray,
                                                                ray.tmin, best, counters)
                         : traverse_wide<kAnyHit, kCount, false>(wide_.data(), packs_.data(), box_ray, tri_ray,
                                                                 ray.tmin, best, counters);
    if constexpr (kAnyHit) {
        return any;
    } else {
        if (best.prim == kInvalidPrim) return false;
        hit->t = best.t;
        hit->u = best.u;
        hit->v = best.v;
        hit->prim = best.prim;
        return true;
    }
}

bool Bvh::intersect(const Ray& ray, Hit& hit, TraversalCounters* counters) const {
    return counters ? traverse<false, true>(ray, &hit, counters) : traverse<false, false>(ray, &hit, nullptr);
}

bool Bvh::occluded(const Ray& ray, TraversalCounters* counters) const {
    return counters ? traverse<true, true>(ray, nullptr, counters) : traverse<true, false>(ray, nullptr, nullptr);
}

}  // namespace coherent
