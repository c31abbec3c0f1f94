// Binary BVH over the scene's triangles: build (bvh_build.cpp; with spatial
// splits, the default, bvh_build_spatial.cpp) is separate from traversal
// (traverse_single.cpp). The binary tree (nodes()) is the
// portable result; single-ray traversal runs on it directly or on a private
// 4- or 8-wide collapse of it (BvhBuildOptions::width; bvh_layout.h,
// bvh_layout.cpp). Packets (traverse_packet.cpp) and breadth-first ray
// streams (ray_stream.h) run over the same tree; every kernel must return
// identical closest hits for the same rays.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "../core/bbox.h"
#include "../core/ray.h"
#include "../core/vec.h"
#include "aligned_allocator.h"
#include "bvh_layout.h"
#include "ray_packet.h"

namespace coherent {

struct Scene;

// Per-ray work counters: the architecture-independent cost metric of the
// packets paper (box and primitive tests per ray).
struct TraversalCounters {
    uint64_t rays = 0;
    uint64_t node_visits = 0;
    uint64_t box_tests = 0;
    uint64_t triangle_tests = 0;

    TraversalCounters& operator+=(const TraversalCounters& o) {
        rays += o.rays; node_visits += o.node_visits; box_tests += o.box_tests; triangle_tests += o.triangle_tests;
        return *this;
    }
};

// 32-byte node. Interior: children at `index` and `index + 1` (left, right),
// count == 0. Leaf: `count` triangles starting at prim_order[index].
struct BvhNode {
    BBox box;  // 24 bytes
    uint32_t index = 0;
    uint32_t count = 0;
    bool is_leaf() const { return count != 0; }
};

struct BvhBuildOptions {
    int bins = 16;             // SAH bins per axis
    int max_leaf_size = 4;     // triangles per leaf at most (except for unsplittable sets)
    float traversal_cost = 1.0f;
    float intersection_cost = 1.0f;  // per group of `leaf_simd_width` triangles
    // Triangles tested together by one SIMD leaf test: the SAH charges a leaf
    // ceil(n / leaf_simd_width) intersections, so leaves fill whole packs.
    int leaf_simd_width = 4;
    // Spatial splits (SBVH, Stich et al. 2009; bvh_build_spatial.h): at most
    // this fraction of the triangle count in extra leaf references (0 turns
    // spatial splits off and selects the plain binned SAH builder). With
    // spatial splits a triangle may appear in several leaves, each leaf box
    // bounding the triangle's part inside it.
    float spatial_split_budget = 0.3f;
    // Spatial splits are tried only where the object split's children overlap
    // by more than this fraction of the root's surface area (Stich's alpha).
    float spatial_split_alpha = 1e-3f;
    // ...and only where that overlap is thicker along the split axis than
    // this fraction of the node's extent on it. An object split's children
    // overlap along its axis by at most the widest reference there, and the
    // boxes a spatial split could trim shrink by about that much, so where
    // every reference is thin next to the node (scanned meshes: most of the
    // search cost, little gain) the search is skipped. 0: Stich's test only.
    // 0.03 keeps Crytek Sponza's box tests per ray within 1 % and takes 40 %
    // off the Stanford dragon's build (docs/results/efficiency_speed.md).
    float spatial_split_min_thickness = 0.03f;
    // Collapse of the binary tree into the 8-wide traversal nodes
    // (bvh_layout.cpp): true = the SAH-optimal collapse (fewest expected node
    // visits; Ylitie et al. 2017), false = the greedy one (open the largest
    // child until eight). Both give the same hits; kept for comparison.
    bool optimal_collapse = true;
    // Width of the tree single rays traverse: 2 (the binary nodes), 4 or 8
    // (the binary tree collapsed into 4- or 8-wide nodes). Same hits for
    // every width; a setting so the widths can be measured side by side.
    // Any other value makes build() throw std::invalid_argument.
    int width = 8;
};

struct BvhBuildStats {
    double seconds = 0.0;
    size_t nodes = 0;
    size_t leaves = 0;
    size_t bytes = 0;  // nodes + reordered triangle data
    int depth = 0;
    size_t references = 0;  // leaf slots (prim_order().size()): triangles plus spatial-split duplicates
    size_t wide_nodes = 0;  // 8-wide traversal nodes
    size_t wide4_nodes = 0;  // 4-wide traversal nodes (built only for width 4)
    // Sum over the wide nodes below the root of area(node) / area(root): the
    // SAH estimate of wide-node visits per ray that enters the root (what
    // the optimal collapse minimises), for the tree single rays traverse
    // (8- or 4-wide; 0 for width 2).
    double wide_node_visit_estimate = 0.0;
    // Seconds of the latest refit() (0 if never refit).
    double refit_seconds = 0.0;
};

// The binned SAH builder of Bvh (no spatial splits) over arbitrary boxes:
// binary `nodes` as Bvh::nodes() (root at 0, siblings adjacent), whose
// leaves index `order` (leaf slot -> box index). Empty or non-finite boxes
// are left out. The top level of instancing (instance_bvh.h) uses it.
void build_box_tree(const std::vector<BBox>& boxes, const BvhBuildOptions& opt, std::vector<BvhNode>& nodes,
                    std::vector<uint32_t>& order);

class Bvh {
public:
    Bvh() = default;
    // Builds over scene.vertices (3 per triangle). Parallel (TBB).
    void build(const Scene& scene, const BvhBuildOptions& opt = {});
    // For tests and tools: build over a raw triangle soup (3 vertices per triangle).
    void build(const std::vector<Vec3f>& triangle_vertices, const BvhBuildOptions& opt = {});

