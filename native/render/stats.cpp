// Render statistics.
#include "stats.h"

namespace coherent {

const char* ray_type_name(RayType t) {
    switch (t) {
        case RayType::Camera: return "camera";
        case RayType::Shadow: return "shadow";
        case RayType::Diffuse: return "diffuse";
        case RayType::Glossy: return "glossy";
        case RayType::Reflection: return "reflection";
        case RayType::Refraction: return "refraction";
        case RayType::Count: break;
    }
    return "unknown";
}

BounceStats& BounceStats::operator+=(const BounceStats& o) {
    rays += o.rays;
    node_visits += o.node_visits;
    box_tests += o.box_tests;
    triangle_tests += o.triangle_tests;
    box_lanes += o.box_lanes;
    box_lanes_active += o.box_lanes_active;
    triangle_lanes += o.triangle_lanes;
    triangle_lanes_active += o.triangle_lanes_active;
    return *this;
}

RenderStats& RenderStats::operator+=(const RenderStats& o) {
    for (size_t i = 0; i < rays.size(); ++i) rays[i] += o.rays[i];
    traversal += o.traversal;
    for (size_t i = 0; i < bounces.size(); ++i) bounces[i] += o.bounces[i];
    trace_seconds += o.trace_seconds;
    sort_seconds += o.sort_seconds;
    nonfinite_samples += o.nonfinite_samples;
    samples += o.samples;
    // spp, converged_pixels, pixels, error_estimate, seconds and memory describe the whole render, not a
    // per-thread sum; the renderer sets them. seconds is wall-clock time of the whole render, not a per-thread sum.
    return *this;
}

}  // namespace coherent
