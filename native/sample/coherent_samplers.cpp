#include "coherent_samplers.h"

#include <algorithm>

namespace coherent {

namespace {
// Distinct key spaces per sampler so that, for one seed, CPT's sequences,
// ICPT's sequences, ICPT's partitions and SPT's pixels are unrelated.
constexpr uint64_t kCptSalt = 0xc3a5c85c97cb3127ull;
constexpr uint64_t kIcptSalt = 0xb492b66fbe98f273ull;
constexpr uint64_t kPartitionSalt = 0x9ae16a3b2f90404full;
}  // namespace

SequenceTable::SequenceTable(uint64_t key, uint32_t sequences, uint32_t dims, uint32_t sample_begin,
                             uint32_t sample_count, SampleSequence sequence)
    : key_(key), sequences_(sequences), dims_(std::min(dims, kMaxTabulatedDims)), sample_begin_(sample_begin),
      sample_count_(sample_count), sequence_(sequence) {
    values_.resize(size_t(sample_count_) * sequences_ * dims_);
    float* out = values_.data();
    for (uint32_t s = 0; s < sample_count_; ++s)
        for (uint32_t q = 0; q < sequences_; ++q) {
            const uint64_t seq_key = sequence_key(key_, q);
            for (uint32_t d = 0; d < dims_; ++d) *out++ = SampleStream::drawn(seq_key, sample_begin_ + s, d, sequence_);
        }
}

CptSampler::CptSampler(uint64_t seed, uint32_t dims, uint32_t sample_begin, uint32_t sample_count,
                       SequenceScope scope, uint32_t packet_width, uint32_t packet_height, SampleSequence sequence)
    : scope_(scope),
      packet_width_(std::max<uint32_t>(packet_width, 1)),
      packet_height_(std::max<uint32_t>(packet_height, 1)),
      // Image-wide sequences are the only ones worth a table.
      table_(mix64(seed ^ kCptSalt), 1, dims, sample_begin, scope == SequenceScope::Image ? sample_count : 0,
             sequence) {}

IcptSampler::IcptSampler(uint64_t seed, uint32_t n, uint32_t dims, uint32_t sample_begin, uint32_t sample_count,
                         SequenceScope scope, SampleSequence sequence)
    : n_(std::clamp<uint32_t>(n, 1, LatinSquares::kMaxOrder)),
      scope_(scope),
      squares_(&latin_squares(n_)),
      partition_key_(mix64(seed ^ kPartitionSalt)),
      table_(mix64(seed ^ kIcptSalt), n_, dims, sample_begin, scope == SequenceScope::Image ? sample_count : 0,
             sequence) {}

}  // namespace coherent
