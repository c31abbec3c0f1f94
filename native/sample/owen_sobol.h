// Owen-scrambled Sobol points, padded in 4D sets (Burley 2020, "Practical
// Hash-based Owen Scrambling", JCGT 9(4); the layout Cycles and pbrt-v4's
// PaddedSobolSampler use).
//
// One "set" is the first four Sobol dimensions (van der Corput and the
// Joe-Kuo polynomials x+1, x^2+x+1, x^3+x+1) of a shuffled sample index.
// Every set has its own seed, from which it derives
//   * a shuffle of the sample index: a nested uniform (Owen) scramble of the
//     index's bits read from the least significant one. It maps the first
//     2^m indices onto one aligned block of 2^m Sobol indices, and every such
//     block of a (0,2)-sequence is again a (0,m,2)-net, so the shuffle keeps
//     stratification while decorrelating the sets from each other;
//   * an independent Owen scramble of each of its four components. Owen
//     scrambling keeps every elementary interval's point count, so the
//     (0,2)-property survives it, and makes each point uniform on [0,1)^4:
//     estimates are unbiased.
// Components 0 and 1 form a (0,2)-sequence, so a 2D decision reads them;
// every component alone is a (0,1)-sequence (stratified in 1D), which is what
// 1D decisions in components 2 and 3 get. No other pair of the four is (0,2)
// (tests/native/test_sobol.cpp checks both facts).
#pragma once

#include <array>
#include <cstdint>

#if defined(__SSE4_1__)
#include <immintrin.h>
#endif

