// The statistics object `coherent render --json` prints on stdout.
#pragma once

#include <string>
#include <vector>

#include "heatmap_output.h"
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
    std::vector<HeatmapImage> heatmaps;  // --heatmaps: the files written
};

// One JSON object, one line:
// {"seconds", "spp" (samples per pixel actually taken), "spp_max" (--spp),
//  "error_estimate" (relative RMSE estimate; null before 2 passes and under
//  --error-estimate auto when nothing decides by it), "target_error",
//  "time_limit", "width", "height", "rays": {<type>: n, ..., "total": n},
//  "mrays_per_s", "dropped": {...}, "nonfinite_samples", "features": [...],
//  "output", plus "load_seconds", "build_seconds", "triangles", "memory" {"triangles", "scene_bytes",
//  "bvh_bytes", "film_bytes", "bytes_per_triangle", "bvh_bytes_per_triangle", "estimate_bytes",
//  "limit_bytes", "peak_rss_bytes" (null where unknown)}, "seed", "threads", "max_bounces",
//  "sampler", "packet", "sequences",
//  the tracing configuration: "integrator", "traversal", "assembly", "bvh_width", "reorder", "wave_size",
//  "ao_samples", "ao_distance", and its statistics: "rays_per_second", "trace_seconds", "sort_seconds",
//  "tests_per_ray" {"node_visits", "box", "triangle"}, "simd_utilisation" {"box", "triangle"} (active /
//  total SIMD lanes of packet box and triangle tests; null without packets), "bounces": [{"bounce",
//  "rays", "node_visits", "box_tests", "triangle_tests", "node_visits_per_ray", "box_tests_per_ray",
//  "triangle_tests_per_ray", "simd_box_utilisation", "simd_triangle_utilisation", "and_deeper"}, ...]
//  (bounce 0 = camera rays and their shadow rays; trailing empty bounces left out; "and_deeper" marks the
//  last slot that collects every deeper bounce), "heatmaps" (null, or per pass: "exr", "png", "scale"
//  [lo, hi] of the PNG's colours, "min", "max", "mean")}.
std::string render_report_json(const RenderReport& report);

}  // namespace coherent::cli
