// Batched driver of the path state machine (path_state.h): the paths of one
// tile advance bounce by bounce, and after every bounce their rays are
// gathered into SIMD packets (Boulos et al. 2007 section 3.2) within each
// packet of pixels:
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
// Shading is the state machine's, and packet kernels return the single-ray
// kernel's hits bit for bit, so the image equals the depth-first driver's
// (path_tracer.h) for the same sampler and seed.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "../accel/ray_packet.h"
#include "../accel/ray_stream.h"
#include "path_state.h"
#include "path_tracer.h"

namespace coherent {

// One tile's paths in packet-major order: paths [packet_begin[k],
// packet_begin[k + 1]) are the pixels of pixel packet k, row by row.
template <class Sampler>
struct PathBatch {
    std::vector<PathState> states;
    std::vector<PathSampler<Sampler>> samplers;
    std::vector<int> px, py;
    std::vector<int> packet_begin;  // packets + 1 entries
    // Heatmaps: node visits per path, and the SIMD lanes (all / active) of
    // the packets its rays were traced in.
    std::vector<uint32_t> node_visits;
    std::vector<uint64_t> lanes, lanes_active;

    // Starts the camera path of pixel (x, y)'s sample (the renderer's and
    // every batched driver's one way to fill a batch).
    template <bool kDepthOfField>
    void start(const PathContext& ctx, const Sampler& sampler, uint32_t sample, int x, int y) {
        samplers.emplace_back(sampler, uint32_t(x), uint32_t(y), sample);
        states.emplace_back();
        start_path<Sampler, kDepthOfField>(ctx, samplers.back(), x, y, states.back());
        px.push_back(x);
        py.push_back(y);
    }

    void clear() {
        states.clear();
        samplers.clear();
        px.clear();
        py.clear();
        packet_begin.assign(1, 0);
        node_visits.clear();
        lanes.clear();
        lanes_active.clear();
    }
    size_t size() const { return states.size(); }
};

namespace packet_detail {

// Books one traced packet: totals, the bounce's statistics, per-path heatmap data.
template <class Sampler>
inline void book_packet(RenderStats& st, int bounce, RayType type, const PacketCounters& pc, const RayPacket& pk,
                        const int* lane_path, const uint32_t* lane_visits, PathBatch<Sampler>& batch) {
    book_rays(st, bounce, type, pc.rays);
    book_work(st, bounce, pc);
    if (batch.node_visits.empty()) return;
    for (int i = 0; i < pk.size; ++i) {
        const int p = lane_path[i];
        batch.node_visits[size_t(p)] += lane_visits[i];
        batch.lanes[size_t(p)] += pc.box_lanes;
        batch.lanes_active[size_t(p)] += pc.box_lanes_active;
    }
}

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
};

}  // namespace packet_detail

