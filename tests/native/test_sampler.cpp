// Unit tests of the sample layer: SPT, CPT (Sadeghi et al. 2009, eq. 3) and
// ICPT (section 2.3): value range, sharing structure, Latin-hypercube
// partitions and their re-randomisation, tables equal to the hash they cache,
// uniform marginals, and the Auto rule.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <set>
#include <utility>
#include <vector>

#include "sample/coherent_samplers.h"
#include "sample/image_sampler.h"
#include "sample/latin_square.h"
#include "sample/sampler.h"
#include "sample/sampler_type.h"

using namespace coherent;

namespace {

constexpr uint32_t kDims = PathDims::count(12);

template <class S>
void expect_unit_range(const S& s, uint32_t dims) {
    for (uint32_t py = 0; py < 9; ++py)
        for (uint32_t px = 0; px < 9; ++px)
            for (uint32_t k = 0; k < 6; ++k)
                for (uint32_t d = 0; d < dims; ++d) {
                    const float v = s.get(px, py, k, d);
                    ASSERT_GE(v, 0.0f);
                    ASSERT_LT(v, 1.0f);
                }
}

// Partition of block (bx, by) of side n in `sample`, as a row-major n*n vector of subset ids.
std::vector<uint32_t> partition(const IcptSampler& s, uint32_t bx, uint32_t by, uint32_t sample) {
    const uint32_t n = s.block_size();
    std::vector<uint32_t> p(size_t(n) * n);
    for (uint32_t r = 0; r < n; ++r)
        for (uint32_t c = 0; c < n; ++c) p[r * n + c] = s.subset(bx * n + c, by * n + r, sample);
    return p;
}

// Relabels subsets by order of first appearance, so two labelings of the
// same set partition compare equal.
std::vector<uint32_t> canonical(std::vector<uint32_t> p) {
    std::map<uint32_t, uint32_t> relabel;
    for (uint32_t& v : p) {
        auto it = relabel.try_emplace(v, uint32_t(relabel.size())).first;
        v = it->second;
    }
    return p;
}

}  // namespace

TEST(Sampler, ValuesInUnitIntervalTabulatedAndHashed) {
    // Past kMaxTabulatedDims and past the tabulated samples the hash takes over.
    const uint32_t dims = kMaxTabulatedDims + 16;
    expect_unit_range(SptSampler(3), dims);
    expect_unit_range(SptSampler(3, SampleSequence::WhiteNoise), dims);
    for (SequenceScope scope : {SequenceScope::Packet, SequenceScope::Image}) {
        expect_unit_range(CptSampler(3, dims, 0, 4, scope), dims);
        expect_unit_range(IcptSampler(3, 4, dims, 0, 4, scope), dims);
        expect_unit_range(IcptSampler(3, 5, dims, 2, 2, scope), dims);
    }
}

TEST(Sampler, SptWhiteNoiseMatchesCounterHashAndIsIndependentPerPixel) {
    // Oracle: the definition SPT had before streams existed, so white-noise
    // SPT images are unchanged.
    const uint64_t seed = 42;
    const uint64_t key = mix64(seed ^ 0x5bd1e9955bd1e995ull);
    const SptSampler s(seed, SampleSequence::WhiteNoise);
    for (uint32_t px : {0u, 7u, 1000u})
        for (uint32_t k : {0u, 5u})
            for (uint32_t d : {0u, 3u, 99u}) {
                const uint64_t pixel = (uint64_t(11) << 32) | px;
                EXPECT_EQ(s.get(px, 11, k, d),
                          to_unit_float(hash_combine(hash_combine(key, pixel), (uint64_t(k) << 32) | d)));
            }
    EXPECT_NE(s.get(0, 0, 0, 4), s.get(1, 0, 0, 4));
}

