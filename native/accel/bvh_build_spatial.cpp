// Spatial-split BVH builder (SBVH, Stich et al. 2009); see bvh_build_spatial.h.
//
// Each node chooses the cheapest of three options by the SAH:
//  - a leaf (at most max_leaf_size references);
//  - an object split: binned on reference centroids, as in bvh_build.cpp;
//  - a spatial split: a plane chosen among `kSpatialBins - 1` evenly spaced
//    planes of the node box; references that straddle it are cut in two, each
//    side keeping the bounds of the triangle's part on its side.
// Spatial splits are only tried where the object split's children overlap
// by more than `spatial_split_alpha` of the root area (Stich's alpha: deep
// nodes with small overlap gain little) and that overlap is thicker than
// spatial_split_min_thickness of the node along the split axis (references
// thin next to the node leave a spatial split little to trim), and only while the node's share of
// the duplication budget lasts. The budget (spatial_split_budget x the number
// of triangles extra references in all) is handed down in proportion to the
// children's sizes, so the output does not depend on scheduling.
//
// Conservativeness: the bounds of a cut triangle are computed in double from
// the float vertices; the cut points are then rounded outward by one float
// ulp (more than covers the double rounding), and the box is clamped to the
// split plane, which is exact. So a reference box always contains the part
// of its triangle that lies in the reference's region.
#include "bvh_build_spatial.h"

#include "box4.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>

#include <tbb/blocked_range.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_reduce.h>

namespace coherent {

namespace {

constexpr int kMaxObjectBins = 64;
constexpr int kSpatialBins = 32;
constexpr size_t kParallelSubtreeSize = 4096;
constexpr size_t kParallelBinningSize = 1 << 15;
constexpr size_t kGrainSize = 1 << 11;
// As in bvh_build.cpp: deeper than this only median splits, which halve the
// set, keep the depth within the traversal stack.
constexpr int kForceMedianDepth = 48;

// A reference: the part of triangle `tri` inside `box`.
struct Ref {
    BBox box;
    uint32_t tri;
};

struct BuildNode {
    BBox box;
    std::unique_ptr<BuildNode> left, right;  // both null for a leaf
    std::vector<uint32_t> tris;              // leaf triangles
};

// Bounds in double of points computed in double.
struct BBoxD {
    double lo[3] = {kInf, kInf, kInf}, hi[3] = {-kInf, -kInf, -kInf};
    void expand(const double p[3]) {
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], p[a]);
            hi[a] = std::max(hi[a], p[a]);
        }
    }
};

// The next float below / above a finite float (std::nextafter without the
// library call: the spatial binning calls this for every cut).
float next_down(float x) {
    if (x == 0.0f) return -0x1p-149f;
    uint32_t b;
    std::memcpy(&b, &x, 4);
    b += x > 0.0f ? -1 : 1;
    std::memcpy(&x, &b, 4);
    return x;
}
float next_up(float x) { return -next_down(-x); }

BBox intersect_boxes(const BBox& a, const BBox& b) {
    BBox r;
    r.lo = max(a.lo, b.lo);
    r.hi = min(a.hi, b.hi);
    return r;
}

// Cuts reference `box` of triangle `v` at the plane x[axis] = pos: conservative
// bounds of the triangle's part with x[axis] <= pos (left) and >= pos (right),
// each within `box`. A side without any part gets an empty box.
void split_reference(const Vec3f* v, const BBox& box, int axis, float pos, BBox& left, BBox& right) {
    BBox lv, rv;  // exact float points: the vertices on each side
    BBoxD lc;     // cut points, which lie on both sides
    for (int i = 0; i < 3; ++i) {
        const Vec3f& a = v[i];
        const Vec3f& b = v[i == 2 ? 0 : i + 1];
        if (a[axis] <= pos) lv.expand(a);
        if (a[axis] >= pos) rv.expand(a);
        if ((a[axis] < pos && b[axis] > pos) || (a[axis] > pos && b[axis] < pos)) {
            const double t = (double(pos) - a[axis]) / (double(b[axis]) - a[axis]);
            double q[3];
            for (int k = 0; k < 3; ++k) q[k] = a[k] + t * (double(b[k]) - a[k]);
            q[axis] = pos;
            lc.expand(q);
        }
    }
    BBox cut;
    if (lc.lo[0] <= lc.hi[0]) {
        for (int k = 0; k < 3; ++k) {
            cut.lo[k] = next_down(static_cast<float>(lc.lo[k]));
            cut.hi[k] = next_up(static_cast<float>(lc.hi[k]));
        }
        lv.expand(cut);
        rv.expand(cut);
    }
    left = intersect_boxes(lv, box);
    right = intersect_boxes(rv, box);
    left.hi[axis] = std::min(left.hi[axis], pos);
    right.lo[axis] = std::max(right.lo[axis], pos);
    left = left.with_positive_zeros();  // as the input references (build_spatial_bvh)
    right = right.with_positive_zeros();
}