// Traces `batch` (all paths alive at bounce 0) to completion with packets.
template <class Sampler, bool kGlass, bool kLights>
void trace_batch_packets(const PathContext& ctx, PacketAssembly assembly, PathBatch<Sampler>& batch,
                         packet_detail::PacketScratch& scratch, RenderStats& st) {
    using namespace packet_detail;
    const Bvh& bvh = *ctx.bvh;
    const bool heat = !batch.node_visits.empty();
    RayPacket& pk = scratch.packet;
    const int packets = int(batch.packet_begin.size()) - 1;
    const float min_coherence = ctx.settings->packet_min_coherence;

    // Traces the extension rays gathered in pk, then shades their paths.
    auto flush_extension = [&](int bounce, RayType type) {
        if (pk.size == 0) return;
        scratch.hits.reset(pk.size);
        if (packet_coherence(pk) >= min_coherence) {
            PacketCounters pc;
            if (heat) {
                std::fill_n(scratch.lane_visits, pk.size, 0u);
                pc.ray_node_visits = scratch.lane_visits;
            }
            bvh.intersect(pk, scratch.hits, &pc);
            book_packet(st, bounce, type, pc, pk, scratch.lane_path, scratch.lane_visits, batch);
        } else {  // incoherent: one ray at a time
            for (int i = 0; i < pk.size; ++i) {
                TraversalCounters c;
                Hit h;
                if (bvh.intersect(pk.ray(i), h, &c)) {
                    scratch.hits.t[i] = h.t;
                    scratch.hits.u[i] = h.u;
                    scratch.hits.v[i] = h.v;
                    scratch.hits.prim[i] = h.prim;
                }
                book_single_ray(st, bounce, type, c, heat ? &batch.node_visits[size_t(scratch.lane_path[i])] : nullptr);
            }
        }
        TraversalCounters motion;  // moving triangles: one ray at a time
        for (int i = 0; i < pk.size; ++i) {
            const size_t p = size_t(scratch.lane_path[i]);
            Hit h = scratch.hits.hit(i);
            const bool found = merge_motion_hit(ctx, batch.states[p], h.valid(), h, &motion);
            shade_hit<Sampler, kGlass, kLights>(ctx, batch.samplers[p], batch.states[p], found, h);
        }
        if (ctx.motion) book_work(st, bounce, motion);
        pk.clear();
    };
    // Traces the occlusion rays gathered in pk; `done(lane, occluded)` takes each result.
    auto flush_occlusion = [&](int bounce, auto&& done) {
        if (pk.size == 0) return;
        scratch.occluded = OcclusionMask{};
        if (packet_coherence(pk) >= min_coherence) {
            PacketCounters pc;
            if (heat) {
                std::fill_n(scratch.lane_visits, pk.size, 0u);
                pc.ray_node_visits = scratch.lane_visits;
            }
            bvh.occluded(pk, scratch.occluded, &pc);
            book_packet(st, bounce, RayType::Shadow, pc, pk, scratch.lane_path, scratch.lane_visits, batch);
        } else {
            for (int i = 0; i < pk.size; ++i) {
                TraversalCounters c;
                if (bvh.occluded(pk.ray(i), &c)) scratch.occluded.set(i);
                book_single_ray(st, bounce, RayType::Shadow, c,
                                heat ? &batch.node_visits[size_t(scratch.lane_path[i])] : nullptr);
            }
        }
        TraversalCounters motion;
        for (int i = 0; i < pk.size; ++i)
            done(i, scratch.occluded.test(i) ||
                        motion_occluded(ctx, batch.states[size_t(scratch.lane_path[i])], pk.ray(i), &motion));
        if (ctx.motion) book_work(st, bounce, motion);
        pk.clear();
    };

    std::vector<int> ao_unoccluded;
    int pending[kMaxPacketRays];
    RayType pending_type[kMaxPacketRays];
    pk.clear();
    for (int bounce = 0;; ++bounce) {
        bool any_alive = false;
        for (int k = 0; k < packets; ++k) {
            const int b = batch.packet_begin[size_t(k)], e = batch.packet_begin[size_t(k) + 1];
            // Extension rays.
            if (assembly == PacketAssembly::RayType) {
                // One packet per ray type present. The participants are
                // fixed first: shading a packet gives its paths their next
                // ray, which must wait for the next bounce.
                int count = 0;
                uint32_t types = 0;
                for (int p = b; p < e; ++p) {
                    const PathState& s = batch.states[size_t(p)];
                    if (!s.alive) continue;
                    pending[count] = p;
                    pending_type[count++] = s.type;
                    types |= 1u << unsigned(s.type);
                }
                for (; types; types &= types - 1) {
                    const RayType t = RayType(__builtin_ctz(types));
                    for (int i = 0; i < count; ++i) {
                        if (pending_type[i] != t) continue;
                        scratch.lane_path[pk.size] = pending[i];
                        pk.push(batch.states[size_t(pending[i])].ray);
                    }
                    flush_extension(bounce, t);
                }
            } else {
                RayType run = RayType::Count;
                for (int p = b; p < e; ++p) {
                    const PathState& s = batch.states[size_t(p)];
                    if (!s.alive || s.type != run) {
                        flush_extension(bounce, run);
                        run = s.alive ? s.type : RayType::Count;
                        if (!s.alive) continue;
                    }
                    scratch.lane_path[pk.size] = p;
                    pk.push(s.ray);
                }
                flush_extension(bounce, run);
            }
            // Shadow rays of this packet's paths (one type: the assemblies
            // differ only in whether a path without one ends the run).
            auto shadow_done = [&](int lane, bool occluded) {
                resolve_shadow(batch.states[size_t(scratch.lane_path[lane])], occluded);
            };
            for (int p = b; p < e; ++p) {
                const PathState& s = batch.states[size_t(p)];
                if (!s.has_shadow) {
                    if (assembly == PacketAssembly::Runs) flush_occlusion(bounce, shadow_done);
                    continue;
                }
                scratch.lane_path[pk.size] = p;
                pk.push(s.shadow);
            }
            flush_occlusion(bounce, shadow_done);
            // Ambient occlusion rays (first hits only), by ray index.
            if (bounce == 0 && ctx.settings->integrator == Integrator::AmbientOcclusion) {
                ao_unoccluded.assign(size_t(e - b), 0);
                auto ao_done = [&](int lane, bool occluded) {
                    if (!occluded) ++ao_unoccluded[size_t(scratch.lane_path[lane] - b)];
                };
                const int rays = ctx.settings->ao_samples;
                for (int i = 0; i < rays; ++i)
                    for (int p = b; p < e; ++p) {
                        const PathState& s = batch.states[size_t(p)];
                        if (s.ao_rays <= i) {
                            if (assembly == PacketAssembly::Runs) flush_occlusion(bounce, ao_done);
                            continue;
                        }
                        if (pk.size == kMaxPacketRays) flush_occlusion(bounce, ao_done);
                        scratch.lane_path[pk.size] = p;
                        pk.push(ao_ray(ctx, batch.samplers[size_t(p)], s, i));
                    }
                flush_occlusion(bounce, ao_done);
                for (int p = b; p < e; ++p) resolve_ao(batch.states[size_t(p)], ao_unoccluded[size_t(p - b)]);
            }
            for (int p = b; p < e && !any_alive; ++p) any_alive = batch.states[size_t(p)].alive;
        }
        if (!any_alive) break;
    }
}

}  // namespace coherent

