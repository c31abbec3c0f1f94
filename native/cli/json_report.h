// The statistics object `coherent render --json` prints on stdout.
#pragma once

#include <string>

#include "render/settings.h"
#include "render/stats.h"
#include "scene/features.h"
#include "scene/scene.h"

namespace coherent::cli {

struct RenderReport {
    double seconds = 0.0;        // Renderer::render() wall time
    double load_seconds = 0.0;   // reading and validating the scene file
    double build_seconds = 0.0;  // Renderer construction (BVH build)
    RenderSettings settings;
    RenderStats stats;
    DropReport dropped;
    SceneFeatures features;      // the renderer's active features
    size_t triangles = 0;
    std::string output;
};

// One JSON object, one line:
// {"seconds", "spp" (samples per pixel actually taken), "spp_max" (--spp),
//  "error_estimate" (relative RMSE estimate or null), "target_error",
//  "time_limit", "width", "height", "rays": {<type>: n, ..., "total": n},
//  "mrays_per_s", "dropped": {...}, "nonfinite_samples", "features": [...],
//  "output", plus "load_seconds", "build_seconds", "triangles", "seed", "threads", "max_bounces"}.
std::string render_report_json(const RenderReport& report);

}  // namespace coherent::cli
