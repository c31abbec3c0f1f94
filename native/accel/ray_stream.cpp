// Breadth-first ray stream traversal (ray_stream.h) over the 8-wide layout.
//
// One slice (StreamOptions::slice_size consecutive rays) is traced by one
// thread with its own workspace:
//  - per ray: the box-test constants, the watertight-test constants, the
//    closest hit so far and its cull distance (the early-out array);
//  - a queue buffer used as a stack of regions: the queue of every pending
//    node is a contiguous run of (ray, entry distance) entries. Processing a
//    node copies its queue to scratch, pops its region and pushes one region
//    per entered child; children are pushed in decreasing order of their
//    rays' mean entry distance, so the nearest child is processed first (the
//    per-ray near-first order of single rays is impossible when rays share a
//    queue; the mean is the usual proxy). Memory is bounded by the queues
//    pending along one root-to-leaf path (at most slice_size entries per
//    sibling), not by a whole tree level.
// The paper processes the tree level by level (one GPU launch per level);
// depth-first over nodes with queues keeps the working set small and lets
// hits found in a near subtree cull rays before the far subtrees are opened.
#include "ray_stream.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "../core/inline.h"
#include "../core/simd.h"
#include "aligned_allocator.h"
#include "bvh.h"
#include "wide_kernel.h"

namespace coherent {

namespace {

using namespace kernel;
using simd::vfloat8;

// A ray waiting at a node: its index in the slice and its entry distance
// into the node's box (the box test's tnear).
struct QueueEntry {
    uint32_t ray;
    float t;
};

// A node with a queue: an interior wide node (count 0, ref = node index) or
// a leaf (count triangles from pack ref); its queue is entries[begin, end).
struct Job {
    uint32_t ref, count;
    size_t begin, end;
    int level;
};

// What a node visit reads of a queued ray, in one cache line: the box-test
// constants, the interval start and the early-out distance.
struct alignas(64) StreamRay {
    RayBoxConstants box;
    float tmin;
    float cull;  // early-out array: cull_distance(best.t); -inf once an any-hit ray is done
};
static_assert(sizeof(StreamRay) == 64);

struct Workspace {
    std::vector<StreamRay, AlignedAllocator<StreamRay, 64>> ray;
    std::vector<WatertightRay> tri;
    std::vector<Closest> best;
    std::vector<QueueEntry> entries;
    std::vector<Job> jobs;
    // Scratch of one node visit, one slot per queue entry.
    std::vector<uint32_t> scratch_ray;
    std::vector<uint8_t> scratch_mask;
    std::vector<float> scratch_entry;  // kWideWidth per queue entry

