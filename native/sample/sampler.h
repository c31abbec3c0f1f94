// Samplers map (pixel, sample, dimension) to a number in [0, 1). Nothing else
// in the engine knows how numbers are drawn: integrators ask a PathSampler for
// the next dimension, and the renderer chooses the sampler type.
//
// Interface (a compile-time concept, so the per-path kernel inlines the draw):
//   struct S {
//       float get(uint32_t px, uint32_t py, uint32_t sample, uint32_t dim) const;
//       SampleStream stream(uint32_t px, uint32_t py, uint32_t sample) const;
//   };
// where stream(px, py, sample).get(dim) == get(px, py, sample, dim). A path
// resolves its stream once (which sequence, which table row) and then pays a
// table load or one hash per dimension.
// Invariant: get() is a pure function of its arguments and the sampler's
// construction parameters (seed, packet size), so the image does not depend
// on thread count, tile order, or which samples a table happens to cover.
//
// Implementations: SptSampler (here), CptSampler and IcptSampler
// (coherent_samplers.h), ImageSampler (image_sampler.h) picks one at run time.
#pragma once

#include <cstdint>

#include "../core/random.h"

namespace coherent {

// The numbers of one (pixel, sample): dimensions below `tabulated_dims` come
// from a precomputed row, the rest from a counter-based hash of (key, sample,
// dim). Samplers fill tables with that same hash, so both give equal values.
class SampleStream {
public:
    SampleStream(uint64_t key, uint32_t sample, const float* row = nullptr, uint32_t tabulated_dims = 0)
        : row_(row), tabulated_dims_(row ? tabulated_dims : 0), key_(key), sample_word_(uint64_t(sample) << 32) {}

    float get(uint32_t dim) const {
        return dim < tabulated_dims_ ? row_[dim] : to_unit_float(hash_combine(key_, sample_word_ | dim));
    }

    // The counter-based draw behind every sampler: [0, 1), never 1.0.
    static float hashed(uint64_t key, uint32_t sample, uint32_t dim) {
        return to_unit_float(hash_combine(key, (uint64_t(sample) << 32) | dim));
    }

private:
    const float* row_;
    uint32_t tabulated_dims_;
    uint64_t key_;
    uint64_t sample_word_;
};

// SPT: an independent random sequence per pixel, drawn from a counter-based hash.
class SptSampler {
public:
    explicit SptSampler(uint64_t seed = 0) : seed_key_(mix64(seed ^ 0x5bd1e9955bd1e995ull)) {}

    SampleStream stream(uint32_t px, uint32_t py, uint32_t sample) const {
        const uint64_t pixel = (uint64_t(py) << 32) | px;
        return SampleStream(hash_combine(seed_key_, pixel), sample);
    }
    float get(uint32_t px, uint32_t py, uint32_t sample, uint32_t dim) const {
        return stream(px, py, sample).get(dim);
    }

private:
    uint64_t seed_key_;
};

// The stream of numbers one path consumes. Dimensions are assigned in a fixed
// layout (see PathDims) so the same (pixel, sample) always uses the same
// dimension for the same decision, which keeps samplers with structure
// (stratified, Latin hypercube) effective and makes CPT's shared sequence
// drive the same decision in every pixel: rays of a packet that are at the
// same bounce consumed the same numbers for it.
class ImageSampler;
class PathSampler {
public:
    // Defined in image_sampler.h, the one sampler a render uses.
    PathSampler(const ImageSampler& s, uint32_t px, uint32_t py, uint32_t sample);
    float get(uint32_t dim) const { return stream_.get(dim); }

private:
    SampleStream stream_;
};

// Fixed dimension layout of a path sample. Each bounce owns a fixed block of
// kPerBounce dimensions whether or not it uses them (e.g. roulette before
// rr_min_bounces), so bounce b of every path reads the same dimensions.
struct PathDims {
    static constexpr uint32_t kPixelX = 0, kPixelY = 1, kLensU = 2, kLensV = 3;
    static constexpr uint32_t kFirstBounce = 4;
    static constexpr uint32_t kPerBounce = 8;
    // Offsets within a bounce.
    static constexpr uint32_t kLightPick = 0, kLightU = 1, kLightV = 2;
    static constexpr uint32_t kBsdfLobe = 3, kBsdfU = 4, kBsdfV = 5, kRoulette = 6, kSpare = 7;
    static constexpr uint32_t bounce(int b, uint32_t offset) { return kFirstBounce + uint32_t(b) * kPerBounce + offset; }
    // The path's shutter time (motion blur) uses the first bounce's spare
    // slot, so adding it moved no other decision's dimension.
    static constexpr uint32_t kTime = kFirstBounce + kSpare;
    // Dimensions a path with at most `max_bounces` bounces can read: bounce
    // indices 0..max_bounces sample (the ray after the last one only collects
    // emission).
    static constexpr uint32_t count(int max_bounces) {
        return kFirstBounce + uint32_t(max_bounces < 0 ? 0 : max_bounces + 1) * kPerBounce;
    }
};

}  // namespace coherent
