// Render statistics: what was traced, by ray type and bounce, and what was
// discarded; and how every driver books its rays and traversal work.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include "../accel/bvh.h"
#include "../accel/ray_packet.h"

namespace coherent {

enum class RayType : uint8_t { Camera, Shadow, Diffuse, Glossy, Reflection, Refraction, Count };
const char* ray_type_name(RayType t);  // "camera", "shadow", "diffuse", ...

// Work of one bounce depth (0 = camera rays and their shadow rays, 1 = the
// first bounce and its shadow rays, ...; the last entry collects every
// deeper bounce), the packets paper's per-bounce metrics.
struct BounceStats {
    uint64_t rays = 0;            // rays traced (all types, shadow rays included)
    uint64_t node_visits = 0;     // single ray: node visits; packets: (packet, node) visits
    uint64_t box_tests = 0;       // ray-box tests (active lanes; see ray_packet.h)
    uint64_t triangle_tests = 0;  // ray-triangle tests
    // SIMD lanes of packet box / triangle tests and how many held an active
    // ray (0 for single-ray traversal, which has no packets).
    uint64_t box_lanes = 0, box_lanes_active = 0;
    uint64_t triangle_lanes = 0, triangle_lanes_active = 0;
    BounceStats& operator+=(const BounceStats& o);

    // Per-ray work and SIMD utilisation; empty where nothing was measured
    // (no rays, no packet lanes): a missing measurement is not a 0.
    std::optional<double> node_visits_per_ray() const { return ratio(node_visits, rays); }
    std::optional<double> box_tests_per_ray() const { return ratio(box_tests, rays); }
    std::optional<double> triangle_tests_per_ray() const { return ratio(triangle_tests, rays); }
    std::optional<double> box_utilisation() const { return ratio(box_lanes_active, box_lanes); }
    std::optional<double> triangle_utilisation() const { return ratio(triangle_lanes_active, triangle_lanes); }

private:
    static std::optional<double> ratio(uint64_t num, uint64_t den) {
        return den ? std::optional<double>(double(num) / double(den)) : std::nullopt;
    }
};
constexpr int kStatBounces = 8;

// What a render holds in memory (memory_budget.h measures and checks it).
struct MemoryStats {
    uint64_t triangles = 0;
    uint64_t scene_bytes = 0;     // the scene's arrays: geometry, per-triangle data, materials, lights
    uint64_t bvh_bytes = 0;       // the BVH as built (plus the motion BVH of moving triangles)
    uint64_t film_bytes = 0;      // the film's per-pixel accumulators
    // The check before the BVH build: what it expected the render to need
    // (scene, the build's peak, film) and the limit it compared that with
    // (0: none known).
    uint64_t estimate_bytes = 0;
    uint64_t limit_bytes = 0;
    // The process's resident-memory high-water mark after the render
    // (VmHWM; the host application's own memory included); 0: unknown.
    uint64_t peak_rss_bytes = 0;
    // Instances of shared meshes and the bytes of their records (transforms,
    // material slots, motion); their BVHs are in bvh_bytes.
    uint64_t instances = 0;
    uint64_t instance_bytes = 0;

    // Scene and BVH bytes per triangle; empty without triangles.
    std::optional<double> bytes_per_triangle() const {
        return triangles ? std::optional<double>(double(scene_bytes + bvh_bytes) / double(triangles)) : std::nullopt;
    }
    std::optional<double> bvh_bytes_per_triangle() const {
        return triangles ? std::optional<double>(double(bvh_bytes) / double(triangles)) : std::nullopt;
    }
    std::optional<double> bytes_per_instance() const {
        return instances ? std::optional<double>(double(instance_bytes) / double(instances)) : std::nullopt;
    }

