// Single-ray traversal of the BVH, for every width of BvhBuildOptions::width:
//  - 8 (default): the 8-wide traversal layout (bvh_layout.h), eight child
//    boxes per AVX2 test;
//  - 4: the 4-wide collapse, four child boxes per SSE test;
//  - 2: the binary nodes themselves, one scalar slab test per child, leaves
//    through the same triangle packs (binary_pack_).
// Closest hit (children visited nearest first) and any hit (early exit).
// The wide kernel is written once over the SIMD width (wide_kernel.h); every
// width shares the triangle test, the tie rule and the culling rule, hence
// returns bit-identical hits.
//
// Hits count for t in (tmin, tmax]. Invalid rays (NaN, zero or infinite
// direction, tmin > tmax) hit nothing.
#include <cmath>
#include <cstddef>

#include "../core/inline.h"
#include "bvh.h"
#include "triangle.h"
#include "wide_kernel.h"

namespace coherent {

namespace {

using namespace kernel;

// Each visited wide node pushes at most W - 1 children, and the wide tree is
// no deeper than the binary one (< 128 levels, see bvh_build.cpp); the binary
// kernel pushes one per level.
constexpr int kStackSize = 7 * 128;

// A stack entry is a child: an interior node (count 0) or a leaf.
struct Entry {
    uint32_t ref, count;
    float t;
};

// Starts loading a stack entry's node or leaf packs.
template <class Node>
COHERENT_ALWAYS_INLINE void prefetch_entry(const Entry& e, const Node* nodes,
                                                          const TrianglePack4* packs) {
    const char* line = e.count == 0 ? reinterpret_cast<const char*>(&nodes[e.ref])
                                    : reinterpret_cast<const char*>(&packs[e.ref]);
    for (size_t l = 0; l < (e.count == 0 ? sizeof(Node) : sizeof(TrianglePack4)); l += 64) simd::prefetch(line + l);
}

// Closest hit, more than one child entered (`mask`, entry distances in
// `entry`): pushes them farthest first onto stack[sp..] and pops the
// nearest, which it returns.
template <class Node>
COHERENT_ALWAYS_INLINE Entry push_near_first(const Node& n, int mask, const float* entry,
                                                            Entry* stack, int& sp, const Node* nodes,
                                                            const TrianglePack4* packs) {
    const int base = sp;
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
    const Entry nearest = stack[--sp];
    // The second nearest child is the likeliest next pop: start loading it
    // now, so its misses overlap the nearest subtree's work.
    prefetch_entry(stack[sp - 1], nodes, packs);
    return nearest;
}

// Any hit, more than one child entered (`mask`): the entry distances do not
// matter (nothing is culled by distance below tmax, which the box test
// already applied). Pushes the interior children (in any order) and starts
// loading the one popped next, so that its cache misses overlap the leaf
// tests; then tests the leaf children with `leaf` (true: a hit, which ends
// the query). Returns whether a leaf was hit.
template <class Node, class Leaf>
COHERENT_ALWAYS_INLINE bool any_hit_children(const Node& n, int mask, float tmin, Entry* stack,
                                                            int& sp, const Node* nodes, Leaf&& leaf) {
    // Interior children have count 0 (so do empty slots, but their empty
    // boxes are never in `mask`).
    const int interior = mask & NodeTraits<Node>::interior_mask(n);
    const int base = sp;
    for (int m = interior; m; m &= m - 1) stack[sp++] = {n.ref[__builtin_ctz(m)], 0, tmin};
    if (sp > base) {
        const char* next = reinterpret_cast<const char*>(&nodes[stack[sp - 1].ref]);
        for (size_t line = 0; line < sizeof(Node) / 64; ++line) simd::prefetch(next + 64 * line);
    }
    for (int m = mask & ~interior; m; m &= m - 1) {
        const int c = __builtin_ctz(m);
        if (leaf(n.ref[c], n.count[c])) return true;
    }
    return false;
}

// The traversal loop, for one form of the box test (see BoxRay). `best.t`
// starts at the ray's tmax and shrinks to the closest hit so far (inclusive).
// Forced inline into Bvh::traverse: a call per ray costs primary rays.
template <bool kAnyHit, bool kCount, bool kFused, class Node>
COHERENT_ALWAYS_INLINE bool traverse_wide(const Node* nodes, const TrianglePack4* packs,
                                                         const BoxRay<Node>& box_ray, const TriRay& tri_ray,
                                                         float tmin, Closest& best, TraversalCounters* counters) {
    constexpr int W = NodeTraits<Node>::kWidth;
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
            const Node& n = nodes[current.ref];
            // The child references (the node's fourth cache line) are read
            // only after the box test; asking for them now overlaps that
            // miss with the box planes' instead of serialising the two.
            simd::prefetch(n.ref);
            typename NodeTraits<Node>::V entry_v;
            const int mask = intersect_node<kFused>(n, box_ray, tmin, cull, entry_v);
            if constexpr (kCount) {
                ++counters->node_visits;
                counters->box_tests += static_cast<uint64_t>(NodeTraits<Node>::used_slots(n));
            }
            if (mask != 0 && (mask & (mask - 1)) == 0) {
                // One child: no stack traffic.
                const int c = __builtin_ctz(mask);
                float t = tmin;
                if constexpr (!kAnyHit) {
                    alignas(32) float entry[W];
                    store(entry, entry_v);
                    t = entry[c];
                }
                current = {n.ref[c], n.count[c], t};
                continue;
            }
            if (mask != 0) {
                if constexpr (kAnyHit) {
                    const int base = sp;
                    if (any_hit_children(n, mask, tmin, stack, sp, nodes, leaf)) return true;
                    if (sp > base) {
                        current = stack[--sp];
                        continue;
                    }
                } else {
                    alignas(32) float entry[W];
                    store(entry, entry_v);
                    current = push_near_first(n, mask, entry, stack, sp, nodes, packs);
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


// Width 2: the binary tree (nodes_), children ordered by entry distance.
// Leaves are tested through their TrianglePack4s (binary_pack_), exactly as
// the wide kernels test them.
template <bool kAnyHit, bool kCount>
inline bool traverse_binary(const BvhNode* nodes, const uint32_t* binary_pack, const TrianglePack4* packs,
                            const RayBoxConstants& box_ray, const TriRay& tri_ray, float tmin, Closest& best,
                            TraversalCounters* counters) {
    float cull = cull_distance(best.t);
    struct BinaryEntry {
        uint32_t node;
        float t;
    };
    BinaryEntry stack[kStackSize];
    int sp = 0;
    uint32_t current = 0;
    // The root's own box is tested like any child's (the wide kernels test it
    // as the union of the root's children).
    float root_entry;
    if constexpr (kCount) ++counters->box_tests;
    if (!intersect_box(nodes[0].box, box_ray, tmin, cull, root_entry)) return false;
    while (true) {
        const BvhNode& n = nodes[current];
        if constexpr (kCount) ++counters->node_visits;
        if (n.is_leaf()) {
            if constexpr (kCount) counters->triangle_tests += n.count;
            if (intersect_leaf<kAnyHit>(packs, binary_pack[current], n.count, tri_ray, tmin, best)) {
                if constexpr (kAnyHit) return true;
                cull = cull_distance(best.t);
            }
        } else {
            float tl, tr;
            const bool hl = intersect_box(nodes[n.index].box, box_ray, tmin, cull, tl);
            const bool hr = intersect_box(nodes[n.index + 1].box, box_ray, tmin, cull, tr);
            if constexpr (kCount) counters->box_tests += 2;
            if (hl && hr) {
                // Nearer first; the farther waits on the stack with its entry distance.
                const bool left_first = kAnyHit || tl <= tr;
                stack[sp++] = left_first ? BinaryEntry{n.index + 1, tr} : BinaryEntry{n.index, tl};
                current = left_first ? n.index : n.index + 1;
                continue;
            }
            if (hl || hr) {
                current = hl ? n.index : n.index + 1;
                continue;
            }
        }
        // Pop the next subtree that can still hold a closer hit.
        while (true) {
            if (sp == 0) return false;
            const BinaryEntry e = stack[--sp];
            if (kAnyHit || e.t <= cull) {
                current = e.node;
                break;
            }
        }
    }
}

}  // namespace

template <bool kAnyHit, bool kCount>
bool Bvh::traverse(const Ray& ray, Hit* hit, TraversalCounters* counters) const {
    if constexpr (kCount) ++counters->rays;
    if (nodes_.empty() || !valid_ray(ray)) return false;

    const BBox& root = nodes_[0].box;
    const RayBoxConstants k =
        RayBoxConstants::from_ray(ray, std::max(max_component(abs(root.lo)), max_component(abs(root.hi))));
    const TriRay tri_ray(ray, k.inverse_direction());
    Closest best;
    best.t = ray.tmax;
    bool any = false;
    if (width_ == 8) {
        const BoxRay<WideNode8> box_ray(k);
        any = box_ray.fused ? traverse_wide<kAnyHit, kCount, true>(wide_.data(), packs_.data(), box_ray, tri_ray,
                                                                   ray.tmin, best, counters)
                            : traverse_wide<kAnyHit, kCount, false>(wide_.data(), packs_.data(), box_ray, tri_ray,
                                                                    ray.tmin, best, counters);
    } else if (width_ == 4) {
        const BoxRay<WideNode4> box_ray(k);
        any = box_ray.fused ? traverse_wide<kAnyHit, kCount, true>(wide4_.data(), packs_.data(), box_ray, tri_ray,
                                                                   ray.tmin, best, counters)
                            : traverse_wide<kAnyHit, kCount, false>(wide4_.data(), packs_.data(), box_ray, tri_ray,
                                                                    ray.tmin, best, counters);
    } else {
        any = traverse_binary<kAnyHit, kCount>(nodes_.data(), binary_pack_.data(), packs_.data(), k, tri_ray,
                                               ray.tmin, best, counters);
    }
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