TEST(Sampler, TablesEqualTheHashTheyCache) {
    // Invariant: get() does not depend on which samples/dims a table covers.
    const uint32_t dims = kMaxTabulatedDims + 8;
    // Only image-wide sequences are tabulated.
    const CptSampler cpt_table(9, dims, 3, 5, SequenceScope::Image), cpt_hash(9, dims, 0, 0, SequenceScope::Image);
    const IcptSampler icpt_table(9, 4, dims, 3, 5, SequenceScope::Image),
        icpt_hash(9, 4, dims, 0, 0, SequenceScope::Image);
    for (uint32_t k = 0; k < 10; ++k)
        for (uint32_t d = 0; d < dims; ++d)
            for (uint32_t px = 0; px < 8; ++px) {
                ASSERT_EQ(cpt_table.get(px, 2, k, d), cpt_hash.get(px, 2, k, d));
                ASSERT_EQ(icpt_table.get(px, 2, k, d), icpt_hash.get(px, 2, k, d));
            }
}

TEST(Sampler, CptImageScopeSharesOneSequencePerSampleOverTheWholeImage) {
    // Paper, eq. (3): the same vector u_k for every pixel x_i in sample k.
    const CptSampler s(1, kDims, 0, 8, SequenceScope::Image);
    for (uint32_t k = 0; k < 8; ++k)
        for (uint32_t d = 0; d < kDims; ++d) {
            const float v = s.get(0, 0, k, d);
            for (uint32_t py : {0u, 3u, 4u, 517u})
                for (uint32_t px : {1u, 3u, 4u, 1023u}) ASSERT_EQ(s.get(px, py, k, d), v);
        }
    // ...and different sequences for different samples, dimensions and seeds.
    std::set<float> values;
    for (uint32_t k = 0; k < 8; ++k)
        for (uint32_t d = 0; d < kDims; ++d) values.insert(s.get(5, 5, k, d));
    EXPECT_GT(values.size(), size_t(8 * kDims) * 99 / 100);
    EXPECT_NE(CptSampler(2, kDims, 0, 1, SequenceScope::Image).get(0, 0, 0, 0), s.get(0, 0, 0, 0));
}

TEST(Sampler, CptPacketScopeSharesOneSequencePerPacket) {
    // Paper, Fig. 3 / introduction: one sequence per packet and sample.
    for (auto [pw, ph] : {std::pair{4u, 4u}, std::pair{8u, 2u}, std::pair{1u, 1u}}) {
        const CptSampler s(1, kDims, 0, 0, SequenceScope::Packet, pw, ph);
        std::set<std::vector<float>> sequences;
        for (uint32_t k = 0; k < 3; ++k)
            for (uint32_t py = 0; py < 16; ++py)
                for (uint32_t px = 0; px < 16; ++px) {
                    std::vector<float> v;
                    for (uint32_t d = 0; d < 40; ++d) v.push_back(s.get(px, py, k, d));
                    // Equal to the packet's first pixel...
                    const uint32_t x0 = px / pw * pw, y0 = py / ph * ph;
                    for (uint32_t d = 0; d < 40; ++d) ASSERT_EQ(v[d], s.get(x0, y0, k, d));
                    sequences.insert(v);
                }
        // ...and different for every (packet, sample).
        EXPECT_EQ(sequences.size(), size_t(3 * (16 / pw) * (16 / ph))) << pw << "x" << ph;
    }
}

