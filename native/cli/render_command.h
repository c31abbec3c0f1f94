// `coherent render`: load a glTF scene, render it, write the image.
#pragma once

#include <string>
#include <vector>

namespace coherent::cli {

// Runs the command with the arguments after "render"; returns the exit code.
int run_render(const std::vector<std::string>& args);

}  // namespace coherent::cli
