// Binned SAH builder for the binary BVH (Wald 2007, "On fast Construction of
// SAH-based Bounding Volume Hierarchies"), parallel with TBB. Used when
// spatial splits are off (spatial_split_budget == 0); otherwise build_from
// hands the work to the spatial-split builder (bvh_build_spatial.h).
//
// Determinism: the output depends only on the input triangles, never on the
// thread count or scheduling. Subtrees are built in parallel into disjoint,
// precomputed slot ranges of a temporary array (a subtree over n references
// uses at most 2n-1 nodes), and bin statistics are reduced with exact
// operations (min, max, integer counts) whose result does not depend on the
// order of the reduction. A final sequential pass renumbers the nodes so
// that siblings are adjacent.
#include <algorithm>
#include <chrono>
#include <stdexcept>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_reduce.h>

#include "../scene/scene.h"
#include "bvh.h"
#include "bvh_build_spatial.h"

namespace coherent {

static_assert(sizeof(BvhNode) == 32, "BvhNode must stay 32 bytes (two siblings per cache line)");

namespace {

constexpr int kMaxBins = 64;
constexpr size_t kParallelSubtreeSize = 4096;    // spawn a task per child above this
constexpr size_t kParallelBinningSize = 1 << 16;  // bin with parallel_reduce above this
constexpr size_t kGrainSize = 1 << 12;
// Beyond this depth the builder only makes median splits, which halve the
// set: total depth stays below kForceMedianDepth + 32, within the traversal stack.
constexpr int kForceMedianDepth = 48;

// Node of the temporary tree. A subtree rooted at slot s over n references
// occupies slots [s, s + 2n - 1): left child at s + 1, right child at s + 2 nl.
struct TempNode {
    BBox box;
    uint32_t left = 0, right = 0;   // interior: child slots
    uint32_t begin = 0, count = 0;  // leaf: reference range (count > 0)
};

struct Bin {
    BBox box;    // bounds of the triangles in the bin
    BBox cbox;   // bounds of their centroids
    uint32_t count = 0;
};

struct BinSet {
    Bin bins[3][kMaxBins];

    void merge(const BinSet& o, int nbins) {
        for (int a = 0; a < 3; ++a)
            for (int i = 0; i < nbins; ++i) {
                bins[a][i].box.expand(o.bins[a][i].box);
                bins[a][i].cbox.expand(o.bins[a][i].cbox);
                bins[a][i].count += o.bins[a][i].count;
            }
    }
};

// Maps centroids to bins. The same mapping is used for binning and for the
// partition, so child counts match the bin counts exactly.
struct BinMapping {
    Vec3f lo;
    Vec3f scale;     // bins / extent, 0 for an axis that cannot be split
    int nbins = 16;

    BinMapping(const BBox& cbox, int bins) : lo(cbox.lo), nbins(bins) {
        const Vec3f e = cbox.extent();
        for (int a = 0; a < 3; ++a) {
            const float s = e[a] > 0.0f ? static_cast<float>(bins) / e[a] : 0.0f;
            scale[a] = std::isfinite(s) ? s : 0.0f;
        }
    }
    bool splittable(int axis) const { return scale[axis] > 0.0f; }
    int index(const Vec3f& c, int axis) const {
        const int i = static_cast<int>((c[axis] - lo[axis]) * scale[axis]);
        return std::clamp(i, 0, nbins - 1);
    }
};

struct Split {
    int axis = -1;
    int bin = 0;  // left side holds bins [0, bin]
    float cost = kInf;
    BBox lbox, rbox, lcbox, rcbox;
    uint32_t lcount = 0;
};

class Builder {
public:
    Builder(const BBox* boxes, const Vec3f* centroids, uint32_t* refs, TempNode* nodes, const BvhBuildOptions& opt)
        : boxes_(boxes), centroids_(centroids), refs_(refs), nodes_(nodes), opt_(opt) {
        bins_ = std::clamp(opt.bins, 2, kMaxBins);
        max_leaf_ = std::max(1, opt.max_leaf_size);
        simd_width_ = static_cast<uint32_t>(std::max(1, opt.leaf_simd_width));
    }

