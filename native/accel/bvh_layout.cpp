// Conversion of the binary tree (nodes_, prim_order_) into the traversal
// layout of bvh_layout.h.
//
// Collapse: each wide node takes up to W (8, or 4 for BvhBuildOptions::width
// = 4) subtrees of a binary node; the 8-wide tree is always built (ray
// streams run on it), the 4-wide one only for width 4. Two
// rules choose which binary nodes become wide nodes:
//  - optimal (default): the SAH-optimal choice by dynamic programming
//    (Ylitie et al. 2017, CollapsePlan below). It minimises the summed area
//    of the wide nodes, i.e. the expected number of wide-node visits.
//  - greedy (Wald et al. 2008 / Embree's BVH8 from BVH2): start from the two
//    children and repeatedly open the interior child of largest surface area
//    until there are W or only leaves. It fills the top of each subtree
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

template <class Node>
constexpr int node_width() {
    return static_cast<int>(sizeof(Node::ref) / sizeof(uint32_t));
}

template <class Node>
void set_child(Node& w, int c, const BBox& box, uint32_t ref, uint32_t count) {
    for (int a = 0; a < 3; ++a) {
        w.lo[a][c] = box.lo[a];
        w.hi[a][c] = box.hi[a];
    }
    w.ref[c] = ref;
    w.count[c] = count;
}

template <class Node>
Node empty_wide_node() {
    Node w;
    for (int c = 0; c < node_width<Node>(); ++c) set_child(w, c, BBox{}, kEmptyChild, 0);
    return w;
}

