// Python bindings of the renderer: Renderer(scene, **settings).render(progress),
// cancel(), pass_pixels(), stats().
//
// Threading model: render() releases the GIL for the whole render and takes
// it back only to call the Python progress callback (on the thread that called
// render(), between or within sample passes). cancel() only flips an atomic,
// so it can be called from any Python thread while render() runs.
#include <algorithm>
#include <cmath>
#include <exception>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "bindings.h"
#include "render/renderer.h"

namespace coherent::python {

namespace {

// Blender writes 1e10 where the Depth pass saw nothing (Cycles does the same);
// the film stores +inf there, which the compositor cannot handle.
constexpr float kBlenderNoDepth = 1e10f;

constexpr PassType kPassTypes[] = {PassType::Combined, PassType::Depth,      PassType::Normal,
                                   PassType::Error,    PassType::NodeVisits, PassType::SimdUtilisation};

PassType pass_from_name(const std::string& name) {
    for (PassType t : kPassTypes)
        if (name == pass_info(t).name) return t;
    if (name == "Z") return PassType::Depth;  // Blender < 2.92 name of the depth pass
    throw py::value_error("pass_pixels: unknown pass '" + name +
                          "' (expected 'Combined', 'Depth', 'Normal', 'Error', 'BVH Visits' or 'SIMD Utilisation')");
}

// A ratio, or None when the denominator is 0 (nothing measured is not a measured 0).
py::object ratio_object(std::optional<double> r) { return r ? py::object(py::float_(*r)) : py::object(py::none()); }

py::dict bounce_dict(int index, const BounceStats& b) {
    py::dict d;
    d["bounce"] = index;
    d["rays"] = b.rays;
    d["node_visits"] = b.node_visits;
    d["box_tests"] = b.box_tests;
    d["triangle_tests"] = b.triangle_tests;
    d["box_lanes"] = b.box_lanes;
    d["box_lanes_active"] = b.box_lanes_active;
    d["triangle_lanes"] = b.triangle_lanes;
    d["triangle_lanes_active"] = b.triangle_lanes_active;
    d["node_visits_per_ray"] = ratio_object(b.node_visits_per_ray());
    d["box_tests_per_ray"] = ratio_object(b.box_tests_per_ray());
    d["triangle_tests_per_ray"] = ratio_object(b.triangle_tests_per_ray());
    d["simd_box_utilisation"] = ratio_object(b.box_utilisation());
    d["simd_triangle_utilisation"] = ratio_object(b.triangle_utilisation());
    d["and_deeper"] = index == kStatBounces - 1;  // the last slot collects every deeper bounce
    return d;
}

// The tracing configuration by the names render_modes.h uses (and the
// Renderer's keyword arguments take).
py::dict settings_dict(const RenderSettings& s) {
    py::dict d;
    d["integrator"] = std::string(integrator_name(s.integrator));
    d["traversal"] = std::string(traversal_name(s.traversal));
    d["assembly"] = std::string(assembly_name(s.assembly));
    d["bvh_width"] = s.bvh_width;
    d["reorder"] = std::string(reorder_name(s.reorder));
    d["wave_size"] = s.wave_size;
    d["ao_samples"] = s.ao_samples;
    d["ao_distance"] = s.ao_distance;
    d["heatmaps"] = s.heatmaps;
    d["counts_path_visits"] = traversal_counts_path_visits(s.traversal);  // the BVH Visits heatmap is not 0
    d["packet"] = py::make_tuple(s.packet_width, s.packet_height);
    d["sampler"] = std::string(sampler_type_name(s.resolved_sampler()));
    return d;
}

// The relative RMSE estimate, None while unknown (fewer than 2 passes).
py::object error_estimate_object(double e) { return e >= 0.0 ? py::object(py::float_(e)) : py::object(py::none()); }

class PyRenderer {
public:
    PyRenderer(std::shared_ptr<PyScene> scene, const RenderSettings& settings) : scene_(std::move(scene)) {
        scene_->ensure_finalized();
        // Claim the scene before building: it must not change under the BVH.
        scene_->active_renderers.fetch_add(1);
        // Reuse the scene's BVH when its triangles did not change since it was
        // built (read and written with the GIL held: PyScene's bookkeeping is
        // only touched from Python threads).
        std::shared_ptr<const Bvh> bvh = scene_->bvh;
        bvh_reused_ = bvh != nullptr;
        try {
            py::gil_scoped_release unlocked;  // the BVH build takes time
            renderer_ = std::make_unique<Renderer>(scene_->scene, settings, std::move(bvh));
        } catch (...) {
            scene_->active_renderers.fetch_sub(1);
            throw;
        }
        scene_->bvh = renderer_->shared_bvh();
        settings_ = settings;
        settings_.traversal = renderer_->settings().traversal;  // auto resolved
    }

