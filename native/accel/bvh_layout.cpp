// Conversion of the binary tree (nodes_, prim_order_) into the traversal
// layout of bvh_layout.h.
//
// Collapse (as in Wald et al. 2008 / Embree's BVH8 from BVH2): a wide node
// starts from the two children of a binary node and repeatedly replaces the
// interior child of largest surface area by its two children, until it has
// eight children or only leaves. The largest child is the one most rays
// enter, so opening it saves the most node visits. Wide nodes are laid out
// depth-first (root first); leaves become TrianglePack4s in prim_order_ order.
#include <algorithm>
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

}  // namespace

void Bvh::build_traversal_layout(const Vec3f* verts) {
    wide_.clear();
    packs_.clear();
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
        return;
    }

    // Depth-first collapse with an explicit stack of (binary node, wide slot).
    wide_.reserve(nodes_.size() / 4 + 1);
    wide_.push_back(empty_wide_node());
    struct Item {
        uint32_t binary, wide;
    };
    std::vector<Item> stack{{0, 0}};
    while (!stack.empty()) {
        const Item it = stack.back();
        stack.pop_back();
        uint32_t children[kWideWidth];
        int n = 0;
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
        // Children in the order they appear in nodes_ (left-to-right in the tree).
        std::sort(children, children + n);
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
            }
        }
    }
}

}  // namespace coherent
