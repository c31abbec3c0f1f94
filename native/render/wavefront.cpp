// The wavefront pipeline (see wavefront.h).
#include "wavefront.h"

#include <time.h>

#include <algorithm>
#include <vector>

#include "../accel/ray_packet.h"
#include "path_tracer.h"

namespace coherent {

namespace {

double thread_seconds() {
    timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

template <class T>
size_t capacity_bytes(const std::vector<T>& v) {
    return v.capacity() * sizeof(T);
}

// Occlusion batch entries: what a ray's result resolves.
constexpr uint8_t kShadowRay = 0, kAoRay = 1;

}  // namespace

WavefrontOptions WavefrontOptions::from_settings(const RenderSettings& rs) {
    WavefrontOptions o;
    o.reorder = rs.reorder;
    o.wave_size = std::max(rs.wave_size, 1);
    o.node_visits = rs.heatmaps;
    return o;
}

// Flat per-path arrays (index p = path of the wave, in row order of its
// pixels) and one batch of rays (index i = ray in the order it was queued,
// path-major). A batch's results are stored by queue index whatever order
// the rays were traced in.
struct WavefrontRenderer::Buffers {
    // Per path.
    std::vector<int> px, py;
    std::vector<PathSampler<ImageSampler>> samplers;
    std::vector<PathState> states;
    std::vector<uint32_t> visits;  // node visits (heatmaps)
    // One batch.
    std::vector<Ray> rays, traced_rays;  // queue order; traced order (gather)
    std::vector<RayTag> tags;
    std::vector<uint32_t> owner;         // path of each ray
    std::vector<uint32_t> shaded;        // paths shaded in the current bounce
    std::vector<uint8_t> kind;           // occlusion batches: kShadowRay / kAoRay
    std::vector<Hit> hits;               // extension results
    std::vector<uint8_t> flag;           // extension: found; occlusion: occluded
    std::vector<uint32_t> order;         // traced position -> queue index
    ReorderWorkspace ws;
    // Packets (WavefrontOptions::packet_size > 0).
    std::unique_ptr<RayPacket> packet;
    std::unique_ptr<HitPacket> hit_packet;
    std::vector<uint32_t> lane_visits;