    void build(uint32_t slot, uint32_t begin, uint32_t end, const BBox& box, const BBox& cbox, int depth) {
        const uint32_t n = end - begin;
        TempNode& node = nodes_[slot];
        node.box = box;
        if (n <= 1) return make_leaf(node, begin, n);

        Split split;
        const BinMapping map(cbox, bins_);
        if (depth < kForceMedianDepth) split = find_sah_split(begin, end, map);

        const float leaf_cost = opt_.intersection_cost * blocks(n);
        if (split.axis >= 0) {
            const float split_cost = opt_.traversal_cost + opt_.intersection_cost * split.cost / box.half_area();
            if (n <= static_cast<uint32_t>(max_leaf_) && leaf_cost <= split_cost) return make_leaf(node, begin, n);
        } else if (n <= static_cast<uint32_t>(max_leaf_)) {
            return make_leaf(node, begin, n);
        }

        uint32_t mid;
        BBox lbox, rbox, lcbox, rcbox;
        if (split.axis >= 0) {
            const int axis = split.axis, bin = split.bin;
            uint32_t* m = std::partition(refs_ + begin, refs_ + end,
                                         [&](uint32_t r) { return map.index(centroids_[r], axis) <= bin; });
            mid = static_cast<uint32_t>(m - refs_);
            lbox = split.lbox; rbox = split.rbox; lcbox = split.lcbox; rcbox = split.rcbox;
        } else {
            // Fallback: object median along the widest centroid axis (ties by
            // reference index keep it deterministic). Also covers sets whose
            // centroids coincide, which no plane can separate.
            const Vec3f e = cbox.extent();
            const int axis = max_dimension(e);
            mid = begin + n / 2;
            std::nth_element(refs_ + begin, refs_ + mid, refs_ + end, [&](uint32_t a, uint32_t b) {
                const float ca = centroids_[a][axis], cb = centroids_[b][axis];
                return ca < cb || (ca == cb && a < b);
            });
            for (uint32_t i = begin; i < mid; ++i) { lbox.expand(boxes_[refs_[i]]); lcbox.expand(centroids_[refs_[i]]); }
            for (uint32_t i = mid; i < end; ++i) { rbox.expand(boxes_[refs_[i]]); rcbox.expand(centroids_[refs_[i]]); }
        }

        const uint32_t nl = mid - begin;
        node.left = slot + 1;
        node.right = slot + 2 * nl;
        node.count = 0;
        if (n > kParallelSubtreeSize) {
            tbb::parallel_invoke([&] { build(node.left, begin, mid, lbox, lcbox, depth + 1); },
                                 [&] { build(node.right, mid, end, rbox, rcbox, depth + 1); });
        } else {
            build(node.left, begin, mid, lbox, lcbox, depth + 1);
            build(node.right, mid, end, rbox, rcbox, depth + 1);
        }
    }

private:
    // SAH intersection count of n triangles: whole SIMD groups.
    float blocks(uint32_t n) const { return static_cast<float>((n + simd_width_ - 1) / simd_width_); }

    static void make_leaf(TempNode& node, uint32_t begin, uint32_t n) {
        node.begin = begin;
        node.count = n;
    }

    void bin_range(BinSet& set, uint32_t begin, uint32_t end, const BinMapping& map) const {
        for (uint32_t i = begin; i < end; ++i) {
            const uint32_t r = refs_[i];
            const Vec3f& c = centroids_[r];
            for (int a = 0; a < 3; ++a) {
                Bin& b = set.bins[a][map.index(c, a)];
                b.box.expand(boxes_[r]);
                b.cbox.expand(c);
                ++b.count;
            }
        }
    }

