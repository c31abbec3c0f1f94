#include "progress_bar.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "render/convergence.h"

namespace coherent::cli {
namespace {

std::string format_duration(double seconds) {
    if (!std::isfinite(seconds) || seconds < 0.0) return "--:--";
    const long s = long(seconds + 0.5);
    char buf[32];
    if (s >= 3600) {
        std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", s / 3600, (s / 60) % 60, s % 60);
    } else {
        std::snprintf(buf, sizeof buf, "%02ld:%02ld", s / 60, s % 60);
    }
    return buf;
}

}  // namespace

ProgressBar::ProgressBar(double target_error)
    : enabled_(isatty(STDERR_FILENO) == 1), target_error_(target_error) {}

void ProgressBar::update(const Progress& p) {
    if (!enabled_) return;
    const auto now = std::chrono::steady_clock::now();
    const bool last = p.samples_done >= p.samples_total;
    if (drawn_ && !last && now - last_draw_ < std::chrono::milliseconds(100)) return;
    last_draw_ = now;
    drawn_ = true;

    constexpr int kWidth = 30;
    const double fraction = std::clamp(p.fraction, 0.0, 1.0);
    const int filled = int(fraction * kWidth);
    std::string bar(size_t(filled), '#');
    bar.resize(kWidth, '.');
    const double rays = p.stats ? double(p.stats->total_rays()) : 0.0;
    const double mrays = p.seconds > 0.0 ? rays / p.seconds * 1e-6 : 0.0;
    const double eta = fraction > 0.0 ? p.seconds * (1.0 - fraction) / fraction : NAN;
    // \r returns to the line start; \033[K clears what a longer line left.
    // "error 2.10 % -> 1.00 % in ~00:42": the time left to the target if the
    // error keeps falling as 1/sqrt(samples).
    char error[96] = "";
    if (p.error_estimate >= 0.0) {
        int n = std::snprintf(error, sizeof(error), "  error %.2f %%", 100.0 * p.error_estimate);
        const double t_target = predicted_seconds_to_error(p.seconds, p.error_estimate, target_error_);
        if (t_target >= 0.0 && n > 0 && size_t(n) < sizeof(error))
            std::snprintf(error + n, sizeof(error) - size_t(n), " -> %.2f %% in ~%s", 100.0 * target_error_,
                          format_duration(std::max(0.0, t_target - p.seconds)).c_str());
    }
    if (p.denoise_fraction >= 0.0) {
        std::fprintf(stderr, "\r[%s] %3d%%  %d/%d spp%s  denoising %3d%%\033[K", bar.c_str(), int(fraction * 100.0),
                     p.samples_done, p.samples_total, error, int(p.denoise_fraction * 100.0));
        std::fflush(stderr);
        return;
    }
    std::fprintf(stderr, "\r[%s] %3d%%  %d/%d spp%s  %.1f Mrays/s  ETA %s\033[K", bar.c_str(),
                 int(fraction * 100.0), p.samples_done, p.samples_total, error, mrays, format_duration(eta).c_str());
    std::fflush(stderr);
}

void ProgressBar::finish() {
    if (enabled_ && drawn_) {
        std::fputc('\n', stderr);
        std::fflush(stderr);
    }
    drawn_ = false;
}

}  // namespace coherent::cli
