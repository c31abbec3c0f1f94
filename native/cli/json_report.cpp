#include "json_report.h"

#include <optional>
#include <type_traits>

#include <nlohmann/json.hpp>

#include "render/setting_table.h"

namespace coherent::cli {
namespace {

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

// Sizes in bytes (stats.h MemoryStats); null where unknown.
nlohmann::ordered_json memory_json(const MemoryStats& m) {
    nlohmann::ordered_json j;
    m.for_each_reported([&](const char* name, const auto& value) {
        if constexpr (std::is_same_v<std::decay_t<decltype(value)>, uint64_t>)
            j[name] = value;
        else
            j[name] = value ? nlohmann::ordered_json(*value) : nlohmann::ordered_json(nullptr);
    });
    return j;
}

// Every settings-table row as the Renderer resolved them (sampler and
// traversal never Auto).
nlohmann::ordered_json settings_json(const RenderSettings& s) {
    nlohmann::ordered_json j = nlohmann::ordered_json::object();
    for (const SettingSpec& spec : setting_table())
        std::visit([&](const auto& v) { j[spec.name] = v; }, spec.get(s));
    return j;
}

}  // namespace

std::string render_report_json(const RenderReport& r) {
    nlohmann::ordered_json j;
    j["seconds"] = r.seconds;
    // The settings as rendered, one key per settings-table row.
    j["settings"] = settings_json(r.settings);
    j["spp"] = r.stats.spp;  // samples per pixel actually taken (stopping rules may end early)
    // Estimated relative RMSE of the image; null with fewer than 2 passes.
    if (r.stats.error_estimate >= 0.0)
        j["error_estimate"] = r.stats.error_estimate;
    else
        j["error_estimate"] = nullptr;
    // Denoising (--denoise): the denoised image's estimate from its filtered
    // halves, next to the noisy one above, and the denoiser's seconds
    // (included in "seconds"); null when not denoised.
    if (r.stats.denoised_error_estimate >= 0.0)
        j["denoised"] = {{"error_estimate", r.stats.denoised_error_estimate},
                         {"seconds", r.stats.denoise_seconds}};
    else
        j["denoised"] = nullptr;
    // Adaptive sampling's outcome: null when off.
    if (r.settings.adaptive)
        j["adaptive"] = {{"converged_pixels", r.stats.converged_pixels},
                         {"converged_fraction", r.stats.converged_fraction()}};
    else
        j["adaptive"] = nullptr;

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
    j["memory"] = memory_json(r.stats.memory);

    // What the tracing cost.
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