    ~PyRenderer() {
        if (worker_.joinable()) {
            renderer_->cancel();
            py::gil_scoped_release unlocked;  // the worker never needs the GIL, but don't hold it while waiting
            worker_.join();
        }
        renderer_.reset();
        scene_->active_renderers.fetch_sub(1);
    }

    bool render(const py::object& progress) {
        join_finished_worker();
        if (rendering_.exchange(true)) throw std::runtime_error("Renderer.render: already rendering");
        struct Reset {
            std::atomic<bool>& flag;
            ~Reset() { flag.store(false); }
        } reset{rendering_};

        // An exception raised by the callback is kept here (created and
        // destroyed only while holding the GIL) and re-raised once the
        // render has stopped, so the caller sees the real Python error.
        std::optional<py::error_already_set> error;
        bool finished;
        {
            py::gil_scoped_release unlocked;
            finished = renderer_->render([&](const Progress& p) -> bool {
                py::gil_scoped_acquire locked;
                if (PyErr_CheckSignals() != 0) {  // Ctrl-C in a plain Python session
                    error.emplace();
                    return false;
                }
                if (progress.is_none()) return true;
                try {
                    return py::bool_(progress(progress_dict(p))).cast<bool>();
                } catch (py::error_already_set& e) {
                    error.emplace(std::move(e));
                    return false;
                }
            });
        }
        if (error) throw *error;
        return finished;
    }

    // --- asynchronous rendering (viewport) ---------------------------------
    //
    // start() renders on a native thread that never touches Python. After
    // every completed sample pass it resolves the Combined pass into a
    // snapshot buffer under a mutex (the film is only consistent between
    // passes); Python polls snapshot()/progress() from any thread.
    void start() {
        join_finished_worker();
        if (rendering_.exchange(true)) throw std::runtime_error("Renderer.start: already rendering");
        {
            std::lock_guard<std::mutex> lock(async_mutex_);
            async_running_ = true;
            async_error_.clear();
            async_progress_ = Progress{};
            async_progress_.samples_total = settings_.spp;
        }
        worker_ = std::thread([this] {
            int last_done = -1;
            try {
                renderer_->render([&](const Progress& p) {
                    // A new samples_done value only appears in the report at the
                    // end of a pass: the only moment the film may be read.
                    if (p.samples_done != last_done) {
                        last_done = p.samples_done;
                        const Film& film = renderer_->film();
                        std::vector<float> pixels(size_t(film.width()) * film.height() * 4);
                        film.resolve_into(PassType::Combined, pixels.data());
                        std::lock_guard<std::mutex> lock(async_mutex_);
                        snapshot_.swap(pixels);
                        snapshot_samples_ = p.samples_done;
                    }
                    std::lock_guard<std::mutex> lock(async_mutex_);
                    async_progress_ = p;
                    async_progress_.stats = nullptr;  // not valid outside the callback
                    async_rays_ = p.stats ? p.stats->total_rays() : 0;
                    return true;  // cancellation goes through Renderer::cancel()
                });
            } catch (const std::exception& e) {
                std::lock_guard<std::mutex> lock(async_mutex_);
                async_error_ = e.what();
            } catch (...) {
                std::lock_guard<std::mutex> lock(async_mutex_);
                async_error_ = "unknown native error";
            }
            std::lock_guard<std::mutex> lock(async_mutex_);
            async_running_ = false;
            rendering_.store(false);
        });
    }

