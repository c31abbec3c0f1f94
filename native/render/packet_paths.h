// Tile drivers of the path state machine (path_state.h): the paths of one
// render tile (PathTile) advance bounce by bounce, and after every bounce
// their rays are traced together.
//
// trace_tile_packets gathers them into SIMD packets (Boulos et al. 2007
// section 3.2) within each packet of pixels:
//   RayType assembly: one packet per ray type (camera, diffuse, glossy,
//     reflection, refraction; shadow rays apart, occlusion-only), the paper's
//     choice;
//   Runs assembly: consecutive paths (in pixel order) whose rays share a
//     type form a packet; a change of type, or a path without such a ray,
//     ends the run.
// Ambient occlusion rays are gathered by ray index (all paths' i-th AO ray,
// then the (i+1)-th, ...): with CPT every pixel of a packet draws the same
// numbers for the i-th ray, so these packets are the coherent ones.
//
// trace_tile_streams traces all the tile's extension rays as one
// breadth-first stream (ray_stream.h), then all its occlusion rays.
//
// Shading is the state machine's, and packet and stream kernels return the
// single-ray kernel's hits bit for bit, so the image equals the depth-first
// driver's (path_tracer.h) for the same sampler and seed.
#pragma once

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "../accel/ray_packet.h"
#include "../accel/ray_stream.h"
#include "batch_shading.h"
#include "path_state.h"

namespace coherent {

// The camera paths of one render tile, in packet-major order: paths
// [packet_begin[k], packet_begin[k + 1]) are the pixels of pixel packet k,
// row by row. (The stream driver ignores the packets.)
struct PathTile {
    std::vector<PathState> states;
    std::vector<PathSampler> samplers;
    std::vector<int> px, py;
    std::vector<int> packet_begin;  // packets + 1 entries
    std::vector<SharedSets> shared_sets;  // per packet (share_numbers)
    // Heatmaps: node visits per path, and the SIMD lanes (all / active) of
    // the packets its rays were traced in.
    std::vector<uint32_t> node_visits;
    std::vector<uint64_t> lanes, lanes_active;

    // Starts the camera path of pixel (x, y)'s sample (the renderer's and
    // every tile driver's one way to fill a tile).
    template <bool kDepthOfField>
    void start(const PathContext& ctx, const ImageSampler& sampler, uint32_t sample, int x, int y) {
        samplers.emplace_back(sampler, uint32_t(x), uint32_t(y), sample);
        states.emplace_back();
        start_fresh_path<kDepthOfField>(ctx, samplers.back(), x, y, states.back());
        px.push_back(x);
        py.push_back(y);
    }
    // Closes the pixel packet of the paths started since the last one
    // closed; an empty packet is not kept.
    void end_packet() {
        if (int(size()) > packet_begin.back()) packet_begin.push_back(int(size()));
    }
    // Where a packet's pixels all lie in one of the sampler's shared blocks
    // (CPT, ImageSampler::shared_stream_block), their paths read identical
    // numbers: each set is then drawn once per packet (SharedSets) instead
    // of once per path. Call once every path is started (one sample per tile).
    void share_numbers(const ImageSampler& sampler) {
        const ImageSampler::SharedBlock block = sampler.shared_stream_block();
        shared_sets.clear();
        if (block.width == 0 || block.height == 0) return;
        shared_sets.resize(size_t(packets()));
        const auto block_of = [&](size_t p) {
            return std::pair(uint32_t(px[p]) / block.width, uint32_t(py[p]) / block.height);
        };
        for (int k = 0; k < packets(); ++k) {
            const auto first = size_t(packet_begin[size_t(k)]), end = size_t(packet_begin[size_t(k) + 1]);
            bool one_block = true;
            for (size_t p = first + 1; p < end && one_block; ++p) one_block = block_of(p) == block_of(first);
            if (!one_block) continue;
            for (size_t p = first; p < end; ++p) samplers[p].share(&shared_sets[size_t(k)]);
        }
    }
    // Heatmaps: per-path counters, zeroed (call once every path is started).
    void enable_heatmaps() {
        node_visits.assign(size(), 0);
        lanes.assign(size(), 0);
        lanes_active.assign(size(), 0);
    }

