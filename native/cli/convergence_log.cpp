#include "convergence_log.h"

#include <cerrno>
#include <cstring>

namespace coherent::cli {

bool ConvergenceLog::open(const std::string& path, std::string& error) {
    file_ = std::fopen(path.c_str(), "w");
    if (!file_) {
        error = "cannot write convergence record '" + path + "': " + std::strerror(errno);
        return false;
    }
    path_ = path;
    std::fputs("seconds,spp,error_estimate\n", file_);
    return true;
}

void ConvergenceLog::record(const Progress& p) {
    if (!file_ || p.samples_done <= last_spp_) return;
    if (!(p.error_estimate >= 0.0)) return;  // no estimate before 2 passes
    last_spp_ = p.samples_done;
    // %.17g round-trips doubles; seconds to microseconds is plenty.
    std::fprintf(file_, "%.6f,%d,%.17g\n", p.seconds, p.samples_done, p.error_estimate);
}

bool ConvergenceLog::close(std::string& error) {
    if (!file_) return true;
    const bool ok = std::ferror(file_) == 0 && std::fflush(file_) == 0;
    const bool closed = std::fclose(file_) == 0;
    file_ = nullptr;
    if (!ok || !closed) {
        error = "failed writing convergence record '" + path_ + "'";
        return false;
    }
    return true;
}

ConvergenceLog::~ConvergenceLog() {
    if (file_) std::fclose(file_);
}

}  // namespace coherent::cli