    bool running() const {
        std::lock_guard<std::mutex> lock(async_mutex_);
        return async_running_;
    }

    // Waits for start()'s render to end; returns False if it was cancelled.
    bool wait() {
        if (worker_.joinable()) {
            py::gil_scoped_release unlocked;
            worker_.join();
        }
        std::lock_guard<std::mutex> lock(async_mutex_);
        if (!async_error_.empty()) throw std::runtime_error("Renderer: " + async_error_);
        return !renderer_->cancelled();
    }

    py::dict async_progress() const {
        std::lock_guard<std::mutex> lock(async_mutex_);
        py::dict d = progress_dict(async_progress_);
        d["rays"] = async_rays_;
        d["mrays_per_s"] = async_progress_.seconds > 0.0 ? double(async_rays_) / async_progress_.seconds * 1e-6 : 0.0;
        d["running"] = async_running_;
        d["error"] = async_error_;
        return d;
    }

    // (samples, float32 (H*W, 4) Combined) of the latest completed pass, or (0, None).
    py::tuple snapshot(bool flip_y) const {
        std::lock_guard<std::mutex> lock(async_mutex_);
        if (snapshot_.empty()) return py::make_tuple(0, py::none());
        const Film& film = renderer_->film();
        const py::ssize_t w = film.width(), h = film.height();
        py::array_t<float> out({w * h, py::ssize_t(4)});
        float* data = out.mutable_data();
        const py::ssize_t row = w * 4;
        for (py::ssize_t y = 0; y < h; ++y) {
            const py::ssize_t src = flip_y ? h - 1 - y : y;
            std::copy_n(snapshot_.data() + src * row, row, data + y * row);
        }
        return py::make_tuple(snapshot_samples_, out);
    }

    void cancel() { renderer_->cancel(); }
    bool cancelled() const { return renderer_->cancelled(); }

    py::array_t<float> pass_pixels(const std::string& name, bool flip_y) const {
        if (running())
            throw std::runtime_error("Renderer.pass_pixels: an asynchronous render is running; use snapshot() "
                                     "or wait() first");
        const PassType type = pass_from_name(name);
        const Film& film = renderer_->film();
        const py::ssize_t w = film.width(), h = film.height(), c = pass_info(type).channels;
        py::array_t<float> out({w * h, c});
        float* data = out.mutable_data();
        film.resolve_into(type, data);
        if (flip_y) {
            // Film row 0 is the top row; Blender's pixel buffers start at the bottom.
            const py::ssize_t row = w * c;
            for (py::ssize_t y = 0; y < h / 2; ++y)
                std::swap_ranges(data + y * row, data + (y + 1) * row, data + (h - 1 - y) * row);
        }
        if (type == PassType::Depth)
            std::replace_if(data, data + w * h * c, [](float v) { return !std::isfinite(v); }, kBlenderNoDepth);
        return out;
    }

    py::dict stats() const { return stats_dict(renderer_->stats()); }
    py::dict bvh_stats() const {
        const BvhBuildStats& b = renderer_->bvh().build_stats();
        py::dict d;
        d["seconds"] = b.seconds;
        d["nodes"] = b.nodes;
        d["leaves"] = b.leaves;
        d["bytes"] = b.bytes;
        d["depth"] = b.depth;
        return d;
    }
    bool bvh_reused() const { return bvh_reused_; }
    std::vector<std::string> features() const { return renderer_->active_features().names(); }
    const RenderSettings& settings() const { return settings_; }
    const Film& film() const { return renderer_->film(); }

private:
    static py::dict progress_dict(const Progress& p) {
        py::dict d;
        d["samples_done"] = p.samples_done;
        d["samples_total"] = p.samples_total;
        d["fraction"] = p.fraction;
        d["seconds"] = p.seconds;
        d["error_estimate"] = error_estimate_object(p.error_estimate);
        const uint64_t rays = p.stats ? p.stats->total_rays() : 0;
        d["rays"] = rays;
        d["mrays_per_s"] = p.seconds > 0.0 ? double(rays) / p.seconds * 1e-6 : 0.0;
        return d;
    }