// Evenly spaced planes over [lo, hi] on one axis: planes[1 .. bins-1] (plane
// i separates bin i-1 from bin i), non-decreasing even when rounding
// collapses some of them.
struct SpatialPlanes {
    float lo = 0.0f, scale = 0.0f;
    float planes[kSpatialBins + 1];

    SpatialPlanes(float lo_, float hi_) : lo(lo_) {
        const float e = hi_ - lo_;
        scale = e > 0.0f && std::isfinite(kSpatialBins / e) ? kSpatialBins / e : 0.0f;
        planes[0] = -kInf;
        planes[kSpatialBins] = kInf;
        for (int i = 1; i < kSpatialBins; ++i)
            planes[i] = std::max(planes[i - 1], lo_ + e * (static_cast<float>(i) / kSpatialBins));
    }
    bool usable() const { return scale > 0.0f; }
    int guess(float x) const { return std::clamp(static_cast<int>((x - lo) * scale), 0, kSpatialBins - 1); }
    // Largest bin i with planes[i] <= x.
    int first_bin(float x) const {
        int i = guess(x);
        while (i > 0 && planes[i] > x) --i;
        while (i + 1 < kSpatialBins && planes[i + 1] <= x) ++i;
        return i;
    }
    // Smallest bin i with x <= planes[i + 1].
    int last_bin(float x) const {
        int i = guess(x);
        while (i + 1 < kSpatialBins && x > planes[i + 1]) ++i;
        while (i > 0 && x <= planes[i]) --i;
        return i;
    }
    // Bins [b0, b1] that a reference spans along the axis.
    void span(const BBox& b, int axis, int& b0, int& b1) const {
        b0 = first_bin(b.lo[axis]);
        b1 = std::max(b0, last_bin(b.hi[axis]));
    }
};

// Only bins [0, nbins) of each axis are initialised: most nodes are small,
// and clearing all kMaxObjectBins for them cost more than binning them.
struct ObjectBins {
    int nbins;
    Box4 box[3][kMaxObjectBins];
    uint32_t count[3][kMaxObjectBins];

    explicit ObjectBins(int bins) : nbins(bins) {
        for (int a = 0; a < 3; ++a)
            for (int i = 0; i < nbins; ++i) {
                box[a][i] = Box4::empty();
                count[a][i] = 0;
            }
    }
    void merge(const ObjectBins& o) {
        for (int a = 0; a < 3; ++a)
            for (int i = 0; i < nbins; ++i) {
                box[a][i].expand(o.box[a][i]);
                count[a][i] += o.count[a][i];
            }
    }
};

struct SpatialBins {
    BBox box[kSpatialBins];
    uint32_t enter[kSpatialBins] = {}, exit[kSpatialBins] = {};
    void merge(const SpatialBins& o) {
        for (int i = 0; i < kSpatialBins; ++i) {
            box[i].expand(o.box[i]);
            enter[i] += o.enter[i];
            exit[i] += o.exit[i];
        }
    }
};

// Binning over [0, n) into `bins` (which holds empty bins on entry): in
// parallel above kParallelBinningSize. The merges are exact (min, max,
// integer sums), so the result does not depend on the split of the range.
// Bins are several kilobytes: the serial path, taken by almost every node,
// bins in place rather than copy them.
template <class Bins, class BinRange, class Merge>
void reduce_bins(size_t n, Bins& bins, BinRange bin_range, Merge merge) {
    if (n < kParallelBinningSize) {
        bin_range(bins, 0, n);
        return;
    }
    bins = tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, n, kGrainSize), bins,
        [&](const tbb::blocked_range<size_t>& r, Bins acc) {
            bin_range(acc, r.begin(), r.end());
            return acc;
        },
        [&](Bins a, const Bins& b) {
            merge(a, b);
            return a;
        });
}

struct Candidate {
    int axis = -1;
    int bin = 0;  // object: left holds bins [0, bin]; spatial: the plane is planes[bin + 1]
    float cost = kInf;  // sum over children of area x SAH blocks
    BBox lbox, rbox;
    size_t lcount = 0;  // object splits: references on the left
};

