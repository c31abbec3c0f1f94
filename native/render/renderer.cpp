// The Renderer: pass-by-pass progressive rendering over tiles with TBB.
//
// Determinism: every random number is keyed by (full-frame pixel, sample,
// dimension), every pixel belongs to exactly one tile, and passes run one
// after another, so the film is bit-identical for any thread count.
// Statistics are accumulated per thread (enumerable_thread_specific) and
// merged after each pass: no atomics in the per-ray path.
#include "renderer.h"

#include "setting_table.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <chrono>
#include <memory>
#include <thread>

#include "../sample/image_sampler.h"
#include "light_sampling.h"
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
    uint32_t sample;
    const std::atomic<bool>* cancelled;
    const uint8_t* converged;  // per film pixel, row stride film width; null = none skipped
    int film_width;
    bool heatmaps;
    int packet_width, packet_height;  // packet traversal: pixels per packet
    PacketAssembly assembly;
    struct WavefrontPool* wavefront;  // wavefront traversal: per-thread pipelines

    bool skip(int x, int y) const {
        // Adaptive sampling: a converged pixel keeps its mean and takes no more samples.
        return converged && converged[size_t(y - border_y0) * size_t(film_width) + size_t(x - border_x0)];
    }
    // Adds a finished sample to the film. No NaN/Inf ever reaches the film:
    // a non-finite sample is discarded whole and counted.
    void add(int x, int y, const PathOutput& o, float node_visits, float simd_utilisation, RenderStats& st) const {
        if (!is_finite(o.radiance) || !std::isfinite(o.alpha) || std::isnan(o.depth) || !is_finite(o.normal)) {
            ++st.nonfinite_samples;
            return;
        }
        film->add_sample(x - border_x0, y - border_y0, o.radiance, o.alpha, o.depth, o.normal, sample);
        if (heatmaps) film->add_heatmap_sample(x - border_x0, y - border_y0, node_visits, simd_utilisation);
        ++st.samples;
    }
};

// Single rays: each pixel's path depth-first (path_tracer.h); returns early on cancel.
template <bool kGlass, bool kDepthOfField, bool kLights>
void render_tile(const TileJob& job, RenderStats& st) {
    for (int y = job.y0; y < job.y1; ++y) {
        if (job.cancelled->load(std::memory_order_relaxed)) return;
        for (int x = job.x0; x < job.x1; ++x) {
            if (job.skip(x, y)) continue;
            const PathSampler<ImageSampler> ps(*job.sampler, uint32_t(x), uint32_t(y), job.sample);
            uint32_t visits = 0;
            const PathOutput o = trace_path<ImageSampler, kGlass, kDepthOfField, kLights>(
                *job.ctx, ps, x, y, st, job.heatmaps ? &visits : nullptr);
            // Single rays use every lane they have: utilisation 1.
            job.add(x, y, o, float(visits), 1.0f, st);
        }
    }
}

