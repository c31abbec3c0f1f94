// The global test seed: COHERENT_TEST_SEED (an unsigned integer, default 0)
// offsets the seeds of the statistical tests, so that the suite can be run
// with other random numbers (a correct test must pass for any of them; its
// thresholds come from the measured noise, not from one lucky seed). The
// CLI and Blender suites read the same variable (tests/cli/seeds.py,
// tests/blender/seeds.py).
#pragma once

#include <cstdint>
#include <cstdlib>
#include <string>

namespace coherent::test {

inline uint64_t global_seed_offset() {
    static const uint64_t offset = [] {
        const char* s = std::getenv("COHERENT_TEST_SEED");
        return s && *s ? std::strtoull(s, nullptr, 10) : 0ull;
    }();
    return offset;
}

// `base` moved by the global offset. The stride keeps the seeds of different
// offsets apart from the small bases the tests pick (1, 7, 1000 + i, ...).
inline uint64_t test_seed(uint64_t base) { return base + global_seed_offset() * 1000003ull; }

}  // namespace coherent::test
