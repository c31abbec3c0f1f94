// The Renderer: pass-by-pass progressive rendering over tiles with TBB, in
// batches of passes between progress reports (TileQueue, batch_size).
//
// Determinism: every random number is keyed by (full-frame pixel, sample,
// dimension), every pixel belongs to exactly one tile, and a tile's passes
// run one after another, so the film is bit-identical for any thread count
// and batch size. Statistics are accumulated per thread
// (enumerable_thread_specific) and merged after each batch: no atomics in
// the per-ray path.
#include "renderer.h"
#include "sample_distribution.h"

#include "setting_table.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <thread>

#include "../denoise/denoiser.h"
#include "../sample/image_sampler.h"
#include "kernel_variants.h"
#include "light_sampling.h"
#include "memory_budget.h"
#include "packet_paths.h"
#include "path_tracer.h"
#include "wavefront.h"

namespace coherent {

namespace {

using Clock = std::chrono::steady_clock;

struct TileJob {
    const PathContext* ctx;
    const ImageSampler* sampler;
    Film* film;
    int x0, y0, x1, y1;  // full-frame pixel rectangle, half-open
    int border_x0, border_y0;
    uint32_t sample;       // the first sample of this call
    uint32_t samples = 1;  // samples each pixel takes, from `sample` on (>1: TileLayout::pixel_runs kernels only)
    const std::atomic<bool>* cancelled;
    const uint8_t* converged;  // per film pixel, row stride film width; null = none skipped
    // Distributing samples (sample_distribution.h): per film pixel, the
    // sample index a pixel stops before; null = every pixel takes every sample.
    const uint32_t* sample_targets = nullptr;
    int film_width;
    bool heatmaps;
    bool denoising_features;
    bool passes;  // Cycles' passes (film/passes.h) are enabled
    int packet_width, packet_height;  // packet traversal: pixels per packet
    PacketAssembly assembly;
    struct WavefrontPool* wavefront;  // wavefront traversal: per-thread pipelines

