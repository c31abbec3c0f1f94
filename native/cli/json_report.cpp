#include "json_report.h"

#include <optional>

#include <nlohmann/json.hpp>

namespace coherent::cli {
namespace {

// A ratio, or null when the denominator is 0 (nothing was measured, which
// is not the same as a measured 0).
// A ratio, or null where nothing was measured (stats.h).
nlohmann::ordered_json ratio(std::optional<double> r) {
    if (!r) return nullptr;
    return *r;
}

nlohmann::ordered_json bounce_json(int index, const BounceStats& b) {
    nlohmann::ordered_json j;
    j["bounce"] = index;
    j["rays"] = b.rays;
    j["node_visits"] = b.node_visits;
    j["box_tests"] = b.box_tests;
    j["triangle_tests"] = b.triangle_tests;
    j["node_visits_per_ray"] = ratio(b.node_visits_per_ray());
    j["box_tests_per_ray"] = ratio(b.box_tests_per_ray());
    j["triangle_tests_per_ray"] = ratio(b.triangle_tests_per_ray());
    j["simd_box_utilisation"] = ratio(b.box_utilisation());
    j["simd_triangle_utilisation"] = ratio(b.triangle_utilisation());
    j["and_deeper"] = index == kStatBounces - 1;
    return j;
}

}  // namespace

std::string render_report_json(const RenderReport& r) {
    nlohmann::ordered_json j;
    j["seconds"] = r.seconds;
    j["spp"] = r.stats.spp;  // samples per pixel actually taken (stopping rules may end early)
    j["spp_max"] = r.settings.spp;
    // Estimated relative RMSE of the image; null with fewer than 2 passes.
    if (r.stats.error_estimate >= 0.0)
        j["error_estimate"] = r.stats.error_estimate;
    else
        j["error_estimate"] = nullptr;
    j["target_error"] = r.settings.target_error;
    j["time_limit"] = r.settings.time_limit;
    // Adaptive sampling: null when off, else its settings and outcome.
    if (r.settings.adaptive)
        j["adaptive"] = {{"threshold", r.settings.adaptive_threshold},
                         {"min_samples", r.settings.adaptive_min_samples},
                         {"converged_pixels", r.stats.converged_pixels},
                         {"converged_fraction", r.stats.converged_fraction()}};
    else
        j["adaptive"] = nullptr;
    j["width"] = r.settings.width;
    j["height"] = r.settings.height;

    nlohmann::ordered_json rays = nlohmann::ordered_json::object();
    for (size_t t = 0; t < size_t(RayType::Count); ++t) rays[ray_type_name(RayType(t))] = r.stats.rays[t];
    rays["total"] = r.stats.total_rays();
    j["rays"] = rays;
    j["mrays_per_s"] = r.seconds > 0.0 ? double(r.stats.total_rays()) / r.seconds * 1e-6 : 0.0;

    j["dropped"] = {
        {"nonfinite_vertices", r.dropped.nonfinite_vertices},
        {"out_of_range_indices", r.dropped.out_of_range_indices},
        {"degenerate_triangles", r.dropped.degenerate_triangles},
        {"bad_material_ids", r.dropped.bad_material_ids},
        {"skipped_meshes", r.dropped.skipped_meshes},
    };
    j["nonfinite_samples"] = r.stats.nonfinite_samples;
    j["features"] = r.features.names();
    j["output"] = r.output;

    j["load_seconds"] = r.load_seconds;
    j["build_seconds"] = r.build_seconds;
    j["triangles"] = r.triangles;
    j["seed"] = r.settings.seed;
    j["threads"] = r.settings.threads;
    j["max_bounces"] = r.settings.max_bounces;
    j["sampler"] = std::string(sampler_type_name(r.settings.resolved_sampler()));  // Auto resolved
    j["packet"] = {r.settings.packet_width, r.settings.packet_height};
    j["sequences"] = std::string(sequence_scope_name(r.settings.sequence_scope));

    // Tracing configuration (render_modes.h) and what it cost.
    const RenderSettings& s = r.settings;
    j["integrator"] = std::string(integrator_name(s.integrator));
    j["traversal"] = std::string(traversal_name(s.traversal));
    j["assembly"] = std::string(assembly_name(s.assembly));
    j["bvh_width"] = s.bvh_width;
    j["reorder"] = std::string(reorder_name(s.reorder));
    j["wave_size"] = s.wave_size;
    j["ao_samples"] = s.ao_samples;
    j["ao_distance"] = s.ao_distance;
    j["rays_per_second"] = r.seconds > 0.0 ? double(r.stats.total_rays()) / r.seconds : 0.0;
    j["trace_seconds"] = r.stats.trace_seconds;
    j["sort_seconds"] = r.stats.sort_seconds;

    // Every driver books its work per bounce (path_tracer.h), so the bounces
    // add up to the render's totals.
    const BounceStats all = r.stats.bounce_total();
    const int last = r.stats.deepest_bounce();
    j["tests_per_ray"] = {{"node_visits", ratio(all.node_visits_per_ray())},
                          {"box", ratio(all.box_tests_per_ray())},
                          {"triangle", ratio(all.triangle_tests_per_ray())}};
    j["simd_utilisation"] = {{"box", ratio(all.box_utilisation())}, {"triangle", ratio(all.triangle_utilisation())}};
    nlohmann::ordered_json bounces = nlohmann::ordered_json::array();
    for (int i = 0; i <= last; ++i) bounces.push_back(bounce_json(i, r.stats.bounces[size_t(i)]));
    j["bounces"] = bounces;

    if (r.heatmaps.empty()) {
        j["heatmaps"] = nullptr;
    } else {
        nlohmann::ordered_json heat = nlohmann::ordered_json::object();
        for (const HeatmapImage& h : r.heatmaps)
            heat[h.pass == PassType::NodeVisits ? "bvh_visits" : "simd"] = {
                {"exr", h.exr_path}, {"png", h.png_path}, {"scale", {h.lo, h.hi}},
                {"min", h.min},      {"max", h.max},      {"mean", h.mean}};
        j["heatmaps"] = heat;
    }
    // Non-UTF-8 bytes (e.g. in a file name) are replaced instead of throwing.
    return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace coherent::cli
