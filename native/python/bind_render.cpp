// Python bindings of the renderer: Renderer(scene, **settings).render(progress),
// cancel(), pass_pixels(), stats().
//
// Threading model: render() releases the GIL for the whole render and takes
// it back only to call the Python progress callback (on the thread that called
// render(), between or within sample passes). cancel() only flips an atomic,
// so it can be called from any Python thread while render() runs.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <exception>
#include <mutex>
#include <optional>
#include <thread>
#include <type_traits>
#include <vector>

#include "bind_settings.h"
#include "bindings.h"
#include "render/memory_budget.h"
#include "denoise/denoiser.h"
#include "render/renderer.h"

namespace coherent::python {

namespace {

// Blender writes 1e10 where the Depth pass saw nothing (Cycles does the same);
// the film stores +inf there, which the compositor cannot handle.
constexpr float kBlenderNoDepth = 1e10f;

constexpr PassType kPassTypes[] = {PassType::Combined,        PassType::Depth,           PassType::Normal,
                                   PassType::Error,           PassType::NodeVisits,      PassType::SimdUtilisation,
                                   PassType::DenoisingAlbedo, PassType::DenoisingNormal, PassType::NoisyImage,
                                   PassType::DenoisingDepth};

PassType pass_from_name(const std::string& name) {
    for (PassType t : kPassTypes)
        if (name == pass_info(t).name) return t;
    for (int i = 0; i < kRenderPassCount; ++i)
        if (name == render_pass_info(RenderPass(i)).name) return pass_type(RenderPass(i));
    if (name == "Z") return PassType::Depth;  // Blender < 2.92 name of the depth pass
    throw py::value_error("pass_pixels: unknown pass '" + name +
                          "' (expected 'Combined', 'Depth', 'Normal', 'Error', 'BVH Visits', 'SIMD Utilisation', "
                          "'Denoising Albedo', 'Denoising Normal', 'Noisy Image' or a Cycles pass such as 'DiffDir')");
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

// The settings as the Renderer resolved them (sampler and traversal never
// Auto), by the table's names, plus whether the BVH Visits heatmap counts
// per path.
py::dict settings_dict(const RenderSettings& s) {
    py::dict d = settings_to_python(s);
    d["counts_path_visits"] = traversal_counts_path_visits(s.traversal);
    return d;
}

// Sizes in bytes (stats.h MemoryStats); None where unknown.
py::dict memory_dict(const MemoryStats& m) {
    py::dict d;
    m.for_each_reported([&](const char* name, const auto& value) {
        if constexpr (std::is_same_v<std::decay_t<decltype(value)>, uint64_t>)
            d[name] = value;
        else
            d[name] = value ? py::cast(*value) : py::object(py::none());
    });
    return d;
}

// A render that does not fit becomes MemoryError with a message naming the
// sizes, never a crash of the host (Blender): OutOfMemoryBudget from the
// check before the build, std::bad_alloc from anywhere else.
void translate_memory_errors(std::exception_ptr error) {
    try {
        if (error) std::rethrow_exception(error);
    } catch (const OutOfMemoryBudget& e) {
        PyErr_SetString(PyExc_MemoryError, e.what());
    } catch (const std::bad_alloc&) {
        PyErr_SetString(PyExc_MemoryError,
                        "out of memory (std::bad_alloc): the scene, its BVH or the film did not fit in this "
                        "machine's memory; fewer triangles (instances instead of copies, lower subdivision) or a "
                        "smaller image would");
    }
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
        std::shared_ptr<const InstanceBvh> instances = scene_->instance_bvh;
        bvh_reused_ = bvh != nullptr;
        try {
            py::gil_scoped_release unlocked;  // the BVH build takes time
            renderer_ = std::make_unique<Renderer>(scene_->scene, settings, std::move(bvh), std::move(instances));
        } catch (...) {
            scene_->active_renderers.fetch_sub(1);
            throw;
        }
        scene_->bvh = renderer_->shared_bvh();
        scene_->instance_bvh = renderer_->shared_instance_bvh();
        settings_ = renderer_->settings();  // as resolved: sampler and traversal never Auto
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
                        take_snapshot(p.samples_done);
                    }
                    std::lock_guard<std::mutex> lock(async_mutex_);
                    async_progress_ = p;
                    async_progress_.stats = nullptr;  // not valid outside the callback
                    async_rays_ = p.stats ? p.stats->total_rays() : 0;
                    return true;  // cancellation goes through Renderer::cancel()
                });
                // The denoised film (settings.denoise): the final snapshot.
                if (renderer_->film().denoised()) take_snapshot(renderer_->stats().spp, false);
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
        const Film& film = renderer_->film();
        if (name.rfind("Crypto", 0) == 0) return cryptomatte_pixels(film, name, flip_y);
        const PassType type = pass_from_name(name);
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