    size_t film_index(int x, int y) const { return size_t(y - border_y0) * size_t(film_width) + size_t(x - border_x0); }
    bool skip(int x, int y) const {
        // Adaptive sampling: a converged pixel keeps its mean and takes no more samples.
        return (converged && converged[film_index(x, y)]) ||
               (sample_targets && sample >= sample_targets[film_index(x, y)]);
    }
    // How many of the call's samples pixel (x, y) takes (pixel-run kernels).
    uint32_t samples_of(int x, int y) const {
        if (!sample_targets) return samples;
        const uint32_t target = sample_targets[film_index(x, y)];
        return target > sample ? std::min(samples, target - sample) : 0u;
    }
    // Adds finished sample `sample` to the film. No NaN/Inf ever reaches the
    // film: a non-finite sample is discarded whole and counted.
    void add(int x, int y, uint32_t sample, const PathOutput& o, float node_visits, float simd_utilisation,
             RenderStats& st) const {
        if (!is_finite(o.radiance) || !std::isfinite(o.alpha) || std::isnan(o.depth) || !is_finite(o.normal)) {
            ++st.nonfinite_samples;
            return;
        }
        film->add_sample(x - border_x0, y - border_y0, o.radiance, o.alpha, o.depth, o.normal, sample);
        if (heatmaps) film->add_heatmap_sample(x - border_x0, y - border_y0, node_visits, simd_utilisation);
        if (denoising_features) {
            const bool ok = is_finite(o.albedo) && is_finite(o.denoising_normal) && std::isfinite(o.denoising_depth);
            film->add_denoising_features(x - border_x0, y - border_y0, ok ? o.albedo : Vec3f(0.0f),
                                         ok ? o.denoising_normal : Vec3f(0.0f), ok ? o.denoising_depth : 0.0f,
                                         sample);
            // Finite where the radiance is (a part of it); the guard keeps that an invariant.
            film->add_direct_light(x - border_x0, y - border_y0, is_finite(o.direct) ? o.direct : Vec3f(0.0f),
                                   sample);
        }
        if (passes) add_passes(x, y, sample, o.passes, st);
        ++st.samples;
    }
    // A non-finite pass value is dropped (counted) without dropping the sample.
    void add_passes(int x, int y, uint32_t sample, const PassSample& values, RenderStats& st) const {
        for (float v : values.v)
            if (!std::isfinite(v)) {
                ++st.nonfinite_samples;
                return;
            }
        film->add_passes(x - border_x0, y - border_y0, values, sample);
    }
};

// Single rays: each pixel's paths depth-first (path_tracer.h), the call's
// samples of one pixel one after another, as Cycles' CPU kernel takes them:
// the texels and BVH nodes a pixel's paths touch are still in cache for its
// next sample, where a pass over the tile would have evicted them.
// Where pixels share their random numbers (CPT's packets,
// ImageSampler::shared_stream_block), the tile is walked block by block:
// each sample's stream is resolved once per block, and each of its sets is
// drawn by the first of the block's paths that reads it (SharedSets). The
// same numbers either way, so the same image. Returns early on cancel.
template <bool kGlass, bool kDepthOfField, bool kLights>
void render_tile(const TileJob& job, RenderStats& st) {
    const ImageSampler::SharedBlock shared = job.sampler->shared_stream_block();
    const bool share = shared.width > 0 && shared.height > 0;
    // Without sharing, a block is one row of the tile.
    const int bw = share ? int(shared.width) : job.x1 - job.x0;
    const int bh = share ? int(shared.height) : 1;
    std::vector<SampleStream> streams;
    std::vector<SharedSets> sets(share ? job.samples : 0);
    for (int by = share ? job.y0 - job.y0 % bh : job.y0; by < job.y1; by += bh)
        for (int bx = share ? job.x0 - job.x0 % bw : job.x0; bx < job.x1; bx += bw) {
            if (job.cancelled->load(std::memory_order_relaxed)) return;
            const int x0 = std::max(bx, job.x0), x1 = std::min(bx + bw, job.x1);
            const int y0 = std::max(by, job.y0), y1 = std::min(by + bh, job.y1);
            if (share) {
                streams.clear();
                for (uint32_t i = 0; i < job.samples; ++i) {
                    streams.push_back(job.sampler->stream(uint32_t(x0), uint32_t(y0), job.sample + i));
                    sets[i].filled = 0;
                    streams.back().share(&sets[i]);
                }
            }
            for (int y = y0; y < y1; ++y)
                for (int x = x0; x < x1; ++x) {
                    if (job.skip(x, y)) continue;
                    const uint32_t samples = job.samples_of(x, y);
                    for (uint32_t i = 0; i < samples; ++i) {
                        const uint32_t sample = job.sample + i;
                        const PathSampler ps = share ? PathSampler(streams[i])
                                                     : PathSampler(*job.sampler, uint32_t(x), uint32_t(y), sample);
                        uint32_t visits = 0;
                        const PathOutput o = trace_path<kGlass, kDepthOfField, kLights>(
                            *job.ctx, ps, x, y, st, job.heatmaps ? &visits : nullptr);
                        // Single rays use every lane they have: utilisation 1.
                        job.add(x, y, sample, o, float(visits), 1.0f, st);
                    }
                }
        }
}

// ICPT: a packet is one Latin-hypercube subset of a region of 2 x 2 blocks
// (n pixels per block, 4n rays), the pixels that share a sequence; a block's
// own pixels use n different sequences.
template <bool kDepthOfField>
void start_icpt_packets(const TileJob& job, PathTile& tile) {
    const int n = int(job.sampler->icpt_block_size());
    std::vector<std::vector<std::pair<int, int>>> subsets(static_cast<size_t>(n));  // pixels of each subset
    for (int ry = job.y0; ry < job.y1; ry += 2 * n)
        for (int rx = job.x0; rx < job.x1; rx += 2 * n) {
            for (auto& list : subsets) list.clear();
            for (int y = ry; y < std::min(ry + 2 * n, job.y1); ++y)
                for (int x = rx; x < std::min(rx + 2 * n, job.x1); ++x)
                    subsets[job.sampler->icpt_subset(uint32_t(x), uint32_t(y), job.sample)].emplace_back(x, y);
            for (const auto& list : subsets) {
                for (const auto& [x, y] : list)
                    if (!job.skip(x, y)) tile.start<kDepthOfField>(*job.ctx, *job.sampler, job.sample, x, y);
                tile.end_packet();
            }
        }
}

// SPT, CPT: a packet is a rectangle of packet_width x packet_height pixels.
template <bool kDepthOfField>
void start_pixel_packets(const TileJob& job, PathTile& tile) {
    for (int by = job.y0; by < job.y1; by += job.packet_height)
        for (int bx = job.x0; bx < job.x1; bx += job.packet_width) {
            for (int y = by; y < std::min(by + job.packet_height, job.y1); ++y)
                for (int x = bx; x < std::min(bx + job.packet_width, job.x1); ++x)
                    if (!job.skip(x, y)) tile.start<kDepthOfField>(*job.ctx, *job.sampler, job.sample, x, y);
            tile.end_packet();
        }
}

// Packets: the tile's paths bounce by bounce, rays gathered per pixel packet
// (packet_paths.h).
template <bool kGlass, bool kDepthOfField, bool kLights>
void render_tile_packets(const TileJob& job, RenderStats& st) {
    if (job.cancelled->load(std::memory_order_relaxed)) return;
    // Kept per thread across calls: a tile's paths are ~0.5 MB, which a fresh
    // PathTile would allocate (and the kernel zero page by page) every pass.
    thread_local PathTile tile;
    thread_local std::unique_ptr<packet_detail::PacketScratch> scratch;
    tile.clear();
    if (job.sampler->type() == SamplerType::Icpt) start_icpt_packets<kDepthOfField>(job, tile);
    else start_pixel_packets<kDepthOfField>(job, tile);
    tile.share_numbers(*job.sampler);
    if (job.heatmaps) tile.enable_heatmaps();
    if (!scratch) scratch = std::make_unique<packet_detail::PacketScratch>();
    trace_tile_packets<kGlass, kLights>(*job.ctx, job.assembly, tile, *scratch, st);
    for (size_t p = 0; p < tile.size(); ++p) {
        const float visits = job.heatmaps ? float(tile.node_visits[p]) : 0.0f;
        const float util = job.heatmaps && tile.lanes[p] ? float(double(tile.lanes_active[p]) / double(tile.lanes[p]))
                                                         : 1.0f;
        job.add(tile.px[p], tile.py[p], job.sample, tile.states[p].out, visits, util, st);
    }
}

// Streams: the tile's paths bounce by bounce, each bounce's rays of the
// whole tile traced as one breadth-first stream (packet_paths.h).
template <bool kGlass, bool kDepthOfField, bool kLights>
void render_tile_streams(const TileJob& job, RenderStats& st) {
    if (job.cancelled->load(std::memory_order_relaxed)) return;
    thread_local PathTile tile;  // kept per thread, as the packet kernel's
    tile.clear();
    for (int y = job.y0; y < job.y1; ++y)
        for (int x = job.x0; x < job.x1; ++x) {
            if (!job.skip(x, y)) tile.start<kDepthOfField>(*job.ctx, *job.sampler, job.sample, x, y);
        }
    StreamScratch scratch;
    trace_tile_streams<kGlass, kLights>(*job.ctx, tile, scratch, st);
    // Streams keep no per-ray visit counts (traversal_counts_path_visits):
    // the BVH Visits heatmap stays 0.
    for (size_t p = 0; p < tile.size(); ++p)
        job.add(tile.px[p], tile.py[p], job.sample, tile.states[p].out, 0.0f, 1.0f, st);
}

// One WavefrontRenderer (and its wave buffers) per thread, kept across passes.
struct WavefrontPool {
    const PathContext* ctx;
    WavefrontOptions options;
    KernelFeatures features;
    tbb::enumerable_thread_specific<std::unique_ptr<WavefrontRenderer>> per_thread;

