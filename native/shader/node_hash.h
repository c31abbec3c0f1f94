// Cycles' hashes (intern/cycles/util/hash.h): Bob Jenkins' lookup3 over the
// bit patterns of integer or float coordinates. The procedural textures use
// them for their random gradients, feature points and cell colours, so they
// must be bit-for-bit Cycles' to give Cycles' patterns.
#pragma once

#include <cstdint>
#include <cmath>
#include <cstring>

#include "../core/vec.h"

namespace coherent::shader {

namespace lookup3 {

inline uint32_t rot(uint32_t x, int k) { return (x << k) | (x >> (32 - k)); }

inline void mix(uint32_t& a, uint32_t& b, uint32_t& c) {
    a -= c; a ^= rot(c, 4); c += b;
    b -= a; b ^= rot(a, 6); a += c;
    c -= b; c ^= rot(b, 8); b += a;
    a -= c; a ^= rot(c, 16); c += b;
    b -= a; b ^= rot(a, 19); a += c;
    c -= b; c ^= rot(b, 4); b += a;
}

inline void final(uint32_t& a, uint32_t& b, uint32_t& c) {
    c ^= b; c -= rot(b, 14);
    a ^= c; a -= rot(c, 11);
    b ^= a; b -= rot(a, 25);
    c ^= b; c -= rot(b, 16);
    a ^= c; a -= rot(c, 4);
    b ^= a; b -= rot(a, 14);
    c ^= b; c -= rot(b, 24);
}

// The initial state for `n` 32-bit words (lookup3's hashword with seed 13).
constexpr uint32_t start(uint32_t n) { return 0xdeadbeefu + (n << 2) + 13u; }

}  // namespace lookup3

inline uint32_t hash_uint(uint32_t kx) {
    uint32_t a = lookup3::start(1), b = a, c = a;
    a += kx;
    lookup3::final(a, b, c);
    return c;
}

inline uint32_t hash_uint2(uint32_t kx, uint32_t ky) {
    uint32_t a = lookup3::start(2), b = a, c = a;
    b += ky;
    a += kx;
    lookup3::final(a, b, c);
    return c;
}

inline uint32_t hash_uint3(uint32_t kx, uint32_t ky, uint32_t kz) {
    uint32_t a = lookup3::start(3), b = a, c = a;
    c += kz;
    b += ky;
    a += kx;
    lookup3::final(a, b, c);
    return c;
}

inline uint32_t hash_uint4(uint32_t kx, uint32_t ky, uint32_t kz, uint32_t kw) {
    uint32_t a = lookup3::start(4), b = a, c = a;
    a += kx;
    b += ky;
    c += kz;
    lookup3::mix(a, b, c);
    a += kw;
    lookup3::final(a, b, c);
    return c;
}

// [0, 2^32) -> [0, 1], as Cycles' uint_to_float_incl.
inline float uint_to_unit(uint32_t n) { return float(n) * (1.0f / float(0xFFFFFFFFu)); }

inline uint32_t bits_of(float f) {
    uint32_t u;
    std::memcpy(&u, &f, sizeof(u));
    return u;
}

// Floats hash by their bit patterns: -0 and +0 differ, as in Cycles.
inline float hash_to_float(float x) { return uint_to_unit(hash_uint(bits_of(x))); }
inline float hash_to_float(float x, float y) { return uint_to_unit(hash_uint2(bits_of(x), bits_of(y))); }
inline float hash_to_float(float x, float y, float z) {
    return uint_to_unit(hash_uint3(bits_of(x), bits_of(y), bits_of(z)));
}
inline float hash_to_float(float x, float y, float z, float w) {
    return uint_to_unit(hash_uint4(bits_of(x), bits_of(y), bits_of(z), bits_of(w)));
}

// A point of a 1- to 4-dimensional texture space (Cycles' float, float2,
// float3, float4), with the component-wise arithmetic the textures use.
template <int N>
struct Pt {
    float v[N];
    float& operator[](int i) { return v[i]; }
    float operator[](int i) const { return v[i]; }
};
template <int N> Pt<N> operator+(Pt<N> a, const Pt<N>& b) { for (int i = 0; i < N; ++i) a.v[i] += b.v[i]; return a; }
template <int N> Pt<N> operator-(Pt<N> a, const Pt<N>& b) { for (int i = 0; i < N; ++i) a.v[i] -= b.v[i]; return a; }
template <int N> Pt<N> operator*(Pt<N> a, float s) { for (int i = 0; i < N; ++i) a.v[i] *= s; return a; }
template <int N> Pt<N> operator*(float s, Pt<N> a) { return a * s; }
template <int N> Pt<N> operator/(Pt<N> a, float s) { for (int i = 0; i < N; ++i) a.v[i] /= s; return a; }
template <int N> Pt<N> splat(float s) { Pt<N> p; for (int i = 0; i < N; ++i) p.v[i] = s; return p; }
template <int N> Pt<N> floor(Pt<N> a) { for (int i = 0; i < N; ++i) a.v[i] = std::floor(a.v[i]); return a; }
template <int N> float dot(const Pt<N>& a, const Pt<N>& b) {
    float s = a.v[0] * b.v[0];
    for (int i = 1; i < N; ++i) s += a.v[i] * b.v[i];
    return s;
}
// Cycles' mix(a, b, t) = a + t (b - a).
template <int N> Pt<N> mix(const Pt<N>& a, const Pt<N>& b, float t) { return a + (b - a) * t; }
inline float mix(float a, float b, float t) { return a + t * (b - a); }
// The same with one rounding, as Cycles' x86 CPU kernels (AVX2, built with
// FMA contraction) evaluate it in Perlin noise.
inline float mix_fused(float a, float b, float t) { return std::fma(t, b - a, a); }
inline Vec3f mix(const Vec3f& a, const Vec3f& b, float t) { return a + t * (b - a); }

inline float hash_to_float(const Pt<1>& k) { return hash_to_float(k[0]); }
inline float hash_to_float(const Pt<2>& k) { return hash_to_float(k[0], k[1]); }
inline float hash_to_float(const Pt<3>& k) { return hash_to_float(k[0], k[1], k[2]); }
inline float hash_to_float(const Pt<4>& k) { return hash_to_float(k[0], k[1], k[2], k[3]); }

// A random point of the same dimension (hash_floatN_to_floatN).
inline Pt<1> hash_to_point(const Pt<1>& k) { return {{hash_to_float(k[0])}}; }
inline Pt<2> hash_to_point(const Pt<2>& k) { return {{hash_to_float(k[0], k[1]), hash_to_float(k[0], k[1], 1.0f)}}; }
inline Pt<3> hash_to_point(const Pt<3>& k) {
    return {{hash_to_float(k[0], k[1], k[2]), hash_to_float(k[0], k[1], k[2], 1.0f),
             hash_to_float(k[0], k[1], k[2], 2.0f)}};
}
inline Pt<4> hash_to_point(const Pt<4>& k) {
    return {{hash_to_float(k[0], k[1], k[2], k[3]), hash_to_float(k[3], k[0], k[1], k[2]),
             hash_to_float(k[2], k[3], k[0], k[1]), hash_to_float(k[1], k[2], k[3], k[0])}};
}

// A random colour (hash_floatN_to_float3).
inline Vec3f hash_to_color(const Pt<1>& k) {
    return {hash_to_float(k[0]), hash_to_float(k[0], 1.0f), hash_to_float(k[0], 2.0f)};
}
inline Vec3f hash_to_color(const Pt<2>& k) {
    return {hash_to_float(k[0], k[1]), hash_to_float(k[0], k[1], 1.0f), hash_to_float(k[0], k[1], 2.0f)};
}
inline Vec3f hash_to_color(const Pt<3>& k) {
    return {hash_to_float(k[0], k[1], k[2]), hash_to_float(k[0], k[1], k[2], 1.0f),
            hash_to_float(k[0], k[1], k[2], 2.0f)};
}
inline Vec3f hash_to_color(const Pt<4>& k) {
    return {hash_to_float(k[0], k[1], k[2], k[3]), hash_to_float(k[2], k[0], k[3], k[1]),
            hash_to_float(k[3], k[2], k[1], k[0])};
}

}  // namespace coherent::shader
