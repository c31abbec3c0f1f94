// The wavefront pipeline (paper 004 section 4, Fig. 5; Laine et al. 2013):
// instead of one path at a time (path_tracer.h), a wave of at most wave_size
// paths advances stage by stage over flat per-path arrays:
//
//   generate  camera rays of the wave's pixels (start_path)
//   extend    every live path's extension ray, as one ray queue: reorder,
//             trace (Bvh::intersect), shade (shade_hit), which may queue a
//             shadow ray or ambient occlusion rays and set up the next
//             extension ray
//   shadow    every queued shadow and AO ray of the wave, as one ray queue:
//             reorder, trace (Bvh::occluded), resolve (resolve_occlusion)
//   repeat extend + shadow until no path is alive; then the wave's samples
//   are handed out and the next wave starts in the same buffers.
//
// Reordering (ray_reorder.h) permutes the order in which a queue is traced,
// never which rays exist or how their results are used, and each path runs
// the state machine (path_state.h) in the same sequence as the depth-first
// driver: so every reorder mode, gather or not, packets or not, gives the
// same image as Traversal::Single, bit for bit, for the same sampler and seed.
//
// Memory: every buffer is sized by the wave, never by the image: at most
// wave_size paths, at most wave_size extension rays and wave_size * max(1,
// ao_samples) occlusion rays per queue. Buffers are kept between waves and
// passes (one WavefrontRenderer per thread).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>

#include "../sample/image_sampler.h"
#include "path_state.h"
#include "ray_reorder.h"

namespace coherent {

struct WavefrontOptions {
    ReorderMode reorder = ReorderMode::None;
    int wave_size = 1 << 16;  // paths in flight at most (>= 1)
    ReorderOptions sort;      // radix or comparison sort, digit width
    // Whether queues of camera rays are reordered too. Off by default, as in
    // the paper: camera rays leave the pixels in generation (row) order,
    // which is already coherent; sorting them would only cost.
    bool reorder_camera_rays = false;
    // After reordering, copy the queue's rays into traced order and trace
    // them from contiguous memory (true), or trace through the permutation
    // (false). Same results; a cost choice (measured in bench/reorder_bench).
    bool gather = true;
    // 0: trace single rays. 1..256: trace consecutive rays of the (ordered)
    // queue as SIMD packets of this many rays (ray_packet.h); same results.
    int packet_size = 0;
    // Traversal counters into RenderStats (rays per bounce, node visits...).
    bool counters = true;
    // Per-path BVH node visits, handed to the output callback (heatmaps);
    // needs `counters`.
    bool node_visits = false;

    // The renderer's choices: reorder and wave_size from the settings.
    static WavefrontOptions from_settings(const RenderSettings& rs);
};

// What the pipeline did, summed over every wave rendered so far.
struct WavefrontStats {
    ReorderTimings reorder;      // reorder time by stage (thread CPU seconds)
    double trace_seconds = 0.0;  // thread CPU seconds in Bvh::intersect / occluded
    double total_seconds = 0.0;  // thread CPU seconds in render_pass, all stages
    uint64_t waves = 0;
    uint64_t queues = 0;         // extension and occlusion ray queues traced
    uint64_t rays = 0;           // rays traced
    size_t max_paths = 0;        // largest wave (<= wave_size)
    size_t peak_bytes = 0;       // largest footprint of all buffers after a wave
    // Bytes of buffers per path in flight at the largest wave.
    double bytes_per_path() const { return max_paths ? double(peak_bytes) / double(max_paths) : 0.0; }
};

// One finished camera sample: pixel (full-frame coordinates), its output,
// its BVH node visits (0 unless WavefrontOptions::node_visits).
using WaveOutput = std::function<void(int x, int y, const PathOutput& out, uint32_t node_visits)>;
// Pixels to leave out (adaptive sampling); may be empty.
using WaveSkip = std::function<bool(int x, int y)>;

class WavefrontRenderer {
public:
    // `ctx` (with ctx.ao_distance resolved) must outlive the renderer. The
    // feature flags select the kernel as for the single-ray driver:
    // glass lobes, lens sampling, lights (next-event estimation).
    WavefrontRenderer(const PathContext& ctx, const WavefrontOptions& opt, bool glass, bool depth_of_field,
                      bool lights);
    ~WavefrontRenderer();
    WavefrontRenderer(const WavefrontRenderer&) = delete;
    WavefrontRenderer& operator=(const WavefrontRenderer&) = delete;

    // Sample `sample` of every pixel of [x0, x1) x [y0, y1) (full-frame
    // coordinates) that `skip` does not leave out, in waves of at most
    // wave_size pixels taken in row order. `output` is called once per pixel,
    // after the pixel's wave finished, in row order, on this thread.
    // Statistics go to `st` (rays, traversal counters per bounce,
    // trace_seconds, sort_seconds). Returns false if `cancelled` was seen
    // set; the waves not finished then were not output.
    bool render_pass(const ImageSampler& sampler, uint32_t sample, int x0, int y0, int x1, int y1,
                     const WaveSkip& skip, const WaveOutput& output, RenderStats& st,
                     const std::atomic<bool>* cancelled = nullptr);

    const WavefrontStats& stats() const { return stats_; }
    const WavefrontOptions& options() const { return opt_; }
    size_t buffer_bytes() const;  // current capacity of every buffer

    struct Buffers;  // the wave's arrays (wavefront.cpp)

private:
    const PathContext& ctx_;
    WavefrontOptions opt_;
    std::unique_ptr<Buffers> buf_;
    WavefrontStats stats_;
    using WaveFn = void (*)(WavefrontRenderer&, const ImageSampler&, uint32_t, RenderStats&, const std::atomic<bool>*);
    WaveFn run_wave_;
    template <bool kGlass, bool kDepthOfField, bool kLights>
    static void run_wave(WavefrontRenderer& self, const ImageSampler& sampler, uint32_t sample, RenderStats& st,
                         const std::atomic<bool>* cancelled);
};

}  // namespace coherent