class SpatialBuilder {
public:
    SpatialBuilder(const Vec3f* verts, const BvhBuildOptions& opt, float root_area)
        : verts_(verts), opt_(opt) {
        bins_ = std::clamp(opt.bins, 2, kMaxObjectBins);
        max_leaf_ = static_cast<uint32_t>(std::max(1, opt.max_leaf_size));
        simd_width_ = static_cast<uint32_t>(std::max(1, opt.leaf_simd_width));
        min_overlap_ = opt.spatial_split_alpha * root_area;
    }

    // Consumes `refs`.
    std::unique_ptr<BuildNode> build(std::vector<Ref>& refs, size_t budget, int depth) {
        auto node = std::make_unique<BuildNode>();
        Box4 box4 = Box4::empty(), cbox4 = Box4::empty();
        for (const Ref& r : refs) {
            const Box4 b = Box4::load(r.box);
            box4.expand(b);
            cbox4.expand_point(b.center());
        }
        const BBox box = box4.to_bbox(), cbox = cbox4.to_bbox();
        node->box = box;
        const size_t n = refs.size();
        if (n <= 1) return make_leaf(std::move(node), refs);

        Candidate object, spatial;
        if (depth < kForceMedianDepth) {
            object = find_object_split(refs, cbox);
            bool try_spatial = budget > 0;
            if (try_spatial && object.axis >= 0) {
                const BBox overlap = intersect_boxes(object.lbox, object.rbox);
                const int a = object.axis;
                try_spatial = !overlap.empty() && overlap.half_area() > min_overlap_ &&
                              overlap.extent()[a] > opt_.spatial_split_min_thickness * box.extent()[a];
            }
            if (try_spatial) spatial = find_spatial_split(refs, box, budget);
        }
        const bool use_spatial = spatial.axis >= 0 && spatial.cost < object.cost;
        const Candidate& best = use_spatial ? spatial : object;

        const float leaf_cost = opt_.intersection_cost * blocks(n);
        if (best.axis >= 0) {
            const float split_cost = opt_.traversal_cost + opt_.intersection_cost * best.cost / box.half_area();
            if (n <= max_leaf_ && leaf_cost <= split_cost) return make_leaf(std::move(node), refs);
        } else if (n <= max_leaf_) {
            return make_leaf(std::move(node), refs);
        }

        std::vector<Ref> left, right;
        bool done = false;
        if (use_spatial) {
            partition_spatial(refs, box, spatial, left, right);
            // Rounding can leave a side without references; the budget check
            // guards against cut pieces that the bins did not foresee.
            done = !left.empty() && !right.empty() && left.size() < n && right.size() < n &&
                   left.size() + right.size() - n <= budget;
            if (!done) {
                left.clear();
                right.clear();
            }
        }
        if (!done && object.axis >= 0) {
            const BinMapping map(cbox, bins_);
            left.reserve(object.lcount);
            right.reserve(n - object.lcount);
            for (const Ref& r : refs) (map.index(r.box.center(), object.axis) <= object.bin ? left : right).push_back(r);
            done = !left.empty() && !right.empty();
            if (!done) {
                left.clear();
                right.clear();
            }
        }
        if (!done) median_split(refs, cbox, left, right);

        const size_t extra = left.size() + right.size() - n;
        const size_t remaining = budget - extra;
        const size_t lbudget = remaining * left.size() / (left.size() + right.size());
        const size_t rbudget = remaining - lbudget;
        std::vector<Ref>().swap(refs);  // release before recursing

        if (n > kParallelSubtreeSize) {
            tbb::parallel_invoke([&] { node->left = build(left, lbudget, depth + 1); },
                                 [&] { node->right = build(right, rbudget, depth + 1); });
        } else {
            node->left = build(left, lbudget, depth + 1);
            node->right = build(right, rbudget, depth + 1);
        }
        return node;
    }

private:
    // Same mapping as bvh_build.cpp: centroids to bins.
    struct BinMapping {
        Vec3f lo, scale;
        int nbins;
        BinMapping(const BBox& cbox, int bins) : lo(cbox.lo), nbins(bins) {
            const Vec3f e = cbox.extent();
            for (int a = 0; a < 3; ++a) {
                const float s = e[a] > 0.0f ? static_cast<float>(bins) / e[a] : 0.0f;
                scale[a] = std::isfinite(s) ? s : 0.0f;
            }
        }
        int index(const Vec3f& c, int axis) const {
            return std::clamp(static_cast<int>((c[axis] - lo[axis]) * scale[axis]), 0, nbins - 1);
        }
    };

    float blocks(size_t n) const { return static_cast<float>((n + simd_width_ - 1) / simd_width_); }

    std::unique_ptr<BuildNode> make_leaf(std::unique_ptr<BuildNode> node, std::vector<Ref>& refs) const {
        node->tris.reserve(refs.size());
        for (const Ref& r : refs) node->tris.push_back(r.tri);
        std::vector<Ref>().swap(refs);
        return node;
    }

