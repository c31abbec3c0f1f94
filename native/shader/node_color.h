// Colour nodes with Cycles 3.4's formulas (intern/cycles/kernel/svm/
// color_util.h, ramp.h, checker.h, util/color.h): Mix blend modes, HSV
// conversion, ColorRamp table lookup, Invert, RGB to BW, Checker Texture,
// and the sRGB decoding Cycles applies to 8-bit textures after filtering.
#pragma once

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdlib>

#include "../core/simd.h"
#include "../core/vec.h"

namespace coherent::shader {

// Blender's ramp_blend_type order (MA_RAMP_*), which the compiler passes through.
enum class MixBlend : uint16_t {
    Mix, Add, Multiply, Subtract, Screen, Divide, Difference, Darken, Lighten, Overlay, Dodge, Burn, Hue,
    Saturation, Value, Color, SoftLight, LinearLight, Count
};

inline Vec3f interp(const Vec3f& a, const Vec3f& b, float t) { return a + t * (b - a); }
inline Vec3f saturate(const Vec3f& c) {
    auto s = [](float v) { return std::fmin(std::fmax(v, 0.0f), 1.0f); };
    return {s(c.x), s(c.y), s(c.z)};
}

inline Vec3f rgb_to_hsv(const Vec3f& rgb) {
    const float cmax = std::fmax(rgb.x, std::fmax(rgb.y, rgb.z));
    const float cmin = std::fmin(rgb.x, std::fmin(rgb.y, rgb.z));
    const float cdelta = cmax - cmin;
    const float v = cmax;
    const float s = cmax != 0.0f ? cdelta / cmax : 0.0f;
    float h = 0.0f;
    if (s != 0.0f) {
        const Vec3f c = (Vec3f(cmax) - rgb) / cdelta;
        if (rgb.x == cmax) h = c.z - c.y;
        else if (rgb.y == cmax) h = 2.0f + c.x - c.z;
        else h = 4.0f + c.y - c.x;
        h /= 6.0f;
        if (h < 0.0f) h += 1.0f;
    }
    return {h, s, v};
}

inline Vec3f hsv_to_rgb(const Vec3f& hsv) {
    float h = hsv.x;
    const float s = hsv.y, v = hsv.z;
    if (s == 0.0f) return Vec3f(v);
    if (h == 1.0f) h = 0.0f;
    h *= 6.0f;
    const float i = std::floor(h);
    const float f = h - i;
    const float p = v * (1.0f - s), q = v * (1.0f - s * f), t = v * (1.0f - s * (1.0f - f));
    if (i == 0.0f) return {v, t, p};
    if (i == 1.0f) return {q, v, p};
    if (i == 2.0f) return {p, v, t};
    if (i == 3.0f) return {p, q, v};
    if (i == 4.0f) return {t, p, v};
    return {v, p, q};
}

namespace detail {
inline float overlay(float a, float b, float t) {
    const float tm = 1.0f - t;
    return a < 0.5f ? a * (tm + 2.0f * t * b) : 1.0f - (tm + 2.0f * t * (1.0f - b)) * (1.0f - a);
}
inline float divide(float a, float b, float t) { return b != 0.0f ? (1.0f - t) * a + t * a / b : a; }
inline float dodge(float a, float b, float t) {
    if (a == 0.0f) return a;
    float tmp = 1.0f - t * b;
    if (tmp <= 0.0f) return 1.0f;
    tmp = a / tmp;
    return tmp > 1.0f ? 1.0f : tmp;
}
inline float burn(float a, float b, float t) {
    float tmp = (1.0f - t) + t * b;
    if (tmp <= 0.0f) return 0.0f;
    tmp = 1.0f - (1.0f - a) / tmp;
    return tmp < 0.0f ? 0.0f : (tmp > 1.0f ? 1.0f : tmp);
}
template <class F>
inline Vec3f each(const Vec3f& a, const Vec3f& b, float t, F f) {
    return {f(a.x, b.x, t), f(a.y, b.y, t), f(a.z, b.z, t)};
}
inline Vec3f hue_or_color(const Vec3f& c1, const Vec3f& c2, float t, bool with_saturation) {
    const Vec3f hsv2 = rgb_to_hsv(c2);
    if (hsv2.y == 0.0f) return c1;
    Vec3f hsv = rgb_to_hsv(c1);
    hsv.x = hsv2.x;
    if (with_saturation) hsv.y = hsv2.y;
    return interp(c1, hsv_to_rgb(hsv), t);
}
}  // namespace detail

inline Vec3f svm_mix(MixBlend type, float t, const Vec3f& c1, const Vec3f& c2) {
    const Vec3f one(1.0f);
    const float tm = 1.0f - t;
    switch (type) {
        case MixBlend::Mix: return interp(c1, c2, t);
        case MixBlend::Add: return interp(c1, c1 + c2, t);
        case MixBlend::Multiply: return interp(c1, c1 * c2, t);
        case MixBlend::Screen: return one - (Vec3f(tm) + t * (one - c2)) * (one - c1);
        case MixBlend::Overlay: return detail::each(c1, c2, t, detail::overlay);
        case MixBlend::Subtract: return interp(c1, c1 - c2, t);
        case MixBlend::Divide: return detail::each(c1, c2, t, detail::divide);
        case MixBlend::Difference: return interp(c1, abs(c1 - c2), t);
        case MixBlend::Darken: return interp(c1, min(c1, c2), t);
        case MixBlend::Lighten: return interp(c1, max(c1, c2), t);
        case MixBlend::Dodge: return detail::each(c1, c2, t, detail::dodge);
        case MixBlend::Burn: return detail::each(c1, c2, t, detail::burn);
        case MixBlend::Hue: return detail::hue_or_color(c1, c2, t, false);
        case MixBlend::Color: return detail::hue_or_color(c1, c2, t, true);
        case MixBlend::Saturation: {
            Vec3f hsv = rgb_to_hsv(c1);
            if (hsv.y == 0.0f) return c1;
            hsv.y = tm * hsv.y + t * rgb_to_hsv(c2).y;
            return hsv_to_rgb(hsv);
        }
        case MixBlend::Value: {
            Vec3f hsv = rgb_to_hsv(c1);
            hsv.z = tm * hsv.z + t * rgb_to_hsv(c2).z;
            return hsv_to_rgb(hsv);
        }
        case MixBlend::SoftLight: {
            const Vec3f scr = one - (one - c2) * (one - c1);
            return tm * c1 + t * ((one - c1) * c2 * c1 + c1 * scr);
        }
        case MixBlend::LinearLight: return c1 + t * (2.0f * c2 + Vec3f(-1.0f));
        case MixBlend::Count: break;
    }
    return Vec3f(0.0f);
}

// Cycles' rgb_ramp_lookup without extrapolation: `table` holds kRampTableSize
// RGBA entries sampled from Blender's own ColorRamp evaluation at i / (n - 1).
inline void ramp_lookup(const float* table, int size, float f, bool interpolate, Vec3f& color, float& alpha) {
    f = std::fmin(std::fmax(f, 0.0f), 1.0f) * float(size - 1);
    const int i = std::clamp(int(f), 0, size - 1);
    const float t = f - float(i);
    const float* a = table + 4 * i;
    float r[4] = {a[0], a[1], a[2], a[3]};
    if (interpolate && t > 0.0f) {
        const float* b = a + 4;
        for (int k = 0; k < 4; ++k) r[k] = (1.0f - t) * r[k] + t * b[k];
    }
    color = {r[0], r[1], r[2]};
    alpha = r[3];
}

// Luminance weights of Blender 3.4's scene linear space (Rec.709), as
// Cycles reads them from OpenColorIO for RGB to BW.
inline float rgb_to_gray(const Vec3f& c) { return 0.212671f * c.x + 0.71516f * c.y + 0.072169f * c.z; }

inline float svm_checker(Vec3f p) {
    // Cycles nudges the coordinate to avoid precision issues on unit coordinates.
    p.x = (p.x + 0.000001f) * 0.999999f;
    p.y = (p.y + 0.000001f) * 0.999999f;
    p.z = (p.z + 0.000001f) * 0.999999f;
    const int xi = std::abs(int(std::floor(p.x)));
    const int yi = std::abs(int(std::floor(p.y)));
    const int zi = std::abs(int(std::floor(p.z)));
    return ((xi % 2 == yi % 2) == (zi % 2)) ? 1.0f : 0.0f;
}

inline float srgb_to_linear(float c) {
    if (c < 0.04045f) return c < 0.0f ? 0.0f : c * (1.0f / 12.92f);
    return std::pow((c + 0.055f) * (1.0f / 1.055f), 2.4f);
}

// x^2.4 as Cycles 3.4's CPU kernels compute it (util/color.h,
// fastpow24_sse2): a guess at x^(4/5) from the float's bits, three Newton
// steps towards the fifth root of x^4, then cubed. Within 6e-7 of the exact
// power for 1e-8 < x < 1e8 (a fraction of powf's time); x^4 overflows past
// about 1.8e9.
inline float fastpow24(float a) {
    // fastpow<4/5>: a * 2^(127/(4/5) - 127) * 0.994^(5/4), its bits read as an
    // integer, scaled by 4/5 and rounded, read back as a float's bits.
    const float scaled = a * std::bit_cast<float>(0x4F55A7FBu);
    float x = std::bit_cast<float>(int32_t(std::nearbyint(float(std::bit_cast<int32_t>(scaled)) *
                                                          std::bit_cast<float>(0x3F4CCCCDu))));
    const float a2 = a * a, a4 = a2 * a2;
    for (int step = 0; step < 3; ++step) {
        const float x2 = x * x, x4 = x2 * x2;
        x = (4.0f * x + a4 / x4) * (1.0f / 5.0f);
    }
    return x * (x * x);
}

// sRGB to linear as Cycles converts an Image Texture's filtered colour on the
// CPU (color_srgb_to_linear_v4, SSE2 path): fastpow24 instead of powf.
inline float srgb_to_linear_image(float c) {
    if (c < 0.04045f) return std::max(c * (1.0f / 12.92f), 0.0f);
    const float a = (c + 0.055f) * (1.0f / 1.055f);
    // Past fastpow24's domain a^4 overflows, and Cycles' would give NaN.
    return a < 1e9f ? fastpow24(a) : std::pow(a, 2.4f);
}

namespace srgb_detail {
// fastpow24's first guess, lane-wise: the scaled value's bits read as an
// integer, times 4/5, rounded to nearest even (cvtps, as nearbyint), read
// back as a float's bits.
inline simd::vfloat4 fastpow24_guess(simd::vfloat4 scaled) {
    const __m128 times = _mm_mul_ps(_mm_cvtepi32_ps(_mm_castps_si128(scaled.v)),
                                    _mm_set1_ps(std::bit_cast<float>(0x3F4CCCCDu)));
    return simd::vfloat4(_mm_castsi128_ps(_mm_cvtps_epi32(times)));
}
inline simd::vfloat8 fastpow24_guess(simd::vfloat8 scaled) {
    const __m256 times = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_castps_si256(scaled.v)),
                                       _mm256_set1_ps(std::bit_cast<float>(0x3F4CCCCDu)));
    return simd::vfloat8(_mm256_castsi256_ps(_mm256_cvtps_epi32(times)));
}
}  // namespace srgb_detail