    void clear() {
        states.clear();
        samplers.clear();
        px.clear();
        py.clear();
        packet_begin.assign(1, 0);
        shared_sets.clear();
        node_visits.clear();
        lanes.clear();
        lanes_active.clear();
    }
    size_t size() const { return states.size(); }
    int packets() const { return int(packet_begin.size()) - 1; }
};

namespace packet_detail {

// |mean of the rays' unit directions|: 1 when all point the same way, near 0
// for directions spread over the sphere.
inline float packet_coherence(const RayPacket& pk) {
    float sx = 0.0f, sy = 0.0f, sz = 0.0f;
    for (int i = 0; i < pk.size; ++i) {
        const float len = std::sqrt(pk.dx[i] * pk.dx[i] + pk.dy[i] * pk.dy[i] + pk.dz[i] * pk.dz[i]);
        if (!(len > 0.0f) || !std::isfinite(len)) continue;  // invalid rays: no vote
        sx += pk.dx[i] / len;
        sy += pk.dy[i] / len;
        sz += pk.dz[i] / len;
    }
    return pk.size ? std::sqrt(sx * sx + sy * sy + sz * sz) / float(pk.size) : 0.0f;
}

// Scratch of one packet (a few tens of KB: kept per thread, not per call).
struct PacketScratch {
    RayPacket packet;
    HitPacket hits;
    OcclusionMask occluded;
    int lane_path[kMaxPacketRays];
    uint32_t lane_visits[kMaxPacketRays];
    float lane_time[kMaxPacketRays];  // moving instances only: each lane's path time
    Hit lane_hit[kMaxPacketRays];     // extension: each lane's hit, motion merged
    bool lane_found[kMaxPacketRays];
    HitShading shading;               // shader programs of many hits, run together
    // Shading deferred to the end of a bounce (scenes with shader programs):
    // the traced paths in order, and each one's hit (motion merged).
    std::vector<int> traced;
    std::vector<Hit> traced_hit;
    std::vector<uint8_t> traced_found;
};

// trace_tile_packets() below, in steps. The packet being gathered is
// scratch.packet; lane i carries a ray of path scratch.lane_path[i].
template <bool kGlass, bool kLights>
class PacketTileTracer {
public:
    PacketTileTracer(const PathContext& ctx, PacketAssembly assembly, PathTile& tile, PacketScratch& scratch,
                     RenderStats& st)
        : ctx_(ctx), bvh_(*ctx.bvh), assembly_(assembly), tile_(tile), scratch_(scratch), pk_(scratch.packet),
          st_(st), heat_(!tile.node_visits.empty()), min_coherence_(ctx.settings->packet_min_coherence) {}

    // Every bounce, packet by packet: the extension rays, then the
    // occlusion rays their shading queued. Where materials run shader
    // programs, the whole tile's extension rays are traced first and their
    // hits shaded together afterwards: a packet's hits beyond the camera
    // spread over many materials, so a program would run on one or two lanes
    // of a batch, where the tile's hits fill its SIMD rows. Paths are
    // independent and each still traces, shades, then resolves its
    // occlusion rays in that order, so the image is the same.
    void run() {
        pk_.clear();
        defer_ = scratch_.shading.wanted(ctx_);
        if (defer_) {
            scratch_.traced_hit.resize(tile_.size());
            scratch_.traced_found.resize(tile_.size());
        }
        for (int bounce = 0;; ++bounce) {
            bool any_alive = false;
            scratch_.traced.clear();
            for (int k = 0; k < tile_.packets(); ++k) {
                const int b = tile_.packet_begin[size_t(k)], e = tile_.packet_begin[size_t(k) + 1];
                if (assembly_ == PacketAssembly::RayType) extend_by_type(bounce, b, e);
                else extend_by_runs(bounce, b, e);
                if (!defer_) trace_occlusion(bounce, b, e);
            }
            if (defer_) {
                shade_traced();
                for (int k = 0; k < tile_.packets(); ++k)
                    trace_occlusion(bounce, tile_.packet_begin[size_t(k)], tile_.packet_begin[size_t(k) + 1]);
            }
            for (size_t p = 0; p < tile_.size() && !any_alive; ++p) any_alive = tile_.states[p].alive;
            if (!any_alive) break;
        }
    }

private:
    void gather(int path, const Ray& r) {
        scratch_.lane_path[pk_.size] = path;
        pk_.push(r);
    }

