// Colour adjustment and surface input nodes with Cycles 3.4's formulas
// (intern/cycles/kernel/svm/ramp.h, hsv.h, gamma.h, brightness.h,
// map_range.h, fresnel.h, light_path.h; util/color.h): RGB / Vector / Float
// Curves, Hue/Saturation/Value, Gamma, Bright/Contrast, Map Range,
// Separate/Combine HSV and HSL, Fresnel and Layer Weight.
#pragma once

#include <algorithm>
#include <cmath>

#include "../core/vec.h"
#include "node_color.h"
#include "node_math.h"

namespace coherent::shader {

// Blender's NodeMapRangeType order.
enum class MapRangeType : uint16_t { Linear, Stepped, Smoothstep, Smootherstep, Count };
// Separate/Combine Color conversions (ColorConvert's mode).
enum class ColorConversion : uint16_t { RgbToHsv, HsvToRgb, RgbToHsl, HslToRgb, Count };
// Fresnel and Layer Weight (FresnelNode's mode).
enum class FresnelKind : uint16_t { Fresnel, LayerFresnel, LayerFacing, Count };

// A curve table as the compiler lays it out in ShaderProgram::data: the
// x range it samples, then kRampTableSize entries of `stride` floats.
constexpr int kCurveHeader = 2;

// Cycles' float_ramp_lookup / rgb_ramp_lookup on one channel: `table` has
// `size` entries `stride` floats apart; linear extrapolation past the ends
// when `extrapolate` (the curve's Extend mode), else clamped.
inline float curve_lookup(const float* table, int size, int stride, float f, bool extrapolate) {
    auto at = [&](int i) { return table[i * stride]; };
    if ((f < 0.0f || f > 1.0f) && extrapolate) {
        float t0, dy;
        if (f < 0.0f) {
            t0 = at(0);
            dy = t0 - at(1);
            f = -f;
        } else {
            t0 = at(size - 1);
            dy = t0 - at(size - 2);
            f = f - 1.0f;
        }
        return t0 + dy * f * float(size - 1);
    }
    f = std::fmin(std::fmax(f, 0.0f), 1.0f) * float(size - 1);
    const int i = std::clamp(int(f), 0, size - 1);
    const float t = f - float(i);
    float a = at(i);
    if (t > 0.0f) a = (1.0f - t) * a + t * at(i + 1);
    return a;
}

// svm_node_curves (RGB and Vector Curves): each channel through its own
// column of the table, over the curves' common x range.
inline Vec3f svm_curves(const float* curve, int size, float fac, const Vec3f& color, bool extrapolate) {
    const float min_x = curve[0], range_x = curve[1] - curve[0];
    const float* table = curve + kCurveHeader;
    const Vec3f rel = (color - Vec3f(min_x)) / range_x;
    const Vec3f mapped{curve_lookup(table, size, 4, rel.x, extrapolate),
                       curve_lookup(table + 1, size, 4, rel.y, extrapolate),
                       curve_lookup(table + 2, size, 4, rel.z, extrapolate)};
    return (1.0f - fac) * color + fac * mapped;
}

// svm_node_curve (Float Curve).
inline float svm_float_curve(const float* curve, int size, float fac, float in, bool extrapolate) {
    const float relpos = (in - curve[0]) / (curve[1] - curve[0]);
    const float v = curve_lookup(curve + kCurveHeader, size, 1, relpos, extrapolate);
    return (1.0f - fac) * in + fac * v;
}

// svm_node_hsv as of 3.4 (fmodf: hue + 0.5 is never negative here).
inline Vec3f svm_hsv(float fac, const Vec3f& in, float hue, float sat, float val) {
    Vec3f hsv = rgb_to_hsv(in);
    hsv.x = std::fmod(hsv.x + hue + 0.5f, 1.0f);
    hsv.y = saturatef(hsv.y * sat);
    hsv.z *= val;
    const Vec3f c = hsv_to_rgb(hsv);
    const Vec3f mixed{fac * c.x + (1.0f - fac) * in.x, fac * c.y + (1.0f - fac) * in.y,
                      fac * c.z + (1.0f - fac) * in.z};
    return {std::max(mixed.x, 0.0f), std::max(mixed.y, 0.0f), std::max(mixed.z, 0.0f)};
}

// svm_math_gamma_color.
inline Vec3f svm_gamma(Vec3f c, float gamma) {
    if (gamma == 0.0f) return Vec3f(1.0f);
    if (c.x > 0.0f) c.x = std::pow(c.x, gamma);
    if (c.y > 0.0f) c.y = std::pow(c.y, gamma);
    if (c.z > 0.0f) c.z = std::pow(c.z, gamma);
    return c;
}

// svm_brightness_contrast.
inline Vec3f svm_brightness_contrast(const Vec3f& c, float brightness, float contrast) {
    const float a = 1.0f + contrast;
    const float b = brightness - contrast * 0.5f;
    return {std::max(a * c.x + b, 0.0f), std::max(a * c.y + b, 0.0f), std::max(a * c.z + b, 0.0f)};
}

inline float smoothstep_edges(float edge0, float edge1, float x) {
    if (x < edge0) return 0.0f;
    if (x >= edge1) return 1.0f;
    const float t = (x - edge0) / (edge1 - edge0);
    return (3.0f - 2.0f * t) * (t * t);
}
inline float smootherstep_edges(float edge0, float edge1, float x) {
    x = std::clamp(safe_divide(x - edge0, edge1 - edge0), 0.0f, 1.0f);
    return x * x * x * (x * (x * 6.0f - 15.0f) + 10.0f);
}

// svm_node_map_range (float; the clamp is a separate Clamp node, as in
// Cycles' MapRangeNode::expand).
inline float svm_map_range(MapRangeType type, float value, float from_min, float from_max, float to_min,
                           float to_max, float steps) {
    if (from_max == from_min) return 0.0f;
    float factor = value;
    switch (type) {
        case MapRangeType::Stepped:
            factor = (value - from_min) / (from_max - from_min);
            factor = steps > 0.0f ? std::floor(factor * (steps + 1.0f)) / steps : 0.0f;
            break;
        case MapRangeType::Smoothstep:
            factor = from_min > from_max ? 1.0f - smoothstep_edges(from_max, from_min, factor)
                                         : smoothstep_edges(from_min, from_max, factor);
            break;
        case MapRangeType::Smootherstep:
            factor = from_min > from_max ? 1.0f - smootherstep_edges(from_max, from_min, factor)
                                         : smootherstep_edges(from_min, from_max, factor);
            break;
        default: factor = (value - from_min) / (from_max - from_min); break;
    }
    return to_min + factor * (to_max - to_min);
}

// svm_node_vector_map_range's factor, per component.
inline float vector_map_range_factor(MapRangeType type, float value, float from_min, float from_max, float steps) {
    float f = safe_divide(value - from_min, from_max - from_min);
    switch (type) {
        case MapRangeType::Stepped: return steps > 0.0f ? std::floor(f * (steps + 1.0f)) / steps : 0.0f;
        case MapRangeType::Smoothstep:
            f = std::clamp(f, 0.0f, 1.0f);
            return (3.0f - 2.0f * f) * (f * f);
        case MapRangeType::Smootherstep:
            f = std::clamp(f, 0.0f, 1.0f);
            return f * f * f * (f * (f * 6.0f - 15.0f) + 10.0f);
        default: return f;
    }
}

// svm_node_vector_map_range's result from the factor; `clamp` only for
// Linear and Stepped (Cycles ignores it for the smooth types).
inline float vector_map_range_apply(float factor, float to_min, float to_max, bool clamp) {
    const float r = to_min + factor * (to_max - to_min);
    if (!clamp) return r;
    return to_min > to_max ? std::fmin(std::fmax(r, to_max), to_min) : std::fmin(std::fmax(r, to_min), to_max);
}

inline Vec3f rgb_to_hsl(const Vec3f& rgb) {
    const float cmax = std::fmax(rgb.x, std::fmax(rgb.y, rgb.z));
    const float cmin = std::min(rgb.x, std::min(rgb.y, rgb.z));
    const float l = std::min(1.0f, (cmax + cmin) / 2.0f);
    float h = 0.0f, s = 0.0f;
    if (cmax != cmin) {
        const float cdelta = cmax - cmin;
        s = l > 0.5f ? cdelta / (2.0f - cmax - cmin) : cdelta / (cmax + cmin);
        if (cmax == rgb.x) h = (rgb.y - rgb.z) / cdelta + (rgb.y < rgb.z ? 6.0f : 0.0f);
        else if (cmax == rgb.y) h = (rgb.z - rgb.x) / cdelta + 2.0f;
        else h = (rgb.x - rgb.y) / cdelta + 4.0f;
    }
    return {h / 6.0f, s, l};
}

inline Vec3f hsl_to_rgb(const Vec3f& hsl) {
    const float h = hsl.x, s = hsl.y, l = hsl.z;
    const float nr = std::clamp(std::fabs(h * 6.0f - 3.0f) - 1.0f, 0.0f, 1.0f);
    const float ng = std::clamp(2.0f - std::fabs(h * 6.0f - 2.0f), 0.0f, 1.0f);
    const float nb = std::clamp(2.0f - std::fabs(h * 6.0f - 4.0f), 0.0f, 1.0f);
    const float chroma = (1.0f - std::fabs(2.0f * l - 1.0f)) * s;
    return {(nr - 0.5f) * chroma + l, (ng - 0.5f) * chroma + l, (nb - 0.5f) * chroma + l};
}

inline Vec3f convert_color(ColorConversion kind, const Vec3f& c) {
    switch (kind) {
        case ColorConversion::RgbToHsv: return rgb_to_hsv(c);
        case ColorConversion::HsvToRgb: return hsv_to_rgb(c);
        case ColorConversion::RgbToHsl: return rgb_to_hsl(c);
        case ColorConversion::HslToRgb: return hsl_to_rgb(c);
        case ColorConversion::Count: break;
    }
    return c;
}

// Cycles' fresnel_dielectric_cos: reflectance without the refracted direction.
inline float fresnel_dielectric_cos(float cosi, float eta) {
    const float c = std::fabs(cosi);
    float g = eta * eta - 1.0f + c * c;
    if (g > 0.0f) {
        g = std::sqrt(g);
        const float a = (g - c) / (g + c);
        const float b = (c * (g + c) - 1.0f) / (c * (g - c) + 1.0f);
        return 0.5f * a * a * (1.0f + b * b);
    }
    return 1.0f;  // total internal reflection
}

namespace detail {
inline float safe_sqrt(float x) { return std::sqrt(std::max(x, 0.0f)); }
}  // namespace detail

// Cycles 3.4's ensure_valid_reflection: N tilted towards Ng just enough that
// the mirror reflection of I about it stays above the surface.
inline Vec3f ensure_valid_reflection(const Vec3f& ng, const Vec3f& i, const Vec3f& n) {
    const Vec3f r = 2.0f * dot(n, i) * n - i;
    const float threshold = std::min(0.9f * dot(ng, i), 0.01f);
    if (dot(ng, r) >= threshold) return n;
    // In the frame (X, Ng) of the plane holding N, solve for N'.z such that
    // dot(reflect(I, N'), Ng) = threshold; two roots can be valid.
    const float n_dot_ng = dot(n, ng);
    const Vec3f x = normalize(n - n_dot_ng * ng);
    const float ix = dot(i, x), iz = dot(i, ng);
    const float ix2 = ix * ix, iz2 = iz * iz;
    const float a = ix2 + iz2;
    const float b = detail::safe_sqrt(ix2 * (a - threshold * threshold));
    const float c = iz * threshold + a;
    const float fac = 0.5f / a;
    const float n1_z2 = fac * (b + c), n2_z2 = fac * (-b + c);
    bool valid1 = n1_z2 > 1e-5f && n1_z2 <= 1.0f + 1e-5f;
    bool valid2 = n2_z2 > 1e-5f && n2_z2 <= 1.0f + 1e-5f;
    float nx, nz;
    if (valid1 && valid2) {
        const float n1x = detail::safe_sqrt(1.0f - n1_z2), n1z = detail::safe_sqrt(n1_z2);
        const float n2x = detail::safe_sqrt(1.0f - n2_z2), n2z = detail::safe_sqrt(n2_z2);
        const float r1 = 2.0f * (n1x * ix + n1z * iz) * n1z - iz;
        const float r2 = 2.0f * (n2x * ix + n2z * iz) * n2z - iz;
        valid1 = r1 >= 1e-5f;
        valid2 = r2 >= 1e-5f;
        // Both valid: the shallower reflection is closer to the input.
        const bool first = (valid1 && valid2) ? r1 < r2 : r1 > r2;
        nx = first ? n1x : n2x;
        nz = first ? n1z : n2z;
    } else if (valid1 || valid2) {
        const float nz2 = valid1 ? n1_z2 : n2_z2;
        nx = detail::safe_sqrt(1.0f - nz2);
        nz = detail::safe_sqrt(nz2);
    } else {
        return ng;
    }
    return nx * x + nz * ng;
}

// svm_node_fresnel and svm_node_layer_weight. `wi` points back along the
// ray, `backfacing`: the ray hit the side opposite the winding normal.
inline float svm_fresnel(FresnelKind kind, float x, const Vec3f& n, const Vec3f& wi, bool backfacing) {
    if (kind == FresnelKind::Fresnel) {
        float eta = std::fmax(x, 1e-5f);
        eta = backfacing ? 1.0f / eta : eta;
        return fresnel_dielectric_cos(dot(wi, n), eta);
    }
    if (kind == FresnelKind::LayerFresnel) {
        float eta = std::fmax(1.0f - x, 1e-5f);
        eta = backfacing ? eta : 1.0f / eta;
        return fresnel_dielectric_cos(dot(wi, n), eta);
    }
    float f = std::fabs(dot(wi, n));
    float blend = x;
    if (blend != 0.5f) {
        blend = std::clamp(blend, 0.0f, 1.0f - 1e-5f);
        blend = blend < 0.5f ? 2.0f * blend : 0.5f / (1.0f - blend);
        f = std::pow(f, blend);
    }
    return 1.0f - f;
}

}  // namespace coherent::shader
