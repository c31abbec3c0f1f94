// Command-line options of `coherent render`. The render settings' options,
// their ranges, choices, defaults and help come from the one settings table
// (render/setting_table.h); this file adds only what is the CLI's own
// (scene and output files, --res, --json, --convergence, --help).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "render/settings.h"

namespace coherent::cli {

// Process exit codes.
enum ExitCode : int {
    kExitOk = 0,
    kExitBadInput = 1,    // unreadable/malformed scene, render or write failure
    kExitBadUsage = 2,    // unknown option, missing or invalid value
    kExitInterrupted = 130,  // SIGINT: 128 + signal number, as shells report it
};

struct RenderOptions {
    std::string scene;   // positional
    std::string output;  // -o
    std::string convergence;  // --convergence CSV, empty = none
    RenderSettings settings;
    bool json = false;
    bool help = false;
};

// One command-line option. `apply` gets the option's value (empty for
// flags; two values joined by a space for a two-value metavar such as
// "W H") and throws std::invalid_argument with a message that does not
// repeat the option's name.
struct OptionSpec {
    std::string name;     // "--spp"
    std::string alias;    // "-o" or ""
    std::string metavar;  // "N"; "" for flags
    std::string help;     // with the default filled in from RenderSettings{}
    std::string group;    // heading in --help
    std::function<void(RenderOptions& options, const std::string& value)> apply;
};

// The CLI's own options followed by one option per settings-table row.
const std::vector<OptionSpec>& render_option_table();

// Parses the arguments after `render`. Returns false with a one-line
// `error` for bad usage. A request for help sets options.help and succeeds.
bool parse_render_args(const std::vector<std::string>& args, RenderOptions& options, std::string& error);

// Help texts.
std::string main_usage();
std::string render_usage();

}  // namespace coherent::cli