    static py::dict stats_dict(const RenderStats& s) {
        py::dict d;
        py::dict rays;
        for (size_t i = 0; i < size_t(RayType::Count); ++i) rays[ray_type_name(RayType(i))] = s.rays[i];
        d["rays"] = rays;
        d["total_rays"] = s.total_rays();
        d["samples"] = s.samples;
        d["spp"] = s.spp;  // sample passes actually taken (stopping rules may end early)
        d["converged_pixels"] = s.converged_pixels;
        d["converged_fraction"] = s.converged_fraction();
        d["error_estimate"] = error_estimate_object(s.error_estimate);
        d["seconds"] = s.seconds;
        d["mrays_per_s"] = s.seconds > 0.0 ? double(s.total_rays()) / s.seconds * 1e-6 : 0.0;
        d["nonfinite_samples"] = s.nonfinite_samples;
        py::dict t;
        t["rays"] = s.traversal.rays;
        t["node_visits"] = s.traversal.node_visits;
        t["box_tests"] = s.traversal.box_tests;
        t["triangle_tests"] = s.traversal.triangle_tests;
        const double n = s.traversal.rays ? double(s.traversal.rays) : 1.0;
        t["box_tests_per_ray"] = double(s.traversal.box_tests) / n;
        t["triangle_tests_per_ray"] = double(s.traversal.triangle_tests) / n;
        d["traversal"] = t;

        // Per-bounce work (stats.h BounceStats), trailing empty bounces left out.
        const BounceStats all = s.bounce_total();
        py::list bounces;
        for (int i = 0; i <= s.deepest_bounce(); ++i) bounces.append(bounce_dict(i, s.bounces[size_t(i)]));
        d["bounces"] = bounces;
        py::dict simd;
        simd["box"] = ratio_object(all.box_utilisation());
        simd["triangle"] = ratio_object(all.triangle_utilisation());
        d["simd_utilisation"] = simd;
        d["rays_per_second"] = s.seconds > 0.0 ? double(s.total_rays()) / s.seconds : 0.0;
        d["trace_seconds"] = s.trace_seconds;
        d["sort_seconds"] = s.sort_seconds;
        return d;
    }

    // A finished start() leaves a joinable thread behind; reap it.
    void join_finished_worker() {
        if (worker_.joinable() && !running()) worker_.join();
    }

    std::shared_ptr<PyScene> scene_;  // keeps the scene alive as long as this renderer
    std::unique_ptr<Renderer> renderer_;
    RenderSettings settings_;
    bool bvh_reused_ = false;  // the BVH came from the scene's cache instead of being built
    std::atomic<bool> rendering_{false};  // a render (sync or async) is in progress

