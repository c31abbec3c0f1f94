#include "plot_command.h"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <system_error>

#include "options.h"

extern char** environ;

namespace coherent::cli {
namespace {

namespace fs = std::filesystem;

// Plotting is Python (matplotlib), kept out of the native build; the system
// interpreter is the one Blender and the tests use.
constexpr const char* kPython = "/usr/bin/python3";
constexpr const char* kScriptName = "coherent_plot.py";

// The script lives at tools/coherent_plot.py in the source tree. This file's
// own path (__FILE__, absolute under CMake) is native/cli/plot_command.cpp,
// so the source tree is known at compile time; an installed copy next to the
// executable (or in ../tools) is the fallback when the tree has moved.
fs::path source_tree_script() { return fs::path(__FILE__).parent_path().parent_path().parent_path() / "tools" / kScriptName; }

fs::path find_script() {
    std::vector<fs::path> candidates = {source_tree_script()};
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (!ec) {
        candidates.push_back(exe.parent_path() / kScriptName);
        candidates.push_back(exe.parent_path().parent_path() / "tools" / kScriptName);
    }
    for (const fs::path& p : candidates)
        if (fs::is_regular_file(p, ec)) return p;
    return {};
}

void print_error(const std::string& message) { std::fprintf(stderr, "coherent: error: %s\n", message.c_str()); }

std::string plot_usage() {
    return "usage: coherent plot CONVERGENCE.csv [-o OUT.png]\n\n"
           "Plots a `coherent render --convergence` record: the error estimate against\n"
           "render time on log-log axes, with a dashed 1/sqrt(t) reference through the\n"
           "last point. The default output is the CSV path with .png. Needs " +
           std::string(kPython) + " with matplotlib.\n";
}

}  // namespace

int run_plot(const std::vector<std::string>& args) {
    for (const std::string& a : args) {
        if (a == "--help" || a == "-h") {
            std::fputs(plot_usage().c_str(), stdout);
            return kExitOk;
        }
    }
    if (args.empty()) {
        print_error("no convergence CSV given (see coherent plot --help)");
        return kExitBadUsage;
    }
    if (access(kPython, X_OK) != 0) {
        print_error(std::string("coherent plot needs ") + kPython + " (with matplotlib), which is not installed");
        return kExitBadInput;
    }
    const fs::path script = find_script();
    if (script.empty()) {
        print_error(std::string("cannot find ") + kScriptName + " (looked in " + source_tree_script().string() +
                    " and next to the executable)");
        return kExitBadInput;
    }

    // argv: python3 script args... ; the script parses and validates them.
    const std::string script_path = script.string();
    std::vector<char*> argv = {const_cast<char*>(kPython), const_cast<char*>(script_path.c_str())};
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);

    std::fflush(stdout);
    std::fflush(stderr);
    pid_t pid = 0;
    const int spawn_error = posix_spawn(&pid, kPython, nullptr, nullptr, argv.data(), environ);
    if (spawn_error != 0) {
        print_error(std::string("cannot run ") + kPython + ": " + std::strerror(spawn_error));
        return kExitBadInput;
    }
    int status = 0;
    while (waitpid(pid, &status, 0) < 0) {
        if (errno != EINTR) {
            print_error(std::string("waiting for ") + kPython + ": " + std::strerror(errno));
            return kExitBadInput;
        }
    }
    if (WIFEXITED(status)) return WEXITSTATUS(status);
    if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);  // as shells report it
    return kExitBadInput;
}

}  // namespace coherent::cli
