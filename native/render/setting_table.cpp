#include "setting_table.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>

namespace coherent {
namespace {

template <class T>
using Member = T RenderSettings::*;

std::string cli_spelling(const std::string& name) {
    std::string s = "--" + name;
    std::replace(s.begin(), s.end(), '_', '-');
    return s;
}

SettingSpec row(std::string name, std::string label, std::string group, SettingType type, std::string help) {
    SettingSpec s;
    s.cli_name = cli_spelling(name);
    s.name = std::move(name);
    s.label = std::move(label);
    s.group = std::move(group);
    s.type = type;
    s.help = std::move(help);
    return s;
}

SettingSpec flag(std::string name, std::string label, std::string group, Member<bool> m, std::string help) {
    SettingSpec s = row(std::move(name), std::move(label), std::move(group), SettingType::Bool, std::move(help));
    s.get = [m](const RenderSettings& r) { return SettingValue(r.*m); };
    s.set = [m](RenderSettings& r, const SettingValue& v) { r.*m = std::get<bool>(v); };
    return s;
}

SettingSpec integer(std::string name, std::string label, std::string group, Member<int> m, int64_t lo, int64_t hi,
                    double soft_max, std::string help) {
    SettingSpec s = row(std::move(name), std::move(label), std::move(group), SettingType::Int, std::move(help));
    s.min = double(lo), s.max = double(hi), s.soft_max = soft_max;
    s.get = [m](const RenderSettings& r) { return SettingValue(int64_t(r.*m)); };
    s.set = [m](RenderSettings& r, const SettingValue& v) { r.*m = int(std::get<int64_t>(v)); };
    return s;
}

template <class T>  // double or float fields
SettingSpec real(std::string name, std::string label, std::string group, Member<T> m, double lo, double hi,
                 double soft_max, std::string help) {
    SettingSpec s = row(std::move(name), std::move(label), std::move(group), SettingType::Real, std::move(help));
    s.min = lo, s.max = hi, s.soft_max = soft_max;
    s.get = [m](const RenderSettings& r) { return SettingValue(double(r.*m)); };
    s.set = [m](RenderSettings& r, const SettingValue& v) { r.*m = T(std::get<double>(v)); };
    return s;
}

template <class E>
struct Option {
    E value;
    SettingChoice choice;
};

// The choice names are the render_modes.h / sampler_type.h names, so
// parse_*() and *_name() there agree with the table.
template <class E>
SettingSpec choice(std::string name, std::string label, std::string group, Member<E> m, std::vector<Option<E>> options,
                   std::string help) {
    SettingSpec s = row(std::move(name), std::move(label), std::move(group), SettingType::Choice, std::move(help));
    for (const Option<E>& o : options) s.choices.push_back(o.choice);
    s.get = [m, options](const RenderSettings& r) {
        for (const Option<E>& o : options)
            if (o.value == r.*m && !o.choice.hidden) return SettingValue(o.choice.name);
        return SettingValue(std::string("?"));
    };
    s.set = [m, options](RenderSettings& r, const SettingValue& v) {
        for (const Option<E>& o : options)
            if (o.choice.name == std::get<std::string>(v)) r.*m = o.value;
    };
    return s;
}

std::vector<SettingSpec> sampling_rows() {
    std::vector<SettingSpec> t;
    t.push_back(integer("spp", "Samples", "Sampling", &RenderSettings::spp, 1, 1 << 24, 4096,
                        "samples per pixel"));
    t.push_back(real("target_error", "Target Error", "Sampling", &RenderSettings::target_error, 0.0, 10.0, 0.2,
                     "stop once the estimated relative RMSE (from the even and odd sample passes, no reference "
                     "needed) is at most this, e.g. 0.02; 0 = off"));
    t.push_back(real("time_limit", "Time Limit", "Sampling", &RenderSettings::time_limit, 0.0, 1e9, 3600.0,
                     "stop after the sample pass that ends past this many seconds of rendering; 0 = off"));
    SettingSpec seed = row("seed", "Seed", "Sampling", SettingType::Seed,
                           "seed of the sample sequences; renders with equal seeds are identical");
    seed.get = [](const RenderSettings& r) { return SettingValue(r.seed); };
    seed.set = [](RenderSettings& r, const SettingValue& v) { r.seed = std::get<uint64_t>(v); };
    t.push_back(std::move(seed));
    t.push_back(flag("adaptive", "Adaptive Sampling", "Sampling", &RenderSettings::adaptive,
                     "adaptive sampling: after adaptive_min_samples passes, a pixel stops taking samples once the "
                     "relative error its neighbours' samples predict for it is below adaptive_threshold (its own "
                     "samples stay out of the decision, which keeps the image unbiased)"));
    t.push_back(real("adaptive_threshold", "Noise Threshold", "Sampling", &RenderSettings::adaptive_threshold, 1e-4,
                     1.0, 0.1,
                     "relative per-pixel error (estimated from the even and odd sample passes) at which adaptive "
                     "sampling stops a pixel"));
    t.push_back(integer("adaptive_min_samples", "Min Samples", "Sampling", &RenderSettings::adaptive_min_samples, 2,
                        1 << 24, 4096,
                        "passes every pixel takes before adaptive sampling may stop it (rounded up to even)"));
    t.push_back(choice<SamplerType>(
        "sampler", "Sampler", "Sampling", &RenderSettings::sampler,
        {{SamplerType::Spt, {"spt", "SPT", "Standard path tracing: an independent random sequence per pixel"}},
         {SamplerType::Cpt, {"cpt", "CPT", "Coherent path tracing: one sequence per sample shared by the pixels of "
                                           "a packet; coherent secondary rays, structured noise that vanishes at "
                                           "high sample counts"}},
         {SamplerType::Icpt, {"icpt", "ICPT", "Interleaved coherent path tracing: packet blocks split into "
                                              "randomised Latin-hypercube subsets that share sequences; hides CPT's "
                                              "structured noise"}},
         {SamplerType::Auto, {"auto", "Auto", "ICPT in the viewport, CPT for final renders (the least error "
                                              "per second there), SPT when denoising (independent pixel "
                                              "noise filters best)"}}},
        "how the random numbers of paths are shared between pixels"));
    SettingSpec packet = row("packet", "Packet Size", "Sampling", SettingType::Size,
                             "ray packet size in pixels (width, height); ICPT uses square blocks of the shorter "
                             "side");
    packet.min = 1, packet.max = 16;  // a packet holds at most 16 x 16 rays (ray_packet.h)
    packet.get = [](const RenderSettings& r) {
        return SettingValue(SettingSize{r.packet_width, r.packet_height});
    };
    packet.set = [](RenderSettings& r, const SettingValue& v) {
        r.packet_width = int(std::get<SettingSize>(v)[0]);
        r.packet_height = int(std::get<SettingSize>(v)[1]);
    };
    t.push_back(std::move(packet));
    t.push_back(choice<SequenceScope>(
        "sequences", "Sequences", "Sampling", &RenderSettings::sequence_scope,
        {{SequenceScope::Packet, {"packet", "Per Packet", "One sequence per packet (the paper's Fig. 3)"}},
         {SequenceScope::Image, {"image", "Per Image", "One sequence per sample for the whole image (its "
                                                       "equation 3)"}}},
        "CPT and ICPT: over which pixels sequences are shared"));
    t.push_back(choice<SampleSequence>(
        "pattern", "Pattern", "Sampling", &RenderSettings::pattern,
        {{SampleSequence::WhiteNoise, {"white", "White Noise", "A counter-based hash per pixel, sample and "
                                                               "dimension"}},
         {SampleSequence::OwenSobol, {"sobol", "Owen-Scrambled Sobol", "Padded Sobol points, Owen-scrambled per "
                                                                       "pixel (SPT), packet (CPT) or subset (ICPT): "
                                                                       "error falls faster on smooth lighting"}}},
        "the random numbers behind every sampler"));
    t.push_back(choice<ErrorEstimate>(
        "error_estimate", "Error Estimate", "Sampling", &RenderSettings::error_estimate,
        {{ErrorEstimate::Auto, {"auto", "Auto", "Estimate the error where target error, adaptive sampling or "
                                                "denoising decide by it; elsewhere take Sobol samples from one "
                                                "scramble: less noise (0.73-0.98x the variance), no estimate"}},
         {ErrorEstimate::Exact, {"exact", "Exact", "Even and odd samples from independent scrambles, so the "
                                                   "estimate is unbiased; for the Error pass and convergence "
                                                   "records"}}},
        "whether the render pays for an error estimate in noise (Sobol pattern)"));
    t.push_back(flag("denoise", "Denoise", "Sampling", &RenderSettings::denoise,
                     "denoise the final image with the native feature-guided, cross-validated filter (the noisy "
                     "image stays in the 'Noisy Image' pass)"));
    t.push_back(real("denoise_strength", "Denoising Strength", "Sampling", &RenderSettings::denoise_strength, 0.0,
                     16.0, 4.0,
                     "how different (in units of the estimated noise) neighbouring pixels may be and still be "
                     "averaged; higher is smoother, 0 keeps only pixels identical within noise"));
    t.push_back(flag("distribute_samples", "Distribute Samples", "Sampling", &RenderSettings::distribute_samples,
                     "when denoising a render of a fixed sample count: every pixel takes a quarter of the samples "
                     "(half in scenes with mirror or glass, whose caustics would mislead an early decision), and the "
                     "rest go where the denoiser is predicted to leave the most error (edges, fine texture, small "
                     "lights), the same samples per pixel on average (SPT sampler)"));
    t.push_back(flag("denoising_data", "Denoising Data", "Sampling", &RenderSettings::denoising_data,
                     "fill the 'Denoising Albedo', 'Denoising Normal' and 'Denoising Depth' passes (also filled "
                     "when denoising)"));
    t.push_back(flag("progressive_display", "Progressive Display", "Sampling", &RenderSettings::progressive_display,
                     "a front end shows sample passes as they finish (the viewport); makes the Auto sampler pick "
                     "ICPT"));
    return t;
}

std::vector<SettingSpec> light_path_rows() {
    std::vector<SettingSpec> t;
    t.push_back(integer("max_bounces", "Total", "Light Paths", &RenderSettings::max_bounces, 0, 1024, 0,
                        "maximum number of bounces of any kind"));
    t.push_back(integer("diffuse_bounces", "Diffuse", "Light Paths", &RenderSettings::diffuse_bounces, 0, 1024, 0,
                        "maximum number of diffuse reflection bounces"));
    t.push_back(integer("glossy_bounces", "Glossy", "Light Paths", &RenderSettings::glossy_bounces, 0, 1024, 0,
                        "maximum number of glossy reflection bounces"));
    t.push_back(integer("transmission_bounces", "Transmission", "Light Paths", &RenderSettings::transmission_bounces,
                        0, 1024, 0, "maximum number of transmission (refraction) bounces"));
    t.push_back(integer("transparent_max_bounces", "Transparent", "Light Paths",
                        &RenderSettings::transparent_max_bounces, 0, 1024, 0,
                        "maximum number of transparent surfaces a path or shadow ray passes through"));
    t.push_back(integer("rr_min_bounces", "Russian Roulette After", "Light Paths", &RenderSettings::rr_min_bounces,
                        0, 1024, 0, "bounces before Russian roulette may end a path"));
    t.push_back(real("clamp_direct", "Clamp Direct", "Light Paths", &RenderSettings::clamp_direct, 0.0, 1e6, 100.0,
                     "largest component of light reaching the camera directly or after its first hit (biased); "
                     "0 = off"));
    t.push_back(real("clamp_indirect", "Clamp Indirect", "Light Paths", &RenderSettings::clamp_indirect, 0.0, 1e6,
                     100.0, "largest component of light after further bounces (biased); 0 = off"));
    t.push_back(flag("uniform_light_selection", "Uniform Light Selection", "Light Paths",
                     &RenderSettings::uniform_light_selection,
                     "pick each light, the emissive meshes and the world (a map; a constant world only when "
                     "nothing else emits) with equal probability for shadow rays, instead of by their estimated "
                     "power (comparisons; more noise)"));
    return t;
}

std::vector<SettingSpec> tracing_rows() {
    std::vector<SettingSpec> t;
    t.push_back(choice<Integrator>(
        "integrator", "Integrator", "Tracing", &RenderSettings::integrator,
        {{Integrator::PathTrace, {"pt", "Path Tracing", "Full global illumination: path tracing with next-event "
                                                        "estimation and multiple importance sampling"}},
         {Integrator::Distribution, {"drt", "Distribution", "Distribution ray tracing: soft shadows from area "
                                                            "lights, glossy reflection and refraction, depth of "
                                                            "field; no diffuse interreflection"}},
         {Integrator::Whitted, {"wrt", "Whitted", "Whitted ray tracing: direct light, paths continue through "
                                                  "mirrors and glass only"}},
         {Integrator::RayCast, {"rcs", "Ray Casting", "Ray casting with shadows: direct light at the first hit "
                                                      "only"}},
         {Integrator::AmbientOcclusion, {"ao", "Ambient Occlusion", "Fraction of cosine-distributed rays from the "
                                                                    "first hit that escape within the AO distance "
                                                                    "(white = unoccluded)"}}},
        "which light transport is computed"));
    t.push_back(choice<Traversal>(
        "traversal", "Traversal", "Tracing", &RenderSettings::traversal,
        {{Traversal::Auto, {"auto", "Auto", "Packets with the CPT sampler (where they pay, measured), single rays "
                                            "otherwise"}},
         {Traversal::Single, {"single", "Single Rays", "One ray at a time over a BVH of the chosen width"}},
         {Traversal::Single, {"wide", "Wide", "The same as single: single rays over the wide BVH", true}},
         {Traversal::Packet, {"packet", "Packets", "SIMD packets of the rays of Packet Size pixels, secondary rays "
                                                   "assembled by Assembly"}},
         {Traversal::Stream, {"stream", "Streams", "Breadth-first ray streams with per-node ray queues over the "
                                                   "wide BVH"}},
         {Traversal::Wavefront, {"wavefront", "Wavefront", "Staged pipeline (generate, extend, reorder, shade, "
                                                           "shadow) over waves of paths, reordered by Reorder"}}},
        "how rays are traced through the BVH; every mode finds the same hits"));
    t.push_back(choice<PacketAssembly>(
        "assembly", "Assembly", "Tracing", &RenderSettings::assembly,
        {{PacketAssembly::RayType, {"types", "Ray Types", "One packet per ray type (shadow, diffuse, glossy, "
                                                          "reflection, refraction)"}},
         {PacketAssembly::RayType, {"type", "Ray Types", "The same as types", true}},
         {PacketAssembly::Runs, {"runs", "Runs", "Consecutive rays of the same type in pixel order form a "
                                                 "packet"}}},
        "packet traversal: how secondary rays are grouped into packets"));
    t.push_back(real("packet_min_coherence", "Packet Coherence", "Tracing", &RenderSettings::packet_min_coherence,
                     0.0, 2.0, 1.0,
                     "packet traversal: a packet whose rays' mean unit direction is shorter than this is traced "
                     "as single rays (same hits); 0 = always packets, above 1 = never"));
    SettingSpec width = integer("bvh_width", "BVH Width", "Tracing", &RenderSettings::bvh_width, 2, 8, 0,
                                "branching factor of the BVH for single-ray and stream traversal");
    width.allowed = {2, 4, 8};
    t.push_back(std::move(width));
    t.push_back(choice<ReorderMode>(
        "reorder", "Reorder", "Tracing", &RenderSettings::reorder,
        {{ReorderMode::None, {"none", "None", "Trace rays in the order paths produced them"}},
         {ReorderMode::Static1D, {"static1d", "Static 1D", "Pixels along a Morton curve"}},
         {ReorderMode::Static3D, {"static3d", "Static 3D", "The paper's static 3D work groups of 8 x 16 x 1 "
                                                           "(width, height, ray of the pixel)"}},
         {ReorderMode::Hash32, {"hash32", "Hash 32", "32-bit keys of origin and direction bits, radix sorted"}},
         {ReorderMode::Hash192, {"hash192", "Hash 192", "192-bit keys of origin and direction bits, radix "
                                                        "sorted"}},
         {ReorderMode::Csd32, {"csd32", "CSD 32", "Compress-sort-decompress of 32-bit keys"}}},
        "wavefront traversal: how rays are sorted for coherence before tracing"));
    t.push_back(integer("wave_size", "Wave Size", "Tracing", &RenderSettings::wave_size, 1, 1 << 24, 1 << 20,
                        "wavefront traversal: paths in flight per wave (bounds memory, ~100 bytes a path)"));
    t.push_back(flag("shader_batch", "Batch Shading", "Tracing", &RenderSettings::shader_batch,
                     "packet, stream and wavefront traversal: run the shader programs of the hits traced "
                     "together as SIMD batches per material (same image); off = one hit at a time"));
    t.push_back(integer("ao_samples", "AO Samples", "Tracing", &RenderSettings::ao_samples, 1, 1024, 256,
                        "ambient occlusion: occlusion rays per camera sample"));
    t.push_back(real("ao_distance", "AO Distance", "Tracing", &RenderSettings::ao_distance, 0.0, 1e30, 100.0,
                     "ambient occlusion: length of occlusion rays in scene units; 0 = a tenth of the scene's "
                     "bounding-box diagonal"));
    t.push_back(flag("heatmaps", "Heatmaps", "Tracing", &RenderSettings::heatmaps,
                     "fill the diagnostic passes 'BVH Visits' (node visits per camera sample) and 'SIMD "
                     "Utilisation' (active fraction of the SIMD lanes that traced the pixel)"));
    return t;
}

std::vector<SettingSpec> frame_rows() {
    std::vector<SettingSpec> t;
    t.push_back(integer("width", "Width", "Output", &RenderSettings::width, 1, 1 << 16, 0,
                        "frame width in pixels"));
    t.push_back(integer("height", "Height", "Output", &RenderSettings::height, 1, 1 << 16, 0,
                        "frame height in pixels"));
    t.push_back(flag("transparent", "Transparent", "Film", &RenderSettings::transparent_film,
                     "the world seen directly gives alpha 0"));
    t.push_back(integer("threads", "Threads", "Performance", &RenderSettings::threads, 0, 4096, 0,
                        "render threads; 0 = all cores"));
    t.push_back(real("report_interval", "Report Interval", "Performance", &RenderSettings::report_interval, 0.0,
                     60.0, 2.0,
                     "seconds of rendering between progress reports (and error estimates); passes in between run "
                     "without waiting for each other. 0 = report after every sample pass"));
    t.push_back(integer("tile_size", "Tile Size", "Performance", &RenderSettings::tile_size, 1, 4096, 1024,
                        "edge length in pixels of the image tiles threads work on"));
    SettingSpec all = flag("force_all_features", "All Features", "Performance", &RenderSettings::force_all_features,
                           "run the general kernel with every effect on instead of the one specialised for this "
                           "scene's features (same image; for measuring what specialisation buys)");
    all.cli_name = "--all-features";
    t.push_back(std::move(all));
    return t;
}

std::vector<SettingSpec> build_table() {
    std::vector<SettingSpec> table;
    for (auto rows : {frame_rows(), sampling_rows(), light_path_rows(), tracing_rows()})
        for (SettingSpec& s : rows) table.push_back(std::move(s));
    return table;
}

// The shortest spelling that reads back to the same double ("10", "0.01").
std::string format_number(double v) {
    char buffer[32];
    const auto [end, ec] = std::to_chars(buffer, buffer + sizeof buffer, v);
    return ec == std::errc() ? std::string(buffer, end) : std::to_string(v);
}

template <class T>
bool parse_whole(std::string_view text, T& out) {
    const char* begin = text.data();
    const char* end = begin + text.size();
    const auto [ptr, ec] = std::from_chars(begin, end, out);
    return ec == std::errc() && ptr == end && begin != end;
}

}  // namespace

const std::vector<SettingSpec>& setting_table() {
    static const std::vector<SettingSpec> table = build_table();
    return table;
}

const SettingSpec* find_setting(std::string_view name) {
    for (const SettingSpec& s : setting_table())
        if (s.name == name) return &s;
    return nullptr;
}

std::string describe_accepted(const SettingSpec& spec) {
    switch (spec.type) {
        case SettingType::Bool: return "true or false";
        case SettingType::Seed: return "an integer in [0, 18446744073709551615]";
        case SettingType::Int: {
            if (spec.allowed.empty())
                return "an integer in [" + format_number(spec.min) + ", " + format_number(spec.max) + "]";
            std::string s = "one of ";
            for (size_t i = 0; i < spec.allowed.size(); ++i)
                s += (i ? (i + 1 == spec.allowed.size() ? " or " : ", ") : "") + std::to_string(spec.allowed[i]);
            return s;
        }
        case SettingType::Real:
            return "a number in [" + format_number(spec.min) + ", " + format_number(spec.max) + "]";
        case SettingType::Size:
            return "WxH with each side an integer in [" + format_number(spec.min) + ", " + format_number(spec.max) +
                   "]";
        case SettingType::Choice: {
            std::vector<std::string> names;
            for (const SettingChoice& c : spec.choices)
                if (!c.hidden) names.push_back(c.name);
            std::string s = "one of ";
            for (size_t i = 0; i < names.size(); ++i) s += (i ? (i + 1 == names.size() ? " or " : ", ") : "") + names[i];
            return s;
        }
    }
    return "";
}

std::string check_setting_value(const SettingSpec& spec, const SettingValue& value) {
    const std::string expected = "expected " + describe_accepted(spec);
    switch (spec.type) {
        case SettingType::Bool:
            return std::holds_alternative<bool>(value) ? "" : expected;
        case SettingType::Seed:
            return std::holds_alternative<uint64_t>(value) ? "" : expected;
        case SettingType::Int: {
            if (!std::holds_alternative<int64_t>(value)) return expected;
            const int64_t v = std::get<int64_t>(value);
            const bool ok = spec.allowed.empty()
                                ? double(v) >= spec.min && double(v) <= spec.max
                                : std::find(spec.allowed.begin(), spec.allowed.end(), v) != spec.allowed.end();
            return ok ? "" : expected + ", got " + std::to_string(v);
        }
        case SettingType::Real: {
            if (!std::holds_alternative<double>(value)) return expected;
            const double v = std::get<double>(value);
            return std::isfinite(v) && v >= spec.min && v <= spec.max ? "" : expected + ", got " + format_number(v);
        }
        case SettingType::Size: {
            if (!std::holds_alternative<SettingSize>(value)) return expected;
            const SettingSize v = std::get<SettingSize>(value);
            for (int64_t side : v)
                if (double(side) < spec.min || double(side) > spec.max)
                    return expected + ", got " + std::to_string(v[0]) + "x" + std::to_string(v[1]);
            return "";
        }
        case SettingType::Choice: {
            if (!std::holds_alternative<std::string>(value)) return expected;
            const std::string& v = std::get<std::string>(value);
            for (const SettingChoice& c : spec.choices)
                if (c.name == v) return "";
            return expected + ", got '" + v + "'";
        }
    }
    return expected;
}

void assign_setting(RenderSettings& settings, const SettingSpec& spec, const SettingValue& value) {
    if (std::string why = check_setting_value(spec, value); !why.empty()) throw SettingError(spec.name, why);
    spec.set(settings, value);
}

SettingValue parse_setting_text(const SettingSpec& spec, std::string_view text) {
    const auto fail = [&]() -> SettingValue {
        throw SettingError(spec.name, "expected " + describe_accepted(spec) + ", got '" + std::string(text) + "'");
    };
    switch (spec.type) {
        case SettingType::Bool:
            if (text == "true" || text == "1") return true;
            if (text == "false" || text == "0") return false;
            return fail();
        case SettingType::Seed: {
            uint64_t v = 0;
            return parse_whole(text, v) ? SettingValue(v) : fail();
        }
        case SettingType::Int: {
            int64_t v = 0;
            return parse_whole(text, v) ? SettingValue(v) : fail();
        }
        case SettingType::Real: {
            double v = 0.0;
            return parse_whole(text, v) ? SettingValue(v) : fail();
        }
        case SettingType::Size: {
            const size_t x = text.find('x');
            SettingSize v{};
            if (x == std::string_view::npos || !parse_whole(text.substr(0, x), v[0]) ||
                !parse_whole(text.substr(x + 1), v[1]))
                return fail();
            return v;
        }
        case SettingType::Choice:
            return std::string(text);
    }
    return fail();
}

std::string format_setting_value(const SettingSpec& spec, const SettingValue& value) {
    return std::visit(
        [](const auto& v) -> std::string {
            using T = std::decay_t<decltype(v)>;
            if constexpr (std::is_same_v<T, bool>) return v ? "true" : "false";
            else if constexpr (std::is_same_v<T, double>) return format_number(v);
            else if constexpr (std::is_same_v<T, std::string>) return v;
            else if constexpr (std::is_same_v<T, SettingSize>) return std::to_string(v[0]) + "x" + std::to_string(v[1]);
            else return std::to_string(v);
        },
        value);
}

void validate(const RenderSettings& settings) {
    for (const SettingSpec& spec : setting_table())
        if (std::string why = check_setting_value(spec, spec.get(settings)); !why.empty())
            throw SettingError(spec.name, why);
    const int64_t pixels = int64_t(settings.width) * settings.height;
    if (pixels > kMaxRenderPixels)
        throw SettingError("", "width x height: " + std::to_string(settings.width) + " x " +
                                   std::to_string(settings.height) + " is " + std::to_string(pixels) +
                                   " pixels, more than the " + std::to_string(kMaxRenderPixels) +
                                   " a film can hold");
    const bool whole_frame = settings.border_x0 == 0 && settings.border_y0 == 0 && settings.border_x1 < 0 &&
                             settings.border_y1 < 0;
    if (!whole_frame) {
        const int x1 = settings.border_x1 < 0 ? settings.width : settings.border_x1;
        const int y1 = settings.border_y1 < 0 ? settings.height : settings.border_y1;
        if (settings.border_x0 < 0 || settings.border_y0 < 0 || x1 > settings.width || y1 > settings.height ||
            settings.border_x0 > x1 || settings.border_y0 > y1)
            throw SettingError("border", "expected 0 <= x0 <= x1 <= width and 0 <= y0 <= y1 <= height (y = 0 at "
                                         "the top; an empty border renders nothing), got (" + std::to_string(settings.border_x0) + ", " +
                                             std::to_string(settings.border_y0) + ", " + std::to_string(x1) + ", " +
                                             std::to_string(y1) + ")");
    }
}

}  // namespace coherent
