// coherent: command-line front end. Renders glTF scenes with the same
// Renderer as the Blender add-on; used by benchmarks and by tests that need
// no Blender.
#include <cstdio>
#include <string>
#include <vector>

#include "core/version.h"
#include "options.h"
#include "plot_command.h"
#include "render_command.h"

int main(int argc, char** argv) {
    using namespace coherent::cli;
    const std::vector<std::string> args(argv + 1, argv + argc);
    if (args.empty()) {
        std::fputs(main_usage().c_str(), stderr);
        return kExitBadUsage;
    }
    const std::string& command = args[0];
    if (command == "--help" || command == "-h" || command == "help") {
        std::fputs(main_usage().c_str(), stdout);
        return kExitOk;
    }
    if (command == "--version") {
        std::printf("coherent %s\n%s\n", coherent::version_string(), coherent::build_info());
        return kExitOk;
    }
    if (command == "render") return run_render(std::vector<std::string>(args.begin() + 1, args.end()));
    if (command == "plot") return run_plot(std::vector<std::string>(args.begin() + 1, args.end()));
    std::fprintf(stderr, "coherent: error: unknown command '%s' (see coherent --help)\n", command.c_str());
    return kExitBadUsage;
}