// Packets: the tile's paths bounce by bounce, rays gathered per pixel packet
// (packet_paths.h).
template <bool kGlass, bool kDepthOfField, bool kLights>
void render_tile_packets(const TileJob& job, RenderStats& st) {
    if (job.cancelled->load(std::memory_order_relaxed)) return;
    PathBatch<ImageSampler> batch;
    batch.clear();
    auto add_path = [&](int x, int y) {
        if (!job.skip(x, y)) batch.template start<kDepthOfField>(*job.ctx, *job.sampler, job.sample, x, y);
    };
    auto end_packet = [&] {
        if (int(batch.size()) > batch.packet_begin.back()) batch.packet_begin.push_back(int(batch.size()));
    };
    if (job.sampler->type() == SamplerType::Icpt) {
        // ICPT: a packet is one Latin-hypercube subset of a region of 2 x 2
        // blocks (n pixels per block, 4n rays), the pixels that share a
        // sequence; a block's own pixels use n different sequences.
        const int n = int(job.sampler->icpt_block_size());
        std::vector<std::vector<std::pair<int, int>>> subsets(static_cast<size_t>(n));  // pixels of each subset
        for (int ry = job.y0; ry < job.y1; ry += 2 * n)
            for (int rx = job.x0; rx < job.x1; rx += 2 * n) {
                for (auto& list : subsets) list.clear();
                for (int y = ry; y < std::min(ry + 2 * n, job.y1); ++y)
                    for (int x = rx; x < std::min(rx + 2 * n, job.x1); ++x)
                        subsets[job.sampler->icpt_subset(uint32_t(x), uint32_t(y), job.sample)].emplace_back(x, y);
                for (const auto& list : subsets) {
                    for (const auto& [x, y] : list) add_path(x, y);
                    end_packet();
                }
            }
    } else {
        for (int by = job.y0; by < job.y1; by += job.packet_height)
            for (int bx = job.x0; bx < job.x1; bx += job.packet_width) {
                for (int y = by; y < std::min(by + job.packet_height, job.y1); ++y)
                    for (int x = bx; x < std::min(bx + job.packet_width, job.x1); ++x) add_path(x, y);
                end_packet();
            }
    }
    if (job.heatmaps) {
        batch.node_visits.assign(batch.size(), 0);
        batch.lanes.assign(batch.size(), 0);
        batch.lanes_active.assign(batch.size(), 0);
    }
    auto scratch = std::make_unique<packet_detail::PacketScratch>();
    trace_batch_packets<ImageSampler, kGlass, kLights>(*job.ctx, job.assembly, batch, *scratch, st);
    for (size_t p = 0; p < batch.size(); ++p) {
        const float visits = job.heatmaps ? float(batch.node_visits[p]) : 0.0f;
        const float util = job.heatmaps && batch.lanes[p] ? float(double(batch.lanes_active[p]) / double(batch.lanes[p]))
                                                          : 1.0f;
        job.add(batch.px[p], batch.py[p], batch.states[p].out, visits, util, st);
    }
}

// Streams: the tile's paths bounce by bounce, each bounce's rays of the
// whole tile traced as one breadth-first stream (packet_paths.h).
template <bool kGlass, bool kDepthOfField, bool kLights>
void render_tile_streams(const TileJob& job, RenderStats& st) {
    if (job.cancelled->load(std::memory_order_relaxed)) return;
    PathBatch<ImageSampler> batch;
    batch.clear();
    for (int y = job.y0; y < job.y1; ++y)
        for (int x = job.x0; x < job.x1; ++x) {
            if (!job.skip(x, y)) batch.template start<kDepthOfField>(*job.ctx, *job.sampler, job.sample, x, y);
        }
    StreamScratch scratch;
    trace_batch_streams<ImageSampler, kGlass, kLights>(*job.ctx, batch, scratch, st);
    // Streams keep no per-ray visit counts (traversal_counts_path_visits):
    // the BVH Visits heatmap stays 0.
    for (size_t p = 0; p < batch.size(); ++p) job.add(batch.px[p], batch.py[p], batch.states[p].out, 0.0f, 1.0f, st);
}

// One WavefrontRenderer (and its wave buffers) per thread, kept across passes.
struct WavefrontPool {
    const PathContext* ctx;
    WavefrontOptions options;
    bool glass, depth_of_field, lights;
    tbb::enumerable_thread_specific<std::unique_ptr<WavefrontRenderer>> per_thread;

    WavefrontRenderer& local() {
        std::unique_ptr<WavefrontRenderer>& w = per_thread.local();
        if (!w) w = std::make_unique<WavefrontRenderer>(*ctx, options, glass, depth_of_field, lights);
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
            job.add(x, y, o, heat ? float(visits) : 0.0f, 1.0f, st);
        },
        st, job.cancelled);
}

using TileFn = void (*)(const TileJob&, RenderStats&);

template <Traversal kTraversal, bool G, bool D, bool L>
constexpr TileFn tile_fn() {
    if constexpr (kTraversal == Traversal::Packet) return &render_tile_packets<G, D, L>;
    else if constexpr (kTraversal == Traversal::Stream) return &render_tile_streams<G, D, L>;
    else return &render_tile<G, D, L>;
}

template <Traversal kTraversal>
TileFn select_kernel_for(bool glass, bool dof, bool lights) {
    static constexpr TileFn table[2][2][2] = {
        {{tile_fn<kTraversal, false, false, false>(), tile_fn<kTraversal, false, false, true>()},
         {tile_fn<kTraversal, false, true, false>(), tile_fn<kTraversal, false, true, true>()}},
        {{tile_fn<kTraversal, true, false, false>(), tile_fn<kTraversal, true, false, true>()},
         {tile_fn<kTraversal, true, true, false>(), tile_fn<kTraversal, true, true, true>()}},
    };
    return table[glass ? 1 : 0][dof ? 1 : 0][lights ? 1 : 0];
}