namespace coherent {

namespace owen_sobol_detail {

constexpr uint32_t kComponents = 4;

// Generator matrix columns: column b is the point of index 2^b.
constexpr std::array<std::array<uint32_t, 32>, kComponents> sobol_columns() {
    // Joe & Kuo (2008) primitive polynomials and initial direction numbers
    // for dimensions 2..4 (degree s, coefficients a, m_1..m_s).
    struct Poly {
        uint32_t s, a, m[3];
    };
    constexpr Poly polys[3] = {{1, 0, {1, 0, 0}}, {2, 1, {1, 3, 0}}, {3, 1, {1, 3, 1}}};
    std::array<std::array<uint32_t, 32>, kComponents> cols{};
    for (uint32_t b = 0; b < 32; ++b) cols[0][b] = 1u << (31 - b);  // van der Corput
    for (uint32_t d = 1; d < kComponents; ++d) {
        const Poly& p = polys[d - 1];
        uint32_t v[33] = {};  // v[k], k = 1..32: direction numbers as 0.b1 b2 ... (MSB first)
        for (uint32_t k = 1; k <= p.s; ++k) v[k] = p.m[k - 1] << (32 - k);
        for (uint32_t k = p.s + 1; k <= 32; ++k) {
            v[k] = v[k - p.s] ^ (v[k - p.s] >> p.s);
            for (uint32_t i = 1; i < p.s; ++i)
                if ((p.a >> (p.s - 1 - i)) & 1u) v[k] ^= v[k - i];
        }
        for (uint32_t b = 0; b < 32; ++b) cols[d][b] = v[b + 1];
    }
    return cols;
}

constexpr uint32_t reverse_bits32(uint32_t x) {
    x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
    x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
    x = ((x >> 4) & 0x0f0f0f0fu) | ((x & 0x0f0f0f0fu) << 4);
#if defined(__GNUC__)
    if (!__builtin_is_constant_evaluated()) return __builtin_bswap32(x);  // one instruction for the byte order
#endif
    x = ((x >> 8) & 0x00ff00ffu) | ((x & 0x00ff00ffu) << 8);
    return (x >> 16) | (x << 16);
}

// The matrix-vector product over GF(2) a byte at a time, in the bit-reversed
// domain where Owen scrambling works: for r = reverse(index),
// reverse(sobol(index)) = XOR over bytes j of rev[j][byte j of r][c].
// The four components of one byte sit side by side, so one 16-byte load
// serves a whole set (owen_sobol_set4).
struct ByteTables {
    alignas(16) uint32_t rev[4][256][kComponents];
};

constexpr ByteTables make_byte_tables() {
    constexpr auto cols = sobol_columns();
    ByteTables t{};
    for (uint32_t c = 0; c < kComponents; ++c)
        for (uint32_t j = 0; j < 4; ++j)
            for (uint32_t x = 0; x < 256; ++x) {
                const uint32_t index = reverse_bits32(x << (8 * j));
                uint32_t r = 0;
                for (uint32_t b = 0; b < 32; ++b)
                    if ((index >> b) & 1u) r ^= cols[c][b];
                t.rev[j][x][c] = reverse_bits32(r);
            }
    return t;
}

inline constexpr ByteTables kTables = make_byte_tables();

inline uint32_t reversed_sobol(uint32_t reversed_index, uint32_t c) {
    const auto& t = kTables.rev;
    const uint32_t r = reversed_index;
    return t[0][r & 0xffu][c] ^ t[1][(r >> 8) & 0xffu][c] ^ t[2][(r >> 16) & 0xffu][c] ^ t[3][r >> 24][c];
}

// The same for indices below 2^24 (reversed: low byte zero), one load less.
inline uint32_t reversed_sobol24(uint32_t reversed_index, uint32_t c) {
    const auto& t = kTables.rev;
    const uint32_t r = reversed_index;
    return t[1][(r >> 8) & 0xffu][c] ^ t[2][(r >> 16) & 0xffu][c] ^ t[3][r >> 24][c];
}

constexpr uint32_t kSeedSalts[kComponents + 1] = {0x39d8bdd3u, 0x3a8f2c6cu, 0x9fb4b3c1u, 0x2c1d9b43u, 0xc2c1a055u};

}  // namespace owen_sobol_detail

using owen_sobol_detail::reverse_bits32;

// Unscrambled Sobol point `index` in component `c` (< 4) as a 32-bit fraction.
inline uint32_t sobol_u32(uint32_t index, uint32_t c) {
    return reverse_bits32(owen_sobol_detail::reversed_sobol(reverse_bits32(index), c));
}

// A hash in which output bit i is input bit i XOR a function of the bits
// below i only (each step is an addition, an odd multiplication, or
// x ^= x * even): on bit-reversed values that is exactly a nested
// permutation of the digits, i.e. an Owen scramble (Laine & Karras 2011; these
// constants from N. Vegdahl's improved variant of Burley's hash).
inline uint32_t owen_hash_reversed(uint32_t x, uint32_t seed) {
    x ^= x * 0x3d20adeau;
    x += seed;
    x *= (seed >> 16) | 1u;
    x ^= x * 0x05526c56u;
    x ^= x * 0x53a22864u;
    return x;
}

// Owen scramble of a 32-bit fraction (most significant digit first).
inline uint32_t owen_scramble(uint32_t x, uint32_t seed) {
    return reverse_bits32(owen_hash_reversed(reverse_bits32(x), seed));
}

// Burley's index shuffle: the same scramble applied to the index's bits, so
// bit i of the result depends on the index's bits >= i only and the first
// 2^m indices go to one aligned block of 2^m.
inline uint32_t shuffle_index(uint32_t index, uint32_t seed) { return owen_scramble(index, seed); }

// Seeds of a set's index shuffle and of its four components.
inline uint32_t set_component_seed(uint32_t set_seed, uint32_t c) {
    uint32_t h = (set_seed ^ owen_sobol_detail::kSeedSalts[c]) * 0x9e3779b1u;
    h ^= h >> 16;
    h *= 0x85ebca6bu;
    return h ^ (h >> 13);
}

// The two steps of a set's point, split so that a stream shuffles the index
// once for the set's four components. Indices are bit-reversed (a stream
// reverses its index once for all sets): shuffle, Sobol and scramble all work
// in the reversed domain, so one reversal remains per value.
// Indices are below 2^24 (16.7 M points per sequence, twice
// RenderSettings' largest spp as a stream takes every second sample): the
// shuffle keeps the low 24 bits of the index, a scramble of [0, 2^24) that
// still maps the first 2^m indices to an aligned block, and Sobol then needs
// three byte tables, not four.
inline uint32_t shuffle_reversed_index(uint32_t reversed_index, uint32_t set_seed) {
    return owen_hash_reversed(reversed_index, set_component_seed(set_seed, owen_sobol_detail::kComponents)) &
           0xffffff00u;
}

// Component c of the set's point at a shuffled reversed index, as a 32-bit fraction.
inline uint32_t owen_sobol_shuffled(uint32_t shuffled_reversed_index, uint32_t c, uint32_t set_seed) {
    return reverse_bits32(owen_hash_reversed(owen_sobol_detail::reversed_sobol24(shuffled_reversed_index, c),
                                             set_component_seed(set_seed, c)));
}

// All four components of the set's point at a shuffled reversed index, as
// floats in [0, 1): float(owen_sobol_shuffled(.., c, ..) >> 8) * 2^-24 for
// c = 0..3, bit for bit. A path reads every component of the sets it
// touches, and drawing them in four SSE lanes (one table load per byte, the
// hashes and the bit reversal lane-parallel) costs about what one component
// costs in scalar code.
inline void owen_sobol_set4(uint32_t shuffled_reversed_index, uint32_t set_seed, float out[4]) {
#if defined(__SSE4_1__)
    const auto& t = owen_sobol_detail::kTables.rev;
    const uint32_t r = shuffled_reversed_index;
    auto row = [&](uint32_t j, uint32_t byte) { return _mm_load_si128(reinterpret_cast<const __m128i*>(t[j][byte])); };
    __m128i x = _mm_xor_si128(_mm_xor_si128(row(1, (r >> 8) & 0xffu), row(2, (r >> 16) & 0xffu)), row(3, r >> 24));
    // set_component_seed, lane c = component c.
    const __m128i salts = _mm_loadu_si128(reinterpret_cast<const __m128i*>(owen_sobol_detail::kSeedSalts));
    __m128i h = _mm_mullo_epi32(_mm_xor_si128(_mm_set1_epi32(int(set_seed)), salts), _mm_set1_epi32(int(0x9e3779b1u)));
    h = _mm_xor_si128(h, _mm_srli_epi32(h, 16));
    h = _mm_mullo_epi32(h, _mm_set1_epi32(int(0x85ebca6bu)));
    const __m128i seed = _mm_xor_si128(h, _mm_srli_epi32(h, 13));
    // owen_hash_reversed.
    x = _mm_xor_si128(x, _mm_mullo_epi32(x, _mm_set1_epi32(0x3d20adea)));
    x = _mm_add_epi32(x, seed);
    x = _mm_mullo_epi32(x, _mm_or_si128(_mm_srli_epi32(seed, 16), _mm_set1_epi32(1)));
    x = _mm_xor_si128(x, _mm_mullo_epi32(x, _mm_set1_epi32(0x05526c56)));
    x = _mm_xor_si128(x, _mm_mullo_epi32(x, _mm_set1_epi32(0x53a22864)));
    // reverse_bits32: bytes reversed within each lane, bits within each byte by nibble lookups.
    x = _mm_shuffle_epi8(x, _mm_setr_epi8(3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12));
    const __m128i nibble_rev = _mm_setr_epi8(0, 8, 4, 12, 2, 10, 6, 14, 1, 9, 5, 13, 3, 11, 7, 15);
    const __m128i low = _mm_set1_epi8(0x0f);
    const __m128i lo = _mm_shuffle_epi8(nibble_rev, _mm_and_si128(x, low));
    const __m128i hi = _mm_shuffle_epi8(nibble_rev, _mm_and_si128(_mm_srli_epi16(x, 4), low));
    x = _mm_or_si128(_mm_slli_epi16(lo, 4), hi);
    _mm_storeu_ps(out, _mm_mul_ps(_mm_cvtepi32_ps(_mm_srli_epi32(x, 8)), _mm_set1_ps(0x1p-24f)));
#else
    for (uint32_t c = 0; c < 4; ++c)
        out[c] = float(owen_sobol_shuffled(shuffled_reversed_index, c, set_seed) >> 8) * 0x1p-24f;
#endif
}

// Component c of sample `index` of the scrambled set with `set_seed`.
inline uint32_t owen_sobol_u32(uint32_t index, uint32_t c, uint32_t set_seed) {
    return owen_sobol_shuffled(shuffle_reversed_index(reverse_bits32(index), set_seed), c, set_seed);
}

}  // namespace coherent
