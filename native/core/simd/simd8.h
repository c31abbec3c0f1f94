// Eight lanes (AVX2): vbool8, vint8, vfloat8. See ../simd.h for the contract.
#pragma once

#include <immintrin.h>

#include <algorithm>
#include <cstdint>

#include "simd4.h"

namespace coherent::simd {

template <int N>
struct vbool;
template <int N>
struct vint;
template <int N>
struct vfloat;

using vbool8 = vbool<8>;
using vint8 = vint<8>;
using vfloat8 = vfloat<8>;

template <>
struct vbool<8> {
    __m256 m;  // lane i is true where its sign bit is set

    vbool() = default;
    explicit vbool(__m256 x) : m(x) {}
    explicit vbool(__m256i x) : m(_mm256_castsi256_ps(x)) {}
    // The lanes of an int mask (bit i = lane i), every bit of a lane set.
    static vbool from_bits(int bits) {
        const __m256i lanes = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        return vbool(_mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(bits), lanes), lanes));
    }
};

inline vbool8 operator&(vbool8 a, vbool8 b) { return vbool8(_mm256_and_ps(a.m, b.m)); }
inline vbool8 operator|(vbool8 a, vbool8 b) { return vbool8(_mm256_or_ps(a.m, b.m)); }
inline vbool8 operator^(vbool8 a, vbool8 b) { return vbool8(_mm256_xor_ps(a.m, b.m)); }
inline vbool8 operator~(vbool8 a) {
    return vbool8(_mm256_andnot_ps(a.m, _mm256_castsi256_ps(_mm256_set1_epi32(-1))));
}
// a and not b.
inline vbool8 andnot(vbool8 a, vbool8 b) { return vbool8(_mm256_andnot_ps(b.m, a.m)); }
// Bit i = lane i.
inline int movemask(vbool8 a) { return _mm256_movemask_ps(a.m); }
inline bool any(vbool8 a) { return movemask(a) != 0; }
inline bool all(vbool8 a) { return movemask(a) == 0xff; }
inline bool none(vbool8 a) { return movemask(a) == 0; }
inline int popcount(vbool8 a) { return __builtin_popcount(static_cast<unsigned>(movemask(a))); }

template <>
struct vint<8> {
    __m256i v;

    vint() = default;
    explicit vint(__m256i x) : v(x) {}
    vint(int32_t x) : v(_mm256_set1_epi32(x)) {}  // broadcast
    static vint zero() { return vint(_mm256_setzero_si256()); }
    static vint load(const int32_t* p) { return vint(_mm256_load_si256(reinterpret_cast<const __m256i*>(p))); }
    static vint load(const uint32_t* p) { return vint(_mm256_load_si256(reinterpret_cast<const __m256i*>(p))); }
    // The same 32 bits as a vbool (lanes of 0 / -1 are false / true).
    vbool8 as_bool() const { return vbool8(v); }
};

inline void store(int32_t* p, vint8 a) { _mm256_store_si256(reinterpret_cast<__m256i*>(p), a.v); }
inline void store(uint32_t* p, vint8 a) { _mm256_store_si256(reinterpret_cast<__m256i*>(p), a.v); }
// Stores the lanes of `m` only.
inline void store(vbool8 m, int32_t* p, vint8 a) { _mm256_maskstore_epi32(p, _mm256_castps_si256(m.m), a.v); }
inline void store(vbool8 m, uint32_t* p, vint8 a) {
    _mm256_maskstore_epi32(reinterpret_cast<int*>(p), _mm256_castps_si256(m.m), a.v);
}

inline vint8 operator&(vint8 a, vint8 b) { return vint8(_mm256_and_si256(a.v, b.v)); }
inline vint8 operator|(vint8 a, vint8 b) { return vint8(_mm256_or_si256(a.v, b.v)); }
inline vint8 operator<<(vint8 a, int bits) { return vint8(_mm256_slli_epi32(a.v, bits)); }
inline vbool8 operator==(vint8 a, vint8 b) { return vbool8(_mm256_cmpeq_epi32(a.v, b.v)); }
// Lane-wise minimum of the lanes read as unsigned.
inline vint8 min_u32(vint8 a, vint8 b) { return vint8(_mm256_min_epu32(a.v, b.v)); }
// Lanes of t where m is true, of f elsewhere.
inline vint8 select(vbool8 m, vint8 t, vint8 f) {
    return vint8(_mm256_castps_si256(_mm256_blendv_ps(_mm256_castsi256_ps(f.v), _mm256_castsi256_ps(t.v), m.m)));
}

template <>
struct vfloat<8> {
    __m256 v;