    size_t bytes() const {
        size_t b = capacity_bytes(px) + capacity_bytes(py) + capacity_bytes(samplers) + capacity_bytes(states) +
                   capacity_bytes(visits) + capacity_bytes(rays) + capacity_bytes(traced_rays) + capacity_bytes(tags) +
                   capacity_bytes(owner) + capacity_bytes(shaded) + capacity_bytes(kind) + capacity_bytes(hits) + capacity_bytes(flag) +
                   capacity_bytes(order) + capacity_bytes(lane_visits) + ws.bytes();
        if (packet) b += sizeof(RayPacket) + sizeof(HitPacket);
        return b;
    }
    void clear_batch() {
        rays.clear();
        tags.clear();
        owner.clear();
        kind.clear();
    }
};

namespace {

using Buffers = WavefrontRenderer::Buffers;

// Reorders and traces the queued batch: closest hits (extension rays) or
// occlusion (shadow and AO rays). Results land at the rays' queue indices.
template <bool kOcclusion>
void trace_batch(const Bvh& bvh, const WavefrontOptions& opt, bool reorder, Buffers& b, int bounce,
                 RenderStats& st, WavefrontStats& ws) {
    const size_t n = b.rays.size();
    b.flag.assign(n, 0);
    if constexpr (!kOcclusion) b.hits.assign(n, Hit{});
    st.bounces[size_t(std::min(bounce, kStatBounces - 1))].rays += n;
    ws.rays += n;
    ++ws.batches;
    if (n == 0) return;

    // Reorder: the traced order as a permutation of queue indices.
    const bool ordered = reorder && opt.reorder != ReorderMode::None;
    if (ordered) {
        ReorderTimings t;
        compute_ray_order(b.rays.data(), b.tags.data(), n, opt.reorder, b.ws, b.order, &t, opt.sort);
        ws.reorder += t;
        st.sort_seconds += t.total();
    }
    const double start = thread_seconds();
    const Ray* src = b.rays.data();
    if (ordered && opt.gather) {
        b.traced_rays.resize(n);
        for (size_t j = 0; j < n; ++j) b.traced_rays[j] = b.rays[b.order[j]];
        src = b.traced_rays.data();
    }
    // Queue index of the j-th traced ray, and the ray itself.
    auto queue_index = [&](size_t j) -> uint32_t { return ordered ? b.order[j] : uint32_t(j); };
    auto traced_ray = [&](size_t j, uint32_t i) -> const Ray& { return (ordered && !opt.gather) ? src[i] : src[j]; };
    const bool per_path = opt.counters && opt.node_visits && !b.visits.empty();

    if (opt.packet_size <= 0) {
        for (size_t j = 0; j < n; ++j) {
            const uint32_t i = queue_index(j);
            const Ray& r = traced_ray(j, i);
            TraversalCounters c;
            TraversalCounters* cp = opt.counters ? &c : nullptr;
            if constexpr (kOcclusion) b.flag[i] = bvh.occluded(r, cp) ? 1 : 0;
            else b.flag[i] = bvh.intersect(r, b.hits[i], cp) ? 1 : 0;
            if (opt.counters) {
                st.traversal.rays += c.rays;  // its type and bounce were counted when queued
                book_work(st, bounce, c);
                if (per_path) b.visits[b.owner[i]] += uint32_t(c.node_visits);
            }
        }
    } else {
        const size_t k = size_t(std::min(opt.packet_size, kMaxPacketRays));
        if (!b.packet) {
            b.packet = std::make_unique<RayPacket>();
            b.hit_packet = std::make_unique<HitPacket>();
        }
        RayPacket& pk = *b.packet;
        HitPacket& hp = *b.hit_packet;
        b.lane_visits.assign(k, 0);
        uint32_t lane_index[kMaxPacketRays];
        for (size_t j0 = 0; j0 < n; j0 += k) {
            const size_t j1 = std::min(j0 + k, n);
            pk.clear();
            for (size_t j = j0; j < j1; ++j) {
                const uint32_t i = queue_index(j);
                lane_index[pk.push(traced_ray(j, i))] = i;
            }
            PacketCounters pc;
            if (per_path) {
                std::fill(b.lane_visits.begin(), b.lane_visits.end(), 0u);
                pc.ray_node_visits = b.lane_visits.data();
            }
            PacketCounters* pcp = opt.counters ? &pc : nullptr;
            if constexpr (kOcclusion) {
                OcclusionMask mask;
                bvh.occluded(pk, mask, pcp);
                for (int l = 0; l < pk.size; ++l) b.flag[lane_index[l]] = mask.test(l) ? 1 : 0;
            } else {
                hp.reset(pk.size);
                bvh.intersect(pk, hp, pcp);
                for (int l = 0; l < pk.size; ++l) {
                    const Hit h = hp.hit(l);
                    b.hits[lane_index[l]] = h;
                    b.flag[lane_index[l]] = h.valid() ? 1 : 0;
                }
            }
            if (opt.counters) {
                st.traversal.rays += pc.rays;
                book_work(st, bounce, pc);
                if (per_path)
                    for (int l = 0; l < pk.size; ++l) b.visits[b.owner[lane_index[l]]] += b.lane_visits[size_t(l)];
            }
        }
    }
    const double seconds = thread_seconds() - start;
    ws.trace_seconds += seconds;
    st.trace_seconds += seconds;
}

}  // namespace

WavefrontRenderer::WavefrontRenderer(const PathContext& ctx, const WavefrontOptions& opt, bool glass,
                                     bool depth_of_field, bool lights)
    : ctx_(ctx), opt_(opt), buf_(std::make_unique<Buffers>()) {
    opt_.wave_size = std::max(opt_.wave_size, 1);
    static constexpr WaveFn table[2][2][2] = {
        {{&run_wave<false, false, false>, &run_wave<false, false, true>},
         {&run_wave<false, true, false>, &run_wave<false, true, true>}},
        {{&run_wave<true, false, false>, &run_wave<true, false, true>},
         {&run_wave<true, true, false>, &run_wave<true, true, true>}},
    };
    run_wave_ = table[glass ? 1 : 0][depth_of_field ? 1 : 0][lights ? 1 : 0];
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
    const size_t paths = b.px.size();

    // Generate.
    b.samplers.clear();
    b.states.resize(paths);
    for (size_t p = 0; p < paths; ++p) {
        b.samplers.emplace_back(sampler, uint32_t(b.px[p]), uint32_t(b.py[p]), sample);
        start_path<ImageSampler, kDepthOfField>(ctx, b.samplers[p], b.px[p], b.py[p], b.states[p]);
    }
    if (opt.node_visits) b.visits.assign(paths, 0);
    else b.visits.clear();

    // Every live path is at the same bounce: all start together and each
    // shade_hit that continues a path advances it by exactly one.
    for (int bounce = 0;; ++bounce) {
        if (cancelled && cancelled->load(std::memory_order_relaxed)) return;

        // Extend: the live paths' extension rays.
        b.clear_batch();
        for (size_t p = 0; p < paths; ++p) {
            const PathState& s = b.states[p];
            if (!s.alive) continue;
            b.rays.push_back(s.ray);
            b.tags.push_back(RayTag{uint16_t(b.px[p]), uint16_t(b.py[p]), 0u});
            b.owner.push_back(uint32_t(p));
            ++st.rays[size_t(s.type)];
        }
        const size_t n = b.rays.size();
        if (n == 0) break;
        trace_batch<false>(bvh, opt, bounce > 0 || opt.reorder_camera_rays, b, bounce, st, self.stats_);

        // Shade, then queue the occlusion rays, path by path. Moving
        // triangles (motion blur) are merged in one ray at a time.
        TraversalCounters motion;
        for (size_t i = 0; i < n; ++i) {
            const uint32_t p = b.owner[i];
            const bool found = merge_motion_hit(ctx, b.states[p], b.flag[i] != 0, b.hits[i], &motion);
            shade_hit<ImageSampler, kGlass, kLights>(ctx, b.samplers[p], b.states[p], found, b.hits[i]);
        }
        // The paths shaded above, kept while the batch buffers are reused.
        b.shaded.swap(b.owner);
        b.clear_batch();
        for (const uint32_t p : b.shaded) {
            const PathState& s = b.states[p];
            const uint16_t x = uint16_t(b.px[p]), y = uint16_t(b.py[p]);
            if (s.has_shadow) {
                b.rays.push_back(s.shadow);
                b.tags.push_back(RayTag{x, y, 0u});
                b.owner.push_back(p);
                b.kind.push_back(kShadowRay);
                ++st.rays[size_t(RayType::Shadow)];
            }
            for (int k = 0; k < s.ao_rays; ++k) {
                b.rays.push_back(ao_ray(ctx, b.samplers[p], s, k));
                b.tags.push_back(RayTag{x, y, uint32_t(k + 1)});
                b.owner.push_back(p);
                b.kind.push_back(kAoRay);
            }
            st.rays[size_t(RayType::Shadow)] += uint64_t(std::max(s.ao_rays, 0));
        }
        const size_t m = b.rays.size();
        if (m == 0) continue;
        trace_batch<true>(bvh, opt, true, b, bounce, st, self.stats_);
        if (ctx.motion)
            for (size_t i = 0; i < m; ++i)
                if (!b.flag[i] && motion_occluded(ctx, b.states[b.owner[i]], b.rays[i], &motion)) b.flag[i] = 1;
        if (ctx.motion) book_work(st, bounce, motion);

        // Resolve in queue order: a path's AO rays are consecutive.
        for (size_t i = 0; i < m;) {
            const uint32_t p = b.owner[i];
            if (b.kind[i] == kShadowRay) {
                resolve_shadow(b.states[p], b.flag[i] != 0);
                ++i;
                continue;
            }
            int unoccluded = 0;
            for (; i < m && b.owner[i] == p && b.kind[i] == kAoRay; ++i) unoccluded += b.flag[i] ? 0 : 1;
            resolve_ao(b.states[p], unoccluded);
        }
    }
}

bool WavefrontRenderer::render_pass(const ImageSampler& sampler, uint32_t sample, int x0, int y0, int x1, int y1,
                                    const WaveSkip& skip, const WaveOutput& output, RenderStats& st,
                                    const std::atomic<bool>* cancelled) {
    const double start = thread_seconds();
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
    stats_.total_seconds += thread_seconds() - start;
    return ok;
}

}  // namespace coherent
