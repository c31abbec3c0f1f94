// MotionBvh: binned SAH build over swept boxes, scalar robust traversal.
// Moving geometry is usually a small part of a scene, so this favours
// simplicity over speed: one ray at a time, binary nodes.
#include "motion_bvh.h"

#include <algorithm>
#include <cmath>

#include "../core/float_bounds.h"
#include "triangle.h"

namespace coherent {

namespace {

constexpr int kBins = 12;
constexpr uint32_t kMaxLeaf = 4;

struct BuildRef {
    BBox box;
    Vec3f centroid;
    uint32_t tri;  // index into the build's triangle list
};

int widest_axis(const BBox& b) {
    const Vec3f e = b.extent();
    return e.x >= e.y && e.x >= e.z ? 0 : (e.y >= e.z ? 1 : 2);
}

// Binned SAH split of refs[begin, end) (bounds `box`, centroid bounds
// `cbox`, more than kMaxLeaf refs) along the centroids' widest axis: sets
// `axis` (left at -1 when the centroids do not spread) and the position
// `pos` (refs with centroid < pos go left).
void find_binned_split(const std::vector<BuildRef>& refs, uint32_t begin, uint32_t end, const BBox& box,
                       const BBox& cbox, int& split_axis, float& split_pos) {
    const uint32_t n = end - begin;
    const int axis = widest_axis(cbox);
    const Vec3f e = cbox.extent();
    if (!(e[axis] > 0.0f)) return;
    BBox bin_box[kBins];
    uint32_t bin_count[kBins] = {};
    const float scale = float(kBins) / e[axis];
    auto bin_of = [&](const BuildRef& r) {
        return std::min(kBins - 1, int((r.centroid[axis] - cbox.lo[axis]) * scale));
    };
    for (uint32_t i = begin; i < end; ++i) {
        const int b = bin_of(refs[i]);
        bin_box[b].expand(refs[i].box);
        ++bin_count[b];
    }
    float best = float(n) * box.half_area();  // cost of a leaf (with n > kMaxLeaf, split if any better)
    BBox right_box[kBins];
    uint32_t right_count[kBins] = {};
    for (int b = kBins - 1; b > 0; --b) {
        right_box[b] = b + 1 < kBins ? right_box[b + 1] : BBox{};
        right_box[b].expand(bin_box[b]);
        right_count[b] = (b + 1 < kBins ? right_count[b + 1] : 0) + bin_count[b];
    }
    BBox left;
    uint32_t left_count = 0;
    for (int b = 1; b < kBins; ++b) {
        left.expand(bin_box[b - 1]);
        left_count += bin_count[b - 1];
        if (left_count == 0 || right_count[b] == 0) continue;
        const float cost = box.half_area() * 0.125f + float(left_count) * left.half_area() +
                           float(right_count[b]) * right_box[b].half_area();
        if (cost < best || split_axis < 0) {
            best = cost;
            split_axis = axis;
            split_pos = cbox.lo[axis] + float(b) / scale;
        }
    }
}

}  // namespace

void MotionBvh::build(const std::vector<Vec3f>& open, const std::vector<Vec3f>& close,
                      const std::vector<uint32_t>& moving) {
    nodes_.clear();
    tris_.clear();
    std::vector<BuildRef> refs;
    refs.reserve(moving.size());
    std::vector<Tri> input;
    input.reserve(moving.size());
    for (uint32_t t : moving) {
        Tri tri;
        BBox box;
        bool finite = true;
        for (int k = 0; k < 3; ++k) {
            tri.open[k] = open[3 * size_t(t) + k];
            tri.close[k] = close[3 * size_t(t) + k];
            finite = finite && is_finite(tri.open[k]) && is_finite(tri.close[k]);
            box.expand(tri.open[k]);
            box.expand(tri.close[k]);
        }
        if (!finite) continue;  // never hit, as in the static BVH
        tri.prim = t;
        refs.push_back({box, box.center(), uint32_t(input.size())});
        input.push_back(tri);
    }
    if (refs.empty()) return;

    // Depth bound: the traversal stack holds one entry per level, so past
    // kMedianDepth levels nodes split at the median (log depth from there).
    constexpr int kMedianDepth = 48;
    struct Task {
        uint32_t node, begin, end;
        int depth;
    };
    nodes_.push_back({});
    std::vector<Task> stack{{0, 0, uint32_t(refs.size()), 0}};
    while (!stack.empty()) {
        const Task task = stack.back();
        stack.pop_back();
        BBox box, cbox;
        for (uint32_t i = task.begin; i < task.end; ++i) {
            box.expand(refs[i].box);
            cbox.expand(refs[i].centroid);
        }
        nodes_[task.node].box = box;
        const uint32_t n = task.end - task.begin;
        // Binned SAH over the centroid bounds' widest axis.
        int split_axis = -1;
        float split_pos = 0.0f;
        if (n > kMaxLeaf && task.depth < kMedianDepth)
            find_binned_split(refs, task.begin, task.end, box, cbox, split_axis, split_pos);
        uint32_t mid = task.begin;
        if (split_axis >= 0) {
            mid = uint32_t(std::partition(refs.begin() + task.begin, refs.begin() + task.end,
                                          [&](const BuildRef& r) { return r.centroid[split_axis] < split_pos; }) -
                           refs.begin());
        }
        if (split_axis < 0 || mid == task.begin || mid == task.end) {
            if (n > kMaxLeaf) {  // deep, or all centroids equal: split at the median
                mid = task.begin + n / 2;
                const int axis = widest_axis(cbox);
                std::nth_element(refs.begin() + task.begin, refs.begin() + mid, refs.begin() + task.end,
                                 [&](const BuildRef& a, const BuildRef& b) { return a.centroid[axis] < b.centroid[axis]; });
            } else {
                nodes_[task.node].index = uint32_t(tris_.size());
                nodes_[task.node].count = n;
                for (uint32_t i = task.begin; i < task.end; ++i) tris_.push_back(input[refs[i].tri]);
                continue;
            }
        }
        const uint32_t left_node = uint32_t(nodes_.size());
        nodes_.push_back({});
        nodes_.push_back({});
        nodes_[task.node].index = left_node;
        nodes_[task.node].count = 0;
        stack.push_back({left_node + 1, mid, task.end, task.depth + 1});
        stack.push_back({left_node, task.begin, mid, task.depth + 1});
    }
}

template <bool kAnyHit>
bool MotionBvh::traverse(const Ray& ray, float tau, Hit* hit, TraversalCounters* counters) const {
    // Rays are counted by the static kernel that traced them first.
    if (nodes_.empty()) return false;
    if (!is_finite(ray.o) || !is_finite(ray.d) || (ray.d.x == 0.0f && ray.d.y == 0.0f && ray.d.z == 0.0f) ||
        std::isnan(ray.tmin) || std::isnan(ray.tmax) || !(ray.tmin <= ray.tmax) || !std::isfinite(tau))
        return false;
    const Vec3f inv{1.0f / ray.d.x, 1.0f / ray.d.y, 1.0f / ray.d.z};
    const WatertightRay wr(ray.o, ray.d, inv);
    float best_t = kAnyHit ? ray.tmax : std::min(ray.tmax, hit->t);
    uint32_t best_prim = kAnyHit ? kInvalidPrim : hit->prim;
    bool replaced = false;
    // Robust slab test (Ize 2013): exact products, NaN slabs (0 * inf) ignored.
    auto enters = [&](const BBox& b) {
        if (counters) ++counters->box_tests;
        float t0 = ray.tmin, t1 = best_t;
        for (int a = 0; a < 3; ++a) {
            float tn = (b.lo[a] - ray.o[a]) * inv[a];
            float tf = (b.hi[a] - ray.o[a]) * inv[a];
            if (tn > tf) std::swap(tn, tf);
            if (tn > t0) t0 = tn;           // false for NaN: slab ignored
            if (tf * kFarScale < t1) t1 = tf * kFarScale;
        }
        // Same relative slack as the static kernels, so ties at shared edges
        // reach the triangle test.
        return t0 <= t1 + std::fabs(t1) * 0x1p-12f;
    };
    uint32_t stack[128];
    int sp = 0;
    uint32_t node = 0;
    while (true) {
        const Node& n = nodes_[node];
        if (counters) ++counters->node_visits;
        if (enters(n.box)) {
            if (n.count == 0) {
                stack[sp++] = n.index + 1;
                node = n.index;
                continue;
            }
            for (uint32_t i = n.index; i < n.index + n.count; ++i) {
                const Tri& tri = tris_[i];
                if (counters) ++counters->triangle_tests;
                TriangleHit th;
                if (!intersect_triangle_watertight(wr, motion_vertex(tri.open[0], tri.close[0], tau),
                                                   motion_vertex(tri.open[1], tri.close[1], tau),
                                                   motion_vertex(tri.open[2], tri.close[2], tau), ray.tmin, best_t, th))
                    continue;
                if constexpr (kAnyHit) {
                    return true;
                } else if (th.t < best_t || (th.t == best_t && tri.prim < best_prim)) {
                    best_t = th.t;
                    best_prim = tri.prim;
                    *hit = Hit{th.t, th.u, th.v, tri.prim};
                    replaced = true;
                }
            }
        }
        if (sp == 0) break;
        node = stack[--sp];
    }
    return replaced;
}

bool MotionBvh::intersect(const Ray& ray, float tau, Hit& hit, TraversalCounters* counters) const {
    return traverse<false>(ray, tau, &hit, counters);
}

bool MotionBvh::occluded(const Ray& ray, float tau, TraversalCounters* counters) const {
    return traverse<true>(ray, tau, nullptr, counters);
}

}  // namespace coherent