    Split find_sah_split(uint32_t begin, uint32_t end, const BinMapping& map) const {
        Split best;
        if (!map.splittable(0) && !map.splittable(1) && !map.splittable(2)) return best;

        BinSet set;
        if (end - begin >= kParallelBinningSize) {
            set = tbb::parallel_reduce(
                tbb::blocked_range<uint32_t>(begin, end, kGrainSize), BinSet{},
                [&](const tbb::blocked_range<uint32_t>& r, BinSet acc) {
                    bin_range(acc, r.begin(), r.end(), map);
                    return acc;
                },
                [&](BinSet a, const BinSet& b) {
                    a.merge(b, bins_);
                    return a;
                });
        } else {
            bin_range(set, begin, end, map);
        }

        for (int a = 0; a < 3; ++a) {
            if (!map.splittable(a)) continue;
            const Bin* bins = set.bins[a];
            // Right-to-left sweep: area and count of bins (i, nbins).
            float rarea[kMaxBins];
            BBox racc;
            uint32_t rcount[kMaxBins];
            uint32_t rc = 0;
            for (int i = bins_ - 1; i > 0; --i) {
                racc.expand(bins[i].box);
                rc += bins[i].count;
                rarea[i - 1] = racc.half_area();
                rcount[i - 1] = rc;
            }
            BBox lacc;
            uint32_t lc = 0;
            for (int i = 0; i < bins_ - 1; ++i) {
                lacc.expand(bins[i].box);
                lc += bins[i].count;
                if (lc == 0 || rcount[i] == 0) continue;
                const float cost = blocks(lc) * lacc.half_area() + blocks(rcount[i]) * rarea[i];
                if (cost < best.cost) {
                    best.cost = cost;
                    best.axis = a;
                    best.bin = i;
                }
            }
        }
        if (best.axis < 0) return best;

        const Bin* bins = set.bins[best.axis];
        for (int i = 0; i < bins_; ++i) {
            if (i <= best.bin) {
                best.lbox.expand(bins[i].box);
                best.lcbox.expand(bins[i].cbox);
                best.lcount += bins[i].count;
            } else {
                best.rbox.expand(bins[i].box);
                best.rcbox.expand(bins[i].cbox);
            }
        }
        return best;
    }

    const BBox* boxes_;
    const Vec3f* centroids_;
    uint32_t* refs_;
    TempNode* nodes_;
    BvhBuildOptions opt_;
    int bins_ = 16;
    int max_leaf_ = 4;
    uint32_t simd_width_ = 4;
};

struct RootBounds {
    BBox box, cbox;
};

// Per-triangle bounds and centroids, and the triangles to build over (refs).
// Triangles with a non-finite vertex are left out: they could poison every
// box above them with NaN.
void triangle_bounds(const Vec3f* verts, size_t triangle_count, std::vector<BBox>& boxes,
                     std::vector<Vec3f>& centroids, std::vector<uint32_t>& refs) {
    boxes.resize(triangle_count);
    centroids.resize(triangle_count);
    std::vector<uint8_t> valid(triangle_count);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, triangle_count, kGrainSize), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i < r.end(); ++i) {
            const Vec3f& a = verts[3 * i];
            const Vec3f& b = verts[3 * i + 1];
            const Vec3f& c = verts[3 * i + 2];
            valid[i] = is_finite(a) && is_finite(b) && is_finite(c);
            BBox box;
            box.expand(a); box.expand(b); box.expand(c);
            box = box.with_positive_zeros();  // parallel merges below stay order-independent
            boxes[i] = box;
            centroids[i] = box.center();
        }
    });
    refs.clear();
    refs.reserve(triangle_count);
    for (size_t i = 0; i < triangle_count; ++i)
        if (valid[i]) refs.push_back(static_cast<uint32_t>(i));
}

// Bounds and centroid bounds of the triangles in refs.
RootBounds root_bounds(const std::vector<BBox>& boxes, const std::vector<Vec3f>& centroids,
                       const std::vector<uint32_t>& refs) {
    const uint32_t n = static_cast<uint32_t>(refs.size());
    return tbb::parallel_reduce(
        tbb::blocked_range<uint32_t>(0, n, kGrainSize), RootBounds{},
        [&](const tbb::blocked_range<uint32_t>& r, RootBounds acc) {
            for (uint32_t i = r.begin(); i < r.end(); ++i) {
                acc.box.expand(boxes[refs[i]]);
                acc.cbox.expand(centroids[refs[i]]);
            }
            return acc;
        },
        [](RootBounds a, const RootBounds& b) {
            a.box.expand(b.box);
            a.cbox.expand(b.cbox);
            return a;
        });
}