    vfloat() = default;
    explicit vfloat(__m256 x) : v(x) {}
    vfloat(float x) : v(_mm256_set1_ps(x)) {}  // broadcast
    // Both halves from 4-lane vectors (lanes 0-3 from lo).
    vfloat(vfloat4 lo, vfloat4 hi) : v(_mm256_set_m128(hi.v, lo.v)) {}
    static vfloat zero() { return vfloat(_mm256_setzero_ps()); }
    static vfloat load(const float* p) { return vfloat(_mm256_load_ps(p)); }  // 32-byte aligned
    static vfloat loadu(const float* p) { return vfloat(_mm256_loadu_ps(p)); }
};

inline void store(float* p, vfloat8 a) { _mm256_store_ps(p, a.v); }  // 32-byte aligned
inline void storeu(float* p, vfloat8 a) { _mm256_storeu_ps(p, a.v); }
// Stores the lanes of `m` only.
inline void store(vbool8 m, float* p, vfloat8 a) { _mm256_maskstore_ps(p, _mm256_castps_si256(m.m), a.v); }

inline vfloat8 operator+(vfloat8 a, vfloat8 b) { return vfloat8(_mm256_add_ps(a.v, b.v)); }
inline vfloat8 operator-(vfloat8 a, vfloat8 b) { return vfloat8(_mm256_sub_ps(a.v, b.v)); }
inline vfloat8 operator*(vfloat8 a, vfloat8 b) { return vfloat8(_mm256_mul_ps(a.v, b.v)); }
inline vfloat8 operator/(vfloat8 a, vfloat8 b) { return vfloat8(_mm256_div_ps(a.v, b.v)); }
// a * b - c with one rounding.
inline vfloat8 fmsub(vfloat8 a, vfloat8 b, vfloat8 c) { return vfloat8(_mm256_fmsub_ps(a.v, b.v, c.v)); }
// b when either is NaN (see ../simd.h).
inline vfloat8 min(vfloat8 a, vfloat8 b) { return vfloat8(_mm256_min_ps(a.v, b.v)); }
inline vfloat8 max(vfloat8 a, vfloat8 b) { return vfloat8(_mm256_max_ps(a.v, b.v)); }
inline vfloat8 abs(vfloat8 a) { return vfloat8(_mm256_andnot_ps(_mm256_set1_ps(-0.0f), a.v)); }

inline vbool8 operator<(vfloat8 a, vfloat8 b) { return vbool8(_mm256_cmp_ps(a.v, b.v, _CMP_LT_OQ)); }
inline vbool8 operator<=(vfloat8 a, vfloat8 b) { return vbool8(_mm256_cmp_ps(a.v, b.v, _CMP_LE_OQ)); }
inline vbool8 operator>(vfloat8 a, vfloat8 b) { return vbool8(_mm256_cmp_ps(a.v, b.v, _CMP_GT_OQ)); }
inline vbool8 operator>=(vfloat8 a, vfloat8 b) { return vbool8(_mm256_cmp_ps(a.v, b.v, _CMP_GE_OQ)); }
inline vbool8 operator==(vfloat8 a, vfloat8 b) { return vbool8(_mm256_cmp_ps(a.v, b.v, _CMP_EQ_OQ)); }
inline vbool8 operator!=(vfloat8 a, vfloat8 b) { return vbool8(_mm256_cmp_ps(a.v, b.v, _CMP_NEQ_UQ)); }
// Lanes where a is finite (neither infinite nor NaN).
inline vbool8 isfinite(vfloat8 a) { return abs(a) < vfloat8(__builtin_inff()); }
// Lanes whose sign bit is set (-0 and negative NaNs included).
inline vbool8 signbit(vfloat8 a) { return vbool8(a.v); }

// Lanes of t where m is true, of f elsewhere.
inline vfloat8 select(vbool8 m, vfloat8 t, vfloat8 f) { return vfloat8(_mm256_blendv_ps(f.v, t.v, m.m)); }
// Lane i of `table`'s 128-bit half that holds lane i, picked by idx[i] in
// 0..3: with both halves equal, a per-lane choice among four values.
inline vfloat8 permute_in_lanes(vfloat8 table, vint8 idx) { return vfloat8(_mm256_permutevar_ps(table.v, idx.v)); }

// Smallest / largest lane, folded left to right with std::min / std::max.
inline float reduce_min(vfloat8 a) {
    alignas(32) float x[8];
    store(x, a);
    float m = x[0];
    for (int i = 1; i < 8; ++i) m = std::min(m, x[i]);
    return m;
}
inline float reduce_max(vfloat8 a) {
    alignas(32) float x[8];
    store(x, a);
    float m = x[0];
    for (int i = 1; i < 8; ++i) m = std::max(m, x[i]);
    return m;
}

}  // namespace coherent::simd