    // RayType assembly: one packet per ray type present. The participants
    // are fixed first: shading a packet gives its paths their next ray,
    // which must wait for the next bounce.
    void extend_by_type(int bounce, int b, int e) {
        int pending[kMaxPacketRays];
        RayType pending_type[kMaxPacketRays];
        int count = 0;
        uint32_t types = 0;
        for (int p = b; p < e; ++p) {
            const PathState& s = tile_.states[size_t(p)];
            if (!s.alive) continue;
            pending[count] = p;
            pending_type[count++] = s.type;
            types |= 1u << unsigned(s.type);
        }
        for (; types; types &= types - 1) {
            const RayType t = RayType(__builtin_ctz(types));
            for (int i = 0; i < count; ++i)
                if (pending_type[i] == t) gather(pending[i], tile_.states[size_t(pending[i])].ray);
            flush_extension(bounce, t);
        }
    }

    // Runs assembly: consecutive paths whose rays share a type.
    void extend_by_runs(int bounce, int b, int e) {
        RayType run = RayType::Count;
        for (int p = b; p < e; ++p) {
            const PathState& s = tile_.states[size_t(p)];
            if (!s.alive || s.type != run) {
                flush_extension(bounce, run);
                run = s.alive ? s.type : RayType::Count;
                if (!s.alive) continue;
            }
            gather(p, s.ray);
        }
        flush_extension(bounce, run);
    }

    // The occlusion rays of paths [b, e) by ray index: every path's ray 0,
    // then every path's ray 1, ... (shadow rays: ray 0 only). With CPT every
    // pixel of a packet draws the same numbers for its k-th AO ray, so these
    // packets are the coherent ones. The assemblies differ only in whether a
    // path without a k-th ray ends the run.
    void trace_occlusion(int bounce, int b, int e) {
        int rays = 0;
        for (int p = b; p < e; ++p) rays = std::max(rays, occlusion_ray_count(tile_.states[size_t(p)]));
        if (rays == 0) return;
        unoccluded_.assign(size_t(e - b), 0);
        for (int k = 0; k < rays; ++k)
            for (int p = b; p < e; ++p) {
                const PathState& s = tile_.states[size_t(p)];
                if (occlusion_ray_count(s) <= k) {
                    if (assembly_ == PacketAssembly::Runs) flush_occlusion(bounce, b);
                    continue;
                }
                if (pk_.size == kMaxPacketRays) flush_occlusion(bounce, b);
                gather(p, occlusion_ray(ctx_, tile_.samplers[size_t(p)], s, k));
            }
        flush_occlusion(bounce, b);
        for (int p = b; p < e; ++p) resolve_occlusion(tile_.states[size_t(p)], unoccluded_[size_t(p - b)]);
    }

    // Traces the gathered extension rays, then shades their paths.
    void flush_extension(int bounce, RayType type) {
        if (pk_.size == 0) return;
        scratch_.hits.reset(pk_.size);
        if (packet_coherence(pk_) >= min_coherence_) {
            PacketCounters pc = packet_counters();
            bvh_.intersect(pk_, scratch_.hits, &pc);
            if (ctx_.instances) ctx_.instances->intersect(pk_, scratch_.hits, &pc, lane_times());
            book_packet(bounce, type, pc);
        } else {
            intersect_singly(bounce, type);
        }
        TraversalCounters motion;  // moving triangles: one ray at a time
        Hit* hits = scratch_.lane_hit;
        bool* found = scratch_.lane_found;
        for (int i = 0; i < pk_.size; ++i) {
            hits[i] = scratch_.hits.hit(i);
            found[i] = merge_motion_hit(ctx_, tile_.states[size_t(scratch_.lane_path[i])], hits[i].valid(), hits[i],
                                        &motion);
        }
        if (ctx_.motion) book_work(st_, bounce, motion);
        if (defer_) {  // shaded with the tile's other hits (shade_traced)
            for (int i = 0; i < pk_.size; ++i) {
                const int p = scratch_.lane_path[i];
                scratch_.traced.push_back(p);
                scratch_.traced_hit[size_t(p)] = hits[i];
                scratch_.traced_found[size_t(p)] = found[i];
            }
            pk_.clear();
            return;
        }
        // No shader programs to batch (defer_ is HitShading::wanted): each hit is shaded alone.
        for (int i = 0; i < pk_.size; ++i) {
            const size_t p = size_t(scratch_.lane_path[i]);
            shade_hit<kGlass, kLights>(ctx_, tile_.samplers[p], tile_.states[p], found[i], hits[i]);
        }
        pk_.clear();
    }

