// `coherent plot`: draws a --convergence record with tools/coherent_plot.py.
#pragma once

#include <string>
#include <vector>

namespace coherent::cli {

// Runs the plotting script on the arguments after `plot`; returns its exit
// status (or kExitBadUsage / kExitBadInput when it cannot be run).
int run_plot(const std::vector<std::string>& args);

}  // namespace coherent::cli
