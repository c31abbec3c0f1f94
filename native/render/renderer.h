// The renderer: drives sampling, tracing and shading over the film, in
// parallel, with progress reporting and prompt cancellation.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <vector>

#include "../accel/bvh.h"
#include "../accel/instance_bvh.h"
#include "../accel/motion_bvh.h"
#include "../film/film.h"
#include "../scene/scene.h"
#include "settings.h"
#include "stats.h"

namespace coherent {

// Called after every completed batch of sample passes (one pass, or several:
// settings.report_interval), and about every 250 ms within a batch with the
// same `samples_done`. Return false to cancel.
// Invoked on the thread that called render(), never concurrently.
struct Progress {
    int samples_done = 0;
    int samples_total = 0;
    double fraction = 0.0;  // [0,1] of the whole render
    double seconds = 0.0;
    double error_estimate = -1.0;  // relative RMSE estimate; negative while unknown
    // After the last pass, while the denoiser runs (settings.denoise): its
    // progress in [0, 1], samples_done unchanged. Negative otherwise.
    double denoise_fraction = -1.0;
    const RenderStats* stats = nullptr;
};
using ProgressCallback = std::function<bool(const Progress&)>;

class Renderer {
public:
    // The scene must be finalize()d and outlive the renderer. Builds the BVH.
    Renderer(const Scene& scene, const RenderSettings& settings);
    // The BVH a Renderer of this scene traces: every triangle, except moving
    // ones (motion blur), which a MotionBvh holds instead.
    static std::shared_ptr<Bvh> build_bvh(const Scene& scene, const BvhBuildOptions& options = {});
    // Renders with a BVH already built over exactly this scene's triangles
    // (interactive sessions: camera, material, light and world edits leave
    // the triangles, and so the BVH, unchanged). Precondition: `bvh` was
    // built from `scene` and no triangle changed since; it is shared, never
    // modified.
    // Likewise `instances`, the two-level BVH of scene.instances (null: built here).
    Renderer(const Scene& scene, const RenderSettings& settings, std::shared_ptr<const Bvh> bvh,
             std::shared_ptr<const InstanceBvh> instances = nullptr);
    ~Renderer();

    // Renders settings.spp samples per pixel, pass by pass (sample 0 over the
    // whole film, then sample 1, ...; a tile may run ahead of another within
    // a batch of passes), stopping early at settings.target_error
    // or settings.time_limit (see settings.h); stats().spp says how many
    // passes were taken. Returns false if cancelled. Thread-safe
    // with respect to cancel() only.
    bool render(const ProgressCallback& progress = {});
    void cancel() { cancelled_.store(true, std::memory_order_relaxed); }
    bool cancelled() const { return cancelled_.load(std::memory_order_relaxed); }

    const Film& film() const { return film_; }
    // The settings as resolved and clamped (traversal never Auto, border in the frame, ...).
    const RenderSettings& settings() const { return settings_; }
    // Adaptive sampling: whether film pixel (x, y) stopped receiving samples.
    bool pixel_converged(int x, int y) const {
        return !converged_.empty() && converged_[size_t(y) * size_t(film_.width()) + size_t(x)] != 0;
    }
    const RenderStats& stats() const { return stats_; }
    const SceneFeatures& active_features() const { return features_; }
    const Bvh& bvh() const { return *bvh_; }
    // The instances' BVH (null without instances), for the next Renderer over the same scene.
    const std::shared_ptr<const InstanceBvh>& shared_instance_bvh() const { return instances_; }
    // The BVH, for handing on to the next Renderer over the same triangles.
    const std::shared_ptr<const Bvh>& shared_bvh() const { return bvh_; }

private:
    const Scene& scene_;
    RenderSettings settings_;
    // Object motion blur: the moving triangles (empty when nothing moves);
    // they are left out of bvh_.
    MotionBvh motion_;
    // Shared geometry (scene.instances): the two-level BVH's top level and
    // the prototypes' BVHs; empty when the scene has no instances.
    std::shared_ptr<const InstanceBvh> instances_;
    SceneFeatures features_;
    std::shared_ptr<const Bvh> bvh_;  // never null after construction
    Film film_;
    RenderStats stats_;
    // Adaptive sampling: 1 per converged film pixel; empty when off.
    // Invariant: once set, a flag is never cleared within a render.
    std::vector<uint8_t> converged_;
    // Distributing samples: each pixel's sample count, set after the
    // uniform passes (sample_distribution.h); empty until then or when off.
    std::vector<uint32_t> sample_targets_;
    // Marks pixels converged by the rule in settings.h; returns how many are now.
    uint64_t update_convergence();
    // render() in steps: statistics and convergence flags of a new render;
    // after a pass, adaptive sampling and the stopping rules (whether to stop).
    void reset_stats();
    bool stop_after_pass(int passes_done, int spp);
    // Passes the next batch renders (settings.h, report_interval), given the
    // passes done, the seconds one took in the last batch, and the seconds
    // since the render started.
    int batch_size(int done, int spp, double seconds_per_pass, double elapsed) const;
    // The pass count of adaptive sampling's first decision: adaptive_min_samples
    // rounded up to even, at least 2.
    int first_adaptive_decision() const;
    // Distributing samples: the passes every pixel takes before the decision.
    int uniform_passes() const;
    // Denoises the film (settings.denoise); report(fraction) returns false to cancel.
    void denoise_film(const std::function<bool(double)>& report);
    std::atomic<bool> cancelled_{false};
    // The settings asked for Traversal::Auto (resolved in the constructor;
    // render() may still trade packets for single rays after measuring).
    bool auto_traversal_ = false;
};

}  // namespace coherent