    // Shades the paths traced this bounce, their programs batched per
    // material over up to kShadeChunk hits at a time.
    void shade_traced() {
        const std::vector<int>& traced = scratch_.traced;
        for (size_t first = 0; first < traced.size(); first += kShadeChunk) {
            const size_t n = std::min(kShadeChunk, traced.size() - first);
            const int* paths = traced.data() + first;
            scratch_.shading.prepare(
                ctx_, n,
                [&](size_t i) {
                    const size_t p = size_t(paths[i]);
                    return scratch_.traced_found[p] ? &scratch_.traced_hit[p] : nullptr;
                },
                [&](size_t i) -> const PathState& { return tile_.states[size_t(paths[i])]; });
            for (size_t i = 0; i < n; ++i) {
                const size_t p = size_t(paths[i]);
                shade_hit<kGlass, kLights>(ctx_, tile_.samplers[p], tile_.states[p], scratch_.traced_found[p] != 0,
                                           scratch_.traced_hit[p], scratch_.shading.at(i));
            }
        }
    }

    // Traces the gathered occlusion rays of paths b.. and counts each
    // path's unoccluded ones.
    void flush_occlusion(int bounce, int b) {
        if (pk_.size == 0) return;
        scratch_.occluded = OcclusionMask{};
        if (packet_coherence(pk_) >= min_coherence_) {
            PacketCounters pc = packet_counters();
            bvh_.occluded(pk_, scratch_.occluded, &pc);
            if (ctx_.instances) ctx_.instances->occluded(pk_, scratch_.occluded, &pc, lane_times());
            book_packet(bounce, RayType::Shadow, pc);
        } else {
            occluded_singly(bounce);
        }
        TraversalCounters motion;
        for (int i = 0; i < pk_.size; ++i) {
            const int p = scratch_.lane_path[i];
            if (!(scratch_.occluded.test(i) || motion_occluded(ctx_, tile_.states[size_t(p)], pk_.ray(i), &motion)))
                ++unoccluded_[size_t(p - b)];
        }
        if (ctx_.motion) book_work(st_, bounce, motion);
        pk_.clear();
    }

    // Incoherent packets: one ray at a time.
    void intersect_singly(int bounce, RayType type) {
        for (int i = 0; i < pk_.size; ++i) {
            TraversalCounters c;
            Hit h;
            const Ray r = pk_.ray(i);
            if (merge_instance_hit(ctx_, tile_.states[size_t(scratch_.lane_path[i])], r, bvh_.intersect(r, h, &c), h,
                                   &c)) {
                scratch_.hits.t[i] = h.t;
                scratch_.hits.u[i] = h.u;
                scratch_.hits.v[i] = h.v;
                scratch_.hits.prim[i] = h.prim;
                scratch_.hits.instance[i] = h.instance;
            }
            book_single_ray(st_, bounce, type, c, lane_node_visits(i));
        }
    }
    void occluded_singly(int bounce) {
        for (int i = 0; i < pk_.size; ++i) {
            TraversalCounters c;
            const Ray r = pk_.ray(i);
            if (bvh_.occluded(r, &c) || instance_occluded(ctx_, tile_.states[size_t(scratch_.lane_path[i])], r, &c))
                scratch_.occluded.set(i);
            book_single_ray(st_, bounce, RayType::Shadow, c, lane_node_visits(i));
        }
    }

