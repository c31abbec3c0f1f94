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

using packet::packet_size;
using packet::PacketRays;
using simd::vbool8;
using simd::vfloat8;
using simd::vint8;

// One push per level of the binary tree (< 128 levels, see bvh_build.cpp).
constexpr int kStackSize = 192;

// Counters kept in locals during one packet, added to the caller's at the end.
struct LocalCounters {
    uint64_t node_visits = 0, box_tests = 0, triangle_tests = 0;
    uint64_t box_lanes = 0, box_lanes_active = 0, triangle_lanes = 0, triangle_lanes_active = 0;
};

// The largest cull distance over live lanes (the interval test's far bound).
float max_cull(const PacketRays& r) {
    vfloat8 m = -kInf;
    for (int c = 0; c < r.chunks; ++c) {
        if (!r.live[c]) continue;
        const vbool8 lm = vbool8::from_bits(static_cast<int>(r.live[c]));
        m = max(m, select(lm, vfloat8::load(r.cull + c * kPacketLanes), vfloat8(-kInf)));
    }
    return reduce_max(m);
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
        return ~movemask(vint8::load(n.ref) == vint8(static_cast<int32_t>(kEmptyChild))) & 0xff;
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
        vfloat8 tnear = r.tmin[i], tfar = r.cull[i];
        for (int a = 0; a < 3; ++a) {
            const bool neg = std::signbit(inv[a]);
            const vfloat8 o = org[a], iv = inv[a];
            const vfloat8 tn = (vfloat8::load(neg ? n.hi[a] : n.lo[a]) - o) * iv;
            const vfloat8 tf = (vfloat8::load(neg ? n.lo[a] : n.hi[a]) - o) * iv;
            // Slab term first: a NaN slab (0 * inf) leaves the interval as it is.
            tnear = max(tn, tnear);
            tfar = min(tf, tfar);
        }
        const int m = movemask(tnear <= tfar * vfloat8(kFarScale));
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
                store(r.cull + o, packet::cull_distance(vfloat8::load(r.best_t + o)));
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
                    simd::prefetch(reinterpret_cast<const char*>(leaf_packs) + 64 * line);
                if (w.leaf(n.box, leaf_packs, n.count, f, l)) return;
            } else {
                // Both children (read by the ordering below) while the box is tested.
                simd::prefetch(tree.nodes + n.index);
                simd::prefetch(tree.nodes + n.index + 1);
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
                            simd::prefetch(reinterpret_cast<const char*>(tree.packs + n.ref[c]) + 64 * line);
                    else
                        for (int line = 0; line < 4; ++line)
                            simd::prefetch(reinterpret_cast<const char*>(tree.wide + n.ref[c]) + 64 * line);
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
    const int size = packet_size(packet);
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
    const int size = packet_size(packet);
    {
        uint32_t neg[3] = {0, 0, 0}, pos[3] = {0, 0, 0};
        for (int c = 0; c * kPacketLanes < size; ++c) {
            const int o = c * kPacketLanes;
            const int in_use = size - o >= kPacketLanes ? kPacketLanes : size - o;
            const uint32_t active = packet.chunk_mask(c) & ((1u << in_use) - 1u);
            const float* d[3] = {packet.dx + o, packet.dy + o, packet.dz + o};
            for (int a = 0; a < 3; ++a) {
                const uint32_t m = static_cast<uint32_t>(movemask(signbit(vfloat8::load(d[a])))) & active;
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
        if (!packet::prepare(p, magnitude, r)) return false;
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
        for (int c = 0; c < r.chunks; ++c) {
            if (!r.valid[c]) continue;
            const int o = c * kPacketLanes;
            const vint8 prim = vint8::load(r.best_prim + o);
            const vbool8 hit = andnot(vbool8::from_bits(static_cast<int>(r.valid[c])), prim == vint8(-1));
            if (none(hit)) continue;
            store(hit, hits.t + o, vfloat8::load(r.best_t + o));
            store(hit, hits.u + o, vfloat8::load(r.best_u + o));
            store(hit, hits.v + o, vfloat8::load(r.best_v + o));
            store(hit, hits.prim + o, prim);
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