// srgb_to_linear_image lane by lane (V = simd::vfloat4 or vfloat8), bit for
// bit the scalar function's result in every lane: the same operations in
// the same order (the build never contracts them), as Cycles' SSE2 path
// converts a texel's four channels together. Lanes the fast path does not
// cover (NaN, or past fastpow24's domain) take the scalar function.
template <class V>
V srgb_to_linear_image_lanes(V c) {
    const V a = (c + V(0.055f)) * V(1.0f / 1.055f);
    V x = srgb_detail::fastpow24_guess(a * V(std::bit_cast<float>(0x4F55A7FBu)));
    const V a2 = a * a, a4 = a2 * a2;
    for (int step = 0; step < 3; ++step) {
        const V x2 = x * x, x4 = x2 * x2;
        x = (V(4.0f) * x + a4 / x4) * V(1.0f / 5.0f);
    }
    const V power = x * (x * x);
    // std::max(l, 0) keeps l when l == 0 (a -0 stays -0); maxps returns its
    // second operand on ties, so 0 goes first.
    const V linear = simd::max(V(0.0f), c * V(1.0f / 12.92f));
    const auto dark = c < V(0.04045f);
    const V out = simd::select(dark, linear, power);
    const int scalar_lanes = simd::movemask(~(dark | (a < V(1e9f))));
    if (!scalar_lanes) return out;
    constexpr int kLanes = sizeof(V) / sizeof(float);
    float in[kLanes], res[kLanes];
    simd::storeu(in, c);
    simd::storeu(res, out);
    for (int k = 0; k < kLanes; ++k)
        if (scalar_lanes & (1 << k)) res[k] = srgb_to_linear_image(in[k]);
    return V::loadu(res);
}

// srgb_to_linear_image of four values at once (an Image Texture's RGBA: its
// alpha is converted too and is the caller's to ignore).
inline void srgb_to_linear_image4(float c[4]) {
    simd::storeu(c, srgb_to_linear_image_lanes(simd::vfloat4::loadu(c)));
}

}  // namespace coherent::shader
