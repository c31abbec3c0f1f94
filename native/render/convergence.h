// Predicting how long a progressive render needs to reach an error target.
#pragma once

#include <cmath>

namespace coherent {

// Monte Carlo error falls as 1/sqrt(samples), and samples grow linearly with
// time, so error(t) = error_now * sqrt(t_now / t). Solving for the target:
//   t_target = t_now * (error_now / target)^2.
// Returns the predicted *total* render seconds at which `target` is reached
// (<= `seconds` when it already is). Returns -1 when no prediction is
// possible: unknown (negative) or non-finite error, non-positive target,
// negative or non-finite time.
inline double predicted_seconds_to_error(double seconds, double error, double target) {
    if (!(target > 0.0) || !(error >= 0.0) || !(seconds >= 0.0) || !std::isfinite(error) ||
        !std::isfinite(seconds) || !std::isfinite(target))
        return -1.0;
    const double ratio = error / target;
    const double t = seconds * ratio * ratio;
    return std::isfinite(t) ? t : -1.0;
}

}  // namespace coherent