    WavefrontRenderer& local() {
        std::unique_ptr<WavefrontRenderer>& w = per_thread.local();
        if (!w)
            w = std::make_unique<WavefrontRenderer>(*ctx, options, features.glass, features.depth_of_field,
                                                    features.lights);
        return *w;
    }
};

// Wavefront: the tile (a band of rows about wave_size pixels large) through
// the staged pipeline of wavefront.h.
void render_tile_wavefront(const TileJob& job, RenderStats& st) {
    const bool heat = job.heatmaps;
    job.wavefront->local().render_pass(
        *job.sampler, job.sample, job.x0, job.y0, job.x1, job.y1, [&](int x, int y) { return job.skip(x, y); },
        [&](int x, int y, const PathOutput& o, uint32_t visits) {
            job.add(x, y, job.sample, o, heat ? float(visits) : 0.0f, 1.0f, st);
        },
        st, job.cancelled);
}

using TileFn = void (*)(const TileJob&, RenderStats&);

TileFn select_tile_kernel(Traversal traversal, const KernelFeatures& features) {
    // The wavefront pipeline selects its own kernel variant (wavefront.h).
    if (traversal == Traversal::Wavefront) return &render_tile_wavefront;
    return select_kernel_variant(features, [traversal](auto g, auto d, auto l) -> TileFn {
        switch (traversal) {
            case Traversal::Packet: return &render_tile_packets<g(), d(), l()>;
            case Traversal::Stream: return &render_tile_streams<g(), d(), l()>;
            case Traversal::Single:
            case Traversal::Wavefront:
            case Traversal::Auto: break;  // Auto is resolved before rendering
        }
        return &render_tile<g(), d(), l()>;
    });
}

// How a traversal cuts the border into tiles, and its kernel.
struct TileLayout {
    TileFn kernel;
    int tw, th, tiles_x, tiles;
    bool pixel_runs = false;  // kernel takes a run of samples per pixel (TileJob::samples)
};

TileLayout tile_layout(const RenderSettings& rs, Traversal traversal, const KernelFeatures& features) {
    TileLayout l;
    l.kernel = select_tile_kernel(traversal, features);
    l.pixel_runs = traversal == Traversal::Single;
    const int bw = rs.border_width(), bh = rs.border_height();
    // Packet traversal: tiles hold whole packets (a multiple of the packet
    // size, about tile_size pixels on a side), so no packet straddles tiles.
    const bool packets = traversal == Traversal::Packet;
    l.tw = packets ? rs.packet_width * std::max(1, rs.tile_size / rs.packet_width) : rs.tile_size;
    l.th = packets ? rs.packet_height * std::max(1, rs.tile_size / rs.packet_height) : rs.tile_size;
    // ICPT packets are subsets of regions of 2 x 2 blocks of side n: tiles
    // hold whole regions.
    if (packets && rs.resolved_sampler() == SamplerType::Icpt) {
        const int region = 2 * std::min(rs.packet_width, rs.packet_height);
        l.tw = l.th = region * std::max(1, rs.tile_size / region);
    }
    // Streams amortise a node visit over the rays queued at it: bigger tiles
    // (128 x 128 paths per stream).
    if (traversal == Traversal::Stream) l.tw = l.th = 4 * rs.tile_size;
    // Wavefront: bands of whole rows holding about wave_size paths, at least
    // two bands when the border has two rows (so both threads work).
    if (traversal == Traversal::Wavefront) {
        l.tw = std::max(bw, 1);
        l.th = std::clamp(rs.wave_size / l.tw, 1, std::max(1, (bh + 1) / 2));
    }
    l.tiles_x = (bw + l.tw - 1) / l.tw;
    l.tiles = l.tiles_x * ((bh + l.th - 1) / l.th);
    return l;
}

// The sampler's tables cover one pass (one sample over the image) and are
// rebuilt per pass: a few KB, independent of resolution and spp.
SamplerConfig sampler_config(const RenderSettings& rs) {
    SamplerConfig c;
    c.type = rs.resolved_sampler();
    c.seed = rs.seed;
    c.packet_width = rs.packet_width;
    c.packet_height = rs.packet_height;
    c.scope = rs.sequence_scope;
    c.dims = PathDims::count(rs.max_bounces);
    c.sequence = rs.resolved_pattern();
    return c;
}

// Progress reports to the caller's callback: after every pass, and every
// 250 ms within a pass from the calling thread (which takes part in the
// parallel loop), never concurrently.
class ProgressReporter {
public:
    ProgressReporter(const ProgressCallback& callback, int spp, Clock::time_point start)
        : callback_(callback), spp_(spp), start_(start), last_report_(Clock::now()),
          caller_(std::this_thread::get_id()) {}