// The builder's tree renumbered depth-first with siblings adjacent: root at
// 0, pairs at (1,2), (3,4), ...; counts depth and leaves into `stats`.
void flatten(const std::vector<TempNode>& temp, std::vector<BvhNode>& nodes, BvhBuildStats& stats) {
    nodes.reserve(temp.size());
    nodes.emplace_back();
    struct Item { uint32_t temp, final_index; int depth; };
    std::vector<Item> stack{{0, 0, 1}};
    while (!stack.empty()) {
        const Item it = stack.back();
        stack.pop_back();
        const TempNode& t = temp[it.temp];
        BvhNode& out = nodes[it.final_index];
        out.box = t.box;
        stats.depth = std::max(stats.depth, it.depth);
        if (t.count > 0) {
            out.index = t.begin;
            out.count = t.count;
            ++stats.leaves;
        } else {
            const uint32_t pair = static_cast<uint32_t>(nodes.size());
            nodes[it.final_index].index = pair;  // `out` may dangle after emplace_back
            nodes[it.final_index].count = 0;
            nodes.emplace_back();
            nodes.emplace_back();
            stack.push_back({t.right, pair + 1, it.depth + 1});
            stack.push_back({t.left, pair, it.depth + 1});
        }
    }
}

}  // namespace

void build_box_tree(const std::vector<BBox>& boxes, const BvhBuildOptions& opt, std::vector<BvhNode>& nodes,
                    std::vector<uint32_t>& order) {
    nodes.clear();
    order.clear();
    std::vector<Vec3f> centroids(boxes.size());
    std::vector<uint32_t> refs;
    refs.reserve(boxes.size());
    for (size_t i = 0; i < boxes.size(); ++i) {
        centroids[i] = boxes[i].center();
        if (!boxes[i].empty() && is_finite(boxes[i].lo) && is_finite(boxes[i].hi)) refs.push_back(uint32_t(i));
    }
    const uint32_t n = static_cast<uint32_t>(refs.size());
    if (n == 0) return;
    const RootBounds root = root_bounds(boxes, centroids, refs);
    std::vector<TempNode> temp(2 * static_cast<size_t>(n) - 1);
    Builder builder(boxes.data(), centroids.data(), refs.data(), temp.data(), opt);
    builder.build(0, 0, n, root.box, root.cbox, 0);
    BvhBuildStats stats;
    flatten(temp, nodes, stats);
    order = std::move(refs);
}

void Bvh::build(const Scene& scene, const BvhBuildOptions& opt) {
    build_from(scene.vertices.data(), scene.vertices.size() / 3, opt);
}

void Bvh::build(const std::vector<Vec3f>& triangle_vertices, const BvhBuildOptions& opt) {
    build_from(triangle_vertices.data(), triangle_vertices.size() / 3, opt);
}

void Bvh::build_from(const Vec3f* verts, size_t triangle_count, const BvhBuildOptions& opt) {
    const auto start = std::chrono::steady_clock::now();
    if (opt.width != 2 && opt.width != 4 && opt.width != 8)
        throw std::invalid_argument("BvhBuildOptions::width must be 2, 4 or 8, got " + std::to_string(opt.width));
    nodes_.clear();
    prim_order_.clear();
    wide_.clear();
    packs_.clear();
    wide4_.clear();
    wide4_binary_.clear();
    width_ = opt.width;
    stats_ = {};

    std::vector<BBox> boxes;
    std::vector<Vec3f> centroids;
    std::vector<uint32_t> refs;
    triangle_bounds(verts, triangle_count, boxes, centroids, refs);
    const uint32_t n = static_cast<uint32_t>(refs.size());

    if (n > 0 && opt.spatial_split_budget > 0.0f) {
        build_spatial_bvh(verts, refs, opt, nodes_, prim_order_, stats_);
        build_traversal_layout(verts, opt.optimal_collapse);
    } else if (n > 0) {
        const RootBounds root = root_bounds(boxes, centroids, refs);
        std::vector<TempNode> temp(2 * static_cast<size_t>(n) - 1);
        Builder builder(boxes.data(), centroids.data(), refs.data(), temp.data(), opt);
        builder.build(0, 0, n, root.box, root.cbox, 0);
        flatten(temp, nodes_, stats_);
        prim_order_ = std::move(refs);
        stats_.references = prim_order_.size();
        build_traversal_layout(verts, opt.optimal_collapse);
    }

    stats_.nodes = nodes_.size();
    // Everything the BVH keeps: the portable tree, the leaf order, and the
    // traversal layout (wide nodes + triangle packs), which is what rays touch.
    stats_.bytes = nodes_.size() * sizeof(BvhNode) + prim_order_.size() * sizeof(uint32_t) +
                   wide_.size() * sizeof(WideNode8) + wide4_.size() * sizeof(WideNode4) +
                   packs_.size() * sizeof(TrianglePack4);
    stats_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace coherent
