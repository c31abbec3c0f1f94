#include "options.h"

#include "film/passes.h"

#include <algorithm>
#include <cstring>
#include <sstream>
#include <stdexcept>

#include "render/setting_table.h"

namespace coherent::cli {
namespace {

// Options that only make sense together with another: giving a threshold
// asks for adaptive sampling.
bool implies_adaptive(const SettingSpec& spec) {
    return spec.name == "adaptive_threshold" || spec.name == "adaptive_min_samples";
}

std::string metavar_for(const SettingSpec& spec) {
    switch (spec.type) {
        case SettingType::Bool: return "";
        case SettingType::Int:
        case SettingType::Seed: return "N";
        case SettingType::Real: return "X";
        case SettingType::Choice: return "NAME";
        case SettingType::Size: return "WxH";
    }
    return "X";
}

// "spt (Standard path tracing: ...), cpt (...)" for choices; the range for
// numbers; and the default, so --help alone documents every setting.
std::string help_for(const SettingSpec& spec) {
    std::string help = spec.help;
    if (spec.type == SettingType::Choice) {
        help += ": ";
        bool first = true;
        for (const SettingChoice& c : spec.choices) {
            if (c.hidden) continue;
            help += (first ? "" : "; ") + c.name + " (" + c.help + ")";
            first = false;
        }
    } else if (spec.type != SettingType::Bool) {
        help += "; " + describe_accepted(spec);
    }
    if (spec.name == "heatmaps")
        help += "; the CLI writes OUT.bvh_visits.exr/.png and OUT.simd.exr/.png (float EXR plus a false-colour "
                "viridis PNG, dark = low) and prints their value ranges";
    if (spec.type != SettingType::Bool) help += " (default " + format_setting_value(spec, spec.default_value()) + ")";
    // A flag turns a setting on; one that is on already needs saying how to turn it off.
    if (spec.type == SettingType::Bool && std::get<bool>(spec.default_value()))
        help += " (on by default; " + spec.cli_name + "=false turns it off)";
    return help;
}

OptionSpec option_for(const SettingSpec& spec) {
    OptionSpec o;
    o.name = spec.cli_name;
    o.metavar = metavar_for(spec);
    o.help = help_for(spec);
    o.group = spec.group;
    o.apply = [&spec](RenderOptions& options, const std::string& value) {
        const SettingValue v = spec.type == SettingType::Bool && value.empty() ? SettingValue(true)
                                                                               : parse_setting_text(spec, value);
        assign_setting(options.settings, spec, v);
        if (implies_adaptive(spec)) options.settings.adaptive = true;
    };
    return o;
}

// The CLI's own flags take no value.
bool flag_value(const std::string& value) {
    if (!value.empty()) throw std::invalid_argument("takes no value");
    return true;
}

// --res W H: the table's width and height rows, in one option.
void apply_res(RenderOptions& options, const std::string& value) {
    const size_t space = value.find(' ');
    for (const char* name : {"width", "height"}) {
        const SettingSpec& spec = *find_setting(name);
        const std::string text = name[0] == 'w' ? value.substr(0, space) : value.substr(space + 1);
        try {
            assign_setting(options.settings, spec, parse_setting_text(spec, text));
        } catch (const SettingError& e) {
            throw std::invalid_argument(std::string(name) + ": " + e.what());
        }
    }
}

// --passes diffdir,mist: the film/passes.h mask.
void apply_passes(RenderOptions& o, const std::string& value) {
    std::vector<std::string> names;
    size_t start = 0;
    while (start <= value.size()) {
        const size_t comma = std::min(value.find(',', start), value.size());
        if (comma > start) names.push_back(value.substr(start, comma - start));
        start = comma + 1;
    }
    if (names.empty()) throw std::invalid_argument("expected pass names separated by commas");
    o.settings.passes = pass_mask_from_names(names);
}

std::vector<OptionSpec> cli_options() {
    const RenderSettings d;
    return {
        {"--output", "-o", "FILE", "output image; .exr (Combined, Depth, Normal) or .png (Combined, sRGB)", "Output",
         [](RenderOptions& o, const std::string& v) { o.output = v; }},
        {"--res", "", "W H",
         "resolution in pixels, the same as --width W --height H (default " + std::to_string(d.width) + " " +
             std::to_string(d.height) + ")",
         "Output", apply_res},
        {"--convergence", "", "CSV",
         "write seconds,spp,error_estimate per progress report (every batch of sample passes, see --report-interval; from the 2nd, when an estimate exists); "
         "implies --error-estimate exact; plot it with coherent plot CSV",
         "Output", [](RenderOptions& o, const std::string& v) { o.convergence = v; }},
        {"--passes", "", "NAMES",
         "Cycles' render passes to accumulate and write into the EXR as layers of Cycles' names, comma-separated: "
         "diffdir, diffind, diffcol, glossdir, glossind, glosscol, transdir, transind, transcol, emit, env, ao, mist, "
         "position, uv, indexob, indexma, vector (zero in the CLI: a scene file has no frames) "
         "(a pass not named costs nothing)",
         "Output", apply_passes},
        {"--json", "", "", "print render statistics as one JSON object on stdout", "Output",
         [](RenderOptions& o, const std::string& v) { o.json = flag_value(v); }},
        {"--help", "-h", "", "show this help", "Output",
         [](RenderOptions& o, const std::string& v) { o.help = flag_value(v); }},
    };
}

const OptionSpec* find_option(const std::string& name) {
    for (const OptionSpec& spec : render_option_table())
        if (name == spec.name || (!spec.alias.empty() && name == spec.alias)) return &spec;
    return nullptr;
}

// How many values an option takes.
int arity(const OptionSpec& spec) {
    if (spec.metavar.empty()) return 0;
    return spec.metavar.find(' ') != std::string::npos ? 2 : 1;
}

// The option's value(s) from "--name=value" or the following arguments.
bool take_value(const OptionSpec& spec, const std::vector<std::string>& args, size_t& i, bool has_inline,
                const std::string& inline_value, std::string& value, std::string& error) {
    const int n = arity(spec);
    if (has_inline) {
        // --flag=true/false is accepted for flags too.
        if (n == 2) {
            error = spec.name + " takes 2 values";
            return false;
        }
        value = inline_value;
        return true;
    }
    for (int k = 0; k < n; ++k) {
        if (i + 1 >= args.size()) {
            error = spec.name + " expects " + spec.metavar;
            return false;
        }
        value += (k ? " " : "") + args[++i];
    }
    return true;
}

bool parse_option(const std::vector<std::string>& args, size_t& i, RenderOptions& options, std::string& error) {
    const std::string& arg = args[i];
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
    std::string value;
    if (!take_value(*spec, args, i, has_inline, inline_value, value, error)) return false;
    try {
        spec->apply(options, value);
    } catch (const std::invalid_argument& e) {
        error = spec->name + ": " + e.what();
        return false;
    }
    return true;
}

// "  --name X    help..." with the help wrapped at 100 columns and indented
// under its first line.
std::string wrap(std::string left, const std::string& help) {
    constexpr size_t kIndent = 28, kWidth = 100;
    if (left.size() < kIndent) left.resize(kIndent, ' ');
    else left += "\n" + std::string(kIndent, ' ');
    std::string out = left, word;
    size_t column = kIndent;
    std::istringstream words(help);
    while (words >> word) {
        if (column > kIndent && column + 1 + word.size() > kWidth) {
            out += "\n" + std::string(kIndent, ' ');
            column = kIndent;
        } else if (column > kIndent) {
            out += ' ';
            ++column;
        }
        out += word;
        column += word.size();
    }
    return out;
}

}  // namespace

const std::vector<OptionSpec>& render_option_table() {
    static const std::vector<OptionSpec> table = [] {
        std::vector<OptionSpec> t = cli_options();
        for (const SettingSpec& spec : setting_table()) t.push_back(option_for(spec));
        return t;
    }();
    return table;
}

bool parse_render_args(const std::vector<std::string>& args, RenderOptions& options, std::string& error) {
    for (size_t i = 0; i < args.size(); ++i) {
        const std::string& arg = args[i];
        if (arg.size() > 1 && arg[0] == '-') {
            if (!parse_option(args, i, options, error)) return false;
            if (options.help) return true;
        } else if (!options.scene.empty()) {
            error = "more than one scene given ('" + options.scene + "' and '" + arg + "')";
            return false;
        } else {
            options.scene = arg;
        }
    }
    // A convergence record is read as the error over time: it gets the
    // unbiased estimate (RenderSettings::error_estimate).
    if (!options.convergence.empty()) options.settings.error_estimate = ErrorEstimate::Exact;
    try {
        validate(options.settings);
    } catch (const SettingError& e) {
        const SettingSpec* spec = find_setting(e.setting());
        error = (spec ? spec->cli_name + ": " : std::string()) + e.what();
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
      << "130 interrupted (Ctrl-C cancels the render and writes no image).\n";
    for (const char* group : {"Output", "Sampling", "Light Paths", "Tracing", "Film", "Performance"}) {
        s << '\n' << group << " options:\n";
        for (const OptionSpec& spec : render_option_table()) {
            if (spec.group != group) continue;
            std::string left = "  " + spec.name;
            if (!spec.alias.empty()) left += ", " + spec.alias;
            if (!spec.metavar.empty()) left += " " + spec.metavar;
            s << wrap(left, spec.help) << '\n';
        }
    }
    return s.str();
}

}  // namespace coherent::cli