    // Moving instances: each lane's shutter time (null when nothing moves).
    const float* lane_times() {
        if (!ctx_.instances->has_motion()) return nullptr;
        for (int i = 0; i < pk_.size; ++i) scratch_.lane_time[i] = tile_.states[size_t(scratch_.lane_path[i])].time;
        return scratch_.lane_time;
    }

    // Counters of one packet trace; with heatmaps, per-lane node visits too.
    PacketCounters packet_counters() {
        PacketCounters pc;
        if (heat_) {
            std::fill_n(scratch_.lane_visits, pk_.size, 0u);
            pc.ray_node_visits = scratch_.lane_visits;
        }
        return pc;
    }
    // Heatmaps: where lane i's path counts its node visits (null when off).
    uint32_t* lane_node_visits(int i) {
        return heat_ ? &tile_.node_visits[size_t(scratch_.lane_path[i])] : nullptr;
    }
    // Books one traced packet: totals, the bounce's statistics, per-path heatmap data.
    void book_packet(int bounce, RayType type, const PacketCounters& pc) {
        book_rays(st_, bounce, type, pc.rays);
        book_work(st_, bounce, pc);
        if (!heat_) return;
        for (int i = 0; i < pk_.size; ++i) {
            const size_t p = size_t(scratch_.lane_path[i]);
            tile_.node_visits[p] += scratch_.lane_visits[i];
            tile_.lanes[p] += pc.box_lanes;
            tile_.lanes_active[p] += pc.box_lanes_active;
        }
    }

