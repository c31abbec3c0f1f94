// A one-line progress bar on stderr (samples done/total, error estimate and
// predicted time to the target error, Mrays/s, ETA),
// drawn only when stderr is a terminal so logs and pipes stay clean.
#pragma once

#include <chrono>

#include "render/renderer.h"

namespace coherent::cli {

class ProgressBar {
public:
    // Enabled iff stderr is a terminal. With a target error (> 0) the bar
    // also predicts the time left to reach it.
    explicit ProgressBar(double target_error = 0.0);
    // Redraws at most ~10 times a second (and always for the last sample).
    void update(const Progress& progress);
    // Ends the line so later messages start on a fresh one.
    void finish();
    bool enabled() const { return enabled_; }

private:
    bool enabled_ = false;
    double target_error_ = 0.0;
    bool drawn_ = false;
    std::chrono::steady_clock::time_point last_draw_{};
};

}  // namespace coherent::cli
