// Counter-based random numbers: a value is a pure function of its inputs, so
// any thread may draw any (pixel, sample, dimension) without shared state.
#pragma once

#include <cstdint>

namespace coherent {

// 64-bit finaliser from MurmurHash3 / SplitMix64: full avalanche.
inline uint64_t mix64(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

inline uint64_t hash_combine(uint64_t a, uint64_t b) { return mix64(a ^ (b + 0x9e3779b97f4a7c15ull + (a << 6) + (a >> 2))); }

// Top 24 bits to a float in [0, 1): exactly representable, never 1.0.
inline float to_unit_float(uint64_t bits) { return float(bits >> 40) * 0x1p-24f; }

// Small sequential generator for places that need a stream (BVH builds, tests).
class Pcg32 {
public:
    explicit Pcg32(uint64_t seed = 0x853c49e6748fea9bull, uint64_t stream = 0xda3e39cb94b95bdbull) {
        inc_ = (stream << 1u) | 1u;
        next_u32();
        state_ += seed;
        next_u32();
    }
    uint32_t next_u32() {
        const uint64_t old = state_;
        state_ = old * 6364136223846793005ull + inc_;
        const uint32_t xorshifted = uint32_t(((old >> 18u) ^ old) >> 27u);
        const uint32_t rot = uint32_t(old >> 59u);
        return (xorshifted >> rot) | (xorshifted << ((~rot + 1u) & 31));
    }
    float next_float() { return float(next_u32() >> 8) * 0x1p-24f; }

private:
    uint64_t state_ = 0, inc_ = 0;
};

}  // namespace coherent
