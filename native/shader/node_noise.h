// Perlin noise and its fractal sums as Blender 3.4's Cycles computes them
// (intern/cycles/kernel/svm/noise.h, fractal_noise.h): gradient
// noise over the lookup3 hash of the lattice corner, with Cycles' gradient
// sets, quintic fade and per-dimension output scales. Interpolation follows
// Cycles' SSE/AVX path (the one its x86 CPU kernels run): x first, then y, z,
// w, each as a + t (b - a), with the fused multiply-adds that Cycles' AVX2
// kernel (the one Blender runs on such CPUs) uses: matching them keeps the
// two within a few float ulps even where Distortion amplifies differences.
#pragma once

#include <algorithm>
#include <cmath>

#include "node_hash.h"

namespace coherent::shader {

namespace perlin {

inline float fade(float t) { return (t * t) * (t * std::fma(t, std::fma(t, 6.0f, -15.0f), 10.0f)); }
inline float negate_if(float v, uint32_t condition) { return condition ? -v : v; }

inline float grad1(uint32_t hash, float x) {
    const uint32_t h = hash & 15u;
    const float g = float(1 + (h & 7u));
    return negate_if(g, h & 8u) * x;
}
inline float grad2(uint32_t hash, float x, float y) {
    const uint32_t h = hash & 7u;
    const float u = h < 4 ? x : y;
    const float v = 2.0f * (h < 4 ? y : x);
    return negate_if(u, h & 1u) + negate_if(v, h & 2u);
}
inline float grad3(uint32_t hash, float x, float y, float z) {
    const uint32_t h = hash & 15u;
    const float u = h < 8 ? x : y;
    const float vt = (h == 12 || h == 14) ? x : z;
    const float v = h < 4 ? y : vt;
    return negate_if(u, h & 1u) + negate_if(v, h & 2u);
}
inline float grad4(uint32_t hash, float x, float y, float z, float w) {
    const uint32_t h = hash & 31u;
    const float u = h < 24 ? x : y;
    const float v = h < 16 ? y : z;
    const float s = h < 8 ? z : w;
    return negate_if(u, h & 1u) + negate_if(v, h & 2u) + negate_if(s, h & 4u);
}

// The lattice cell of x and the offset inside it.
inline float floorfrac(float x, int& i) {
    const float f = std::floor(x);
    i = int(f);
    return x - f;
}
inline uint32_t u(int i) { return uint32_t(i); }

inline float noise1(float x) {
    int X;
    const float fx = floorfrac(x, X);
    return mix_fused(grad1(hash_uint(u(X)), fx), grad1(hash_uint(u(X + 1)), fx - 1.0f), fade(fx));
}

inline float noise2(float x, float y) {
    int X, Y;
    const float fx = floorfrac(x, X), fy = floorfrac(y, Y);
    const float v00 = grad2(hash_uint2(u(X), u(Y)), fx, fy);
    const float v10 = grad2(hash_uint2(u(X + 1), u(Y)), fx - 1.0f, fy);
    const float v01 = grad2(hash_uint2(u(X), u(Y + 1)), fx, fy - 1.0f);
    const float v11 = grad2(hash_uint2(u(X + 1), u(Y + 1)), fx - 1.0f, fy - 1.0f);
    const float tx = fade(fx);
    return mix_fused(mix_fused(v00, v10, tx), mix_fused(v01, v11, tx), fade(fy));
}

// Gradients at the 8 corners of the cell (corner bit 0: x+1, bit 1: y+1, bit 2: z+1), mixed.
inline float noise3(float x, float y, float z) {
    int X, Y, Z;
    const float fx = floorfrac(x, X), fy = floorfrac(y, Y), fz = floorfrac(z, Z);
    float g[8];
    for (int c = 0; c < 8; ++c) {
        const int dx = c & 1, dy = (c >> 1) & 1, dz = (c >> 2) & 1;
        g[c] = grad3(hash_uint3(u(X + dx), u(Y + dy), u(Z + dz)), fx - float(dx), fy - float(dy), fz - float(dz));
    }
    const float tx = fade(fx), ty = fade(fy), tz = fade(fz);
    const float y0 = mix_fused(mix_fused(g[0], g[1], tx), mix_fused(g[2], g[3], tx), ty);
    const float y1 = mix_fused(mix_fused(g[4], g[5], tx), mix_fused(g[6], g[7], tx), ty);
    return mix_fused(y0, y1, tz);
}

inline float noise4(float x, float y, float z, float w) {
    int X, Y, Z, W;
    const float fx = floorfrac(x, X), fy = floorfrac(y, Y), fz = floorfrac(z, Z), fw = floorfrac(w, W);
    float g[16];
    for (int c = 0; c < 16; ++c) {
        const int dx = c & 1, dy = (c >> 1) & 1, dz = (c >> 2) & 1, dw = (c >> 3) & 1;
        g[c] = grad4(hash_uint4(u(X + dx), u(Y + dy), u(Z + dz), u(W + dw)), fx - float(dx), fy - float(dy),
                     fz - float(dz), fw - float(dw));
    }
    const float tx = fade(fx), ty = fade(fy), tz = fade(fz), tw = fade(fw);
    float cube[2];
    for (int k = 0; k < 2; ++k) {
        const float* h = g + 8 * k;
        const float y0 = mix_fused(mix_fused(h[0], h[1], tx), mix_fused(h[2], h[3], tx), ty);
        const float y1 = mix_fused(mix_fused(h[4], h[5], tx), mix_fused(h[6], h[7], tx), ty);
        cube[k] = mix_fused(y0, y1, tz);
    }
    return mix_fused(cube[0], cube[1], tw);
}

inline float finite_or_zero(float x) { return std::isfinite(x) ? x : 0.0f; }

}  // namespace perlin

// Signed noise in about [-1, 1] (Cycles' snoise_Nd, with OSL's scales).
inline float snoise(const Pt<1>& p) { return 0.2500f * perlin::finite_or_zero(perlin::noise1(p[0])); }
inline float snoise(const Pt<2>& p) { return 0.6616f * perlin::finite_or_zero(perlin::noise2(p[0], p[1])); }
inline float snoise(const Pt<3>& p) { return 0.9820f * perlin::finite_or_zero(perlin::noise3(p[0], p[1], p[2])); }
inline float snoise(const Pt<4>& p) {
    return 0.8344f * perlin::finite_or_zero(perlin::noise4(p[0], p[1], p[2], p[3]));
}
// Unsigned noise in about [0, 1].
template <int N>
float unoise(const Pt<N>& p) { return 0.5f * snoise(p) + 0.5f; }

// Blender 3.4's fractal_noise_Nd: `octaves` + 1 octaves of unsigned noise at
// doubling frequencies, the last one faded in by the fraction of octaves.
template <int N>
float fractal_noise(const Pt<N>& p, float octaves, float roughness) {
    float fscale = 1.0f, amp = 1.0f, maxamp = 0.0f, sum = 0.0f;
    octaves = std::clamp(octaves, 0.0f, 15.0f);
    const int n = int(octaves);
    for (int i = 0; i <= n; ++i) {
        sum = std::fma(unoise(fscale * p), amp, sum);
        maxamp += amp;
        amp *= std::clamp(roughness, 0.0f, 1.0f);
        fscale *= 2.0f;
    }
    const float rmd = octaves - std::floor(octaves);
    if (rmd == 0.0f) return sum / maxamp;
    const float sum2 = sum + unoise(fscale * p) * amp;
    return (1.0f - rmd) * (sum / maxamp) + rmd * (sum2 / (maxamp + amp));
}

}  // namespace coherent::shader