    const PathContext& ctx_;
    const Bvh& bvh_;
    const PacketAssembly assembly_;
    PathTile& tile_;
    PacketScratch& scratch_;
    RayPacket& pk_;
    RenderStats& st_;
    const bool heat_;
    const float min_coherence_;
    bool defer_ = false;           // shading waits for the tile's extension rays (run())
    std::vector<int> unoccluded_;  // per path of the packet: its unoccluded occlusion rays
};

}  // namespace packet_detail

// Traces `tile` (all paths alive at bounce 0) to completion with packets.
template <bool kGlass, bool kLights>
void trace_tile_packets(const PathContext& ctx, PacketAssembly assembly, PathTile& tile,
                        packet_detail::PacketScratch& scratch, RenderStats& st) {
    packet_detail::PacketTileTracer<kGlass, kLights>(ctx, assembly, tile, scratch, st).run();
}

// Stream scratch: the tile's rays of one kind, traced as one stream.
struct StreamScratch {
    std::vector<Ray> rays;
    std::vector<Hit> hits;
    std::vector<uint8_t> occluded;
    std::vector<int> path;  // ray -> path
    std::vector<float> times;  // ray -> its path's shutter time (moving instances only)
    std::vector<uint8_t> found;  // ray -> a surface hit (motion merged)
    HitShading shading;          // a stretch of the stream's shader programs, run together
};

namespace stream_detail {

// Single-threaded, the whole stream at once: the renderer already runs one
// tile per task.
inline StreamOptions tile_stream_options() {
    StreamOptions options;
    options.slice_size = 0;  // the whole stream at once
    options.parallel = false;
    return options;
}

// Moving instances: each ray's shutter time (null when nothing moves).
inline const float* ray_times(const PathContext& ctx, const PathTile& tile, StreamScratch& scratch) {
    if (!ctx.instances->has_motion()) return nullptr;
    scratch.times.resize(scratch.path.size());
    for (size_t i = 0; i < scratch.path.size(); ++i) scratch.times[i] = tile.states[size_t(scratch.path[i])].time;
    return scratch.times.data();
}

inline void book_stream_work(RenderStats& st, int bounce, const StreamStats& ss) {
    book_work(st, bounce, work_of(ss));
}

// The live paths' extension rays as one stream, then their shading.
// Returns false when no path was alive.
template <bool kGlass, bool kLights>
bool extend(const PathContext& ctx, PathTile& tile, StreamScratch& scratch, RenderStats& st, int bounce) {
    scratch.rays.clear();
    scratch.path.clear();
    for (size_t p = 0; p < tile.size(); ++p)
        if (tile.states[p].alive) {
            scratch.rays.push_back(tile.states[p].ray);
            scratch.path.push_back(int(p));
        }
    if (scratch.rays.empty()) return false;
    scratch.hits.assign(scratch.rays.size(), Hit{});
    StreamStats ss;
    intersect_stream(*ctx.bvh, scratch.rays.data(), scratch.rays.size(), scratch.hits.data(), &ss,
                     tile_stream_options());
    if (ctx.instances)
        ctx.instances->intersect_stream(scratch.rays.data(), scratch.rays.size(), scratch.hits.data(), &ss,
                                        ray_times(ctx, tile, scratch));
    for (const int p : scratch.path) book_rays(st, bounce, tile.states[size_t(p)].type, 1);
    book_stream_work(st, bounce, ss);
    TraversalCounters motion;
    const size_t n = scratch.path.size();
    scratch.found.resize(n);
    for (size_t i = 0; i < n; ++i)
        scratch.found[i] = merge_motion_hit(ctx, tile.states[size_t(scratch.path[i])], scratch.hits[i].valid(),
                                            scratch.hits[i], &motion);
    for (size_t first = 0; first < n; first += kShadeChunk) {
        const size_t m = std::min(kShadeChunk, n - first);
        scratch.shading.prepare(
            ctx, m, [&](size_t i) { return scratch.found[first + i] ? &scratch.hits[first + i] : nullptr; },
            [&](size_t i) -> const PathState& { return tile.states[size_t(scratch.path[first + i])]; });
        for (size_t i = 0; i < m; ++i) {
            const size_t p = size_t(scratch.path[first + i]);
            shade_hit<kGlass, kLights>(ctx, tile.samplers[p], tile.states[p], scratch.found[first + i] != 0,
                                       scratch.hits[first + i], scratch.shading.at(i));
        }
    }
    if (ctx.motion) book_work(st, bounce, motion);
    return true;
}

// Every path's occlusion rays as one stream (path-major), then resolved.
inline void occlude(const PathContext& ctx, PathTile& tile, StreamScratch& scratch, RenderStats& st, int bounce) {
    scratch.rays.clear();
    scratch.path.clear();
    for (size_t p = 0; p < tile.size(); ++p) {
        const PathState& s = tile.states[p];
        for (int k = 0, n = occlusion_ray_count(s); k < n; ++k) {
            scratch.rays.push_back(occlusion_ray(ctx, tile.samplers[p], s, k));
            scratch.path.push_back(int(p));
        }
    }
    if (scratch.rays.empty()) return;
    scratch.occluded.assign(scratch.rays.size(), 0);
    StreamStats ss;
    occluded_stream(*ctx.bvh, scratch.rays.data(), scratch.rays.size(), scratch.occluded.data(), &ss,
                    tile_stream_options());
    if (ctx.instances)
        ctx.instances->occluded_stream(scratch.rays.data(), scratch.rays.size(), scratch.occluded.data(), &ss,
                                       ray_times(ctx, tile, scratch));
    book_rays(st, bounce, RayType::Shadow, scratch.rays.size());
    book_stream_work(st, bounce, ss);
    if (ctx.motion) {
        TraversalCounters mc;
        for (size_t i = 0; i < scratch.rays.size(); ++i)
            if (!scratch.occluded[i] &&
                motion_occluded(ctx, tile.states[size_t(scratch.path[i])], scratch.rays[i], &mc))
                scratch.occluded[i] = 1;
        book_work(st, bounce, mc);
    }
    resolve_occlusion_queue(scratch.occluded.data(), scratch.rays.size(),
                            [&](size_t i) -> PathState& { return tile.states[size_t(scratch.path[i])]; });
}

}  // namespace stream_detail

// Traces `tile` to completion with breadth-first ray streams (ray_stream.h):
// after every bounce, all the tile's extension rays form one stream, then
// all its occlusion rays (shadow rays; at the first hit, AO rays) another.
// Same shading, hence the same image, as the other drivers.
template <bool kGlass, bool kLights>
void trace_tile_streams(const PathContext& ctx, PathTile& tile, StreamScratch& scratch, RenderStats& st) {
    for (int bounce = 0; stream_detail::extend<kGlass, kLights>(ctx, tile, scratch, st, bounce); ++bounce)
        stream_detail::occlude(ctx, tile, scratch, st, bounce);
}

}  // namespace coherent