    void reserve(size_t n) {
        ray.resize(n);
        tri.resize(n);
        best.resize(n);
        scratch_ray.resize(n);
        scratch_mask.resize(n);
        scratch_entry.resize(n * kWideWidth);
    }
};

// The steps of trace_slice below are forced inline: as separate calls per
// node visit they cost any-hit streams of short queues ~3% (measured with
// wide-bench on the bunny, AO rays, slices of 256 and 1024).

// A slice of a stream: consecutive rays traced together with one set of
// queues, by one thread. Exactly one of hits (closest hit) and occluded (any
// hit) is set; both index like rays.
struct StreamSlice {
    const Ray* rays;
    size_t n;
    Hit* hits;
    uint8_t* occluded;
};

// Per-ray constants of the slice; valid rays form the root's queue.
COHERENT_ALWAYS_INLINE void start_slice(const StreamSlice& s, float magnitude, Workspace& ws,
                                                       StreamStats& st) {
    ws.reserve(s.n);
    ws.entries.clear();
    ws.jobs.clear();
    st.rays += s.n;
    st.slices += 1;
    for (size_t i = 0; i < s.n; ++i) {
        const Ray& r = s.rays[i];
        ws.best[i] = Closest{r.tmax};
        if (!valid_ray(r)) continue;  // never queued: hits nothing
        StreamRay& sr = ws.ray[i];
        sr.box = RayBoxConstants::from_ray(r, magnitude);
        sr.tmin = r.tmin;
        sr.cull = cull_distance(r.tmax);
        ws.tri[i] = WatertightRay(r.o, r.d, sr.box.inverse_direction());
        ws.entries.push_back({static_cast<uint32_t>(i), r.tmin});
    }
    if (!ws.entries.empty()) ws.jobs.push_back({0, 0, 0, ws.entries.size(), 0});
}

// Early out: a closer hit (or, for any hit, an occluder) was found since
// this entry was queued.
COHERENT_ALWAYS_INLINE bool culled(const QueueEntry& q, const StreamRay& sr, StreamStats& st) {
    if (q.t <= sr.cull) return false;
    ++st.culled;
    return true;
}

// Leaf: every queued ray against the leaf's triangles; pops the queue.
template <bool kAnyHit>
COHERENT_ALWAYS_INLINE void visit_leaf(const Job& job, int level, const TrianglePack4* packs,
                                                      uint8_t* occluded, Workspace& ws, StreamStats& st) {
    for (size_t e = job.begin; e < job.end; ++e) {
        const QueueEntry q = ws.entries[e];
        StreamRay& sr = ws.ray[q.ray];
        if (culled(q, sr, st)) continue;
        ++st.ray_node_visits;
        ++st.level_rays[level];
        st.triangle_tests += job.count;
        const TriRay tri(ws.tri[q.ray]);
        Closest& best = ws.best[q.ray];
        if (intersect_leaf<kAnyHit>(packs, job.ref, job.count, tri, sr.tmin, best)) {
            sr.cull = kAnyHit ? -kInf : cull_distance(best.t);
            if constexpr (kAnyHit) occluded[q.ray] = 1;
        }
    }
    ws.entries.resize(job.begin);
}

// Rays queued per child of an interior node, and the sum of their entry
// distances (for the near-first order).
struct ChildQueues {
    uint32_t rays[kWideWidth] = {};
    double entry_sum[kWideWidth] = {};
};

// Tests every ray queued at `job` against the node's children; the rays that
// enter any child go to scratch (ray, child mask, entry distances), counted
// in `children`. Returns how many rays were kept.
COHERENT_ALWAYS_INLINE size_t test_children(const Job& job, int level, const WideNode8& node,
                                                           Workspace& ws, StreamStats& st, ChildQueues& children) {
    const int slots = NodeTraits<WideNode8>::used_slots(node);
    size_t kept = 0;
    for (size_t e = job.begin; e < job.end; ++e) {
        const QueueEntry q = ws.entries[e];
        const StreamRay& sr = ws.ray[q.ray];
        if (culled(q, sr, st)) continue;
        vfloat8 entry;
        int mask;
        if (sr.box.fused) mask = intersect_node<true>(node, BoxRay<WideNode8>(sr.box), sr.tmin, sr.cull, entry);
        else mask = intersect_node<false>(node, BoxRay<WideNode8>(sr.box), sr.tmin, sr.cull, entry);
        ++st.ray_node_visits;
        ++st.level_rays[level];
        st.box_tests += static_cast<uint64_t>(slots);
        if (mask == 0) continue;
        ws.scratch_ray[kept] = q.ray;
        ws.scratch_mask[kept] = static_cast<uint8_t>(mask);
        float* entries = &ws.scratch_entry[kept * kWideWidth];
        storeu(entries, entry);
        for (int m = mask; m; m &= m - 1) {
            const int c = __builtin_ctz(m);
            ++children.rays[c];
            // Entry distances are finite for rays that enter a box in
            // practice; clamp so one infinite value cannot spoil the mean.
            children.entry_sum[c] += std::clamp(entries[c], -1e30f, 1e30f);
        }
        ++kept;
    }
    return kept;
}

// Replaces the node's queue region by one region per entered child, pushed
// farthest first (by mean entry distance) so that the nearest is processed
// next, then writes each of the `kept` scratch rays into the queue of every
// child it entered.
COHERENT_ALWAYS_INLINE void push_children(const Job& job, const WideNode8& node,
                                                         const ChildQueues& children, size_t kept, Workspace& ws) {
    ws.entries.resize(job.begin);
    auto mean_entry = [&](int c) { return children.entry_sum[c] / children.rays[c]; };
    // Insertion sort by decreasing mean (stable, as std::sort is on so few).
    int order[kWideWidth];
    int entered = 0;
    for (int c = 0; c < kWideWidth; ++c) {
        if (children.rays[c] == 0) continue;
        const double key = mean_entry(c);
        int j = entered++;
        for (; j > 0 && mean_entry(order[j - 1]) < key; --j) order[j] = order[j - 1];
        order[j] = c;
    }
    size_t fill[kWideWidth];
    size_t begin = ws.entries.size();
    for (int o = 0; o < entered; ++o) {
        const int c = order[o];
        fill[c] = begin;
        ws.jobs.push_back({node.ref[c], node.count[c], begin, begin + children.rays[c], job.level + 1});
        begin += children.rays[c];
    }
    ws.entries.resize(begin);
    QueueEntry* out = ws.entries.data();
    for (size_t i = 0; i < kept; ++i) {
        const float* entries = &ws.scratch_entry[i * kWideWidth];
        for (int m = ws.scratch_mask[i]; m; m &= m - 1) {
            const int c = __builtin_ctz(m);
            out[fill[c]++] = {ws.scratch_ray[i], entries[c]};
        }
    }
}

template <bool kAnyHit>
void trace_slice(const WideNode8* nodes, const TrianglePack4* packs, float magnitude, const StreamSlice& s,
                 Workspace& ws, StreamStats& st) {
    start_slice(s, magnitude, ws, st);
    while (!ws.jobs.empty()) {
        const Job job = ws.jobs.back();
        ws.jobs.pop_back();
        const int level = std::min(job.level, kStreamMaxLevels - 1);
        ++st.node_visits;
        ++st.level_visits[level];
        st.max_queue = std::max<uint64_t>(st.max_queue, job.end - job.begin);
        if (job.count != 0) {
            visit_leaf<kAnyHit>(job, level, packs, s.occluded, ws, st);
        } else {
            ChildQueues children;
            const size_t kept = test_children(job, level, nodes[job.ref], ws, st, children);
            push_children(job, nodes[job.ref], children, kept, ws);
        }
    }
    if constexpr (!kAnyHit) {
        for (size_t i = 0; i < s.n; ++i) {
            const Closest& b = ws.best[i];
            s.hits[i] = b.prim == kInvalidPrim ? Hit{} : Hit{b.t, b.u, b.v, b.prim};
        }
    }
}

template <bool kAnyHit>
void trace_stream(const Bvh& bvh, const Ray* rays, size_t n, Hit* hits, uint8_t* occluded, StreamStats* stats,
                  const StreamOptions& options) {
    if (stats) *stats = StreamStats{};
    if constexpr (kAnyHit) std::fill(occluded, occluded + n, uint8_t(0));
    else std::fill(hits, hits + n, Hit{});
    if (n == 0) return;
    if (bvh.empty()) {
        if (stats) stats->rays = n;
        return;
    }
    const BBox root = bvh.bounds();
    const float magnitude = std::max(max_component(abs(root.lo)), max_component(abs(root.hi)));
    const size_t slice_size = options.slice_size == 0 ? n : options.slice_size;
    const size_t slices = (n + slice_size - 1) / slice_size;
    const WideNode8* nodes = bvh.wide_nodes();
    const TrianglePack4* packs = bvh.triangle_packs();

    auto run = [&](size_t k, Workspace& ws, StreamStats& st) {
        const size_t begin = k * slice_size, count = std::min(slice_size, n - begin);
        const StreamSlice s{rays + begin, count, kAnyHit ? nullptr : hits + begin,
                            kAnyHit ? occluded + begin : nullptr};
        trace_slice<kAnyHit>(nodes, packs, magnitude, s, ws, st);
    };
    if (!options.parallel || slices == 1) {
        Workspace ws;
        StreamStats st;
        for (size_t k = 0; k < slices; ++k) run(k, ws, st);
        if (stats) *stats = st;
        return;
    }
    // One workspace and one set of counters per thread: slices write
    // disjoint output ranges, so nothing is shared in the inner loops.
    tbb::enumerable_thread_specific<Workspace> workspaces;
    tbb::enumerable_thread_specific<StreamStats> counters;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, slices, 1), [&](const tbb::blocked_range<size_t>& r) {
        Workspace& ws = workspaces.local();
        StreamStats& st = counters.local();
        for (size_t k = r.begin(); k < r.end(); ++k) run(k, ws, st);
    });
    if (stats)
        for (const StreamStats& st : counters) *stats += st;
}

}  // namespace

void intersect_stream(const Bvh& bvh, const Ray* rays, size_t n, Hit* hits, StreamStats* stats,
                      const StreamOptions& options) {
    trace_stream<false>(bvh, rays, n, hits, nullptr, stats, options);
}

void occluded_stream(const Bvh& bvh, const Ray* rays, size_t n, uint8_t* occluded, StreamStats* stats,
                     const StreamOptions& options) {
    trace_stream<true>(bvh, rays, n, nullptr, occluded, stats, options);
}

}  // namespace coherent
