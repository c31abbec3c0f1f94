// Conversion of the binary tree (nodes_, prim_order_) into the traversal
// layout of bvh_layout.h.
//
// Collapse: each wide node takes up to eight subtrees of a binary node. Two
// rules choose which binary nodes become wide nodes:
//  - optimal (default): the SAH-optimal choice by dynamic programming
//    (Ylitie et al. 2017, CollapsePlan below). It minimises the summed area
//    of the wide nodes, i.e. the expected number of wide-node visits.
//  - greedy (Wald et al. 2008 / Embree's BVH8 from BVH2): start from the two
//    children and repeatedly open the interior child of largest surface area
//    until there are eight or only leaves. It fills the top of each subtree
//    and leaves small remnant nodes below (about 4.3 of 8 slots filled on
//    sponza), which the DP avoids by trading slots between siblings.
// Leaves are the binary tree's in both, so the hits are the same. Wide nodes
// are laid out depth-first (root first); leaves become TrianglePack4s in
// prim_order_ order.
#include <algorithm>
#include <limits>
#include <vector>

#include "bvh.h"

namespace coherent {

namespace {

uint32_t packs_for(uint32_t count) { return (count + 3) / 4; }

void set_child(WideNode8& w, int c, const BBox& box, uint32_t ref, uint32_t count) {
    for (int a = 0; a < 3; ++a) {
        w.lo[a][c] = box.lo[a];
        w.hi[a][c] = box.hi[a];
    }
    w.ref[c] = ref;
    w.count[c] = count;
}

WideNode8 empty_wide_node() {
    WideNode8 w;
    for (int c = 0; c < kWideWidth; ++c) set_child(w, c, BBox{}, kEmptyChild, 0);
    return w;
}

// SAH-optimal collapse (Ylitie, Karras, Laine 2017, "Efficient Incoherent Ray
// Traversal on GPUs Through Compressed Wide BVHs", section 3, restricted to
// keeping the binary leaves as they are). A ray visits a wide node with a
// probability proportional to the surface area of its box, and every visit
// costs about the same (one 8-wide box test), so the collapse should
// minimise the summed area of the wide nodes it creates. Leaves are the
// binary tree's in every collapse, so their cost is a constant left out.
//
//   cost(n, 1) = area(n) + dist(n, 8)          n becomes a wide node
//   cost(n, i) = min(cost(n, 1), dist(n, i))   i >= 2: n may instead spill
//                                               its subtrees into i slots
//   dist(n, j) = min_k cost(left, k) + cost(right, j - k)
//   cost(leaf, i) = 0
//
// Memory: 8 floats + 8 bytes per binary node, released after the collapse.
class CollapsePlan {
public:
    void plan(const std::vector<BvhNode>& nodes) {
        nodes_ = &nodes;
        const size_t count = nodes.size();
        cost_.assign(count * kWideWidth, 0.0f);
        split_.assign(count * kWideWidth, 0);
        // Children follow their parent in nodes_ (the builders append each
        // pair after the node that owns it), so a reverse sweep is bottom-up.
        for (size_t idx = count; idx-- > 0;) {
            const BvhNode& node = nodes[idx];
            if (node.is_leaf()) continue;  // cost 0 for every slot count
            const uint32_t l = node.index, r = node.index + 1;
            float dist[kWideWidth + 1];
            uint8_t best_k[kWideWidth + 1];
            for (int j = 2; j <= kWideWidth; ++j) {
                dist[j] = std::numeric_limits<float>::infinity();
                best_k[j] = 1;
                for (int k = 1; k < j; ++k) {
                    const float c = cost(l, k) + cost(r, j - k);
                    if (c < dist[j]) {
                        dist[j] = c;
                        best_k[j] = static_cast<uint8_t>(k);
                    }
                }
            }
            const float own = node.box.half_area() + dist[kWideWidth];
            cost_[idx * kWideWidth + 0] = own;
            split_[idx * kWideWidth + 0] = best_k[kWideWidth];  // the split of n's own wide node
            for (int i = 2; i <= kWideWidth; ++i) {
                // Ties spill (more slots filled, one node fewer).
                const bool spill = dist[i] <= own;
                cost_[idx * kWideWidth + i - 1] = spill ? dist[i] : own;
                split_[idx * kWideWidth + i - 1] = spill ? best_k[i] : 0;  // 0: n takes one slot
            }
        }
    }

    // The slots of the wide node made for interior binary node `n`.
    void emit(uint32_t n, uint32_t* slots, int& count) const {
        const uint32_t l = (*nodes_)[n].index;
        const int k = split_[size_t(n) * kWideWidth];
        emit_into(l, k, slots, count);
        emit_into(l + 1, kWideWidth - k, slots, count);
    }

private:
    float cost(uint32_t n, int i) const { return cost_[size_t(n) * kWideWidth + i - 1]; }

    // Subtree `n` placed into at most `i` slots of a wide node.
    void emit_into(uint32_t n, int i, uint32_t* slots, int& count) const {
        const BvhNode& node = (*nodes_)[n];
        const int k = i >= 2 && !node.is_leaf() ? split_[size_t(n) * kWideWidth + i - 1] : 0;
        if (k == 0) {
            slots[count++] = n;
            return;
        }
        emit_into(node.index, k, slots, count);
        emit_into(node.index + 1, i - k, slots, count);
    }