// The pixels of a CPT packet read one stream per sample, so drivers draw
// each set once per packet (SharedSets): the first path that reads a set
// draws it into the store, the others copy it. Every path must still get
// exactly its own stream's numbers, whichever sets it reads, in any order,
// including sets beyond the store's.
TEST(Sampler, SharedSetsGiveEveryPathOfAPacketTheNumbersOfItsOwnStream) {
    const CptSampler s(3, kDims, 0, 0, SequenceScope::Packet, 4, 4);
    const uint32_t deepest = PathDims::count(12);
    ASSERT_GT(deepest, 4 * SharedSets::kSets);
    for (uint32_t k = 0; k < 4; ++k) {
        SharedSets shared;
        for (uint32_t p = 0; p < 16; ++p) {
            const uint32_t px = 4 + p % 4, py = 8 + p / 4;
            SampleStream st = s.stream(px, py, k);
            st.share(&shared);
            std::vector<uint32_t> dims;  // path p's reads: forwards, backwards, or a stride of 3
            for (uint32_t d = 0; d < deepest; ++d) dims.push_back(p % 3 == 2 ? (d * 3) % deepest : d);
            if (p % 3 == 1) std::reverse(dims.begin(), dims.end());
            if (p < 4) dims.resize(size_t(PathDims::count(p)));  // paths that end early
            for (uint32_t d : dims) ASSERT_EQ(st.get(d), s.get(px, py, k, d)) << "pixel " << p << " dim " << d;
        }
        EXPECT_EQ(shared.filled, (1u << SharedSets::kSets) - 1) << "every set the store covers went through it";
    }
    // Later paths copy, they do not draw again: a value planted in the store is what they read.
    SharedSets shared;
    SampleStream first = s.stream(0, 0, 9);
    first.share(&shared);
    (void)first.get(PathDims::bounce(1, PathDims::kBsdfU));
    const SobolSlot slot = sobol_slot(PathDims::bounce(1, PathDims::kBsdfU));
    ASSERT_TRUE(shared.filled & (1u << slot.set));
    shared.values[slot.set][slot.component] = 0.125f;
    SampleStream second = s.stream(3, 3, 9);
    second.share(&shared);
    EXPECT_EQ(second.get(PathDims::bounce(1, PathDims::kBsdfU)), 0.125f);
}

// Which pixels the drivers may treat as sharing a stream.
TEST(Sampler, OnlyCptPacketsAreSharedStreamBlocks) {
    SamplerConfig c;
    c.sequence = SampleSequence::OwenSobol;
    c.packet_width = 8;
    c.packet_height = 2;
    c.type = SamplerType::Cpt;
    const ImageSampler cpt(c, 0, 4);
    EXPECT_EQ(cpt.shared_stream_block().width, 8u);
    EXPECT_EQ(cpt.shared_stream_block().height, 2u);
    for (uint32_t y = 0; y < 4; ++y)
        for (uint32_t x = 0; x < 16; ++x)
            for (uint32_t d : {0u, 5u, 40u})
                ASSERT_EQ(cpt.get(x, y, 1, d), cpt.get(x / 8 * 8, y / 2 * 2, 1, d));
    c.scope = SequenceScope::Image;
    EXPECT_EQ(ImageSampler(c, 0, 4).shared_stream_block().width, 0u);
    c.scope = SequenceScope::Packet;
    for (SamplerType t : {SamplerType::Spt, SamplerType::Icpt}) {
        c.type = t;
        EXPECT_EQ(ImageSampler(c, 0, 4).shared_stream_block().width, 0u) << sampler_type_name(t);
    }
}

TEST(LatinSquares, EnumerationCountsAreKnown) {
    // Number of Latin squares of order n (OEIS A002860): 1, 2, 12, 576.
    EXPECT_EQ(latin_squares(1).enumerated_count(), 1u);
    EXPECT_EQ(latin_squares(2).enumerated_count(), 2u);
    EXPECT_EQ(latin_squares(3).enumerated_count(), 12u);
    EXPECT_EQ(latin_squares(4).enumerated_count(), 576u);
    EXPECT_EQ(latin_squares(5).enumerated_count(), 0u);  // isotope mode
}