    // "CryptoObject00" ...: layer 0.. of a Cryptomatte type, RGBA.
    static py::array_t<float> cryptomatte_pixels(const Film& film, const std::string& name, bool flip_y) {
        for (int t = 0; t < kCryptoTypeCount; ++t) {
            const std::string prefix = crypto_pass_prefix(CryptoType(t));
            if (name.size() != prefix.size() + 2 || name.rfind(prefix, 0) != 0 || !std::isdigit(name[prefix.size()]) ||
                !std::isdigit(name[prefix.size() + 1]))
                continue;
            const int layer = std::stoi(name.substr(prefix.size()));
            const py::ssize_t w = film.width(), h = film.height();
            py::array_t<float> out({w * h, py::ssize_t(4)});
            float* data = out.mutable_data();
            film.resolve_cryptomatte(CryptoType(t), layer, data);
            if (flip_y)
                for (py::ssize_t y = 0; y < h / 2; ++y)
                    std::swap_ranges(data + y * w * 4, data + (y + 1) * w * 4, data + (h - 1 - y) * w * 4);
            return out;
        }
        throw py::value_error("pass_pixels: unknown pass '" + name + "' (Cryptomatte passes are CryptoObject00, "
                              "CryptoMaterial01, ...)");
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
        // While denoising after the last pass: its progress in [0, 1], else None.
        d["denoise_fraction"] = p.denoise_fraction >= 0.0 ? py::object(py::float_(p.denoise_fraction)) : py::none();
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
        // Denoising: the denoised image's estimate (None when not denoised).
        d["denoised_error_estimate"] = error_estimate_object(s.denoised_error_estimate);
        d["denoise_seconds"] = s.denoise_seconds;
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
        d["memory"] = memory_dict(s.memory);
        return d;
    }