// SAH-optimal collapse (Ylitie, Karras, Laine 2017, "Efficient Incoherent Ray
// Traversal on GPUs Through Compressed Wide BVHs", section 3, restricted to
// keeping the binary leaves as they are). A ray visits a wide node with a
// probability proportional to the surface area of its box, and every visit
// costs about the same (one W-wide box test), so the collapse should
// minimise the summed area of the wide nodes it creates. Leaves are the
// binary tree's in every collapse, so their cost is a constant left out.
//
//   cost(n, 1) = area(n) + dist(n, W)          n becomes a wide node
//   cost(n, i) = min(cost(n, 1), dist(n, i))   i >= 2: n may instead spill
//                                               its subtrees into i slots
//   dist(n, j) = min_k cost(left, k) + cost(right, j - k)
//   cost(leaf, i) = 0
//
// Memory: W floats + W bytes per binary node, released after the collapse.
template <int W>
class CollapsePlan {
public:
    void plan(const std::vector<BvhNode>& nodes) {
        nodes_ = &nodes;
        const size_t count = nodes.size();
        cost_.assign(count * W, 0.0f);
        split_.assign(count * W, 0);
        // Children follow their parent in nodes_ (the builders append each
        // pair after the node that owns it), so a reverse sweep is bottom-up.
        for (size_t idx = count; idx-- > 0;) {
            const BvhNode& node = nodes[idx];
            if (node.is_leaf()) continue;  // cost 0 for every slot count
            const uint32_t l = node.index, r = node.index + 1;
            float dist[W + 1];
            uint8_t best_k[W + 1];
            for (int j = 2; j <= W; ++j) {
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
            const float own = node.box.half_area() + dist[W];
            cost_[idx * W + 0] = own;
            split_[idx * W + 0] = best_k[W];  // the split of n's own wide node
            for (int i = 2; i <= W; ++i) {
                // Ties spill (more slots filled, one node fewer).
                const bool spill = dist[i] <= own;
                cost_[idx * W + i - 1] = spill ? dist[i] : own;
                split_[idx * W + i - 1] = spill ? best_k[i] : 0;  // 0: n takes one slot
            }
        }
    }

    // The slots of the wide node made for interior binary node `n`.
    void emit(uint32_t n, uint32_t* slots, int& count) const {
        const uint32_t l = (*nodes_)[n].index;
        const int k = split_[size_t(n) * W];
        emit_into(l, k, slots, count);
        emit_into(l + 1, W - k, slots, count);
    }

private:
    float cost(uint32_t n, int i) const { return cost_[size_t(n) * W + i - 1]; }

    // Subtree `n` placed into at most `i` slots of a wide node.
    void emit_into(uint32_t n, int i, uint32_t* slots, int& count) const {
        const BvhNode& node = (*nodes_)[n];
        const int k = i >= 2 && !node.is_leaf() ? split_[size_t(n) * W + i - 1] : 0;
        if (k == 0) {
            slots[count++] = n;
            return;
        }
        emit_into(node.index, k, slots, count);
        emit_into(node.index + 1, i - k, slots, count);
    }

    const std::vector<BvhNode>* nodes_ = nullptr;
    std::vector<float> cost_;      // cost(n, i) at [n * W + i - 1]
    std::vector<uint8_t> split_;   // [n * W]: k of n's own node; [n * W + i - 1]: k of the spill into i slots, 0 = none
};

// Collapses the binary tree `nodes` (leaves already packed: pack_of[leaf] is
// its first TrianglePack4) into W-wide nodes, root first, depth-first.
// `slot_binary` receives the binary node of every slot (kEmptyChild for
// unused ones). Returns the SAH estimate of wide-node visits per ray.
template <class Node, class NodeVector>
double collapse(const std::vector<BvhNode>& nodes, const std::vector<uint32_t>& pack_of, bool optimal_collapse,
                NodeVector& wide, std::vector<uint32_t>& slot_binary) {
    constexpr int W = node_width<Node>();
    wide.clear();
    slot_binary.clear();
    if (nodes.empty()) return 0.0;

    // A tree that is a single leaf: one wide node with one leaf child.
    if (nodes[0].is_leaf()) {
        wide.push_back(empty_wide_node<Node>());
        set_child(wide[0], 0, nodes[0].box, pack_of[0], nodes[0].count);
        slot_binary.assign(W, kEmptyChild);
        slot_binary[0] = 0;
        return 0.0;
    }

    // Depth-first collapse with an explicit stack of (binary node, wide slot).
    wide.reserve(nodes.size() / (W / 2) + 1);
    wide.push_back(empty_wide_node<Node>());
    struct Item {
        uint32_t binary, wide;
    };
    std::vector<Item> stack{{0, 0}};
    // The DP sweeps nodes backwards, which is bottom-up only if every pair
    // of children follows its parent (true of both builders; checked, so a
    // tree from elsewhere falls back to the greedy collapse instead of
    // reading costs not yet computed).
    bool children_follow_parents = true;
    for (size_t i = 0; i < nodes.size(); ++i)
        if (!nodes[i].is_leaf() && nodes[i].index <= i) children_follow_parents = false;
    const bool use_dp = optimal_collapse && children_follow_parents;
    CollapsePlan<W> plan;
    if (use_dp) plan.plan(nodes);
    const float root_area = nodes[0].box.half_area();
    double visit_estimate = 0.0;
    while (!stack.empty()) {
        const Item it = stack.back();
        stack.pop_back();
        uint32_t children[W];
        int n = 0;
        if (use_dp) {
            plan.emit(it.binary, children, n);
        } else {
            children[n++] = nodes[it.binary].index;
            children[n++] = nodes[it.binary].index + 1;
            while (n < W) {
                int best = -1;
                float best_area = -1.0f;
                for (int c = 0; c < n; ++c) {
                    const BvhNode& child = nodes[children[c]];
                    if (child.is_leaf()) continue;
                    const float area = child.box.half_area();
                    if (area > best_area) {
                        best_area = area;
                        best = c;
                    }
                }
                if (best < 0) break;
                const uint32_t opened = children[best];
                children[best] = nodes[opened].index;
                children[n++] = nodes[opened].index + 1;
            }
        }
        if (n < 2 || n > W) __builtin_unreachable();  // both collapses fill 2..W slots
        // Children in the order they appear in nodes (left-to-right in the tree).
        std::sort(children, children + n);
        slot_binary.resize(wide.size() * W, kEmptyChild);
        for (int c = 0; c < n; ++c) slot_binary[size_t(it.wide) * W + c] = children[c];
        // Reserve the interior children's wide nodes now, so that each wide
        // node's children follow it (depth-first within the stack order).
        for (int c = 0; c < n; ++c) {
            const BvhNode& child = nodes[children[c]];
            if (child.is_leaf()) {
                set_child(wide[it.wide], c, child.box, pack_of[children[c]], child.count);
            } else {
                const uint32_t w = static_cast<uint32_t>(wide.size());
                wide.push_back(empty_wide_node<Node>());
                set_child(wide[it.wide], c, child.box, w, 0);
                stack.push_back({children[c], w});
                if (root_area > 0.0f) visit_estimate += double(child.box.half_area()) / root_area;
            }
        }
    }
    slot_binary.resize(wide.size() * W, kEmptyChild);  // the last nodes' slots
    return visit_estimate;
}

}  // namespace

void Bvh::build_traversal_layout(const Vec3f* verts, bool optimal_collapse) {
    wide_.clear();
    packs_.clear();
    wide_binary_.clear();
    wide4_.clear();
    wide4_binary_.clear();
    stats_.wide_nodes = 0;
    stats_.wide4_nodes = 0;
    stats_.wide_node_visit_estimate = 0.0;
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

    // The 8-wide tree: single rays of width 8 and every ray stream.
    const double estimate8 = collapse<WideNode8>(nodes_, pack_of, optimal_collapse, wide_, wide_binary_);
    stats_.wide_nodes = wide_.size();
    // The estimate of the tree single rays traverse (width 2: none computed).
    stats_.wide_node_visit_estimate = width_ == 8 ? estimate8 : 0.0;
    if (width_ == 4) {
        stats_.wide_node_visit_estimate = collapse<WideNode4>(nodes_, pack_of, optimal_collapse, wide4_, wide4_binary_);
        stats_.wide4_nodes = wide4_.size();
    }
    binary_pack_ = std::move(pack_of);
}

}  // namespace coherent