namespace coherent {

// Stream scratch: the batch's rays of one kind, traced as one stream.
struct StreamScratch {
    std::vector<Ray> rays;
    std::vector<Hit> hits;
    std::vector<uint8_t> occluded;
    std::vector<int> path;  // ray -> path
};

// Traces `batch` to completion with breadth-first ray streams (ray_stream.h):
// after every bounce, all the batch's extension rays form one stream, then
// all its shadow rays (and at the first hit all its AO rays) another. The
// stream runs on the calling thread (the renderer already runs one batch
// per task). Same shading, hence the same image, as the other drivers.
template <class Sampler, bool kGlass, bool kLights>
void trace_batch_streams(const PathContext& ctx, PathBatch<Sampler>& batch, StreamScratch& scratch,
                         RenderStats& st) {
    const Bvh& bvh = *ctx.bvh;
    StreamOptions options;
    options.slice_size = 0;  // the whole stream at once
    options.parallel = false;
    auto book = [&](int bounce, const StreamStats& ss, const std::vector<int>& path, auto&& type_of) {
        for (size_t i = 0; i < path.size(); ++i) book_rays(st, bounce, type_of(path[i]), 1);
        TraversalCounters c;
        c.node_visits = ss.node_visits;
        c.box_tests = ss.box_tests;
        c.triangle_tests = ss.triangle_tests;
        book_work(st, bounce, c);
    };
    auto shadow_type = [](int) { return RayType::Shadow; };
    for (int bounce = 0;; ++bounce) {
        scratch.rays.clear();
        scratch.path.clear();
        for (size_t p = 0; p < batch.size(); ++p)
            if (batch.states[p].alive) {
                scratch.rays.push_back(batch.states[p].ray);
                scratch.path.push_back(int(p));
            }
        if (scratch.rays.empty()) break;
        scratch.hits.assign(scratch.rays.size(), Hit{});
        StreamStats ss;
        intersect_stream(bvh, scratch.rays.data(), scratch.rays.size(), scratch.hits.data(), &ss, options);
        book(bounce, ss, scratch.path, [&](int p) { return batch.states[size_t(p)].type; });
        TraversalCounters motion;
        for (size_t i = 0; i < scratch.path.size(); ++i) {
            const size_t p = size_t(scratch.path[i]);
            const bool found = merge_motion_hit(ctx, batch.states[p], scratch.hits[i].valid(), scratch.hits[i], &motion);
            shade_hit<Sampler, kGlass, kLights>(ctx, batch.samplers[p], batch.states[p], found, scratch.hits[i]);
        }
        if (ctx.motion) book_work(st, bounce, motion);
        // Occlusion rays: shadow rays, and at the first hit the AO rays.
        scratch.rays.clear();
        scratch.path.clear();
        for (size_t p = 0; p < batch.size(); ++p) {
            const PathState& s = batch.states[p];
            if (s.has_shadow) {
                scratch.rays.push_back(s.shadow);
                scratch.path.push_back(int(p));
            }
            for (int i = 0; i < s.ao_rays; ++i) {
                scratch.rays.push_back(ao_ray(ctx, batch.samplers[p], s, i));
                scratch.path.push_back(int(p));
            }
        }
        if (scratch.rays.empty()) continue;
        scratch.occluded.assign(scratch.rays.size(), 0);
        occluded_stream(bvh, scratch.rays.data(), scratch.rays.size(), scratch.occluded.data(), &ss, options);
        book(bounce, ss, scratch.path, shadow_type);
        if (ctx.motion) {
            TraversalCounters mc;
            for (size_t i = 0; i < scratch.rays.size(); ++i)
                if (!scratch.occluded[i] && motion_occluded(ctx, batch.states[size_t(scratch.path[i])], scratch.rays[i], &mc))
                    scratch.occluded[i] = 1;
            book_work(st, bounce, mc);
        }
        // Rays of a path are consecutive: its shadow ray, or its AO rays.
        for (size_t i = 0; i < scratch.path.size();) {
            PathState& s = batch.states[size_t(scratch.path[i])];
            if (s.has_shadow) {
                resolve_shadow(s, scratch.occluded[i] != 0);
                ++i;
            } else {
                int unoccluded = 0;
                for (int k = 0; k < s.ao_rays; ++k, ++i) unoccluded += scratch.occluded[i] ? 0 : 1;
                resolve_ao(s, unoccluded);
            }
        }
    }
}

}  // namespace coherent
