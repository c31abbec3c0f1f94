// CPU time of the calling thread, the clock of every per-thread timing (ray
// reordering, wavefront stages, single-thread benches): on a shared machine
// wall time would also count the time the thread spent descheduled.
#pragma once

#include <time.h>

namespace coherent {

// Seconds on CLOCK_THREAD_CPUTIME_ID; only differences are meaningful.
inline double thread_cpu_seconds() {
    timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

}  // namespace coherent
