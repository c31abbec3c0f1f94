#include "options.h"

#include <charconv>
#include <cmath>
#include <cstring>
#include <optional>
#include <sstream>

namespace coherent::cli {
namespace {

// Strict integer parsing: the whole text must be a number within [lo, hi].
template <typename Int>
bool parse_integer(const char* text, Int lo, Int hi, const char* option, Int& out, std::string& error) {
    const char* end = text + std::strlen(text);
    Int value{};
    const auto [ptr, ec] = std::from_chars(text, end, value);
    if (ec == std::errc::result_out_of_range || (ec == std::errc() && ptr == end && (value < lo || value > hi))) {
        error = std::string(option) + " must be between " + std::to_string(lo) + " and " + std::to_string(hi) +
                ", got '" + text + "'";
        return false;
    }
    if (ec != std::errc() || ptr != end || text == end) {
        error = std::string(option) + " expects an integer, got '" + text + "'";
        return false;
    }
    out = value;
    return true;
}

// Strict non-negative real parsing: the whole text must be a finite number
// within [0, hi].
bool parse_nonnegative_real(const char* text, double hi, const char* option, double& out, std::string& error) {
    const char* end = text + std::strlen(text);
    double value = 0.0;
    const auto [ptr, ec] = std::from_chars(text, end, value);
    if (ec != std::errc() || ptr != end || text == end || !std::isfinite(value)) {
        error = std::string(option) + " expects a number, got '" + text + "'";
        return false;
    }
    if (value < 0.0 || value > hi) {
        error = std::string(option) + " must be between 0 and " + std::to_string(hi) + ", got '" + text + "'";
        return false;
    }
    out = value;
    return true;
}

// Upper limits keep a typo from asking for terabytes of film or years of work.
constexpr int kMaxResolution = 1 << 14;
constexpr int64_t kMaxPixels = int64_t(1) << 26;  // 8192 x 8192: ~3 GB of film
constexpr int kMaxSpp = 1 << 20;
constexpr int kMaxThreads = 4096;
constexpr int kMaxBounces = 1024;
constexpr int kMaxPacket = 16;
constexpr int kMaxWaveSize = 1 << 24;  // paths in flight; ~100 bytes of state each
constexpr int kMaxAoSamples = 1 << 12;

bool parse_output(RenderOptions& o, const char* v, std::string&) {
    o.output = v;
    return true;
}
bool parse_spp(RenderOptions& o, const char* v, std::string& e) {
    return parse_integer(v, 1, kMaxSpp, "--spp", o.settings.spp, e);
}
bool parse_target_error(RenderOptions& o, const char* v, std::string& e) {
    return parse_nonnegative_real(v, 1e6, "--target-error", o.settings.target_error, e);
}
bool parse_time_limit(RenderOptions& o, const char* v, std::string& e) {
    return parse_nonnegative_real(v, 1e9, "--time-limit", o.settings.time_limit, e);
}
bool parse_adaptive(RenderOptions& o, const char*, std::string&) {
    o.settings.adaptive = true;
    return true;
}
bool parse_adaptive_threshold(RenderOptions& o, const char* v, std::string& e) {
    o.settings.adaptive = true;  // giving a threshold asks for adaptive sampling
    if (!parse_nonnegative_real(v, 1.0, "--adaptive-threshold", o.settings.adaptive_threshold, e)) return false;
    if (o.settings.adaptive_threshold > 0.0) return true;
    e = "--adaptive-threshold: expected a number in (0, 1], got " + std::string(v);
    return false;
}
bool parse_seed(RenderOptions& o, const char* v, std::string& e) {
    return parse_integer<uint64_t>(v, 0, UINT64_MAX, "--seed", o.settings.seed, e);
}
bool parse_threads(RenderOptions& o, const char* v, std::string& e) {
    return parse_integer(v, 0, kMaxThreads, "--threads", o.settings.threads, e);
}
bool parse_max_bounces(RenderOptions& o, const char* v, std::string& e) {
    return parse_integer(v, 0, kMaxBounces, "--max-bounces", o.settings.max_bounces, e);
}
bool parse_sampler(RenderOptions& o, const char* v, std::string& e) {
    const std::optional<SamplerType> t = parse_sampler_type(v);
    if (!t) {
        e = std::string("--sampler expects spt, cpt, icpt or auto, got '") + v + "'";
        return false;
    }
    o.settings.sampler = *t;
    return true;
}
bool parse_sequences(RenderOptions& o, const char* v, std::string& e) {
    const std::optional<SequenceScope> s = parse_sequence_scope(v);
    if (!s) {
        e = std::string("--sequences expects packet or image, got '") + v + "'";
        return false;
    }
    o.settings.sequence_scope = *s;
    return true;
}
// --packet WxH, e.g. 4x4. ICPT's Latin squares go up to 16 a side.
bool parse_packet(RenderOptions& o, const char* v, std::string& e) {
    const char* x = std::strchr(v, 'x');
    if (!x) {
        e = std::string("--packet expects WxH (e.g. 4x4), got '") + v + "'";
        return false;
    }
    const std::string w(v, size_t(x - v)), h(x + 1);
    return parse_integer(w.c_str(), 1, kMaxPacket, "--packet width", o.settings.packet_width, e) &&
           parse_integer(h.c_str(), 1, kMaxPacket, "--packet height", o.settings.packet_height, e);
}
// Enumerated choices: the value must be one of the names render_modes.h
// prints; the error lists them so a typo is fixed without the help text.
template <typename Enum>
bool parse_choice(const char* v, std::optional<Enum> (*parse)(std::string_view), const char* option,
                  const char* choices, Enum& out, std::string& e) {
    const std::optional<Enum> parsed = parse(v);
    if (!parsed) {
        e = std::string(option) + " expects " + choices + ", got '" + v + "'";
        return false;
    }
    out = *parsed;
    return true;
}
bool parse_integrator_option(RenderOptions& o, const char* v, std::string& e) {
    return parse_choice(v, &parse_integrator, "--integrator", "pt, drt, wrt, rcs or ao", o.settings.integrator, e);
}
bool parse_traversal_option(RenderOptions& o, const char* v, std::string& e) {
    return parse_choice(v, &parse_traversal, "--traversal", "auto, single, wide, packet, stream or wavefront",
                        o.settings.traversal, e);
}
bool parse_assembly_option(RenderOptions& o, const char* v, std::string& e) {
    return parse_choice(v, &parse_assembly, "--assembly", "types or runs", o.settings.assembly, e);
}
bool parse_reorder_option(RenderOptions& o, const char* v, std::string& e) {
    return parse_choice(v, &parse_reorder, "--reorder", "none, static1d, static3d, hash32, hash192 or csd32",
                        o.settings.reorder, e);
}
bool parse_bvh_width(RenderOptions& o, const char* v, std::string& e) {
    int width = 0;
    if (!parse_integer(v, 1, 64, "--bvh-width", width, e) || (width != 2 && width != 4 && width != 8)) {
        e = std::string("--bvh-width expects 2, 4 or 8, got '") + v + "'";
        return false;
    }
    o.settings.bvh_width = width;
    return true;
}
bool parse_wave_size(RenderOptions& o, const char* v, std::string& e) {
    return parse_integer(v, 1, kMaxWaveSize, "--wave-size", o.settings.wave_size, e);
}
bool parse_ao_samples(RenderOptions& o, const char* v, std::string& e) {
    return parse_integer(v, 1, kMaxAoSamples, "--ao-samples", o.settings.ao_samples, e);
}
bool parse_ao_distance(RenderOptions& o, const char* v, std::string& e) {
    double d = 0.0;
    if (!parse_nonnegative_real(v, 1e30, "--ao-distance", d, e)) return false;
    o.settings.ao_distance = float(d);
    return true;
}
bool parse_heatmaps(RenderOptions& o, const char*, std::string&) {
    o.settings.heatmaps = true;
    return true;
}
bool parse_adaptive_min_samples(RenderOptions& o, const char* v, std::string& e) {
    o.settings.adaptive = true;  // as --adaptive-threshold: giving it asks for adaptive sampling
    return parse_integer(v, 2, kMaxSpp, "--adaptive-min-samples", o.settings.adaptive_min_samples, e);
}
bool parse_convergence(RenderOptions& o, const char* v, std::string&) {
    o.convergence = v;
    return true;
}
bool parse_json(RenderOptions& o, const char*, std::string&) {
    o.json = true;
    return true;
}
bool parse_all_features(RenderOptions& o, const char*, std::string&) {
    o.settings.force_all_features = true;
    return true;
}
bool parse_help(RenderOptions& o, const char*, std::string&) {
    o.help = true;
    return true;
}

// --res takes two values; the table gives one, so the parser receives
// "W H" joined by a space (see parse_render_args).
bool parse_res(RenderOptions& o, const char* v, std::string& e) {
    const char* space = std::strchr(v, ' ');
    const std::string w(v, space ? size_t(space - v) : std::strlen(v));
    const std::string h(space ? space + 1 : "");
    return parse_integer(w.c_str(), 1, kMaxResolution, "--res width", o.settings.width, e) &&
           parse_integer(h.c_str(), 1, kMaxResolution, "--res height", o.settings.height, e);
}

const OptionSpec* find_option(const std::string& name) {
    for (const OptionSpec& spec : render_option_table())
        if (name == spec.name || (spec.alias && name == spec.alias)) return &spec;
    return nullptr;
}

// How many values an option takes.
int arity(const OptionSpec& spec) {
    if (!spec.metavar) return 0;
    return std::strchr(spec.metavar, ' ') ? 2 : 1;
}

}  // namespace

const std::vector<OptionSpec>& render_option_table() {
    // Defaults shown in the help come from RenderSettings itself so they cannot drift.
    static const RenderSettings d;
    static const std::vector<OptionSpec> table = {
        {"--output", "-o", "FILE", "output image; .exr (Combined, Depth, Normal) or .png (Combined, sRGB)", parse_output},
        {"--res", nullptr, "W H",
         "resolution in pixels, up to 16384 a side and 8192x8192 in all (default " + std::to_string(d.width) + " " +
             std::to_string(d.height) + ")",
         parse_res},
        {"--spp", nullptr, "N", "samples per pixel (default " + std::to_string(d.spp) + ")", parse_spp},
        {"--target-error", nullptr, "E",
         "stop once the estimated relative RMSE (from even/odd sample passes, no reference needed) is at most E, "
         "e.g. 0.02; 0 = off (default 0)",
         parse_target_error},
        {"--time-limit", nullptr, "S",
         "stop after the sample pass that ends past S seconds of rendering; 0 = off (default 0)", parse_time_limit},
        {"--adaptive", nullptr, nullptr,
         "adaptive sampling: after " + std::to_string(d.adaptive_min_samples) +
             " spp, pixels whose estimated relative error (and their 3x3 neighbours') is below the threshold stop "
             "taking samples",
         parse_adaptive},
        {"--adaptive-threshold", nullptr, "T",
         "relative per-pixel error at which adaptive sampling stops a pixel; implies --adaptive (default " +
             std::to_string(d.adaptive_threshold).substr(0, 4) + ")",
         parse_adaptive_threshold},
        {"--adaptive-min-samples", nullptr, "N",
         "passes every pixel takes before adaptive sampling may stop it (rounded up to even); implies --adaptive "
         "(default " + std::to_string(d.adaptive_min_samples) + ")",
         parse_adaptive_min_samples},
        {"--seed", nullptr, "S", "random seed (default " + std::to_string(d.seed) + ")", parse_seed},
        {"--threads", nullptr, "T", "worker threads, 0 = all cores (default " + std::to_string(d.threads) + ")",
         parse_threads},
        {"--max-bounces", nullptr, "B", "maximum path length in bounces (default " + std::to_string(d.max_bounces) + ")",
         parse_max_bounces},
        {"--sampler", nullptr, "S",
         "random sequences: spt (independent per pixel), cpt (one per sample, shared by the pixels of a packet), icpt "
         "(packet blocks split into randomised Latin-hypercube subsets that share sequences), auto (icpt below " +
             std::to_string(kAutoCptMinSpp) + " spp, else cpt) (default " +
             std::string(sampler_type_name(d.sampler)) + ")",
         parse_sampler},
        {"--packet", nullptr, "WxH",
         "packet size in pixels, up to 16x16; icpt blocks are square, of the shorter side (default " +
             std::to_string(d.packet_width) + "x" + std::to_string(d.packet_height) + ")",
         parse_packet},
        {"--sequences", nullptr, "SCOPE",
         "cpt/icpt: share sequences per packet (packet: the paper's Fig. 3) or over the whole image (image: its "
         "equation 3) (default " + std::string(sequence_scope_name(d.sequence_scope)) + ")",
         parse_sequences},
        {"--integrator", nullptr, "I",
         "light transport: pt (path tracing), drt (distribution ray tracing: direct light, glossy and specular "
         "paths), wrt (Whitted: direct light, mirror and glass paths), rcs (ray casting with shadows), ao "
         "(ambient occlusion, white = unoccluded) (default " + std::string(integrator_name(d.integrator)) + ")",
         parse_integrator_option},
        {"--traversal", nullptr, "T",
         "how rays are traced: auto (packet with the CPT sampler, else single: where packets pay), single (one ray "
         "at a time over the --bvh-width BVH; wide is the same), packet (SIMD "
         "packets of --packet pixels), stream (breadth-first ray streams), wavefront (staged pipeline over waves "
         "of --wave-size paths) (default " + std::string(traversal_name(d.traversal)) + ")",
         parse_traversal_option},
        {"--assembly", nullptr, "A",
         "packet traversal: secondary rays form packets by ray type (types) or by runs of equal type in pixel "
         "order (runs) (default " + std::string(assembly_name(d.assembly)) + ")",
         parse_assembly_option},
        {"--bvh-width", nullptr, "N",
         "BVH branching factor for single-ray and stream traversal: 2, 4 or 8 (default " +
             std::to_string(d.bvh_width) + ")",
         parse_bvh_width},
        {"--reorder", nullptr, "R",
         "wavefront ray reordering: none, static1d (pixel Morton order), static3d (origin Morton order), hash32, "
         "hash192 (hashed origin/direction keys, radix sorted), csd32 (compress-sort-decompress) (default " +
             std::string(reorder_name(d.reorder)) + ")",
         parse_reorder_option},
        {"--wave-size", nullptr, "N",
         "wavefront: paths in flight per wave, bounds memory (default " + std::to_string(d.wave_size) + ")",
         parse_wave_size},
        {"--ao-samples", nullptr, "N",
         "ao: occlusion rays per camera sample (default " + std::to_string(d.ao_samples) + ")", parse_ao_samples},
        {"--ao-distance", nullptr, "D",
         "ao: occlusion ray length in scene units; 0 = a tenth of the scene's bounding-box diagonal (default 0)",
         parse_ao_distance},
        {"--heatmaps", nullptr, nullptr,
         "also write OUT.bvh_visits.exr/.png (BVH node visits per camera sample) and OUT.simd.exr/.png (SIMD lane "
         "utilisation of the packets that traced each pixel, 0..1): float EXR plus a false-colour PNG (viridis, "
         "dark = low), with the value range printed",
         parse_heatmaps},
        {"--convergence", nullptr, "CSV",
         "write seconds,spp,error_estimate per completed sample pass (from the 2nd, when an estimate exists); "
         "plot it with coherent plot CSV",
         parse_convergence},
        {"--json", nullptr, nullptr, "print render statistics as one JSON object on stdout", parse_json},
        {"--all-features", nullptr, nullptr,
         "run the general kernel with every effect on instead of the one specialised for this scene's features "
         "(same image; for measuring what specialisation buys)",
         parse_all_features},
        {"--help", "-h", nullptr, "show this help", parse_help},
    };
    return table;
}

bool parse_render_args(const std::vector<std::string>& args, RenderOptions& options, std::string& error) {
    for (size_t i = 0; i < args.size(); ++i) {
        const std::string& arg = args[i];
        if (arg.size() > 1 && arg[0] == '-') {
            // --name=value is accepted for single-value options.
            std::string name = arg, inline_value;
            bool has_inline = false;
            if (const size_t eq = arg.find('='); arg.rfind("--", 0) == 0 && eq != std::string::npos) {
                name = arg.substr(0, eq);
                inline_value = arg.substr(eq + 1);
                has_inline = true;
            }
            const OptionSpec* spec = find_option(name);
            if (!spec) {
                error = "unknown option '" + name + "'";
                return false;
            }
            const int n = arity(*spec);
            std::string value;
            if (has_inline) {
                if (n != 1) {
                    error = std::string(spec->name) + (n == 0 ? " takes no value" : " takes " + std::to_string(n) + " values");
                    return false;
                }
                value = inline_value;
            } else {
                for (int k = 0; k < n; ++k) {
                    if (i + 1 >= args.size()) {
                        error = std::string(spec->name) + " expects " + spec->metavar;
                        return false;
                    }
                    value += (k ? " " : "") + args[++i];
                }
            }
            if (!spec->parse(options, n ? value.c_str() : nullptr, error)) return false;
            if (options.help) return true;
        } else {
            if (!options.scene.empty()) {
                error = "more than one scene given ('" + options.scene + "' and '" + arg + "')";
                return false;
            }
            options.scene = arg;
        }
    }
    if (int64_t(options.settings.width) * options.settings.height > kMaxPixels) {
        error = "--res " + std::to_string(options.settings.width) + " " + std::to_string(options.settings.height) +
                " has more than " + std::to_string(kMaxPixels) + " pixels";
        return false;
    }
    if (options.scene.empty()) {
        error = "no scene file given";
        return false;
    }
    if (options.output.empty()) {
        error = "no output image given (-o FILE.exr or -o FILE.png)";
        return false;
    }
    return true;
}

std::string main_usage() {
    return "usage: coherent <command> [options]\n"
           "\n"
           "commands:\n"
           "  render SCENE.glb -o OUT.exr|OUT.png [options]   render a glTF scene to an image\n"
           "  plot CONVERGENCE.csv [-o OUT.png]               plot a --convergence record (error vs time)\n"
           "\n"
           "options:\n"
           "  --help, -h     show this help (coherent render --help for render options)\n"
           "  --version      show version and build information\n";
}

std::string render_usage() {
    std::ostringstream s;
    s << "usage: coherent render SCENE.glb|SCENE.gltf -o OUT.exr|OUT.png [options]\n\n"
      << "Renders the scene's first camera (or a default view framing the scene).\n"
      << "Exit codes: 0 success, 1 bad input file or render/write failure, 2 bad usage,\n"
      << "130 interrupted (Ctrl-C cancels the render and writes no image).\n\n"
      << "options:\n";
    for (const OptionSpec& spec : render_option_table()) {
        std::string left = std::string("  ") + spec.name;
        if (spec.alias) left += std::string(", ") + spec.alias;
        if (spec.metavar) left += std::string(" ") + spec.metavar;
        if (left.size() < 24) left.resize(24, ' ');
        else left += "  ";
        s << left << spec.help << '\n';
    }
    return s.str();
}

}  // namespace coherent::cli