    // The figures every report shows (the CLI's JSON report, Renderer.stats()
    // in Python), in order: visit(name, value) with value a uint64_t, or an
    // optional (empty: unknown or undefined) uint64_t or double.
    template <class Visit>
    void for_each_reported(Visit&& visit) const {
        auto known = [](uint64_t v) { return v ? std::optional<uint64_t>(v) : std::nullopt; };
        visit("triangles", triangles);
        visit("scene_bytes", scene_bytes);
        visit("bvh_bytes", bvh_bytes);
        visit("film_bytes", film_bytes);
        visit("bytes_per_triangle", bytes_per_triangle());  // scene + BVH
        visit("bvh_bytes_per_triangle", bvh_bytes_per_triangle());
        visit("estimate_bytes", estimate_bytes);  // what the check before the BVH build expected
        visit("limit_bytes", known(limit_bytes));
        visit("peak_rss_bytes", known(peak_rss_bytes));  // the process's high-water mark (VmHWM)
        visit("instances", instances);
        visit("bytes_per_instance", bytes_per_instance());  // records only; their BVHs are in bvh_bytes
    }
};

struct RenderStats {
    std::array<uint64_t, size_t(RayType::Count)> rays{};
    TraversalCounters traversal;
    std::array<BounceStats, kStatBounces> bounces{};
    // Seconds spent in tracing and in reordering (wavefront; summed over
    // threads, so CPU seconds). 0 where a mode does not separate them.
    double trace_seconds = 0.0;
    double sort_seconds = 0.0;
    uint64_t nonfinite_samples = 0;  // samples whose value was NaN/Inf, discarded
    uint64_t samples = 0;            // pixel samples finished
    // Sample passes actually completed (samples per pixel taken); distributing
    // samples (settings.h), the mean samples per pixel, rounded.
    int spp = 0;
    // Adaptive sampling: pixels that stopped receiving samples (0 when off),
    // out of `pixels` in the film (the render border).
    uint64_t converged_pixels = 0;
    uint64_t pixels = 0;
    double converged_fraction() const { return pixels ? double(converged_pixels) / double(pixels) : 0.0; }
    // Film::relative_rmse_estimate() after the last completed pass; negative
    // while unknown (fewer than 2 passes) and when not estimated
    // (RenderSettings::error_estimated()).
    double error_estimate = -1.0;
    // Denoising (settings.denoise): the denoised image's relative RMSE
    // estimate from its filtered halves (negative: not denoised), and the
    // denoiser's wall-clock seconds (part of `seconds`).
    double denoised_error_estimate = -1.0;
    double denoise_seconds = 0.0;
    double seconds = 0.0;
    MemoryStats memory;  // set by the renderer, not summed over threads

    // All bounces together, and the deepest bounce that traced a ray (-1: none).
    BounceStats bounce_total() const {
        BounceStats all;
        for (const BounceStats& b : bounces) all += b;
        return all;
    }
    int deepest_bounce() const {
        int last = -1;
        for (int i = 0; i < kStatBounces; ++i)
            if (bounces[size_t(i)].rays) last = i;
        return last;
    }

    uint64_t total_rays() const {
        uint64_t n = 0;
        for (uint64_t r : rays) n += r;
        return n;
    }
    RenderStats& operator+=(const RenderStats& o);
};

// Booking of traversal work into RenderStats, shared by every driver. The
// invariant the tests check: the bounces' rays add up to total_rays() and
// to traversal.rays, and their tests to the traversal totals.
inline BounceStats& bounce_stats(RenderStats& st, int bounce) {
    return st.bounces[size_t(std::min(bounce, kStatBounces - 1))];
}

// Work only (node visits, box and triangle tests), not rays: for work that
// traced no new ray (the moving triangles' BVH after the static one).
inline void book_work(RenderStats& st, int bounce, const TraversalCounters& c) {
    st.traversal.node_visits += c.node_visits;
    st.traversal.box_tests += c.box_tests;
    st.traversal.triangle_tests += c.triangle_tests;
    BounceStats& b = bounce_stats(st, bounce);
    b.node_visits += c.node_visits;
    b.box_tests += c.box_tests;
    b.triangle_tests += c.triangle_tests;
}

// The node visits, box and triangle tests of any kernel's counters
// (PacketCounters, StreamStats) as TraversalCounters.
template <class Counters>
TraversalCounters work_of(const Counters& k) {
    TraversalCounters c;
    c.node_visits = k.node_visits;
    c.box_tests = k.box_tests;
    c.triangle_tests = k.triangle_tests;
    return c;
}

// A packet's work, with its SIMD lanes.
inline void book_work(RenderStats& st, int bounce, const PacketCounters& pc) {
    book_work(st, bounce, work_of(pc));
    BounceStats& b = bounce_stats(st, bounce);
    b.box_lanes += pc.box_lanes;
    b.box_lanes_active += pc.box_lanes_active;
    b.triangle_lanes += pc.triangle_lanes;
    b.triangle_lanes_active += pc.triangle_lanes_active;
}

// `rays` new rays of `type` at `bounce` (their work booked separately).
inline void book_rays(RenderStats& st, int bounce, RayType type, uint64_t rays) {
    st.rays[size_t(type)] += rays;
    st.traversal.rays += rays;
    bounce_stats(st, bounce).rays += rays;
}

// One single ray and its work; for heatmaps, its node visits to the path.
inline void book_single_ray(RenderStats& st, int bounce, RayType type, const TraversalCounters& c,
                            uint32_t* path_node_visits) {
    book_rays(st, bounce, type, 1);
    book_work(st, bounce, c);
    if (path_node_visits) *path_node_visits += uint32_t(c.node_visits);
}

}  // namespace coherent
