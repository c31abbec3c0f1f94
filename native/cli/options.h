// Command-line options of `coherent render`, described by one table so that
// adding an option is adding one row (name, value placeholder, help, parser).
#pragma once

#include <cstdint>
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

// One row of the option table. `parse` gets the option's value (nullptr for
// flags) and returns false with `error` set when the value is invalid.
struct OptionSpec {
    const char* name;     // "--spp"
    const char* alias;    // "-o" or nullptr
    const char* metavar;  // "N", nullptr for flags
    std::string help;     // defaults are filled in from RenderSettings{}
    bool (*parse)(RenderOptions& options, const char* value, std::string& error);
};

const std::vector<OptionSpec>& render_option_table();

// Parses the arguments after `render`. Returns false with a one-line
// `error` for bad usage. A request for help sets options.help and succeeds.
bool parse_render_args(const std::vector<std::string>& args, RenderOptions& options, std::string& error);

// Help texts.
std::string main_usage();
std::string render_usage();

}  // namespace coherent::cli