    // Resolves Combined into the snapshot buffer (on the worker thread, at
    // the end of a pass: the only moment the film may be read). With
    // denoising on, the viewport sees a denoised image at pass 2, 4, 8, ...
    // (a cheaper filter: smaller window); the final one comes from the
    // Renderer's own denoiser after the last pass.
    void take_snapshot(int samples_done, bool between_passes = true) {
        const Film& film = renderer_->film();
        std::vector<float> pixels(size_t(film.width()) * film.height() * 4);
        film.resolve_into(PassType::Combined, pixels.data());
        const bool power_of_two = samples_done >= 2 && (samples_done & (samples_done - 1)) == 0;
        if (between_passes && settings_.denoise && power_of_two && samples_done < settings_.spp) {
            DenoiseOptions options;
            options.strength = settings_.denoise_strength;
            options.caustics = renderer_->active_features().can_make_caustics();
            options.threads = settings_.threads;
            options.window_radius = kViewportWindowRadius;
            options.ring_radius = 0;
            const DenoiseResult d = denoise(film, options, [this](double) { return !renderer_->cancelled(); });
            for (size_t i = 0; i < d.rgb.size() / 3; ++i)
                for (int c = 0; c < 3; ++c) pixels[4 * i + c] = d.rgb[3 * i + c];
        }
        std::lock_guard<std::mutex> lock(async_mutex_);
        snapshot_.swap(pixels);
        snapshot_samples_ = samples_done;
    }
    // A 5 x 5 window and no ring: the display between passes stays a
    // fraction of a pass's time, where the final render's filter weighs up
    // to 121 pairs a pixel instead of 25.
    static constexpr int kViewportWindowRadius = 2;

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

std::unique_ptr<PyRenderer> make_renderer(std::shared_ptr<PyScene> scene, const py::object& settings,
                                          const py::kwargs& kwargs) {
    if (!scene) throw py::type_error("scene: expected a coherent Scene, got None");
    // passes=[names]: Cycles' render passes (film/passes.h), a set rather than a table row.
    // cryptomatte=["object", "material", "asset"], cryptomatte_levels=N likewise.
    py::kwargs rest;
    PassMask passes = 0;
    uint32_t crypto = 0;
    int levels = RenderSettings{}.cryptomatte_levels;
    for (const auto& item : kwargs) {
        const std::string key = py::str(item.first).cast<std::string>();
        if (key != "passes" && key != "cryptomatte" && key != "cryptomatte_levels") {
            rest[item.first] = item.second;
            continue;
        }
        try {
            if (key == "cryptomatte_levels") levels = item.second.cast<int>();
            else if (key == "cryptomatte") crypto = crypto_mask_from_names(item.second.cast<std::vector<std::string>>());
            else passes = pass_mask_from_names(item.second.cast<std::vector<std::string>>());
        } catch (const std::invalid_argument& e) {
            throw py::value_error(key + ": " + e.what());
        } catch (const py::cast_error&) {
            throw py::type_error(key + (key == "cryptomatte_levels" ? ": expected an int" : ": expected a list of names"));
        }
    }
    if (levels < 1 || levels > 16) throw py::value_error("cryptomatte_levels: expected 1 to 16");
    RenderSettings rs = settings_from_python(settings, rest);
    rs.passes = passes;
    rs.cryptomatte = crypto;
    rs.cryptomatte_levels = levels;
    return std::make_unique<PyRenderer>(std::move(scene), rs);
}

}  // namespace

void bind_render(py::module_& m) {
    py::register_exception_translator(&translate_memory_errors);
    static const std::string doc = std::string(R"doc(
Renderer(scene, settings=None, **kwargs): renders a Scene. The settings are
the rows of settings_table(), given as a dict, as keyword arguments (which
win over the dict), or both; any left out keep their defaults. A wrong name
or type raises TypeError, a value out of range ValueError, each naming the
setting. Construction builds the BVH (the GIL is released). The scene is
kept alive and read-only while the Renderer exists.

border=(x0, y0, x1, y1) in pixels, y = 0 at the TOP row, x1/y1 exclusive: the
film (and every pass) then covers only that region.

Stopping rules: whichever of spp, target_error and time_limit comes first
ends the render. stats()["spp"] says how many passes were taken; stats()
and the progress dict carry error_estimate (None before 2 passes). The
`settings` property returns every setting as resolved (sampler and
traversal never 'auto'). stats() adds per-bounce work ("bounces": rays,
node visits, box and triangle tests per ray, SIMD utilisation of box and
triangle tests; None where no packet traced), "simd_utilisation",
"rays_per_second", "trace_seconds", "sort_seconds" and "memory" (bytes:
scene, BVH, film, per triangle, the estimate checked before the build and
its limit, the process's peak RSS).

Memory: before building, the renderer estimates what the render needs and
raises MemoryError, naming the sizes, when that exceeds the available memory
(or COHERENT_MEMORY_LIMIT, e.g. "8G", a budget for scene, BVH and film);
running out of memory anywhere else raises MemoryError too.

Settings:
)doc") + settings_docstring();
    py::class_<PyRenderer>(m, "Renderer", doc.c_str())
        .def(py::init(&make_renderer), py::arg("scene"), py::arg("settings") = py::none())
        .def("render", &PyRenderer::render, py::arg("progress") = py::none(), R"doc(
Renders all samples; returns False if cancelled. `progress(dict)` is called
after every batch of sample passes (report_interval) and periodically within
one, with keys samples_done, samples_total, fraction, seconds, error_estimate,
rays, mrays_per_s; a falsy
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
                               "Every setting as resolved (settings_table() names; sampler and traversal never "
                               "'auto'), plus counts_path_visits.");
}

}  // namespace coherent::python
