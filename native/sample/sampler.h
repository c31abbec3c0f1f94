// Samplers map (pixel, sample, dimension) to a number in [0, 1). Nothing else
// in the engine knows how numbers are drawn: integrators ask a PathSampler for
// the next dimension, and the renderer chooses the sampler type.
//
// Interface (a compile-time concept, so the per-path kernel inlines the draw):
//   struct S {
//       float get(uint32_t px, uint32_t py, uint32_t sample, uint32_t dim) const;
//   };
// Invariant: get() is a pure function of its arguments and the sampler's
// construction parameters (seed), so the image does not depend on thread
// count or tile order. CPT/ICPT (tabulated per-packet sequences) are added as
// further types with the same get().
#pragma once

#include <cstdint>

#include "../core/random.h"

namespace coherent {

// SPT: an independent random sequence per pixel, drawn from a counter-based hash.
class SptSampler {
public:
    explicit SptSampler(uint64_t seed = 0) : seed_key_(mix64(seed ^ 0x5bd1e9955bd1e995ull)) {}

    float get(uint32_t px, uint32_t py, uint32_t sample, uint32_t dim) const {
        const uint64_t pixel = (uint64_t(py) << 32) | px;
        const uint64_t h = hash_combine(hash_combine(seed_key_, pixel), (uint64_t(sample) << 32) | dim);
        return to_unit_float(h);
    }

private:
    uint64_t seed_key_;
};

// The stream of numbers one path consumes. Dimensions are assigned in a fixed
// layout (see PathDims) so the same (pixel, sample) always uses the same
// dimension for the same decision, which keeps samplers with structure
// (stratified, Latin hypercube) effective.
template <class Sampler>
class PathSampler {
public:
    PathSampler(const Sampler& s, uint32_t px, uint32_t py, uint32_t sample)
        : s_(s), px_(px), py_(py), sample_(sample) {}
    float get(uint32_t dim) const { return s_.get(px_, py_, sample_, dim); }

private:
    const Sampler& s_;
    uint32_t px_, py_, sample_;
};

// Fixed dimension layout of a path sample.
struct PathDims {
    static constexpr uint32_t kPixelX = 0, kPixelY = 1, kLensU = 2, kLensV = 3;
    static constexpr uint32_t kFirstBounce = 4;
    static constexpr uint32_t kPerBounce = 8;
    // Offsets within a bounce.
    static constexpr uint32_t kLightPick = 0, kLightU = 1, kLightV = 2;
    static constexpr uint32_t kBsdfLobe = 3, kBsdfU = 4, kBsdfV = 5, kRoulette = 6, kLightExtra = 7;
    static constexpr uint32_t bounce(int b, uint32_t offset) { return kFirstBounce + uint32_t(b) * kPerBounce + offset; }
};

}  // namespace coherent
