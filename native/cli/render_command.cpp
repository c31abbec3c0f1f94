#include "render_command.h"

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <exception>
#include <memory>

#include "convergence_log.h"
#include "heatmap_output.h"
#include "io/gltf.h"
#include "shader/textures.h"
#include "io/image.h"
#include "json_report.h"
#include "options.h"
#include "progress_bar.h"
#include "render/renderer.h"

namespace coherent::cli {
namespace {

// SIGINT handling. The handler only touches lock-free atomics (allowed in a
// signal handler): it records the interrupt and asks the live renderer, if
// any, to cancel. SA_RESETHAND restores the default action, so a second
// Ctrl-C kills the process at once if the first one is not honoured quickly.
std::atomic<bool> g_interrupted{false};
std::atomic<Renderer*> g_renderer{nullptr};
static_assert(std::atomic<bool>::is_always_lock_free && std::atomic<Renderer*>::is_always_lock_free);

extern "C" void on_sigint(int) {
    g_interrupted.store(true, std::memory_order_relaxed);
    if (Renderer* r = g_renderer.load(std::memory_order_relaxed)) r->cancel();
}

void install_sigint_handler() {
    struct sigaction action {};
    action.sa_handler = on_sigint;
    sigemptyset(&action.sa_mask);
    action.sa_flags = SA_RESETHAND;
    sigaction(SIGINT, &action, nullptr);
}

// Publishes a renderer to the signal handler for as long as it lives.
struct RendererRegistration {
    explicit RendererRegistration(Renderer& r) {
        g_renderer.store(&r);
        if (g_interrupted.load()) r.cancel();  // interrupted before we registered
    }
    ~RendererRegistration() { g_renderer.store(nullptr); }
};

double seconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void print_error(const std::string& message) { std::fprintf(stderr, "coherent: error: %s\n", message.c_str()); }

int interrupted() {
    std::fprintf(stderr, "coherent: interrupted, no image written\n");
    return kExitInterrupted;
}

int render(const RenderOptions& options) {
    const RenderSettings& settings = options.settings;
    install_sigint_handler();

    // --- load ---------------------------------------------------------------
    const auto load_start = std::chrono::steady_clock::now();
    Scene scene;
    const float aspect = float(settings.width) / float(settings.height);
    const GltfLoadResult loaded = load_gltf(options.scene, scene, aspect);
    if (!loaded.ok) {
        print_error(loaded.error);
        return kExitBadInput;
    }
    scene.finalize();
    const double load_seconds = seconds_since(load_start);
    if (!scene.dropped.empty()) std::fprintf(stderr, "coherent: warning: %s\n", scene.dropped.summary().c_str());
    if (scene.shading.textures)
        for (const std::string& w : scene.shading.textures->warnings()) std::fprintf(stderr, "coherent: warning: %s\n", w.c_str());
    if (g_interrupted.load()) return interrupted();

    // --- render -------------------------------------------------------------
    const auto build_start = std::chrono::steady_clock::now();
    Renderer renderer(scene, settings);
    const double build_seconds = seconds_since(build_start);
    RendererRegistration registration(renderer);

    ConvergenceLog convergence;
    std::string error;
    if (!options.convergence.empty() && !convergence.open(options.convergence, error)) {
        print_error(error);
        return kExitBadInput;
    }

    ProgressBar bar(settings.target_error);
    const auto render_start = std::chrono::steady_clock::now();
    const bool finished = renderer.render([&](const Progress& p) {
        bar.update(p);
        convergence.record(p);
        return !g_interrupted.load(std::memory_order_relaxed);
    });
    const double render_seconds = seconds_since(render_start);
    bar.finish();
    if (!finished || g_interrupted.load()) return interrupted();
    if (!convergence.close(error)) {
        print_error(error);
        return kExitBadInput;
    }

    // --- write --------------------------------------------------------------
    if (!write_film(options.output, renderer.film(), error)) {
        print_error(error);
        return kExitBadInput;
    }

    std::vector<HeatmapImage> heatmaps;
    if (settings.heatmaps) {
        // Written even when empty, so a script finds the files it asked for;
        // the warning says why the visits are all zero.
        if (!traversal_counts_path_visits(renderer.settings().traversal))
            std::fprintf(stderr,
                         "coherent: warning: --traversal %s does not count BVH visits per path; the BVH visits "
                         "heatmap is zero\n",
                         std::string(traversal_name(renderer.settings().traversal)).c_str());
        if (!write_heatmaps(options.output, renderer.film(), heatmaps, error)) {
            print_error(error);
            return kExitBadInput;
        }
    }

    RenderReport report;
    report.seconds = render_seconds;
    report.load_seconds = load_seconds;
    report.build_seconds = build_seconds;
    report.settings = renderer.settings();  // as resolved (traversal auto -> single or packet)
    report.stats = renderer.stats();
    report.dropped = scene.dropped;
    report.features = renderer.active_features();
    report.triangles = scene.triangle_count();
    report.output = options.output;
    report.heatmaps = heatmaps;
    if (options.json) {
        std::printf("%s\n", render_report_json(report).c_str());
    } else {
        const double mrays = render_seconds > 0.0 ? double(report.stats.total_rays()) / render_seconds * 1e-6 : 0.0;
        std::printf("coherent: wrote %s (%dx%d, %d spp, %.3f s, %.2f Mrays/s", options.output.c_str(),
                    settings.width, settings.height, report.stats.spp, render_seconds, mrays);
        if (report.stats.error_estimate >= 0.0) std::printf(", error %.2f %%", 100.0 * report.stats.error_estimate);
        if (report.stats.denoised_error_estimate >= 0.0)
            std::printf(", denoised in %.3f s: error %.2f %%", report.stats.denoise_seconds,
                        100.0 * report.stats.denoised_error_estimate);
        std::printf(", %s, %s", std::string(integrator_name(settings.integrator)).c_str(),
                    std::string(traversal_name(renderer.settings().traversal)).c_str());
        uint64_t lanes = 0, active = 0;
        for (const BounceStats& b : report.stats.bounces) {
            lanes += b.box_lanes;
            active += b.box_lanes_active;
        }
        if (lanes) std::printf(", SIMD utilisation %.1f %%", 100.0 * double(active) / double(lanes));
        std::printf(")\n");
        for (const HeatmapImage& h : heatmaps)
            std::printf("coherent: wrote %s and %s: %s, colours from %g (dark) to %g (bright); min %g, mean %g, "
                        "max %g\n",
                        h.exr_path.c_str(), h.png_path.c_str(),
                        h.pass == PassType::NodeVisits ? "BVH node visits per camera sample"
                                                       : "SIMD lane utilisation",
                        double(h.lo), double(h.hi), double(h.min), double(h.mean), double(h.max));
    }
    std::fflush(stdout);
    return kExitOk;
}

}  // namespace

int run_render(const std::vector<std::string>& args) {
    RenderOptions options;
    std::string error;
    if (!parse_render_args(args, options, error)) {
        print_error(error + " (see coherent render --help)");
        return kExitBadUsage;
    }
    if (options.help) {
        std::fputs(render_usage().c_str(), stdout);
        return kExitOk;
    }
    // Refuse an unwritable format before spending time on the render.
    if (image_format_for(options.output) == ImageFormat::Unknown) {
        print_error("unknown output format '" + options.output + "' (use .exr or .png)");
        return kExitBadUsage;
    }
    if (options.settings.passes && image_format_for(options.output) != ImageFormat::Exr) {
        print_error("--passes needs an .exr output ('" + options.output + "' holds Combined only)");
        return kExitBadUsage;
    }
    try {
        return render(options);
    } catch (const std::bad_alloc&) {
        print_error("out of memory");
        return kExitBadInput;
    } catch (const std::exception& e) {
        print_error(e.what());
        return kExitBadInput;
    }
}

}  // namespace coherent::cli