    double seconds() const { return std::chrono::duration<double>(Clock::now() - start_).count(); }
    // Whether a report within a pass is due on this thread.
    bool due() const {
        return std::this_thread::get_id() == caller_ && Clock::now() - last_report_ >= std::chrono::milliseconds(250);
    }
    // Sets stats.seconds and reports; returns false if the callback asked to cancel.
    bool report(int samples_done, double fraction, RenderStats& stats, double denoise_fraction = -1.0) {
        stats.seconds = seconds();
        if (!callback_) return true;
        Progress p;
        p.denoise_fraction = denoise_fraction;
        p.samples_done = samples_done;
        p.samples_total = spp_;
        p.fraction = fraction;
        p.seconds = stats.seconds;
        p.error_estimate = stats.error_estimate;
        p.stats = &stats;
        const bool go_on = callback_(p);
        last_report_ = Clock::now();
        return go_on;
    }

private:
    const ProgressCallback& callback_;
    int spp_;
    Clock::time_point start_, last_report_;
    std::thread::id caller_;
};

}  // namespace

Renderer::Renderer(const Scene& scene, const RenderSettings& settings) : Renderer(scene, settings, nullptr) {}

Renderer::Renderer(const Scene& scene, const RenderSettings& settings, std::shared_ptr<const Bvh> bvh,
                   std::shared_ptr<const InstanceBvh> instances)
    : scene_(scene), settings_(settings), instances_(std::move(instances)) {
    validate(settings_);  // setting_table.h: the one check every front end relies on
    features_ = settings_.force_all_features ? SceneFeatures::all() : scene_.features;
    auto_traversal_ = settings_.traversal == Traversal::Auto;
    settings_.traversal = settings_.resolved_traversal();  // never Auto from here on
    settings_.sampler = settings_.resolved_sampler();      // likewise (resolution is idempotent)
    if (settings_.border_x1 < 0) settings_.border_x1 = settings_.width;
    if (settings_.border_y1 < 0) settings_.border_y1 = settings_.height;
    // Before the BVH build and the film allocate: a render that cannot fit
    // fails here, naming the sizes (memory_budget.h).
    const MemoryEstimate estimate = estimate_render_memory(scene_, settings_, !bvh);
    const MemoryLimit limit = memory_limit();
    check_memory(estimate, limit);
    if (!bvh) {  // the usual case: build over the scene's triangles
        BvhBuildOptions options;
        options.width = settings_.bvh_width;
        bvh = build_bvh(scene_, options);
    }
    if (!scene_.moving_triangles.empty())
        motion_.build(scene_.vertices, scene_.motion_vertices, scene_.moving_triangles);
    if (!scene_.instances.empty() && !instances_) {
        BvhBuildOptions options;
        options.width = settings_.bvh_width;
        auto built = std::make_shared<InstanceBvh>();
        built->build(scene_, options);
        instances_ = std::move(built);
    }
    bvh_ = std::move(bvh);
    film_ = Film(settings_.border_width(), settings_.border_height());
    if (settings_.heatmaps) film_.enable_heatmaps();
    MemoryStats& m = stats_.memory;
    m.triangles = estimate.triangles;
    m.scene_bytes = estimate.scene;
    m.bvh_bytes = bvh_->build_stats().bytes + motion_.bytes() + (instances_ ? instances_->bytes() : 0);
    m.instances = scene_.instances.size();
    m.instance_bytes = instance_record_bytes(scene_);
    m.film_bytes = estimate.film;
    m.estimate_bytes = estimate.total();
    m.limit_bytes = limit.bytes;
    if (settings_.denoising_features()) film_.enable_denoising_features();
    film_.enable_passes(PassMask(settings_.passes));
    if (settings_.cryptomatte) {
        film_.enable_cryptomatte(settings_.cryptomatte, settings_.cryptomatte_levels);
        settings_.passes |= kCryptomatteIds;  // paths record their ids
    }
}

Renderer::~Renderer() = default;

std::shared_ptr<Bvh> Renderer::build_bvh(const Scene& scene, const BvhBuildOptions& options) {
    auto bvh = std::make_shared<Bvh>();
    if (scene.moving_triangles.empty()) {
        bvh->build(scene, options);
        return bvh;
    }
    // Moving triangles get non-finite corners here, which the build leaves
    // out while keeping every other triangle's index.
    std::vector<Vec3f> still = scene.vertices;
    for (uint32_t t : scene.moving_triangles)
        for (int k = 0; k < 3; ++k) still[3 * size_t(t) + k] = Vec3f(kInf);
    bvh->build(still, options);
    return bvh;
}

namespace {

// The kernel variant a render needs. Without any emitter no path can carry
// light: the kernel without NEE, light hits and world MIS is exact;
// force_all_features keeps it on. Lens sampling only where the camera has
// depth of field and the integrator is one that models it (render_modes.h).
KernelFeatures kernel_features(const RenderSettings& rs, const SceneFeatures& features, const LightSet& lights) {
    KernelFeatures k;
    k.glass = features.glass;
    k.depth_of_field = features.depth_of_field && integrator_uses_lens(rs.integrator);
    k.lights = rs.force_all_features || (!lights.empty() && features.any_light());
    return k;
}

std::unique_ptr<WavefrontPool> make_wavefront_pool(const PathContext& ctx, const RenderSettings& rs,
                                                   const KernelFeatures& features) {
    auto pool = std::make_unique<WavefrontPool>();
    pool->ctx = &ctx;
    pool->options = WavefrontOptions::from_settings(rs);
    pool->options.node_visits = rs.heatmaps;
    pool->features = features;
    return pool;
}

// What every tile of a batch of passes shares (all but the pixel rectangle
// and the pass).
TileJob pass_job(const PathContext& ctx, const ImageSampler& sampler, Film& film, const RenderSettings& rs,
                 const std::atomic<bool>& cancelled, const std::vector<uint8_t>& converged,
                 const std::vector<uint32_t>& sample_targets, WavefrontPool* wavefront) {
    TileJob job;
    job.ctx = &ctx;
    job.sampler = &sampler;
    job.film = &film;
    job.border_x0 = rs.border_x0;
    job.border_y0 = rs.border_y0;
    job.sample = 0;  // render_batch sets each pass's
    job.cancelled = &cancelled;
    job.converged = converged.empty() ? nullptr : converged.data();
    job.sample_targets = sample_targets.empty() ? nullptr : sample_targets.data();
    job.film_width = rs.border_width();
    job.heatmaps = rs.heatmaps;
    job.denoising_features = rs.denoising_features();
    job.passes = rs.passes != 0;
    job.packet_width = rs.packet_width;
    job.packet_height = rs.packet_height;
    job.assembly = rs.assembly;
    job.wavefront = wavefront;
    return job;
}

// Tile t of `layout`: `pass_job` with the tile's pixel rectangle.
TileJob place_tile(const TileJob& pass_job, const TileLayout& layout, int t, const RenderSettings& rs) {
    TileJob job = pass_job;
    job.x0 = rs.border_x0 + (t % layout.tiles_x) * layout.tw;
    job.y0 = rs.border_y0 + (t / layout.tiles_x) * layout.th;
    job.x1 = std::min(job.x0 + layout.tw, rs.border_x1);
    job.y1 = std::min(job.y0 + layout.th, rs.border_y1);
    return job;
}

// A batch of passes [first, first + count): every tile takes them in
// order, a few at a time (a run), never on two threads at once (the film
// accumulates without atomics), while a thread may move to any tile between
// two runs. So each pixel receives its samples in the order a pass-by-pass
// render gives them (the same film, bit for bit, for any batch size and
// thread count); a batch waits for its slowest thread once, not once per
// pass; and a run keeps the tile's texels and BVH nodes in cache from one
// sample to the next, where sweeping the whole image per pass evicts them.
class TileQueue {
public:
    // Runs as long as a quarter of one thread's share of the batch: the batch
    // ends at most that long after the other threads finish. With many
    // tiles per thread that is the whole batch, which keeps a tile's (with
    // single rays: a pixel's) texels and nodes in cache the longest.
    TileQueue(int tiles, int count, int threads)
        : next_(size_t(tiles)), busy_(size_t(tiles)), count_(count), run_(run_length(tiles, count, threads)) {}