    std::thread worker_;  // start()'s render thread
    mutable std::mutex async_mutex_;  // guards everything below
    bool async_running_ = false;
    std::string async_error_;
    Progress async_progress_;
    uint64_t async_rays_ = 0;
    std::vector<float> snapshot_;  // Combined, top row first
    int snapshot_samples_ = 0;
};

int checked_int(int v, int lo, int hi, const char* arg) {
    if (v < lo || v > hi)
        throw py::value_error(std::string(arg) + ": must be in [" + std::to_string(lo) + ", " + std::to_string(hi) +
                              "], got " + std::to_string(v));
    return v;
}

std::unique_ptr<PyRenderer> make_renderer(std::shared_ptr<PyScene> scene, int width, int height, int spp,
                                          unsigned long long seed, int threads, int max_bounces,
                                          int diffuse_bounces, int glossy_bounces, int transmission_bounces,
                                          int rr_min_bounces, bool transparent, const py::object& border,
                                          int tile_size, bool force_all_features, const std::string& sampler,
                                          const py::object& packet, bool progressive_display,
                                          const std::string& sequences, double target_error, double time_limit,
                                          bool adaptive, double adaptive_threshold, int adaptive_min_samples,
                                          const std::string& integrator, const std::string& traversal,
                                          const std::string& assembly, int bvh_width, const std::string& reorder,
                                          int wave_size, int ao_samples, double ao_distance, bool heatmaps) {
    if (!scene) throw py::type_error("scene: expected a coherent Scene, got None");
    constexpr int kMaxSize = 1 << 16;
    RenderSettings s;
    s.width = checked_int(width, 1, kMaxSize, "width");
    s.height = checked_int(height, 1, kMaxSize, "height");
    s.spp = checked_int(spp, 1, 1 << 24, "spp");
    s.seed = seed;
    if (!(target_error >= 0.0 && std::isfinite(target_error)))
        throw py::value_error("target_error: expected a finite number >= 0 (0 = off)");
    if (!(time_limit >= 0.0 && std::isfinite(time_limit)))
        throw py::value_error("time_limit: expected a finite number of seconds >= 0 (0 = off)");
    s.target_error = target_error;
    s.time_limit = time_limit;
    if (!(adaptive_threshold > 0.0 && adaptive_threshold <= 1.0))
        throw py::value_error("adaptive_threshold: expected a relative error in (0, 1]");
    s.adaptive = adaptive;
    s.adaptive_threshold = adaptive_threshold;
    s.adaptive_min_samples = checked_int(adaptive_min_samples, 2, 1 << 24, "adaptive_min_samples");
    s.threads = checked_int(threads, 0, 4096, "threads");
    s.max_bounces = checked_int(max_bounces, 0, 1024, "max_bounces");
    s.diffuse_bounces = checked_int(diffuse_bounces, 0, 1024, "diffuse_bounces");
    s.glossy_bounces = checked_int(glossy_bounces, 0, 1024, "glossy_bounces");
    s.transmission_bounces = checked_int(transmission_bounces, 0, 1024, "transmission_bounces");
    s.rr_min_bounces = checked_int(rr_min_bounces, 0, 1024, "rr_min_bounces");
    s.transparent_film = transparent;
    s.tile_size = checked_int(tile_size, 1, 4096, "tile_size");
    s.force_all_features = force_all_features;
    // Sampler (native/sample): "spt" | "cpt" | "icpt" | "auto"; auto resolves
    // with progressive_display (True for the viewport) and spp.
    if (const auto t = parse_sampler_type(sampler)) s.sampler = *t;
    else throw py::value_error("sampler: expected 'spt', 'cpt', 'icpt' or 'auto', got '" + sampler + "'");
    const auto pk = packet.cast<std::vector<int>>();
    if (pk.size() != 2) throw py::value_error("packet: expected (width, height) in pixels");
    s.packet_width = checked_int(pk[0], 1, 16, "packet width");
    s.packet_height = checked_int(pk[1], 1, 16, "packet height");
    s.progressive_display = progressive_display;
    if (const auto sc = parse_sequence_scope(sequences)) s.sequence_scope = *sc;
    else throw py::value_error("sequences: expected 'packet' or 'image', got '" + sequences + "'");
    // Light transport and tracing (render_modes.h names).
    if (const auto v = parse_integrator(integrator)) s.integrator = *v;
    else throw py::value_error("integrator: expected 'pt', 'drt', 'wrt', 'rcs' or 'ao', got '" + integrator + "'");
    if (const auto v = parse_traversal(traversal)) s.traversal = *v;
    else throw py::value_error("traversal: expected 'single', 'wide', 'packet', 'stream' or 'wavefront', got '" +
                               traversal + "'");
    if (const auto v = parse_assembly(assembly)) s.assembly = *v;
    else throw py::value_error("assembly: expected 'types' or 'runs', got '" + assembly + "'");
    if (bvh_width != 2 && bvh_width != 4 && bvh_width != 8)
        throw py::value_error("bvh_width: expected 2, 4 or 8, got " + std::to_string(bvh_width));
    s.bvh_width = bvh_width;
    if (const auto v = parse_reorder(reorder)) s.reorder = *v;
    else throw py::value_error("reorder: expected 'none', 'static1d', 'static3d', 'hash32', 'hash192' or 'csd32', got '" +
                               reorder + "'");
    s.wave_size = checked_int(wave_size, 1, 1 << 24, "wave_size");
    s.ao_samples = checked_int(ao_samples, 1, 1 << 12, "ao_samples");
    if (!(ao_distance >= 0.0 && std::isfinite(float(ao_distance))))  // finite also as a float
        throw py::value_error("ao_distance: expected a finite length >= 0 (0 = a tenth of the scene's diagonal)");
    s.ao_distance = float(ao_distance);
    s.heatmaps = heatmaps;
    if (!border.is_none()) {
        const auto b = border.cast<std::vector<int>>();
        if (b.size() != 4) throw py::value_error("border: expected (x0, y0, x1, y1) in pixels");
        if (b[0] < 0 || b[1] < 0 || b[2] > s.width || b[3] > s.height || b[0] >= b[2] || b[1] >= b[3])
            throw py::value_error("border: expected 0 <= x0 < x1 <= width and 0 <= y0 < y1 <= height (y = 0 at the top), got (" +
                                  std::to_string(b[0]) + ", " + std::to_string(b[1]) + ", " + std::to_string(b[2]) +
                                  ", " + std::to_string(b[3]) + ")");
        s.border_x0 = b[0];
        s.border_y0 = b[1];
        s.border_x1 = b[2];
        s.border_y1 = b[3];
    }
    return std::make_unique<PyRenderer>(std::move(scene), s);
}

}  // namespace

void bind_render(py::module_& m) {
    py::class_<PyRenderer>(m, "Renderer", R"doc(
Renders a Scene. Construction builds the BVH (the GIL is released). The scene
is kept alive and read-only while the Renderer exists.

border=(x0, y0, x1, y1) in pixels, y = 0 at the TOP row, x1/y1 exclusive: the
film (and every pass) then covers only that region.

sampler="spt" | "cpt" | "icpt" | "auto" picks the random sequences (Sadeghi et
al. 2009); "auto" gives ICPT when progressive_display=True (the viewport) or
below 256 spp, else CPT. packet=(w, h): packet size in pixels (ICPT blocks
are square, of the shorter side), at most 16. sequences="packet" | "image":
CPT/ICPT share sequences per packet (the paper's Fig. 3) or over the whole
image (its equation 3).

Stopping rules (0 = off; whichever of spp, target_error and time_limit comes
first ends the render): target_error is a relative RMSE, estimated without a
reference from the even and odd sample passes and checked after every even
pass count; time_limit is in seconds, checked between passes. stats()["spp"]
says how many passes were taken; stats() and the progress dict carry
error_estimate (None before 2 passes).

adaptive=True: after adaptive_min_samples passes (rounded up to even), at
every even pass count, a pixel whose estimated relative error and whose 3x3
neighbours' are at most adaptive_threshold stops taking samples; stats()
carries converged_pixels and converged_fraction.

Light transport and tracing (the same names as `coherent render`):
integrator="pt" | "drt" | "wrt" | "rcs" | "ao" (path tracing, distribution
ray tracing, Whitted, ray casting with shadows, ambient occlusion);
traversal="single" | "wide" (= single) | "packet" | "stream" | "wavefront";
assembly="types" | "runs" (packet traversal: secondary rays grouped by ray
type or by runs of equal type); bvh_width=2 | 4 | 8; reorder="none" |
"static1d" | "static3d" | "hash32" | "hash192" | "csd32" and wave_size
(wavefront); ao_samples and ao_distance (ao; 0 = a tenth of the scene's
diagonal). heatmaps=True fills the 'BVH Visits' and 'SIMD Utilisation'
passes. The `settings` property returns the configuration as resolved.
stats() adds per-bounce work ("bounces": rays, node visits, box and triangle
tests per ray, SIMD utilisation of box and triangle tests; None where no
packet traced), "simd_utilisation", "rays_per_second", "trace_seconds" and
"sort_seconds".
)doc")
        .def(py::init(&make_renderer), py::arg("scene"), py::kw_only(), py::arg("width") = 512,
             py::arg("height") = 512, py::arg("spp") = 16, py::arg("seed") = 0, py::arg("threads") = 0,
             py::arg("max_bounces") = 12, py::arg("diffuse_bounces") = 4, py::arg("glossy_bounces") = 4,
             py::arg("transmission_bounces") = 12, py::arg("rr_min_bounces") = 3, py::arg("transparent") = false,
             py::arg("border") = py::none(), py::arg("tile_size") = 32, py::arg("force_all_features") = false,
             py::arg("sampler") = "spt", py::arg("packet") = py::make_tuple(4, 4),
             py::arg("progressive_display") = false, py::arg("sequences") = "packet", py::arg("target_error") = 0.0,
             py::arg("time_limit") = 0.0, py::arg("adaptive") = false, py::arg("adaptive_threshold") = 0.01,
             py::arg("adaptive_min_samples") = 16, py::arg("integrator") = "pt", py::arg("traversal") = "auto",
             py::arg("assembly") = "types", py::arg("bvh_width") = 8, py::arg("reorder") = "none",
             py::arg("wave_size") = RenderSettings{}.wave_size, py::arg("ao_samples") = RenderSettings{}.ao_samples,
             py::arg("ao_distance") = 0.0, py::arg("heatmaps") = false)
        .def("render", &PyRenderer::render, py::arg("progress") = py::none(), R"doc(
Renders all samples; returns False if cancelled. `progress(dict)` is called
after every sample pass (and periodically within long passes) with keys
samples_done, samples_total, fraction, seconds, error_estimate, rays,
mrays_per_s; a falsy
return value cancels. An exception raised by the callback cancels the render
and is re-raised when render() returns.)doc")
        .def("start", &PyRenderer::start, R"doc(
Starts rendering on a native background thread and returns at once (for
interactive viewports). Poll progress()/snapshot(); wait() joins. The thread
never calls into Python.)doc")
        .def("wait", &PyRenderer::wait, "Waits for start()'s render; returns False if cancelled.")
        .def_property_readonly("running", &PyRenderer::running, "True while start()'s render runs.")
        .def("progress", &PyRenderer::async_progress, "Progress of start()'s render as a dict (adds running, error).")
        .def("snapshot", &PyRenderer::snapshot, py::arg("flip_y") = true, R"doc(
(samples, pixels) of start()'s render: the Combined pass as of the latest
completed sample pass, float32 (film_height*film_width, 4), or (0, None)
before the first pass completes.)doc")
        .def("cancel", &PyRenderer::cancel, "Requests cancellation; safe from any thread.")
        .def_property_readonly("cancelled", &PyRenderer::cancelled)
        .def("pass_pixels", &PyRenderer::pass_pixels, py::arg("name"), py::arg("flip_y") = true, R"doc(
The resolved pass as a new float32 array of shape (film_height*film_width,
channels): 'Combined' (RGBA), 'Depth' (1; 1e10 where nothing was hit) or
'Normal' (XYZ) or 'Error' (1; per-pixel estimated RMS error of the mean
radiance, from even/odd sample passes, 0 before 2 passes), and with
heatmaps=True 'BVH Visits' (1; BVH node visits per camera sample) and 'SIMD
Utilisation' (1; mean active fraction, 0..1, of the SIMD lanes that traced
the pixel's rays; 0 where no heatmap sample was taken). flip_y=True orders
rows bottom-up as Blender expects.)doc")
        .def("stats", &PyRenderer::stats, "Render statistics: rays per type, traversal counters, time.")
        .def("bvh_stats", &PyRenderer::bvh_stats, "BVH build statistics.")
        .def_property_readonly("bvh_reused", &PyRenderer::bvh_reused,
                               "True if this Renderer reused the BVH a previous one built over the same scene.")
        .def_property_readonly("features", &PyRenderer::features, "Features the kernels were specialised for.")
        .def_property_readonly("width", [](const PyRenderer& r) { return r.settings().width; })
        .def_property_readonly("height", [](const PyRenderer& r) { return r.settings().height; })
        .def_property_readonly("film_width", [](const PyRenderer& r) { return r.film().width(); })
        .def_property_readonly("film_height", [](const PyRenderer& r) { return r.film().height(); })
        .def_property_readonly("spp", [](const PyRenderer& r) { return r.settings().spp; })
        .def_property_readonly("settings", [](const PyRenderer& r) { return settings_dict(r.settings()); },
                               "The tracing configuration as a dict: integrator, traversal, assembly, bvh_width, "
                               "reorder, wave_size, ao_samples, ao_distance, heatmaps, packet, sampler (resolved).");
}

}  // namespace coherent::python