    const std::vector<BvhNode>* nodes_ = nullptr;
    std::vector<float> cost_;      // cost(n, i) at [n * 8 + i - 1]
    std::vector<uint8_t> split_;   // [n * 8]: k of n's own node; [n * 8 + i - 1]: k of the spill into i slots, 0 = none
};

}  // namespace

void Bvh::build_traversal_layout(const Vec3f* verts, bool optimal_collapse) {
    wide_.clear();
    packs_.clear();
    wide_binary_.clear();
    if (nodes_.empty()) return;

    // Leaves -> packs, in node order (any fixed order works; this one follows
    // the depth-first numbering of nodes_, hence the leaf order of the tree).
    std::vector<uint32_t> pack_of(nodes_.size(), 0);
    uint32_t npacks = 0;
    for (size_t i = 0; i < nodes_.size(); ++i)
        if (nodes_[i].is_leaf()) {
            pack_of[i] = npacks;
            npacks += packs_for(nodes_[i].count);
        }
    packs_.resize(npacks);
    for (size_t i = 0; i < nodes_.size(); ++i) {
        const BvhNode& n = nodes_[i];
        if (!n.is_leaf()) continue;
        for (uint32_t k = 0; k < packs_for(n.count); ++k) {
            TrianglePack4& pack = packs_[pack_of[i] + k];
            for (int lane = 0; lane < 4; ++lane) {
                const uint32_t local = k * 4 + lane;
                // Unused lanes repeat the leaf's first triangle (masked out in traversal).
                const uint32_t slot = n.index + (local < n.count ? local : 0);
                const uint32_t tri = prim_order_[slot];
                for (int vtx = 0; vtx < 3; ++vtx)
                    for (int a = 0; a < 3; ++a) pack.v[vtx][a][lane] = verts[3 * size_t(tri) + vtx][a];
                pack.prim[lane] = local < n.count ? tri : kInvalidPrim;
            }
        }
    }

    // A tree that is a single leaf: one wide node with one leaf child.
    if (nodes_[0].is_leaf()) {
        wide_.push_back(empty_wide_node());
        set_child(wide_[0], 0, nodes_[0].box, pack_of[0], nodes_[0].count);
        wide_binary_.assign(kWideWidth, kEmptyChild);
        wide_binary_[0] = 0;
        stats_.wide_nodes = 1;
        stats_.wide_node_visit_estimate = 0.0;
        return;
    }

    // Depth-first collapse with an explicit stack of (binary node, wide slot).
    wide_.reserve(nodes_.size() / 4 + 1);
    wide_.push_back(empty_wide_node());
    struct Item {
        uint32_t binary, wide;
    };
    std::vector<Item> stack{{0, 0}};
    // The DP sweeps nodes_ backwards, which is bottom-up only if every pair
    // of children follows its parent (true of both builders; checked, so a
    // tree from elsewhere falls back to the greedy collapse instead of
    // reading costs not yet computed).
    bool children_follow_parents = true;
    for (size_t i = 0; i < nodes_.size(); ++i)
        if (!nodes_[i].is_leaf() && nodes_[i].index <= i) children_follow_parents = false;
    const bool use_dp = optimal_collapse && children_follow_parents;
    CollapsePlan plan;
    if (use_dp) plan.plan(nodes_);
    const float root_area = nodes_[0].box.half_area();
    double visit_estimate = 0.0;
    while (!stack.empty()) {
        const Item it = stack.back();
        stack.pop_back();
        uint32_t children[kWideWidth];
        int n = 0;
        if (use_dp) {
            plan.emit(it.binary, children, n);
        } else {
            children[n++] = nodes_[it.binary].index;
            children[n++] = nodes_[it.binary].index + 1;
            while (n < kWideWidth) {
                int best = -1;
                float best_area = -1.0f;
                for (int c = 0; c < n; ++c) {
                    const BvhNode& child = nodes_[children[c]];
                    if (child.is_leaf()) continue;
                    const float area = child.box.half_area();
                    if (area > best_area) {
                        best_area = area;
                        best = c;
                    }
                }
                if (best < 0) break;
                const uint32_t opened = children[best];
                children[best] = nodes_[opened].index;
                children[n++] = nodes_[opened].index + 1;
            }
        }
        if (n < 2 || n > kWideWidth) __builtin_unreachable();  // both collapses fill 2..8 slots
        // Children in the order they appear in nodes_ (left-to-right in the tree).
        std::sort(children, children + n);
        wide_binary_.resize(wide_.size() * kWideWidth, kEmptyChild);
        for (int c = 0; c < n; ++c) wide_binary_[size_t(it.wide) * kWideWidth + c] = children[c];
        // Reserve the interior children's wide nodes now, so that each wide
        // node's children follow it (depth-first within the stack order).
        for (int c = 0; c < n; ++c) {
            const BvhNode& child = nodes_[children[c]];
            if (child.is_leaf()) {
                set_child(wide_[it.wide], c, child.box, pack_of[children[c]], child.count);
            } else {
                const uint32_t w = static_cast<uint32_t>(wide_.size());
                wide_.push_back(empty_wide_node());
                set_child(wide_[it.wide], c, child.box, w, 0);
                stack.push_back({children[c], w});
                if (root_area > 0.0f) visit_estimate += double(child.box.half_area()) / root_area;
            }
        }
    }
    wide_binary_.resize(wide_.size() * kWideWidth, kEmptyChild);  // the last nodes' slots
    binary_pack_ = std::move(pack_of);
    stats_.wide_nodes = wide_.size();
    stats_.wide_node_visit_estimate = visit_estimate;
}

}  // namespace coherent
