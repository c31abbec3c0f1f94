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
#include "owen_sobol.h"
#include "sampler_type.h"

namespace coherent {

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

// Where a dimension lives in the padded Owen-Sobol sequence (owen_sobol.h):
// which 4D set and which of its components. Each 2D decision reads
// components 0 and 1 of its own set (a (0,2)-sequence); 1D decisions take
// components 2 and 3, each stratified on its own:
//   set 0: pixel x, y          set 1: lens u, v
//   set 2 + 2b: light u, v, light pick, spare (shutter time at b = 0)
//   set 3 + 2b: bsdf u, v, bsdf lobe, roulette
struct SobolSlot {
    uint32_t set, component;
};

constexpr SobolSlot sobol_slot(uint32_t dim) {
    if (dim < PathDims::kFirstBounce) return {dim >> 1, dim & 1u};
    // Per bounce offset: {0 = light set / 1 = bsdf set, component}.
    constexpr SobolSlot in_bounce[PathDims::kPerBounce] = {{0, 2}, {0, 0}, {0, 1}, {1, 2},
                                                          {1, 0}, {1, 1}, {1, 3}, {0, 3}};
    const uint32_t b = (dim - PathDims::kFirstBounce) / PathDims::kPerBounce;
    const SobolSlot s = in_bounce[(dim - PathDims::kFirstBounce) % PathDims::kPerBounce];
    return {2 + 2 * b + s.set, s.component};
}

// The numbers of one (pixel, sample): dimensions below `tabulated_dims` come
// from a precomputed row, the rest are drawn from the stream's key:
//   OwenSobol: sample k is point k/2 of one of two independently scrambled
//     padded Sobol sequences (even k from one, odd k from the other). The
//     film's error estimate compares the even and the odd half-images and
//     needs them independent; the halves of one Sobol sequence are not (they
//     are complementary strata), the points of two scrambles are.
//   OwenSobolOneScramble: sample k is point k of one scrambled sequence
//     (the first 2^m samples are one net: less error, a biased-high estimate).
//   WhiteNoise: a counter-based hash of (key, sample, dim).
// Samplers fill tables from the same function, so both give equal values.
//
// SharedSets: where many paths read the same stream (CPT: every pixel of a
// packet, in the same sample), the first path to need a set draws it into
// the SharedSets and the others copy it: the same numbers, one draw instead
// of one per pixel. A SharedSets belongs to one (stream key, sample) and one
// thread; SampleStream::share() attaches it.
struct SharedSets {
    // Sets 0 .. kSets-1: the camera's two and bounces 0..8; deeper sets are drawn per path.
    static constexpr uint32_t kSets = 20;
    uint32_t filled = 0;  // bit s: values[s] holds set s
    alignas(16) float values[kSets][4];
};

class SampleStream {
public:
    SampleStream(uint64_t key, uint32_t sample, SampleSequence sequence = SampleSequence::OwenSobol,
                 const float* row = nullptr, uint32_t tabulated_dims = 0)
        : row_(row),
          tabulated_dims_(row ? tabulated_dims : 0),
          sobol_(sequence != SampleSequence::WhiteNoise),
          reversed_index_(reverse_bits32(sequence == SampleSequence::OwenSobol ? sample >> 1 : sample)),
          key_(sobol_ ? hash_combine(key, 0x50b01000ull | (sequence == SampleSequence::OwenSobol ? sample & 1u : 0u))
                      : key),
          sample_word_(uint64_t(sample) << 32) {}

    float get(uint32_t dim) const {
        if (dim < tabulated_dims_) return row_[dim];
        if (!sobol_) return to_unit_float(hash_combine(key_, sample_word_ | dim));
        const SobolSlot slot = sobol_slot(dim);
        // A path reads a set's components one after another: the set's four
        // values are drawn together (independent chains the CPU overlaps)
        // when the path first reads it.
        if (slot.set != cached_set_) draw_set(slot.set);
        return cached_values_[slot.component];
    }

    // Draws sets through `shared`, which must be fresh or have been filled
    // by a stream with this one's key, sample and sequence.
    void share(SharedSets* shared) { shared_ = sobol_ ? shared : nullptr; }

    // The value stream(key, sample, sequence) gives for `dim`: [0, 1), never 1.0.
    static float drawn(uint64_t key, uint32_t sample, uint32_t dim, SampleSequence sequence) {
        return SampleStream(key, sample, sequence).get(dim);
    }

private:
    void draw_set(uint32_t set) const {
        cached_set_ = set;
        if (shared_ && set < SharedSets::kSets) {
            float* values = shared_->values[set];
            if (!(shared_->filled & (1u << set))) {
                compute_set(set, values);
                shared_->filled |= 1u << set;
            }
            for (int c = 0; c < 4; ++c) cached_values_[c] = values[c];
            return;
        }
        compute_set(set, cached_values_);
    }
    void compute_set(uint32_t set, float out[4]) const {
        const uint32_t seed = uint32_t(key_ >> 32) ^ (set * 0x9e3779b9u);
        const uint32_t shuffled = shuffle_reversed_index(reversed_index_, seed);
        owen_sobol_set4(shuffled, seed, out);
    }

    const float* row_;
    uint32_t tabulated_dims_;
    bool sobol_;
    uint32_t reversed_index_;  // Sobol: bit-reversed point index, sample / 2
    uint64_t key_;
    uint64_t sample_word_;  // white noise: sample << 32
    SharedSets* shared_ = nullptr;
    // Sobol: the set last read and its four values. A stream belongs to one
    // path, read by one thread at a time, so get() may fill this cache.
    mutable uint32_t cached_set_ = ~0u;
    mutable float cached_values_[4] = {};
};

// SPT: an independent sequence per pixel (its own scrambles, keyed by the pixel).
class SptSampler {
public:
    explicit SptSampler(uint64_t seed = 0, SampleSequence sequence = SampleSequence::OwenSobol)
        : seed_key_(mix64(seed ^ 0x5bd1e9955bd1e995ull)), sequence_(sequence) {}

    SampleStream stream(uint32_t px, uint32_t py, uint32_t sample) const {
        const uint64_t pixel = (uint64_t(py) << 32) | px;
        return SampleStream(hash_combine(seed_key_, pixel), sample, sequence_);
    }
    float get(uint32_t px, uint32_t py, uint32_t sample, uint32_t dim) const {
        return stream(px, py, sample).get(dim);
    }

private:
    uint64_t seed_key_;
    SampleSequence sequence_;
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
    // A stream the caller resolved, e.g. once for the pixels that share it.
    explicit PathSampler(const SampleStream& stream) : stream_(stream) {}
    float get(uint32_t dim) const { return stream_.get(dim); }
    // Sets not yet read come through `shared` (SampleStream::share).
    void share(SharedSets* shared) { stream_.share(shared); }

private:
    SampleStream stream_;
};


}  // namespace coherent