    static int run_length(int tiles, int count, int threads) {
        const int64_t share = int64_t(count) * tiles / (4 * int64_t(std::max(threads, 1)));
        return int(std::clamp<int64_t>(share, 1, std::max(count, 1)));
    }

    // Claims a run of the idle tile furthest behind among the next kWindow
    // tiles from a rotating start (threads spread out, and a claim costs the
    // same at any image size), or further on if none there is idle with work
    // left: passes [pass, pass + n) of the batch. False when every tile is
    // done or busy, as the threads holding the busy ones finish them.
    bool claim(int& tile, int& pass, int& n) {
        constexpr int kWindow = 64;
        const int tiles = int(next_.size());
        const int start = int(cursor_.fetch_add(1, std::memory_order_relaxed) % uint32_t(tiles));
        for (;;) {
            int best = -1, best_pass = count_;
            for (int i = 0; i < tiles && (i < kWindow || best < 0); ++i) {
                const int t = (start + i) % tiles;
                const int p = next_[size_t(t)].load(std::memory_order_relaxed);
                if (p < best_pass && !busy_[size_t(t)].load(std::memory_order_relaxed)) best = t, best_pass = p;
            }
            if (best < 0) return false;
            // acquire: the previous holder's film writes happen before ours.
            if (busy_[size_t(best)].exchange(true, std::memory_order_acquire)) continue;  // lost the race
            tile = best;
            pass = next_[size_t(best)].load(std::memory_order_relaxed);
            n = std::min(run_, count_ - pass);
            if (n > 0) return true;
            busy_[size_t(best)].store(false, std::memory_order_release);
        }
    }
    void release(int tile, int n) {
        next_[size_t(tile)].fetch_add(n, std::memory_order_relaxed);
        busy_[size_t(tile)].store(false, std::memory_order_release);
    }

private:
    std::vector<std::atomic<int>> next_;  // per tile: passes of the batch done
    std::vector<std::atomic<bool>> busy_;
    std::atomic<uint32_t> cursor_{0};
    int count_, run_;
};

// Renders passes [first, first + count) of every tile of `layout` inside
// `arena`, statistics per thread, summed into `stats` at the end.
// on_progress(tile passes done so far) runs after each kernel call (a tile
// pass, or a pixel-run kernel's run of them), on the thread that made it.
template <class OnProgress>
void render_batch(tbb::task_arena& arena, const TileLayout& layout, const TileJob& batch_job, int first, int count,
                  const RenderSettings& rs, RenderStats& stats, OnProgress&& on_progress) {
    tbb::enumerable_thread_specific<RenderStats> local;
    TileQueue queue(layout.tiles, count, arena.max_concurrency());
    std::atomic<int> done{0};
    arena.execute([&] {
        tbb::parallel_for(0, arena.max_concurrency(), [&](int) {
            RenderStats& st = local.local();
            int tile = 0, pass = 0, n = 0;
            while (!batch_job.cancelled->load(std::memory_order_relaxed) && queue.claim(tile, pass, n)) {
                TileJob job = place_tile(batch_job, layout, tile, rs);
                // Pixel-run kernels take the whole run in one call, the others a pass per call.
                const int step = layout.pixel_runs ? n : 1;
                int ran = 0;
                for (; ran < n && !batch_job.cancelled->load(std::memory_order_relaxed); ran += step) {
                    job.sample = uint32_t(first + pass + ran);
                    job.samples = uint32_t(step);
                    layout.kernel(job, st);
                    on_progress(done.fetch_add(step, std::memory_order_relaxed) + step);
                }
                queue.release(tile, ran);
            }
        });
    });
    for (const RenderStats& s : local) stats += s;
}

}  // namespace

bool Renderer::render(const ProgressCallback& progress) {
    const auto start = Clock::now();
    const LightSet lights(scene_, settings_.uniform_light_selection ? LightSelection::Uniform : LightSelection::Power);
    PathContext ctx{&scene_, bvh_.get(), &lights, &settings_};
    ctx.ao_distance = resolve_ao_distance(settings_, scene_);
    ctx.motion = motion_.empty() ? nullptr : &motion_;
    ctx.instances = instances_ && !instances_->empty() ? instances_.get() : nullptr;
    const SamplerConfig samplers = sampler_config(settings_);
    const KernelFeatures kernel = kernel_features(settings_, features_, lights);
    std::unique_ptr<WavefrontPool> wavefront;
    if (settings_.traversal == Traversal::Wavefront) wavefront = make_wavefront_pool(ctx, settings_, kernel);
    TileLayout layout = tile_layout(settings_, settings_.traversal, kernel);
    // Traversal Auto chose packets (CPT): whether they beat single rays
    // depends on the scene and the resolution (docs/results/coherent_paths.md:
    // 1.1-1.3x on Sponza at 512 x 512, 0.9x on the dragon), so the first two
    // passes measure it: pass 0 with single rays, pass 1 with packets, and
    // the faster renders the rest. Both trace the same hits: same image.
    const bool trial = auto_traversal_ && settings_.traversal == Traversal::Packet && settings_.spp >= 4;
    const TileLayout single_layout = trial ? tile_layout(settings_, Traversal::Single, kernel) : layout;
    double trial_seconds[2] = {0.0, 0.0};
    const int tiles = layout.tiles;
    const int spp = std::max(settings_.spp, 0);
    // Distributing samples, passes go on until the pixels with the most
    // samples have them; spp stays the mean (sample_distribution.h).
    const bool distribute = settings_.distributes_samples();
    int passes = spp;  // distributing: the largest count, once decided

    tbb::task_arena arena(settings_.threads > 0 ? settings_.threads : tbb::task_arena::automatic);
    ProgressReporter reporter(progress, spp, start);
    reset_stats();
    int done = 0;
    double seconds_per_pass = 0.0;
    while (done < passes && !cancelled() && tiles > 0) {
        const int count = batch_size(done, passes, seconds_per_pass, reporter.seconds());
        const ImageSampler sampler(samplers, uint32_t(done), uint32_t(count));
        const TileLayout& L = trial && done == 0 ? single_layout : layout;
        const auto batch_start = Clock::now();
        const TileJob job =
            pass_job(ctx, sampler, film_, settings_, cancelled_, converged_, sample_targets_, wavefront.get());
        render_batch(arena, L, job, done, count, settings_, stats_, [&](int tile_passes) {
            // (Distributing, the mean count of the last batch: this batch's
            // samples are counted in per-thread stats until it ends.)
            const double fraction = !sample_targets_.empty()
                                        ? double(stats_.spp) / spp
                                        : (done + double(tile_passes) / L.tiles) / spp;
            // The batch's last kernel call leaves the report to the batch's
            // end, which counts its samples: a report here would say the
            // whole render is done while samples_done is still the old count.
            if (tile_passes < count * L.tiles && reporter.due() &&
                !reporter.report(stats_.spp, std::min(fraction, 1.0), stats_))
                cancel();
        });
        if (cancelled()) break;
        const double seconds = std::chrono::duration<double>(Clock::now() - batch_start).count();
        if (trial && done < 2) {  // batches of one pass until then
            trial_seconds[done] = seconds;
            if (done == 1 && trial_seconds[0] < trial_seconds[1]) {  // single rays were faster
                layout = single_layout;
                settings_.traversal = Traversal::Single;
            }
        }
        seconds_per_pass = seconds / count;
        done += count;
        // Distributing, pixels hold different counts: report their mean (the
        // stats count exactly the samples the film took).
        stats_.spp = sample_targets_.empty() ? done
                                             : int(std::lround(double(stats_.samples) / double(stats_.pixels)));
        // O(pixels), once per batch.
        if (done >= 2 && settings_.error_estimated()) stats_.error_estimate = film_.relative_rmse_estimate();
        if (distribute && sample_targets_.empty() && done == uniform_passes()) {
            sample_targets_ = SampleDistribution::targets(film_, spp);
            passes = int(*std::max_element(sample_targets_.begin(), sample_targets_.end()));
        }
        if (!reporter.report(stats_.spp, std::min(1.0, double(stats_.spp) / spp), stats_)) cancel();
        if (stop_after_pass(done, passes)) break;
    }
    if (settings_.denoise && !cancelled())
        denoise_film([&](double f) { return reporter.report(stats_.spp, 1.0, stats_, f); });
    stats_.seconds = reporter.seconds();
    stats_.memory.peak_rss_bytes = peak_rss_bytes();
    return !cancelled();
}

void Renderer::denoise_film(const std::function<bool(double)>& report) {
    const auto start = Clock::now();
    DenoiseOptions options;
    options.strength = settings_.denoise_strength;
    options.caustics = features_.can_make_caustics();
    options.threads = settings_.threads;
    options.cancel = &cancelled_;
    DenoiseResult result = denoise(film_, options, [&](double f) {
        if (!report(f)) cancel();
        return !cancelled();
    });
    stats_.denoise_seconds = std::chrono::duration<double>(Clock::now() - start).count();
    if (result.rgb.empty()) return;  // cancelled, or fewer than 2 passes
    film_.set_denoised(std::move(result.rgb));
    stats_.denoised_error_estimate = result.error_estimate;
}

void Renderer::reset_stats() {
    const int bw = settings_.border_width(), bh = settings_.border_height();
    stats_.spp = 0;
    stats_.error_estimate = -1.0;
    stats_.denoised_error_estimate = -1.0;
    stats_.denoise_seconds = 0.0;
    stats_.pixels = uint64_t(bw) * uint64_t(bh);
    stats_.converged_pixels = 0;
    converged_.clear();
    if (settings_.adaptive) converged_.assign(size_t(bw) * size_t(bh), 0);
    sample_targets_.clear();
}

bool Renderer::stop_after_pass(int passes_done, int spp) {
    // Adaptive sampling decides only at even pass counts, where every
    // unconverged pixel holds as many even as odd samples; the first time
    // at adaptive_min_samples rounded up to even.
    const int adaptive_min = first_adaptive_decision();
    if (settings_.adaptive && passes_done >= adaptive_min && passes_done % 2 == 0 && passes_done < spp) {
        stats_.converged_pixels = update_convergence();
        if (stats_.converged_pixels == stats_.pixels) return true;  // nothing left to sample
    }
    // The error target is checked only after an even number of passes,
    // where both halves hold equally many samples.
    if (settings_.target_error > 0.0 && passes_done >= 2 && passes_done % 2 == 0 && stats_.error_estimate >= 0.0 &&
        stats_.error_estimate <= settings_.target_error)
        return true;
    // stats_.seconds was set by the pass's progress report: the decision
    // uses exactly the time the progress callback was shown.
    return settings_.time_limit > 0.0 && stats_.seconds >= settings_.time_limit;
}

int Renderer::uniform_passes() const {
    return SampleDistribution::uniform_passes(std::max(settings_.spp, 0), features_.can_make_caustics());
}

int Renderer::first_adaptive_decision() const {
    return std::max(2, settings_.adaptive_min_samples + (settings_.adaptive_min_samples & 1));
}

int Renderer::batch_size(int done, int spp, double seconds_per_pass, double elapsed) const {
    const int left = spp - done;
    // The first two passes alone: the traversal trial times them, and the
    // error estimate starts after them.
    if (done < 2 || settings_.report_interval <= 0.0 || settings_.progressive_display || seconds_per_pass <= 0.0)
        return 1;
    int count = int(std::min(settings_.report_interval / seconds_per_pass, double(left)));
    // Grow by at most half the passes done, so reports, error estimates and
    // stopping decisions keep coming at a steady rate in log(spp).
    count = std::min(count, std::max(2, done / 2));
    if (settings_.distributes_samples()) {
        // A batch ends at the decision.
        const int uniform = uniform_passes();
        if (done < uniform) count = std::min(count, uniform - done);
    }
    if (settings_.adaptive) {
        const int first_decision = first_adaptive_decision();
        count = std::min(count, done < first_decision ? first_decision - done : std::max(2, done / 4));
    }
    // Not far past the error target: at error ~ 1/sqrt(passes) it needs
    // done x (error / target)^2 passes in all; go half way there, as the
    // estimate is itself noisy.
    const double error = stats_.error_estimate;
    if (settings_.target_error > 0.0 && error > settings_.target_error) {
        const double needed = done * (error / settings_.target_error) * (error / settings_.target_error);
        count = std::min(count, std::max(2, int(std::ceil((needed - done) / 2.0))));
    }
    count = std::max(count, 2);  // batches end at even pass counts (both halves equal)
    // End by the time limit, even at an odd count: the render stops there.
    if (settings_.time_limit > 0.0)
        count = std::min(count, std::max(1, int((settings_.time_limit - elapsed) / seconds_per_pass)));
    if (count < left && count > 1 && (done + count) % 2 != 0) --count;
    return std::clamp(count, 1, left);
}

namespace {

// Pixels whose samples share random numbers: a CPT packet with packet-scoped
// sequences, else the pixel alone (SPT scrambles per pixel; ICPT's Latin
// subsets change every sample). Film coordinates; the grid is aligned to
// image coordinates, as the sampler's is, so border renders agree.
struct SharedBlock {
    int x0, y0, x1, y1;  // [x0, x1) x [y0, y1), clipped to the film
};

SharedBlock shared_block_of(const RenderSettings& s, int width, int height, int x, int y) {
    const bool packets = s.sampler == SamplerType::Cpt && s.sequence_scope == SequenceScope::Packet;
    const int bw = packets ? std::max(1, s.packet_width) : 1, bh = packets ? std::max(1, s.packet_height) : 1;
    const int ix = x + s.border_x0, iy = y + s.border_y0;
    const int x0 = ix - ix % bw - s.border_x0, y0 = iy - iy % bh - s.border_y0;
    return {std::max(0, x0), std::max(0, y0), std::min(width, x0 + bw), std::min(height, y0 + bh)};
}

// The relative error pixel (x, y) of block b would have at its own sample
// count if its samples were as noisy as those of the pixels just around its
// block: each pixel j of the one-pixel ring around b gives a per-sample
// variance e_j^2 n_j from its half-buffer error e_j at its count n_j, and
//   predicted error = sqrt(mean_j(e_j^2 n_j) / n) / max(mean_j of radiance, floor).
// Returns +inf when a ring pixel has no estimate yet.
//
// Why leave the block's own samples out: a stopping rule that reads them is
// biased, because it stops a pixel exactly when its samples happen to look
// converged, and that correlates with their value (a penumbra pixel whose
// samples all hit the light has a bright mean *and* a small even/odd
// difference). With low-discrepancy samples most pixels sit at the threshold
// at the minimum count and this became measurable (+0.25 % of the image
// mean, 5.7 sigma in Adaptive.UnbiasedAgainstFullRenderOverSeeds). The ring's
// samples are independent of the block's, so the block's stopping time is
// independent of its samples and its mean stays unbiased. Neighbours see
// nearly the same integrand, and several of them give a steadier estimate
// than one pixel's few samples. Scaling by the counts lets stopped
// neighbours (frozen at their own count) keep informing the decision; for
// sequences whose error falls faster than 1/sqrt(n) it overestimates, i.e.
// it errs towards sampling more.
double predicted_relative_error(const Film& film, const SharedBlock& b, int x, int y) {
    const int w = film.width(), h = film.height();
    // A block covering the whole film has no ring: judge it by itself.
    const bool no_ring = b.x0 == 0 && b.y0 == 0 && b.x1 == w && b.y1 == h;
    double variance = 0.0, mean = 0.0;
    int count = 0;
    for (int ny = std::max(0, b.y0 - 1); ny <= std::min(h - 1, b.y1); ++ny)
        for (int nx = std::max(0, b.x0 - 1); nx <= std::min(w - 1, b.x1); ++nx) {
            const bool inside = nx >= b.x0 && nx < b.x1 && ny >= b.y0 && ny < b.y1;
            if (inside != no_ring) continue;
            const uint32_t n = film.samples_at(nx, ny);
            if (n < 2) return kInf;  // no error estimate (e.g. all samples non-finite)
            const double e = film.pixel_error(nx, ny);
            variance += e * e * double(n);
            mean += film.pixel_mean(nx, ny);
            ++count;
        }
    const double own_count = std::max<uint32_t>(film.samples_at(x, y), 1u);
    return std::sqrt(variance / count / own_count) / std::max(mean / count, RenderSettings::kAdaptiveLuminanceFloor);
}

}  // namespace

uint64_t Renderer::update_convergence() {
    const int w = film_.width(), h = film_.height();
    // O(ring pixels) per pixel and even pass, negligible next to path tracing.
    uint64_t converged = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            uint8_t& done = converged_[size_t(y) * size_t(w) + size_t(x)];
            if (!done) {
                const SharedBlock block = shared_block_of(settings_, w, h, x, y);
                done = predicted_relative_error(film_, block, x, y) <= settings_.adaptive_threshold ? 1 : 0;
            }
            converged += done;
        }
    return converged;
}

}  // namespace coherent
