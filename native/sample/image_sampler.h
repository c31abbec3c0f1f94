// The sampler a render uses, chosen at run time: one of SPT, CPT, ICPT behind
// the sampler interface of sampler.h. The choice is resolved once per path
// (in stream()), not per dimension, so the path kernel is instantiated once
// and still pays only a table load or one hash per number.
//
// Tables are built per pass: the renderer renders one sample over the whole
// image at a time, so a pass needs S sequences x dims floats (CPT: S = 1,
// ICPT: S = n), a few KB, and nothing is allocated per path or per sample.
// (Packet-scoped sequences are hashed, see coherent_samplers.h.)
#pragma once

#include <algorithm>
#include <cstdint>

#include "coherent_samplers.h"
#include "sampler.h"
#include "sampler_type.h"

namespace coherent {

struct SamplerConfig {
    SamplerType type = SamplerType::Spt;  // resolved: never Auto (Auto is treated as Spt)
    uint64_t seed = 0;
    // Packet size in pixels. ICPT uses square blocks of side
    // min(packet_width, packet_height) (Latin hypercube subsets need as many
    // rows as columns); CPT's packets share a sequence (Packet scope).
    int packet_width = 4, packet_height = 4;
    SequenceScope scope = SequenceScope::Packet;
    uint32_t dims = PathDims::count(12);  // dimensions worth tabulating
    SampleSequence sequence = SampleSequence::WhiteNoise;  // RenderSettings::pattern
};

class ImageSampler {
public:
    // Tables cover samples [sample_begin, sample_begin + sample_count); other
    // samples are still drawn correctly, from the hash.
    ImageSampler(const SamplerConfig& c, uint32_t sample_begin, uint32_t sample_count)
        : type_(c.type == SamplerType::Auto ? SamplerType::Spt : c.type),
          spt_(c.seed, c.sequence),
          cpt_(c.seed, c.dims, sample_begin, type_ == SamplerType::Cpt ? sample_count : 0, c.scope,
               uint32_t(std::max(c.packet_width, 1)), uint32_t(std::max(c.packet_height, 1)), c.sequence),
          icpt_(c.seed, icpt_block(c), c.dims, sample_begin, type_ == SamplerType::Icpt ? sample_count : 0, c.scope,
                c.sequence) {}

    SampleStream stream(uint32_t px, uint32_t py, uint32_t sample) const {
        switch (type_) {
            case SamplerType::Cpt: return cpt_.stream(px, py, sample);
            case SamplerType::Icpt: return icpt_.stream(px, py, sample);
            default: return spt_.stream(px, py, sample);
        }
    }
    float get(uint32_t px, uint32_t py, uint32_t sample, uint32_t dim) const {
        return stream(px, py, sample).get(dim);
    }
    SamplerType type() const { return type_; }
    // ICPT: the Latin-hypercube subset (which of the block's n sequences)
    // pixel (px, py) uses in `sample`, and the block side n. Pixels of one
    // subset across an ICPT region share every random number: the coherent
    // packet of the paper's Fig. 3. (0 and 1 for the other samplers.)
    uint32_t icpt_subset(uint32_t px, uint32_t py, uint32_t sample) const {
        return type_ == SamplerType::Icpt ? icpt_.subset(px, py, sample) : 0;
    }
    uint32_t icpt_block_size() const { return type_ == SamplerType::Icpt ? icpt_.block_size() : 1; }

    // Rectangles of pixels that read one stream in every sample, aligned to
    // multiples of their size in image coordinates: CPT's packets (Packet
    // scope). 0 x 0 where a driver has nothing to share: SPT (a stream per
    // pixel), ICPT (which pixels share changes every sample) and Image-scope
    // CPT (its numbers come from a table already).
    struct SharedBlock {
        uint32_t width = 0, height = 0;
    };
    SharedBlock shared_stream_block() const {
        if (type_ != SamplerType::Cpt || cpt_.scope() != SequenceScope::Packet) return {};
        return {cpt_.packet_width(), cpt_.packet_height()};
    }

    static uint32_t icpt_block(const SamplerConfig& c) {
        const int n = c.packet_width < c.packet_height ? c.packet_width : c.packet_height;
        return uint32_t(n < 1 ? 1 : n);
    }

private:
    SamplerType type_;
    SptSampler spt_;
    CptSampler cpt_;
    IcptSampler icpt_;
};

inline PathSampler::PathSampler(const ImageSampler& s, uint32_t px, uint32_t py, uint32_t sample)
    : stream_(s.stream(px, py, sample)) {}

}  // namespace coherent