TEST(Sampler, IcptSubsetsAreLatinHypercubesAndShareSequences) {
    for (uint32_t n : {1u, 2u, 3u, 4u, 5u, 8u})
    for (SequenceScope scope : {SequenceScope::Packet, SequenceScope::Image}) {
        const IcptSampler s(7, n, kDims, 0, 6, scope);
        ASSERT_EQ(s.block_size(), n);
        for (uint32_t k = 0; k < 6; ++k)
            for (uint32_t by = 0; by < 5; ++by)
                for (uint32_t bx = 0; bx < 5; ++bx) {
                    const auto p = partition(s, bx, by, k);
                    // Every subset: exactly one pixel per row and per column.
                    for (uint32_t i = 0; i < n; ++i) {
                        std::set<uint32_t> row, col;
                        for (uint32_t j = 0; j < n; ++j) {
                            ASSERT_LT(p[i * n + j], n);
                            row.insert(p[i * n + j]);
                            col.insert(p[j * n + i]);
                        }
                        ASSERT_EQ(row.size(), n) << "n=" << n << " row " << i;
                        ASSERT_EQ(col.size(), n) << "n=" << n << " col " << i;
                    }
                    // Same subset <=> same sequence, in this block and in any other
                    // block of the region (Packet: 2x2 blocks; Image: all).
                    const uint32_t dims[] = {0u, 1u, 4u, 9u, kDims - 1};
                    auto vec = [&](uint32_t x, uint32_t y) {
                        std::vector<float> v;
                        for (uint32_t d : dims) v.push_back(s.get(x, y, k, d));
                        return v;
                    };
                    const uint32_t ox = ((bx + 1) % 5) * n, oy = by * n;  // a pixel of another block
                    const bool same_region = s.region(ox, oy) == s.region(bx * n, by * n);
                    if (scope == SequenceScope::Image) ASSERT_TRUE(same_region);
                    else ASSERT_EQ(same_region, bx / 2 == ((bx + 1) % 5) / 2);
                    for (uint32_t a = 0; a < n * n; ++a) {
                        const auto va = vec(bx * n + a % n, by * n + a / n);
                        for (uint32_t b = 0; b < n * n; ++b) {
                            const auto vb = vec(bx * n + b % n, by * n + b / n);
                            ASSERT_EQ(p[a] == p[b], va == vb) << "n=" << n << " cells " << a << ", " << b;
                        }
                        ASSERT_EQ(same_region && s.subset(ox, oy, k) == p[a], vec(ox, oy) == va);
                    }
                }
    }
}

TEST(Sampler, IcptPartitionIsRerandomisedPerBlockAndSampleUniformly) {
    // n = 4 has 24 set partitions into 4 Latin-hypercube subsets (576 squares
    // / 4! labelings). Drawn uniformly, each should appear ~1/24 of the time,
    // both across blocks of one sample and across samples of one block.
    const IcptSampler s(11, 4, kDims, 0, 0);
    std::map<std::vector<uint32_t>, int> across_blocks, across_samples;
    const int draws = 24000;
    for (int i = 0; i < draws; ++i) {
        ++across_blocks[canonical(partition(s, uint32_t(i % 160), uint32_t(i / 160), 3))];
        ++across_samples[canonical(partition(s, 2, 5, uint32_t(i)))];
    }
    for (const auto* counts : {&across_blocks, &across_samples}) {
        ASSERT_EQ(counts->size(), 24u);
        for (const auto& [p, c] : *counts) {
            // Expected 1000, sd ~31: +-20% is > 6 sd.
            EXPECT_GT(c, 800);
            EXPECT_LT(c, 1200);
        }
    }
    // Which sequence a given pixel gets is uniform too.
    std::array<int, 4> seq{};
    for (int i = 0; i < draws; ++i) ++seq[s.subset(1, 2, uint32_t(i))];
    for (int c : seq) EXPECT_NEAR(c, draws / 4, draws / 4 / 5);
}

