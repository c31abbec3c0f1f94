// Four lanes (SSE): vbool4, vint4, vfloat4. See ../simd.h for the contract.
#pragma once

#include <immintrin.h>

#include <cstdint>

namespace coherent::simd {

template <int N>
struct vbool;
template <int N>
struct vint;
template <int N>
struct vfloat;

using vbool4 = vbool<4>;
using vint4 = vint<4>;
using vfloat4 = vfloat<4>;

template <>
struct vbool<4> {
    __m128 m;  // lane i is true where its sign bit is set

    vbool() = default;
    explicit vbool(__m128 x) : m(x) {}
    explicit vbool(__m128i x) : m(_mm_castsi128_ps(x)) {}
    vbool(bool a, bool b, bool c, bool d)
        : m(_mm_castsi128_ps(_mm_setr_epi32(a ? -1 : 0, b ? -1 : 0, c ? -1 : 0, d ? -1 : 0))) {}
};

inline vbool4 operator&(vbool4 a, vbool4 b) { return vbool4(_mm_and_ps(a.m, b.m)); }
inline vbool4 operator|(vbool4 a, vbool4 b) { return vbool4(_mm_or_ps(a.m, b.m)); }
inline vbool4 operator^(vbool4 a, vbool4 b) { return vbool4(_mm_xor_ps(a.m, b.m)); }
inline vbool4 operator~(vbool4 a) { return vbool4(_mm_andnot_ps(a.m, _mm_castsi128_ps(_mm_set1_epi32(-1)))); }
// a and not b.
inline vbool4 andnot(vbool4 a, vbool4 b) { return vbool4(_mm_andnot_ps(b.m, a.m)); }
// Bit i = lane i.
inline int movemask(vbool4 a) { return _mm_movemask_ps(a.m); }
inline bool any(vbool4 a) { return movemask(a) != 0; }
inline bool all(vbool4 a) { return movemask(a) == 0xf; }
inline bool none(vbool4 a) { return movemask(a) == 0; }
inline int popcount(vbool4 a) { return __builtin_popcount(static_cast<unsigned>(movemask(a))); }

template <>
struct vint<4> {
    __m128i v;

    vint() = default;
    explicit vint(__m128i x) : v(x) {}
    vint(int32_t x) : v(_mm_set1_epi32(x)) {}  // broadcast
    static vint load(const int32_t* p) { return vint(_mm_load_si128(reinterpret_cast<const __m128i*>(p))); }
    static vint load(const uint32_t* p) { return vint(_mm_load_si128(reinterpret_cast<const __m128i*>(p))); }
};

inline vbool4 operator==(vint4 a, vint4 b) { return vbool4(_mm_cmpeq_epi32(a.v, b.v)); }

template <>
struct vfloat<4> {
    __m128 v;

    vfloat() = default;
    explicit vfloat(__m128 x) : v(x) {}
    vfloat(float x) : v(_mm_set1_ps(x)) {}  // broadcast
    vfloat(float a, float b, float c, float d) : v(_mm_setr_ps(a, b, c, d)) {}
    static vfloat zero() { return vfloat(_mm_setzero_ps()); }
    static vfloat load(const float* p) { return vfloat(_mm_load_ps(p)); }  // 16-byte aligned
    static vfloat loadu(const float* p) { return vfloat(_mm_loadu_ps(p)); }
};

inline void store(float* p, vfloat4 a) { _mm_store_ps(p, a.v); }  // 16-byte aligned
inline void storeu(float* p, vfloat4 a) { _mm_storeu_ps(p, a.v); }

inline vfloat4 operator+(vfloat4 a, vfloat4 b) { return vfloat4(_mm_add_ps(a.v, b.v)); }
inline vfloat4 operator-(vfloat4 a, vfloat4 b) { return vfloat4(_mm_sub_ps(a.v, b.v)); }
inline vfloat4 operator*(vfloat4 a, vfloat4 b) { return vfloat4(_mm_mul_ps(a.v, b.v)); }
inline vfloat4 operator/(vfloat4 a, vfloat4 b) { return vfloat4(_mm_div_ps(a.v, b.v)); }
// a * b - c with one rounding.
inline vfloat4 fmsub(vfloat4 a, vfloat4 b, vfloat4 c) { return vfloat4(_mm_fmsub_ps(a.v, b.v, c.v)); }
// b when either is NaN (see ../simd.h).
inline vfloat4 min(vfloat4 a, vfloat4 b) { return vfloat4(_mm_min_ps(a.v, b.v)); }
inline vfloat4 max(vfloat4 a, vfloat4 b) { return vfloat4(_mm_max_ps(a.v, b.v)); }
inline vfloat4 abs(vfloat4 a) { return vfloat4(_mm_andnot_ps(_mm_set1_ps(-0.0f), a.v)); }

inline vbool4 operator<(vfloat4 a, vfloat4 b) { return vbool4(_mm_cmplt_ps(a.v, b.v)); }
inline vbool4 operator<=(vfloat4 a, vfloat4 b) { return vbool4(_mm_cmple_ps(a.v, b.v)); }
inline vbool4 operator>(vfloat4 a, vfloat4 b) { return vbool4(_mm_cmpgt_ps(a.v, b.v)); }
inline vbool4 operator>=(vfloat4 a, vfloat4 b) { return vbool4(_mm_cmpge_ps(a.v, b.v)); }
inline vbool4 operator==(vfloat4 a, vfloat4 b) { return vbool4(_mm_cmpeq_ps(a.v, b.v)); }
inline vbool4 operator!=(vfloat4 a, vfloat4 b) { return vbool4(_mm_cmpneq_ps(a.v, b.v)); }
// Lanes whose sign bit is set (-0 and negative NaNs included).
inline vbool4 signbit(vfloat4 a) { return vbool4(a.v); }

// Lanes of t where m is true, of f elsewhere.
inline vfloat4 select(vbool4 m, vfloat4 t, vfloat4 f) { return vfloat4(_mm_blendv_ps(f.v, t.v, m.m)); }

}  // namespace coherent::simd
