#include "json_report.h"

#include <nlohmann/json.hpp>

namespace coherent::cli {

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
    // Non-UTF-8 bytes (e.g. in a file name) are replaced instead of throwing.
    return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace coherent::cli
