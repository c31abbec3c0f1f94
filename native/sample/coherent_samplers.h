// CPT and ICPT (Sadeghi et al. 2009, "Coherent Path Tracing", sections 2.2,
// 2.3): pixels share tabulated random sequences so that their secondary rays
// take the same directions and stay coherent enough for packet tracing.
//
// Sequences. For sample k there are S shared sequences u_{k,0..S-1}, each a
// uniform vector (CPT: S = 1, ICPT: S = n, the block side). As in the paper,
// which tabulates an LCG, they are generated once per render (or pass) from
// the seed and read from a table; here each value is
// SampleStream::drawn(sequence key, k, dim): point k of the sequence's own
// scrambled Owen-Sobol sequence (or white noise), so a table is only a cache
// and dimensions or samples outside it get the identical value.
// Sobol and the three samplers: SPT scrambles per pixel; CPT's packet shares
// one scrambled sequence, so every pixel of it still gets a low-discrepancy
// set over its samples; ICPT's subset j of a region reads sequence j, so a
// pixel (whose subset is re-drawn every sample) mixes points of n
// sequences: stratified per sequence but not over its own samples, and its
// error falls at white noise's rate. That is inherent: a pixel can follow one
// stratified sequence only if the pixels it shares numbers with stay the same.
// (Tried: squares per round of 2n samples with labels rotating, so each pixel
// reads every sequence once per round: slope -0.93 instead of -0.51 on the
// lit plane of test_sobol.cpp, but then every pixel of a region uses the same
// 2n points per round, in another order, and neighbour error correlation
// rises from 0.03 to 0.24 at 4 spp, towards CPT's at 8.)
//
// Where sequences are shared (SequenceScope, sampler_type.h):
//  * Image, equation (3): CPT uses the same vector u_k for every pixel x_i of
//    the image in sample k; ICPT's subset j uses u_{k,j} in every block.
//    Tabulated per sample: S x dims floats.
//  * Packet (the paper's Fig. 3, the default): sequences are additionally
//    keyed by a region: CPT's packet (packet_width x packet_height pixels),
//    ICPT's group of 2 x 2 blocks. A table per region would grow with the
//    image, so these are drawn from the hash of (sequence, region, sample,
//    dim) directly: the same numbers a table would hold, one hash per number.
// Either way every pixel of a packet (CPT) or of a subset within a region
// (ICPT) reads identical numbers for every dimension.
//
// ICPT: the image is cut into n x n blocks (n = 4 in the paper); for every
// block and every sample, the block is partitioned into n Latin-hypercube
// subsets (n-rooks: one pixel per row and per column, see latin_square.h),
// re-randomised per block and per sample, and subset j uses sequence u_{k,j}
// of the block's region. So a block holds n different sequences, and subset
// j of the blocks of a region forms a coherent packet (the paper's 8 x 8
// region = four packets of 16 rays, each from 4 subsets of 4 pixels).
//
// Unbiasedness: each pixel's u is a uniform vector in every sample (Owen
// scrambling makes every point uniform) and the pixel's samples are either
// independent (white noise) or a scrambled stratified set, so every pixel's
// estimate has the SPT expectation; only the correlation *between* pixels
// changes (the paper's "method of dependent tests").
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "latin_square.h"
#include "sampler.h"
#include "sampler_type.h"

namespace coherent {

// Table of `sequences` shared sequences of `dims` floats for each sample in
// [sample_begin, sample_begin + sample_count).
class SequenceTable {
public:
    SequenceTable() = default;
    SequenceTable(uint64_t key, uint32_t sequences, uint32_t dims, uint32_t sample_begin, uint32_t sample_count,
                  SampleSequence sequence = SampleSequence::OwenSobol);

    // Region id of sequences shared by the whole image (the tabulated ones).
    static constexpr uint64_t kImageRegion = ~uint64_t(0);

    // The stream of sequence `seq` for `sample` in `region`: tabulated if
    // image-wide and covered, else hashed from a region-specific key.
    SampleStream stream(uint32_t sample, uint32_t seq, uint64_t region = kImageRegion) const {
        const uint64_t seq_key = sequence_key(key_, seq);
        if (region != kImageRegion) return SampleStream(hash_combine(seq_key, region), sample, sequence_);
        const uint32_t rel = sample - sample_begin_;  // wraps for sample < begin: then >= count
        if (rel < sample_count_ && seq < sequences_)
            return SampleStream(seq_key, sample, sequence_, &values_[(size_t(rel) * sequences_ + seq) * dims_],
                                dims_);
        return SampleStream(seq_key, sample, sequence_);
    }