TEST(Sampler, EveryPixelSeesUniformIndependentSamples) {
    // Unbiasedness rests on each pixel's u being uniform in each sample and
    // independent across samples. Moments of a uniform: mean 1/2, var 1/12;
    // lag-1 correlation between consecutive samples 0.
    const int n = 20000;
    for (SamplerType t : {SamplerType::Spt, SamplerType::Cpt, SamplerType::Icpt})
    for (SequenceScope scope : {SequenceScope::Packet, SequenceScope::Image}) {
        SamplerConfig c;
        c.type = t;
        c.seed = 5;
        c.scope = scope;
        const ImageSampler s(c, 0, uint32_t(n));
        for (uint32_t d : {0u, 4u, 9u}) {
            double sum = 0, sum2 = 0, lag = 0;
            float prev = s.get(6, 9, 0, d);
            for (int k = 0; k < n; ++k) {
                const float v = s.get(6, 9, uint32_t(k), d);
                sum += v;
                sum2 += double(v) * v;
                if (k > 0) lag += (double(v) - 0.5) * (double(prev) - 0.5);
                prev = v;
            }
            const double mean = sum / n, var = sum2 / n - mean * mean;
            // sd of the mean: sqrt(1/12/n) = 0.002; of the variance ~0.0006; of the lag corr ~0.007.
            EXPECT_NEAR(mean, 0.5, 0.01) << sampler_type_name(t) << " dim " << d;
            EXPECT_NEAR(var, 1.0 / 12.0, 0.004) << sampler_type_name(t);
            EXPECT_NEAR(lag / (n - 1) * 12.0, 0.0, 0.04) << sampler_type_name(t);
        }
    }
}

TEST(Sampler, ImageSamplerDispatchesAndPathSamplerReadsTheSameStream) {
    SamplerConfig c;
    c.sequence = SampleSequence::OwenSobol;  // the samplers' own default, which the references below use
    c.seed = 8;
    c.packet_width = 4;
    c.packet_height = 4;
    c.type = SamplerType::Cpt;
    const ImageSampler cpt(c, 0, 4);
    c.type = SamplerType::Icpt;
    const ImageSampler icpt(c, 0, 4);
    c.type = SamplerType::Spt;
    const ImageSampler spt(c, 0, 4);
    const CptSampler cpt_ref(8, kDims, 0, 0);
    const IcptSampler icpt_ref(8, 4, kDims, 0, 0);
    const SptSampler spt_ref(8);
    for (uint32_t k = 0; k < 6; ++k)
        for (uint32_t d = 0; d < 30; ++d) {
            EXPECT_EQ(cpt.get(3, 5, k, d), cpt_ref.get(3, 5, k, d));
            EXPECT_EQ(icpt.get(3, 5, k, d), icpt_ref.get(3, 5, k, d));
            EXPECT_EQ(spt.get(3, 5, k, d), spt_ref.get(3, 5, k, d));
            EXPECT_EQ(PathSampler(icpt, 3, 5, k).get(d), icpt_ref.get(3, 5, k, d));
        }
    // Non-square packets: ICPT blocks use the shorter side.
    c.type = SamplerType::Icpt;
    c.packet_width = 8;
    c.packet_height = 3;
    EXPECT_EQ(ImageSampler::icpt_block(c), 3u);
}

TEST(Sampler, AutoIsIcptWhenDisplayedAndCptForFinalRenders) {
    // docs/results/efficiency_vs_cycles.md: CPT has the least error per
    // second for final renders; ICPT hides structured noise while passes show.
    EXPECT_EQ(resolve_sampler_type(SamplerType::Auto, true), SamplerType::Icpt);
    EXPECT_EQ(resolve_sampler_type(SamplerType::Auto, false), SamplerType::Cpt);
    // Denoising wants noise independent per pixel (docs/results/denoise.md).
    EXPECT_EQ(resolve_sampler_type(SamplerType::Auto, false, true), SamplerType::Spt);
    EXPECT_EQ(resolve_sampler_type(SamplerType::Auto, true, true), SamplerType::Spt);
    EXPECT_EQ(resolve_sampler_type(SamplerType::Cpt, false, true), SamplerType::Cpt);
    for (SamplerType t : {SamplerType::Spt, SamplerType::Cpt, SamplerType::Icpt}) {
        EXPECT_EQ(resolve_sampler_type(t, true), t);
        EXPECT_EQ(resolve_sampler_type(t, false), t);
        EXPECT_EQ(parse_sampler_type(sampler_type_name(t)), t);
    }
    EXPECT_FALSE(parse_sampler_type("SPT").has_value());
}