    // Sweeps `nbins` bins whose boxes box_of(i) gives; left counts come from
    // lcount_of, right counts from rcount_of (the same for object splits).
    template <class BoxOf, class LeftCount, class RightCount>
    void sweep(BoxOf box_of, int nbins, LeftCount lcount_of, RightCount rcount_of, int axis, size_t n,
               bool spatial, Candidate& best) const {
        float rarea[kMaxObjectBins];
        size_t rcount[kMaxObjectBins];
        BBox racc;
        size_t rc = 0;
        for (int i = nbins - 1; i > 0; --i) {
            racc.expand(box_of(i));
            rc += rcount_of(i);
            rarea[i - 1] = racc.half_area();
            rcount[i - 1] = rc;
        }
        BBox lacc;
        size_t lc = 0;
        for (int i = 0; i < nbins - 1; ++i) {
            lacc.expand(box_of(i));
            lc += lcount_of(i);
            if (lc == 0 || rcount[i] == 0) continue;
            if (spatial && (lc >= n || rcount[i] >= n)) continue;  // each side must shrink
            const float cost = blocks(lc) * lacc.half_area() + blocks(rcount[i]) * rarea[i];
            if (cost < best.cost) {
                best.cost = cost;
                best.axis = axis;
                best.bin = i;
            }
        }
    }

    Candidate find_object_split(const std::vector<Ref>& refs, const BBox& cbox) const {
        Candidate best;
        const BinMapping map(cbox, bins_);
        if (map.scale[0] == 0.0f && map.scale[1] == 0.0f && map.scale[2] == 0.0f) return best;
        const BinIndex4 index(map.lo, map.scale, bins_);
        ObjectBins bins(bins_);
        reduce_bins(
            refs.size(), bins,
            [&](ObjectBins& b, size_t begin, size_t end) {
                for (size_t i = begin; i < end; ++i) {
                    const Box4 r = Box4::load(refs[i].box);
                    int32_t k[4];
                    index.bins(r.center(), k);
                    for (int a = 0; a < 3; ++a) {
                        b.box[a][k[a]].expand(r);
                        ++b.count[a][k[a]];
                    }
                }
            },
            [](ObjectBins& a, const ObjectBins& b) { a.merge(b); });
        for (int a = 0; a < 3; ++a) {
            if (map.scale[a] == 0.0f) continue;
            auto box = [&](int i) { return bins.box[a][i].to_bbox(); };
            auto count = [&](int i) { return static_cast<size_t>(bins.count[a][i]); };
            sweep(box, bins_, count, count, a, refs.size(), false, best);
        }
        if (best.axis >= 0)
            for (int i = 0; i < bins_; ++i) {
                const BBox b = bins.box[best.axis][i].to_bbox();
                if (i <= best.bin) {
                    best.lbox.expand(b);
                    best.lcount += bins.count[best.axis][i];
                } else {
                    best.rbox.expand(b);
                }
            }
        return best;
    }

    const Vec3f* tri(uint32_t t) const { return verts_ + 3 * size_t(t); }

    Candidate find_spatial_split(const std::vector<Ref>& refs, const BBox& box, size_t budget) const {
        Candidate best;
        for (int a = 0; a < 3; ++a) {
            const SpatialPlanes planes(box.lo[a], box.hi[a]);
            if (!planes.usable()) continue;
            SpatialBins bins;
            reduce_bins(
                refs.size(), bins,
                [&](SpatialBins& b, size_t begin, size_t end) {
                    for (size_t i = begin; i < end; ++i) {
                        const Ref& r = refs[i];
                        int b0, b1;
                        planes.span(r.box, a, b0, b1);
                        ++b.enter[b0];
                        ++b.exit[b1];
                        BBox rest = r.box;
                        for (int k = b0; k < b1; ++k) {
                            BBox piece, next;
                            split_reference(tri(r.tri), rest, a, planes.planes[k + 1], piece, next);
                            b.box[k].expand(piece);  // an empty piece leaves the bin as it was
                            rest = next;
                        }
                        b.box[b1].expand(rest);
                    }
                },
                [](SpatialBins& x, const SpatialBins& y) { x.merge(y); });
            Candidate c;
            sweep([&](int i) { return bins.box[i]; }, kSpatialBins, [&](int i) { return static_cast<size_t>(bins.enter[i]); },
                  [&](int i) { return static_cast<size_t>(bins.exit[i]); }, a, refs.size(), true, c);
            if (c.axis < 0 || c.cost >= best.cost) continue;
            // Extra references this plane would create (the straddlers).
            size_t lc = 0, rc = 0;
            for (int i = 0; i < kSpatialBins; ++i) {
                if (i <= c.bin) lc += bins.enter[i];
                else rc += bins.exit[i];
            }
            if (lc + rc - refs.size() > budget) continue;
            best = c;
        }
        return best;
    }

