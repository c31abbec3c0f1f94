// The wavefront pipeline (see wavefront.h).
#include "wavefront.h"

#include <algorithm>
#include <vector>

#include "../accel/ray_packet.h"
#include "../core/thread_time.h"
#include "batch_shading.h"
#include "kernel_variants.h"
#include "path_state.h"

namespace coherent {

namespace wavefront_detail {

template <class T>
size_t capacity_bytes(const std::vector<T>& v) {
    return v.capacity() * sizeof(T);
}

// One ray queue: a wave's extension rays, or its occlusion rays, of one
// bounce (index i = ray in the order it was queued, path-major). Results are
// stored by queue index whatever order the rays were traced in.
struct RayQueue {
    std::vector<Ray> rays;
    std::vector<RayTag> tags;     // for the static reorder modes
    std::vector<uint32_t> owner;  // path of each ray
    std::vector<Hit> hits;        // extension queues: closest hits
    std::vector<uint8_t> flag;    // extension: found; occlusion: occluded

    size_t size() const { return rays.size(); }
    void push(const Ray& r, RayTag tag, uint32_t path) {
        rays.push_back(r);
        tags.push_back(tag);
        owner.push_back(path);
    }
    void clear() {
        rays.clear();
        tags.clear();
        owner.clear();
    }
    size_t bytes() const {
        return capacity_bytes(rays) + capacity_bytes(tags) + capacity_bytes(owner) + capacity_bytes(hits) +
               capacity_bytes(flag);
    }
};

// How a queue is traced: its traced order (a permutation of queue indices),
// the rays gathered into that order, and packets.
struct TraceScratch {
    std::vector<uint32_t> order;  // traced position -> queue index
    std::vector<Ray> traced_rays;  // the queue's rays in traced order (gather)
    ReorderWorkspace ws;
    // Packets (WavefrontOptions::packet_size > 0).
    std::unique_ptr<RayPacket> packet;
    std::unique_ptr<HitPacket> hit_packet;
    std::vector<uint32_t> lane_visits;
    std::vector<float> lane_time;  // moving instances: each lane's shutter time

    size_t bytes() const {
        size_t b = capacity_bytes(order) + capacity_bytes(traced_rays) + capacity_bytes(lane_visits) +
                   capacity_bytes(lane_time) + ws.bytes();
        if (packet) b += sizeof(RayPacket) + sizeof(HitPacket);
        return b;
    }
};

}  // namespace wavefront_detail

using namespace wavefront_detail;

WavefrontOptions WavefrontOptions::from_settings(const RenderSettings& rs) {
    WavefrontOptions o;
    o.reorder = rs.reorder;
    o.wave_size = std::max(rs.wave_size, 1);
    o.node_visits = rs.heatmaps;
    return o;
}

// Flat per-path arrays (index p = path of the wave, in row order of its
// pixels), the ray queue of the current stage and its trace scratch.
struct WavefrontRenderer::Buffers {
    // Per path.
    std::vector<int> px, py;
    std::vector<PathSampler> samplers;
    std::vector<PathState> states;
    std::vector<uint32_t> visits;   // node visits (heatmaps)
    std::vector<uint32_t> shaded;   // paths shaded in the current bounce
    RayQueue queue;
    TraceScratch trace;
    HitShading shading;  // a queue stretch's programs, run together

    size_t bytes() const {
        return capacity_bytes(px) + capacity_bytes(py) + capacity_bytes(samplers) + capacity_bytes(states) +
               capacity_bytes(visits) + capacity_bytes(shaded) + queue.bytes() + trace.bytes() +
               shading.bytes();
    }
};

namespace {

using Buffers = WavefrontRenderer::Buffers;

// The j-th traced ray of a queue and its queue index, for any reorder and
// gather choice.
struct TracedOrder {
    const Ray* rays;          // queue order, or traced order when gathered
    const uint32_t* order;    // traced position -> queue index; null: identity
    bool through_permutation;  // reordered but not gathered: rays[order[j]]