    uint32_t sequences() const { return sequences_; }
    uint32_t dims() const { return dims_; }

    static uint64_t sequence_key(uint64_t key, uint32_t seq) { return hash_combine(key, 0x9e37000000000000ull | seq); }

private:
    uint64_t key_ = 0;
    uint32_t sequences_ = 0, dims_ = 0, sample_begin_ = 0, sample_count_ = 0;
    SampleSequence sequence_ = SampleSequence::OwenSobol;
    std::vector<float> values_;
};

// Most dimensions a table holds per sequence; deeper bounces read the hash.
constexpr uint32_t kMaxTabulatedDims = PathDims::count(32);

// CPT: one sequence per sample, shared by every pixel of a packet (Packet
// scope) or of the image (Image scope, paper eq. 3).
class CptSampler {
public:
    // Tabulates `dims` dimensions of samples [sample_begin, sample_begin + sample_count)
    // (Image scope only). Packet sizes are clamped to >= 1.
    explicit CptSampler(uint64_t seed = 0, uint32_t dims = PathDims::count(12), uint32_t sample_begin = 0,
                        uint32_t sample_count = 0, SequenceScope scope = SequenceScope::Packet,
                        uint32_t packet_width = 4, uint32_t packet_height = 4,
                        SampleSequence sequence = SampleSequence::OwenSobol);

    // The region whose pixels share a sequence.
    uint64_t region(uint32_t px, uint32_t py) const {
        if (scope_ == SequenceScope::Image) return SequenceTable::kImageRegion;
        return (uint64_t(py / packet_height_) << 32) | (px / packet_width_);
    }
    SampleStream stream(uint32_t px, uint32_t py, uint32_t sample) const {
        return table_.stream(sample, 0, region(px, py));
    }
    float get(uint32_t px, uint32_t py, uint32_t sample, uint32_t dim) const {
        return stream(px, py, sample).get(dim);
    }
    SequenceScope scope() const { return scope_; }
    uint32_t packet_width() const { return packet_width_; }
    uint32_t packet_height() const { return packet_height_; }

private:
    SequenceScope scope_;
    uint32_t packet_width_, packet_height_;
    SequenceTable table_;
};

// ICPT: n x n blocks, n Latin-hypercube subsets per block re-randomised per
// block and sample, one shared sequence per subset index and region.
class IcptSampler {
public:
    // n = block side, clamped to [1, LatinSquares::kMaxOrder].
    explicit IcptSampler(uint64_t seed = 0, uint32_t n = 4, uint32_t dims = PathDims::count(12),
                         uint32_t sample_begin = 0, uint32_t sample_count = 0,
                         SequenceScope scope = SequenceScope::Packet,
                         SampleSequence sequence = SampleSequence::OwenSobol);

    // Which of the n sequences pixel (px, py) uses in `sample`.
    uint32_t subset(uint32_t px, uint32_t py, uint32_t sample) const {
        const uint64_t block = (uint64_t(py / n_) << 32) | (px / n_);
        const uint64_t h = hash_combine(hash_combine(partition_key_, block), sample);
        return squares_->subset(h, py % n_, px % n_);
    }
    // The region (2 x 2 blocks, or the image) whose subsets share sequences.
    uint64_t region(uint32_t px, uint32_t py) const {
        if (scope_ == SequenceScope::Image) return SequenceTable::kImageRegion;
        return (uint64_t(py / (2 * n_)) << 32) | (px / (2 * n_));
    }
    SampleStream stream(uint32_t px, uint32_t py, uint32_t sample) const {
        return table_.stream(sample, subset(px, py, sample), region(px, py));
    }
    float get(uint32_t px, uint32_t py, uint32_t sample, uint32_t dim) const {
        return stream(px, py, sample).get(dim);
    }
    uint32_t block_size() const { return n_; }

private:
    uint32_t n_;
    SequenceScope scope_;
    const LatinSquares* squares_;
    uint64_t partition_key_;
    SequenceTable table_;
};

}  // namespace coherent