TileFn select_kernel(Traversal traversal, bool glass, bool dof, bool lights) {
    switch (traversal) {
        case Traversal::Packet: return select_kernel_for<Traversal::Packet>(glass, dof, lights);
        case Traversal::Stream: return select_kernel_for<Traversal::Stream>(glass, dof, lights);
        // The wavefront pipeline selects its own kernel variant (wavefront.h).
        case Traversal::Wavefront: return &render_tile_wavefront;
        case Traversal::Single:
        case Traversal::Auto: break;  // resolved before rendering
    }
    return select_kernel_for<Traversal::Single>(glass, dof, lights);
}

}  // namespace

Renderer::Renderer(const Scene& scene, const RenderSettings& settings) : Renderer(scene, settings, nullptr) {}

Renderer::Renderer(const Scene& scene, const RenderSettings& settings, std::shared_ptr<const Bvh> bvh)
    : scene_(scene), settings_(settings) {
    validate(settings_);  // setting_table.h: the one check every front end relies on
    features_ = settings_.force_all_features ? SceneFeatures::all() : scene_.features;
    auto_traversal_ = settings_.traversal == Traversal::Auto;
    settings_.traversal = settings_.resolved_traversal();  // never Auto from here on
    if (settings_.border_x1 < 0) settings_.border_x1 = settings_.width;
    if (settings_.border_y1 < 0) settings_.border_y1 = settings_.height;
    if (!bvh) {  // the usual case: build over the scene's triangles
        BvhBuildOptions options;
        options.width = settings_.bvh_width;
        bvh = build_bvh(scene_, options);
    }
    if (!scene_.moving_triangles.empty())
        motion_.build(scene_.vertices, scene_.motion_vertices, scene_.moving_triangles);
    bvh_ = std::move(bvh);
    film_ = Film(settings_.border_width(), settings_.border_height());
    if (settings_.heatmaps) film_.enable_heatmaps();
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

bool Renderer::render(const ProgressCallback& progress) {
    const auto start = Clock::now();
    const LightSet lights(scene_);
    PathContext ctx{&scene_, bvh_.get(), &lights, &settings_};
    ctx.ao_distance = resolve_ao_distance(settings_, scene_);
    ctx.motion = motion_.empty() ? nullptr : &motion_;
    // The sampler's tables cover one pass (one sample over the image) and are
    // rebuilt per pass: a few KB, independent of resolution and spp.
    SamplerConfig sampler_config;
    sampler_config.type = settings_.resolved_sampler();
    sampler_config.seed = settings_.seed;
    sampler_config.packet_width = settings_.packet_width;
    sampler_config.packet_height = settings_.packet_height;
    sampler_config.scope = settings_.sequence_scope;
    sampler_config.dims = PathDims::count(settings_.max_bounces);
    // Without any emitter no path can carry light: the kernel without NEE,
    // light hits and world MIS is exact. force_all_features keeps it on.
    const bool use_lights = settings_.force_all_features || (!lights.empty() && features_.any_light());
    // Lens sampling only where the camera has depth of field and the
    // integrator is one that models it (render_modes.h).
    const bool dof = features_.depth_of_field && integrator_uses_lens(settings_.integrator);
    const int bw = settings_.border_width(), bh = settings_.border_height();
    std::unique_ptr<WavefrontPool> wavefront;
    // How a traversal cuts the border into tiles, and its kernel.
    struct Layout {
        TileFn kernel;
        int tw, th, tiles_x, tiles;
    };
    auto make_layout = [&](Traversal traversal) {
        Layout l;
        l.kernel = select_kernel(traversal, features_.glass, dof, use_lights);
        // Packet traversal: tiles hold whole packets (a multiple of the
        // packet size, about tile_size pixels on a side), so no packet
        // straddles tiles.
        const bool packets = traversal == Traversal::Packet;
        l.tw = packets ? settings_.packet_width * std::max(1, settings_.tile_size / settings_.packet_width)
                       : settings_.tile_size;
        l.th = packets ? settings_.packet_height * std::max(1, settings_.tile_size / settings_.packet_height)
                       : settings_.tile_size;
        // ICPT packets are subsets of regions of 2 x 2 blocks of side n:
        // tiles hold whole regions.
        if (packets && settings_.resolved_sampler() == SamplerType::Icpt) {
            const int region = 2 * std::min(settings_.packet_width, settings_.packet_height);
            l.tw = l.th = region * std::max(1, settings_.tile_size / region);
        }
        // Streams amortise a node visit over the rays queued at it: bigger
        // tiles (128 x 128 paths per stream).
        if (traversal == Traversal::Stream) l.tw = l.th = 4 * settings_.tile_size;
        // Wavefront: bands of whole rows holding about wave_size paths, at
        // least two bands when the border has two rows (so both threads work).
        if (traversal == Traversal::Wavefront) {
            l.tw = std::max(bw, 1);
            l.th = std::clamp(settings_.wave_size / l.tw, 1, std::max(1, (bh + 1) / 2));
            wavefront = std::make_unique<WavefrontPool>();
            wavefront->ctx = &ctx;
            wavefront->options = WavefrontOptions::from_settings(settings_);
            wavefront->options.node_visits = settings_.heatmaps;
            wavefront->glass = features_.glass;
            wavefront->depth_of_field = dof;
            wavefront->lights = use_lights;
        }
        l.tiles_x = (bw + l.tw - 1) / l.tw;
        l.tiles = l.tiles_x * ((bh + l.th - 1) / l.th);
        return l;
    };
    Layout layout = make_layout(settings_.traversal);
    // Traversal Auto chose packets (CPT): whether they beat single rays
    // depends on the scene and the resolution (docs/results/coherent_paths.md:
    // 1.1-1.3x on Sponza at 512 x 512, 0.9x on the dragon), so the first two
    // passes measure it: pass 0 with single rays, pass 1 with packets, and
    // the faster renders the rest. Both trace the same hits: same image.
    const bool trial = auto_traversal_ && settings_.traversal == Traversal::Packet && settings_.spp >= 4;
    const Layout single_layout = trial ? make_layout(Traversal::Single) : layout;
    double trial_seconds[2] = {0.0, 0.0};
    const int tiles = layout.tiles;
    const int spp = std::max(settings_.spp, 0);

    tbb::task_arena arena(settings_.threads > 0 ? settings_.threads : tbb::task_arena::automatic);
    const std::thread::id caller = std::this_thread::get_id();
    auto last_report = Clock::now();
    const auto report_interval = std::chrono::milliseconds(250);

    auto seconds_since_start = [&] { return std::chrono::duration<double>(Clock::now() - start).count(); };
    auto report = [&](int samples_done, double fraction) {
        stats_.seconds = seconds_since_start();
        if (!progress) return;
        Progress p;
        p.samples_done = samples_done;
        p.samples_total = spp;
        p.fraction = fraction;
        p.seconds = stats_.seconds;
        p.error_estimate = stats_.error_estimate;
        p.stats = &stats_;
        if (!progress(p)) cancel();
        last_report = Clock::now();
    };

    stats_.spp = 0;
    stats_.error_estimate = -1.0;
    stats_.pixels = uint64_t(bw) * uint64_t(bh);
    stats_.converged_pixels = 0;
    converged_.clear();
    if (settings_.adaptive) converged_.assign(size_t(bw) * size_t(bh), 0);
    // Even, so that both half-buffers hold equally many samples when first judged.
    const int adaptive_min = std::max(2, settings_.adaptive_min_samples + (settings_.adaptive_min_samples & 1));
    for (int pass = 0; pass < spp && !cancelled() && tiles > 0; ++pass) {
        const ImageSampler sampler(sampler_config, uint32_t(pass), 1);
        const Layout& L = trial && pass == 0 ? single_layout : layout;
        const auto pass_start = Clock::now();
        tbb::enumerable_thread_specific<RenderStats> local;
        std::atomic<int> tiles_done{0};
        arena.execute([&] {
            tbb::parallel_for(tbb::blocked_range<int>(0, L.tiles, 1), [&](const tbb::blocked_range<int>& r) {
                RenderStats& st = local.local();
                for (int t = r.begin(); t != r.end(); ++t) {
                    if (cancelled()) return;
                    TileJob job;
                    job.ctx = &ctx;
                    job.sampler = &sampler;
                    job.film = &film_;
                    job.x0 = settings_.border_x0 + (t % L.tiles_x) * L.tw;
                    job.y0 = settings_.border_y0 + (t / L.tiles_x) * L.th;
                    job.x1 = std::min(job.x0 + L.tw, settings_.border_x1);
                    job.y1 = std::min(job.y0 + L.th, settings_.border_y1);
                    job.border_x0 = settings_.border_x0;
                    job.border_y0 = settings_.border_y0;
                    job.sample = uint32_t(pass);
                    job.cancelled = &cancelled_;
                    job.converged = converged_.empty() ? nullptr : converged_.data();
                    job.film_width = bw;
                    job.heatmaps = settings_.heatmaps;
                    job.packet_width = settings_.packet_width;
                    job.packet_height = settings_.packet_height;
                    job.assembly = settings_.assembly;
                    job.wavefront = wavefront.get();
                    L.kernel(job, st);
                    const int done = tiles_done.fetch_add(1, std::memory_order_relaxed) + 1;
                    // Periodic progress within a long pass, always on the calling
                    // thread (which takes part in the parallel loop).
                    if (std::this_thread::get_id() == caller && Clock::now() - last_report >= report_interval)
                        report(pass, (pass + double(done) / L.tiles) / spp);
                }
            });
        });
        for (const RenderStats& s : local) stats_ += s;
        if (cancelled()) break;
        if (trial && pass < 2) {
            trial_seconds[pass] = std::chrono::duration<double>(Clock::now() - pass_start).count();
            if (pass == 1 && trial_seconds[0] < trial_seconds[1]) {  // single rays were faster
                layout = single_layout;
                settings_.traversal = Traversal::Single;
            }
        }
        const int passes_done = pass + 1;
        stats_.spp = passes_done;
        // O(pixels), negligible next to a pass of path tracing.
        if (passes_done >= 2) stats_.error_estimate = film_.relative_rmse_estimate();
        report(passes_done, double(passes_done) / spp);
        // Adaptive sampling decides only at even pass counts, where every
        // unconverged pixel holds as many even as odd samples.
        if (settings_.adaptive && passes_done >= adaptive_min && passes_done % 2 == 0 && passes_done < spp) {
            stats_.converged_pixels = update_convergence();
            if (stats_.converged_pixels == stats_.pixels) break;  // nothing left to sample
        }
        // Stopping rules. The error target is checked only after an even
        // number of passes, where both halves hold equally many samples.
        if (settings_.target_error > 0.0 && passes_done >= 2 && passes_done % 2 == 0 &&
            stats_.error_estimate >= 0.0 && stats_.error_estimate <= settings_.target_error)
            break;
        // stats_.seconds was set by report() above: the decision uses exactly
        // the time the progress callback was shown.
        if (settings_.time_limit > 0.0 && stats_.seconds >= settings_.time_limit) break;
    }
    stats_.seconds = seconds_since_start();
    return !cancelled();
}

uint64_t Renderer::update_convergence() {
    const int w = film_.width(), h = film_.height();
    const double threshold = settings_.adaptive_threshold;
    // Pass 1: which pixels meet the threshold on their own. O(pixels) per
    // even pass, negligible next to path tracing.
    std::vector<uint8_t> meets(size_t(w) * size_t(h), 0);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const size_t i = size_t(y) * size_t(w) + size_t(x);
            if (converged_[i]) {  // stopped pixels still count as meeting it
                meets[i] = 1;
                continue;
            }
            const uint32_t n = film_.samples_at(x, y);
            if (n < 2) continue;  // no error estimate (e.g. all samples non-finite)
            const double mean = film_.pixel_mean(x, y);
            const double rel = double(film_.pixel_error(x, y)) / std::max(mean, RenderSettings::kAdaptiveLuminanceFloor);
            meets[i] = rel <= threshold ? 1 : 0;
        }
    // Pass 2: a pixel converges when its whole 3x3 neighbourhood meets it.
    uint64_t converged = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const size_t i = size_t(y) * size_t(w) + size_t(x);
            if (!converged_[i]) {
                bool all = true;
                for (int dy = -1; dy <= 1 && all; ++dy)
                    for (int dx = -1; dx <= 1 && all; ++dx) {
                        const int nx = x + dx, ny = y + dy;
                        if (nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
                        all = meets[size_t(ny) * size_t(w) + size_t(nx)] != 0;
                    }
                converged_[i] = all ? 1 : 0;
            }
            converged += converged_[i];
        }
    return converged;
}

}  // namespace coherent