    uint32_t queue_index(size_t j) const { return order ? order[j] : uint32_t(j); }
    const Ray& ray(size_t j, uint32_t i) const { return through_permutation ? rays[i] : rays[j]; }
};

// Reorders the queue (ray_reorder.h) into b.trace.order.
void reorder_queue(const WavefrontOptions& opt, Buffers& b, RenderStats& st, WavefrontStats& ws) {
    ReorderTimings t;
    compute_ray_order(b.queue.rays.data(), b.queue.tags.data(), b.queue.size(), opt.reorder, b.trace.ws,
                      b.trace.order, &t, opt.sort);
    ws.reorder += t;
    st.sort_seconds += t.total();
}

// The traced order of the queue; gathers its rays into that order if asked.
TracedOrder traced_order(const WavefrontOptions& opt, bool ordered, Buffers& b) {
    const RayQueue& q = b.queue;
    if (!ordered) return {q.rays.data(), nullptr, false};
    if (!opt.gather) return {q.rays.data(), b.trace.order.data(), true};
    b.trace.traced_rays.resize(q.size());
    for (size_t j = 0; j < q.size(); ++j) b.trace.traced_rays[j] = q.rays[b.trace.order[j]];
    return {b.trace.traced_rays.data(), b.trace.order.data(), false};
}

// The queue's rays one at a time, in traced order.
template <bool kOcclusion>
void trace_singly(const Bvh& bvh, const InstanceBvh* instances, const WavefrontOptions& opt,
                  const TracedOrder& traced, Buffers& b, int bounce, RenderStats& st, bool per_path) {
    RayQueue& q = b.queue;
    for (size_t j = 0; j < q.size(); ++j) {
        const uint32_t i = traced.queue_index(j);
        const Ray& r = traced.ray(j, i);
        TraversalCounters c;
        TraversalCounters* cp = opt.counters ? &c : nullptr;
        if constexpr (kOcclusion) q.flag[i] = bvh.occluded(r, cp) ? 1 : 0;
        else q.flag[i] = bvh.intersect(r, q.hits[i], cp) ? 1 : 0;
        if (instances) {
            const float time = b.states[q.owner[i]].time;
            if constexpr (kOcclusion) q.flag[i] = q.flag[i] || instances->occluded(r, cp, time) ? 1 : 0;
            else q.flag[i] = instances->intersect(r, q.hits[i], cp, time) || q.flag[i] ? 1 : 0;
        }
        if (opt.counters) {
            book_work(st, bounce, c);  // the ray itself was booked when queued
            if (per_path) b.visits[q.owner[i]] += uint32_t(c.node_visits);
        }
    }
}

// Moving instances: the shutter time of each lane's path (null when nothing moves).
const float* lane_times(const InstanceBvh* instances, Buffers& b, const uint32_t* lane_index, int lanes) {
    if (!instances->has_motion()) return nullptr;
    b.trace.lane_time.resize(size_t(lanes));
    for (int l = 0; l < lanes; ++l) b.trace.lane_time[size_t(l)] = b.states[b.queue.owner[lane_index[l]]].time;
    return b.trace.lane_time.data();
}

// The queue's rays as SIMD packets of consecutive traced rays.
template <bool kOcclusion>
void trace_packets(const Bvh& bvh, const InstanceBvh* instances, const WavefrontOptions& opt,
                   const TracedOrder& traced, Buffers& b, int bounce, RenderStats& st, bool per_path) {
    RayQueue& q = b.queue;
    TraceScratch& ts = b.trace;
    const size_t n = q.size();
    const size_t k = size_t(std::min(opt.packet_size, kMaxPacketRays));
    if (!ts.packet) {
        ts.packet = std::make_unique<RayPacket>();
        ts.hit_packet = std::make_unique<HitPacket>();
    }
    RayPacket& pk = *ts.packet;
    HitPacket& hp = *ts.hit_packet;
    ts.lane_visits.assign(k, 0);
    uint32_t lane_index[kMaxPacketRays];
    for (size_t j0 = 0; j0 < n; j0 += k) {
        const size_t j1 = std::min(j0 + k, n);
        pk.clear();
        for (size_t j = j0; j < j1; ++j) {
            const uint32_t i = traced.queue_index(j);
            lane_index[pk.push(traced.ray(j, i))] = i;
        }
        PacketCounters pc;
        if (per_path) {
            std::fill(ts.lane_visits.begin(), ts.lane_visits.end(), 0u);
            pc.ray_node_visits = ts.lane_visits.data();
        }
        PacketCounters* pcp = opt.counters ? &pc : nullptr;
        if constexpr (kOcclusion) {
            OcclusionMask mask;
            bvh.occluded(pk, mask, pcp);
            if (instances) instances->occluded(pk, mask, pcp, lane_times(instances, b, lane_index, pk.size));
            for (int l = 0; l < pk.size; ++l) q.flag[lane_index[l]] = mask.test(l) ? 1 : 0;
        } else {
            hp.reset(pk.size);
            bvh.intersect(pk, hp, pcp);
            if (instances) instances->intersect(pk, hp, pcp, lane_times(instances, b, lane_index, pk.size));
            for (int l = 0; l < pk.size; ++l) {
                const Hit h = hp.hit(l);
                q.hits[lane_index[l]] = h;
                q.flag[lane_index[l]] = h.valid() ? 1 : 0;
            }
        }
        if (opt.counters) {
            book_work(st, bounce, pc);
            if (per_path)
                for (int l = 0; l < pk.size; ++l) b.visits[q.owner[lane_index[l]]] += ts.lane_visits[size_t(l)];
        }
    }
}

// Reorders and traces the queue: closest hits (extension rays) or occlusion
// (shadow and AO rays). Results land at the rays' queue indices.
template <bool kOcclusion>
void trace_queue(const Bvh& bvh, const InstanceBvh* instances, const WavefrontOptions& opt, bool reorder, Buffers& b,
                 int bounce, RenderStats& st, WavefrontStats& ws) {
    const size_t n = b.queue.size();
    b.queue.flag.assign(n, 0);
    if constexpr (!kOcclusion) b.queue.hits.assign(n, Hit{});
    ws.rays += n;
    ++ws.queues;
    if (n == 0) return;

    const bool ordered = reorder && opt.reorder != ReorderMode::None;
    if (ordered) reorder_queue(opt, b, st, ws);
    const double start = thread_cpu_seconds();
    const TracedOrder traced = traced_order(opt, ordered, b);
    const bool per_path = opt.counters && opt.node_visits && !b.visits.empty();
    if (opt.packet_size <= 0) trace_singly<kOcclusion>(bvh, instances, opt, traced, b, bounce, st, per_path);
    else trace_packets<kOcclusion>(bvh, instances, opt, traced, b, bounce, st, per_path);
    const double seconds = thread_cpu_seconds() - start;
    ws.trace_seconds += seconds;
    st.trace_seconds += seconds;
}

// Generate: the camera paths of the wave's pixels (b.px, b.py).
template <bool kDepthOfField>
void start_wave(const PathContext& ctx, const WavefrontOptions& opt, const ImageSampler& sampler, uint32_t sample,
                Buffers& b) {
    const size_t paths = b.px.size();
    b.samplers.clear();
    b.states.resize(paths);
    for (size_t p = 0; p < paths; ++p) {
        b.samplers.emplace_back(sampler, uint32_t(b.px[p]), uint32_t(b.py[p]), sample);
        start_path<kDepthOfField>(ctx, b.samplers[p], b.px[p], b.py[p], b.states[p]);
    }
    if (opt.node_visits) b.visits.assign(paths, 0);
    else b.visits.clear();
}

// Queues the live paths' extension rays; returns how many.
size_t queue_extension_rays(Buffers& b, int bounce, RenderStats& st) {
    b.queue.clear();
    for (size_t p = 0; p < b.states.size(); ++p) {
        const PathState& s = b.states[p];
        if (!s.alive) continue;
        b.queue.push(s.ray, RayTag{uint16_t(b.px[p]), uint16_t(b.py[p]), 0u}, uint32_t(p));
        book_rays(st, bounce, s.type, 1);
    }
    return b.queue.size();
}

// Shades the traced extension queue, path by path, each stretch's shader
// programs run together first (batch_shading.h). Moving triangles (motion
// blur) are merged in one ray at a time.
template <bool kGlass, bool kLights>
void shade_queue(const PathContext& ctx, Buffers& b, int bounce, RenderStats& st) {
    RayQueue& q = b.queue;
    TraversalCounters motion;
    for (size_t i = 0; i < q.size(); ++i)
        q.flag[i] = merge_motion_hit(ctx, b.states[q.owner[i]], q.flag[i] != 0, q.hits[i], &motion) ? 1 : 0;
    for (size_t first = 0; first < q.size(); first += kShadeChunk) {
        const size_t n = std::min(kShadeChunk, q.size() - first);
        b.shading.prepare(
            ctx, n, [&](size_t i) { return q.flag[first + i] ? &q.hits[first + i] : nullptr; },
            [&](size_t i) -> const PathState& { return b.states[q.owner[first + i]]; });
        for (size_t i = 0; i < n; ++i) {
            const uint32_t p = q.owner[first + i];
            shade_hit<kGlass, kLights>(ctx, b.samplers[p], b.states[p], q.flag[first + i] != 0, q.hits[first + i],
                                       b.shading.at(i));
        }
    }
    if (ctx.motion) book_work(st, bounce, motion);
}

// Queues the occlusion rays of the paths just shaded (path-major, tagged
// with their index within the pixel's sample); returns how many.
size_t queue_occlusion_rays(const PathContext& ctx, Buffers& b, int bounce, RenderStats& st) {
    // The paths shaded, kept while the queue buffers are reused.
    b.shaded.swap(b.queue.owner);
    b.queue.clear();
    for (const uint32_t p : b.shaded) {
        const PathState& s = b.states[p];
        const int n = occlusion_ray_count(s);
        for (int k = 0; k < n; ++k) {
            const RayTag tag{uint16_t(b.px[p]), uint16_t(b.py[p]), s.has_shadow ? 0u : uint32_t(k + 1)};
            b.queue.push(occlusion_ray(ctx, b.samplers[p], s, k), tag, p);
        }
        book_rays(st, bounce, RayType::Shadow, uint64_t(n));
    }
    return b.queue.size();
}

// Motion blur: moving triangles may block the traced occlusion queue's
// unoccluded rays too.
void occlude_moving(const PathContext& ctx, Buffers& b, int bounce, RenderStats& st) {
    if (!ctx.motion) return;
    RayQueue& q = b.queue;
    TraversalCounters motion;
    for (size_t i = 0; i < q.size(); ++i)
        if (!q.flag[i] && motion_occluded(ctx, b.states[q.owner[i]], q.rays[i], &motion)) q.flag[i] = 1;
    book_work(st, bounce, motion);
}

}  // namespace

WavefrontRenderer::WavefrontRenderer(const PathContext& ctx, const WavefrontOptions& opt, bool glass,
                                     bool depth_of_field, bool lights)
    : ctx_(ctx), opt_(opt), buf_(std::make_unique<Buffers>()) {
    opt_.wave_size = std::max(opt_.wave_size, 1);
    run_wave_ = select_kernel_variant(KernelFeatures{glass, depth_of_field, lights},
                                      [](auto g, auto d, auto l) -> WaveFn { return &run_wave<g(), d(), l()>; });
}

WavefrontRenderer::~WavefrontRenderer() = default;

size_t WavefrontRenderer::buffer_bytes() const { return buf_->bytes(); }

// One wave: the paths of the pixels in buf_->px/py, from camera ray to end.
// Leaves the finished states in buf_->states (all !alive), or returns early
// with paths still alive if cancelled.
template <bool kGlass, bool kDepthOfField, bool kLights>
void WavefrontRenderer::run_wave(WavefrontRenderer& self, const ImageSampler& sampler, uint32_t sample,
                                 RenderStats& st, const std::atomic<bool>* cancelled) {
    Buffers& b = *self.buf_;
    const PathContext& ctx = self.ctx_;
    const WavefrontOptions& opt = self.opt_;
    const Bvh& bvh = *ctx.bvh;
    start_wave<kDepthOfField>(ctx, opt, sampler, sample, b);
    // Every live path is at the same bounce: all start together and each
    // shade_hit that continues a path advances it by exactly one.
    for (int bounce = 0;; ++bounce) {
        if (cancelled && cancelled->load(std::memory_order_relaxed)) return;
        // Extend: trace the live paths' extension rays, shade their hits.
        if (queue_extension_rays(b, bounce, st) == 0) break;
        trace_queue<false>(bvh, ctx.instances, opt, bounce > 0 || opt.reorder_camera_rays, b, bounce, st,
                           self.stats_);
        shade_queue<kGlass, kLights>(ctx, b, bounce, st);
        // Shadow: trace the shadow and AO rays the shading queued, resolve them.
        const size_t m = queue_occlusion_rays(ctx, b, bounce, st);
        if (m == 0) continue;
        trace_queue<true>(bvh, ctx.instances, opt, true, b, bounce, st, self.stats_);
        occlude_moving(ctx, b, bounce, st);
        resolve_occlusion_queue(b.queue.flag.data(), m,
                                [&](size_t i) -> PathState& { return b.states[b.queue.owner[i]]; });
    }
}

bool WavefrontRenderer::render_pass(const ImageSampler& sampler, uint32_t sample, int x0, int y0, int x1, int y1,
                                    const WaveSkip& skip, const WaveOutput& output, RenderStats& st,
                                    const std::atomic<bool>* cancelled) {
    const double start = thread_cpu_seconds();
    Buffers& b = *buf_;
    const size_t wave = size_t(opt_.wave_size);
    bool ok = true;
    auto flush = [&] {
        if (b.px.empty()) return;
        run_wave_(*this, sampler, sample, st, cancelled);
        if (cancelled && cancelled->load(std::memory_order_relaxed)) {
            ok = false;
        } else {
            for (size_t p = 0; p < b.px.size(); ++p)
                output(b.px[p], b.py[p], b.states[p].out, b.visits.empty() ? 0u : b.visits[p]);
        }
        ++stats_.waves;
        stats_.max_paths = std::max(stats_.max_paths, b.px.size());
        stats_.peak_bytes = std::max(stats_.peak_bytes, b.bytes());
        b.px.clear();
        b.py.clear();
    };
    for (int y = y0; y < y1 && ok; ++y)
        for (int x = x0; x < x1 && ok; ++x) {
            if (skip && skip(x, y)) continue;
            b.px.push_back(x);
            b.py.push_back(y);
            if (b.px.size() == wave) flush();
        }
    if (ok) flush();
    b.px.clear();
    b.py.clear();
    stats_.total_seconds += thread_cpu_seconds() - start;
    return ok;
}

}  // namespace coherent