    void partition_spatial(const std::vector<Ref>& refs, const BBox& box, const Candidate& c, std::vector<Ref>& left,
                           std::vector<Ref>& right) const {
        const SpatialPlanes planes(box.lo[c.axis], box.hi[c.axis]);
        const float pos = planes.planes[c.bin + 1];
        for (const Ref& r : refs) {
            int b0, b1;
            planes.span(r.box, c.axis, b0, b1);
            if (b1 <= c.bin) {
                left.push_back(r);
            } else if (b0 > c.bin) {
                right.push_back(r);
            } else {
                BBox lb, rb;
                split_reference(tri(r.tri), r.box, c.axis, pos, lb, rb);
                if (!lb.empty()) left.push_back({lb, r.tri});
                if (!rb.empty()) right.push_back({rb, r.tri});
            }
        }
    }

    // Object median along the widest centroid axis; ties by triangle, then by
    // box, keep it deterministic.
    static void median_split(std::vector<Ref>& refs, const BBox& cbox, std::vector<Ref>& left,
                             std::vector<Ref>& right) {
        const int axis = max_dimension(cbox.extent());
        const size_t mid = refs.size() / 2;
        std::nth_element(refs.begin(), refs.begin() + mid, refs.end(), [&](const Ref& x, const Ref& y) {
            const float cx = x.box.center()[axis], cy = y.box.center()[axis];
            if (cx != cy) return cx < cy;
            if (x.tri != y.tri) return x.tri < y.tri;
            return x.box.lo[axis] < y.box.lo[axis];
        });
        left.assign(refs.begin(), refs.begin() + mid);
        right.assign(refs.begin() + mid, refs.end());
    }

    const Vec3f* verts_;
    BvhBuildOptions opt_;
    int bins_ = 16;
    uint32_t max_leaf_ = 4;
    uint32_t simd_width_ = 4;
    float min_overlap_ = 0.0f;
};

}  // namespace

void build_spatial_bvh(const Vec3f* verts, const std::vector<uint32_t>& tris, const BvhBuildOptions& opt,
                       std::vector<BvhNode>& nodes, std::vector<uint32_t>& prim_order, BvhBuildStats& stats) {
    nodes.clear();
    prim_order.clear();
    if (tris.empty()) return;
    std::vector<Ref> refs(tris.size());
    BBox root;
    for (size_t i = 0; i < tris.size(); ++i) {
        BBox b;
        for (int k = 0; k < 3; ++k) b.expand(verts[3 * size_t(tris[i]) + k]);
        b = b.with_positive_zeros();  // the parallel bin merges stay order-independent
        refs[i] = {b, tris[i]};
        root.expand(b);
    }
    const double fraction = std::max(0.0, static_cast<double>(opt.spatial_split_budget));
    const size_t budget = static_cast<size_t>(fraction * static_cast<double>(tris.size()));
    SpatialBuilder builder(verts, opt, root.half_area());
    std::unique_ptr<BuildNode> tree = builder.build(refs, budget, 0);

    // Flatten depth-first with siblings adjacent: root at 0, pairs at (1,2), (3,4), ...
    nodes.emplace_back();
    struct Item {
        const BuildNode* node;
        uint32_t index;
        int depth;
    };
    std::vector<Item> stack{{tree.get(), 0, 1}};
    while (!stack.empty()) {
        const Item it = stack.back();
        stack.pop_back();
        stats.depth = std::max(stats.depth, it.depth);
        nodes[it.index].box = it.node->box;
        if (!it.node->left) {
            nodes[it.index].index = static_cast<uint32_t>(prim_order.size());
            nodes[it.index].count = static_cast<uint32_t>(it.node->tris.size());
            prim_order.insert(prim_order.end(), it.node->tris.begin(), it.node->tris.end());
            ++stats.leaves;
        } else {
            const uint32_t pair = static_cast<uint32_t>(nodes.size());
            nodes[it.index].index = pair;
            nodes[it.index].count = 0;
            nodes.emplace_back();
            nodes.emplace_back();
            stack.push_back({it.node->right.get(), pair + 1, it.depth + 1});
            stack.push_back({it.node->left.get(), pair, it.depth + 1});
        }
    }
    stats.references = prim_order.size();
}

}  // namespace coherent