    // Refit (bvh_refit.cpp): the triangles kept their indices and only their
    // vertices moved (e.g. an object transform). Recomputes every box
    // bottom-up from the current vertices and refreshes the traversal layout
    // in place, keeping the topology, leaf order and 8-wide collapse. Hits
    // stay exact (boxes stay conservative; spatial-split references get the
    // whole triangle's box), only the tree's quality may degrade when
    // triangles move far. The caller passes the triangles the BVH was built
    // over (same count, same order; throws std::invalid_argument if a
    // referenced triangle does not exist). Triangles left out of the build
    // (non-finite vertices) stay out; a triangle whose vertices became
    // non-finite keeps its leaf but no longer widens any box.
    void refit(const Scene& scene);
    void refit(const std::vector<Vec3f>& triangle_vertices);

    // Closest hit with t in (ray.tmin, ray.tmax] (half-open, as in ray.h and
    // Embree: a hit exactly at tmin, e.g. from an origin lying on a surface,
    // does not count). On a hit, fills `hit` and returns true. Ties (a ray
    // through a shared edge) go to the lowest triangle index.
    // Watertight (Woop et al. 2013): rays through shared edges/vertices never escape.
    // Invalid rays (NaN, zero or non-finite direction, tmin > tmax) hit nothing.
    bool intersect(const Ray& ray, Hit& hit, TraversalCounters* counters = nullptr) const;
    // Any hit with t in (ray.tmin, ray.tmax] (shadow rays).
    bool occluded(const Ray& ray, TraversalCounters* counters = nullptr) const;

    // Packets (traverse_packet.cpp, ray_packet.h): the packet's active rays,
    // traced together, with exactly the per-ray results of intersect() and
    // occluded() above. intersect writes hits.* of the active rays that hit;
    // occluded sets the bits of the active rays that are occluded.
    void intersect(const RayPacket& packet, HitPacket& hits, PacketCounters* counters = nullptr) const;
    void occluded(const RayPacket& packet, OcclusionMask& occluded, PacketCounters* counters = nullptr) const;

    const std::vector<BvhNode>& nodes() const { return nodes_; }
    const BvhBuildStats& build_stats() const { return stats_; }
    BBox bounds() const { return nodes_.empty() ? BBox{} : nodes_[0].box; }
    bool empty() const { return nodes_.empty(); }

    // Leaf slot -> scene triangle index (leaves index into this order). With
    // spatial splits a triangle may occupy several slots (in different leaves).
    const std::vector<uint32_t>& prim_order() const { return prim_order_; }

    // Width single rays traverse (BvhBuildOptions::width of the last build).
    int width() const { return width_; }

    // The 8-wide traversal layout (bvh_layout.h), for kernels outside this
    // class (breadth-first ray streams, ray_stream.h). Built for every
    // width: streams always run on it. Root at index 0; empty when empty().
    const WideNode8* wide_nodes() const { return wide_.data(); }
    size_t wide_node_count() const { return wide_.size(); }
    const TrianglePack4* triangle_packs() const { return packs_.data(); }

private:
    void build_from(const Vec3f* triangle_vertices, size_t triangle_count, const BvhBuildOptions& opt);
    template <bool kAnyHit, bool kCount>
    bool traverse(const Ray& ray, Hit* hit, TraversalCounters* counters) const;

    void build_traversal_layout(const Vec3f* triangle_vertices, bool optimal_collapse);
    void refit_from(const Vec3f* triangle_vertices, size_t triangle_count);

    std::vector<BvhNode> nodes_;
    std::vector<uint32_t> prim_order_;  // leaf slot -> scene triangle index
    // Traversal layout (bvh_layout.h): the tree collapsed to 8-wide nodes
    // (root first), one or more TrianglePack4 per leaf.
    std::vector<WideNode8, AlignedAllocator<WideNode8, 64>> wide_;
    std::vector<TrianglePack4, AlignedAllocator<TrianglePack4, 64>> packs_;
    // Binary node of each wide child slot (kWideWidth per wide node,
    // kEmptyChild for unused slots): lets refit() refresh the wide boxes
    // without redoing the collapse.
    std::vector<uint32_t> wide_binary_;
    // First TrianglePack4 of each binary leaf, indexed by binary node (0 for
    // interior nodes): kernels that walk the binary tree (packets) test the
    // same packs as the wide one.
    std::vector<uint32_t> binary_pack_;
    // Width 4 only: the 4-wide collapse (root first) and, as wide_binary_
    // for the 8-wide one, the binary node of each of its slots (for refit).
    std::vector<WideNode4, AlignedAllocator<WideNode4, 64>> wide4_;
    std::vector<uint32_t> wide4_binary_;
    int width_ = 8;
    BvhBuildStats stats_;
};

}  // namespace coherent
