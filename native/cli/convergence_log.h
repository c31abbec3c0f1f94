// --convergence: a CSV record of how the error estimate fell over time, one
// row per batch of sample passes (--report-interval), for plotting (coherent
// plot) and for seeing what accuracy costs in time.
#pragma once

#include <cstdio>
#include <string>

#include "render/renderer.h"

namespace coherent::cli {

class ConvergenceLog {
public:
    // Opens `path` and writes the header "seconds,spp,error_estimate".
    // Returns false with `error` set if the file cannot be written; called
    // before rendering so a bad path fails before the work is spent.
    bool open(const std::string& path, std::string& error);
    // Appends one row per newly completed pass that has an error estimate
    // (from the second pass on). Progress also arrives within long passes
    // with an unchanged samples_done; those repeat a row already written and
    // are skipped, so rows have strictly increasing spp and non-decreasing
    // seconds.
    void record(const Progress& progress);
    // Flushes and closes; returns false with `error` set on a write failure.
    bool close(std::string& error);
    ~ConvergenceLog();

private:
    std::FILE* file_ = nullptr;
    std::string path_;
    int last_spp_ = 0;
};

}  // namespace coherent::cli
