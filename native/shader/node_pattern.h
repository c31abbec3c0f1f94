// The analytic pattern textures of Blender 3.4's Cycles: Wave, Gradient,
// Magic and Brick (intern/cycles/kernel/svm/wave.h, gradient.h, magic.h,
// brick.h), with Cycles' formulas and enum values.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "../core/vec.h"
#include "node_noise.h"

namespace coherent::shader {

constexpr float kTwoPi = 6.283185307179586f;
constexpr float kHalfPi = 1.5707963267948966f;

enum class WaveType : uint16_t { Bands = 0, Rings = 1 };
enum class WaveBandsDirection : uint16_t { X = 0, Y = 1, Z = 2, Diagonal = 3 };
enum class WaveRingsDirection : uint16_t { X = 0, Y = 1, Z = 2, Spherical = 3 };
enum class WaveProfile : uint16_t { Sine = 0, Saw = 1, Triangle = 2 };

struct WaveParams {
    WaveType type;
    WaveBandsDirection bands;
    WaveRingsDirection rings;
    WaveProfile profile;
    float distortion, detail, detail_scale, detail_roughness, phase;
};

inline float svm_wave(const WaveParams& w, Vec3f p) {
    p = (p + Vec3f(0.000001f)) * 0.999999f;  // Cycles: avoids precision issues on unit coordinates
    float n;
    if (w.type == WaveType::Bands) {
        switch (w.bands) {
            case WaveBandsDirection::X: n = p.x * 20.0f; break;
            case WaveBandsDirection::Y: n = p.y * 20.0f; break;
            case WaveBandsDirection::Z: n = p.z * 20.0f; break;
            default: n = (p.x + p.y + p.z) * 10.0f; break;
        }
    } else {
        Vec3f rp = p;
        if (w.rings == WaveRingsDirection::X) rp.x = 0.0f;
        else if (w.rings == WaveRingsDirection::Y) rp.y = 0.0f;
        else if (w.rings == WaveRingsDirection::Z) rp.z = 0.0f;
        n = std::sqrt(rp.x * rp.x + rp.y * rp.y + rp.z * rp.z) * 20.0f;
    }
    n += w.phase;
    if (w.distortion != 0.0f) {
        const Vec3f q = p * w.detail_scale;
        n += w.distortion * (fractal_noise(Pt<3>{{q.x, q.y, q.z}}, w.detail, w.detail_roughness) * 2.0f - 1.0f);
    }
    if (w.profile == WaveProfile::Sine) return 0.5f + 0.5f * std::sin(n - kHalfPi);
    n /= kTwoPi;
    if (w.profile == WaveProfile::Saw) return n - std::floor(n);
    return std::fabs(n - std::floor(n + 0.5f)) * 2.0f;
}

enum class GradientType : uint16_t { Linear = 0, Quadratic = 1, Easing = 2, Diagonal = 3, Radial = 4,
                                     QuadraticSphere = 5, Spherical = 6, Count };

// Cycles' svm_gradient, clamped to [0, 1] as its node does.
inline float svm_gradient(GradientType type, const Vec3f& p) {
    const float x = p.x, y = p.y, z = p.z;
    float f = 0.0f;
    switch (type) {
        case GradientType::Linear: f = x; break;
        case GradientType::Quadratic: {
            const float r = std::fmax(x, 0.0f);
            f = r * r;
            break;
        }
        case GradientType::Easing: {
            const float r = std::fmin(std::fmax(x, 0.0f), 1.0f);
            const float t = r * r;
            f = 3.0f * t - 2.0f * t * r;
            break;
        }
        case GradientType::Diagonal: f = (x + y) * 0.5f; break;
        case GradientType::Radial: f = std::atan2(y, x) / kTwoPi + 0.5f; break;
        case GradientType::QuadraticSphere:
        case GradientType::Spherical: {
            // Cycles' bias: a unit-length p gives exactly 0.
            const float r = std::fmax(0.999999f - std::sqrt(x * x + y * y + z * z), 0.0f);
            f = type == GradientType::Spherical ? r : r * r;
            break;
        }
        case GradientType::Count: break;
    }
    return std::fmin(std::fmax(f, 0.0f), 1.0f);
}

// Cycles' svm_magic: nested sines and cosines, `depth` of them (0..10).
// Cycles wraps the unscaled coordinates into [0, 2 pi) first (against
// precision loss far from the origin) and scales inside the sines.
inline Vec3f svm_magic(const Vec3f& p, float scale, int depth, float distortion) {
    const float px = std::fmod(p.x, kTwoPi), py = std::fmod(p.y, kTwoPi), pz = std::fmod(p.z, kTwoPi);
    float x = std::sin((px + py + pz) * 5.0f * scale);
    float y = std::cos((-px + py - pz) * 5.0f * scale);
    float z = -std::cos((-px - py + pz) * 5.0f * scale);
    const float d = distortion;
    if (depth > 0) {
        x *= d, y *= d, z *= d;
        y = -std::cos(x - y + z) * d;
        if (depth > 1) x = std::cos(x - y - z) * d;
        if (depth > 2) z = std::sin(-x - y - z) * d;
        if (depth > 3) x = -std::cos(-x + y - z) * d;
        if (depth > 4) y = -std::sin(-x + y + z) * d;
        if (depth > 5) y = -std::cos(-x + y + z) * d;
        if (depth > 6) x = std::cos(x + y + z) * d;
        if (depth > 7) z = std::sin(x + y - z) * d;
        if (depth > 8) x = -std::cos(-x - y + z) * d;
        if (depth > 9) y = -std::sin(x - y + z) * d;
    }
    if (distortion != 0.0f) {
        const float twice = distortion * 2.0f;
        x /= twice, y /= twice, z /= twice;
    }
    return {0.5f - x, 0.5f - y, 0.5f - z};
}

struct BrickParams {
    float mortar_size, mortar_smooth, bias, brick_width, row_height, offset_amount, squash_amount;
    int offset_frequency, squash_frequency;
};

// Cycles' brick_noise: a fast integer hash in [0, 1).
inline float brick_noise(uint32_t n) {
    n = (n + 1013u) & 0x7fffffffu;
    n = (n >> 13) ^ n;
    const uint32_t nn = (n * (n * n * 60493u + 19990303u) + 1376312589u) & 0x7fffffffu;
    return 0.5f * (float(nn) / 1073741824.0f);
}

// Cycles' smoothstepf, 0 below 0 and 1 above 1.
inline float smoothstep_clamped(float f) {
    if (f <= 0.0f) return 0.0f;
    if (f >= 1.0f) return 1.0f;
    const float ff = f * f;
    return 3.0f * ff - 2.0f * ff * f;
}

// Cycles' svm_brick: (tint, mortar factor) at p.
inline void svm_brick(const BrickParams& b, const Vec3f& p, float& tint, float& mortar) {
    float brick_width = b.brick_width, offset = 0.0f;
    const int row = int(std::floor(p.y / b.row_height));
    if (b.offset_frequency && b.squash_frequency) {
        brick_width *= (row % b.squash_frequency) ? 1.0f : b.squash_amount;
        offset = (row % b.offset_frequency) ? 0.0f : brick_width * b.offset_amount;
    }
    const int brick = int(std::floor((p.x + offset) / brick_width));
    const float x = (p.x + offset) - brick_width * float(brick);
    const float y = p.y - b.row_height * float(row);
    tint = std::clamp(brick_noise((uint32_t(row) << 16) + (uint32_t(brick) & 0xFFFFu)) + b.bias, 0.0f, 1.0f);
    float min_dist = std::min(std::min(x, y), std::min(brick_width - x, b.row_height - y));
    if (min_dist >= b.mortar_size) {
        mortar = 0.0f;
    } else if (b.mortar_smooth == 0.0f) {
        mortar = 1.0f;
    } else {
        min_dist = 1.0f - min_dist / b.mortar_size;
        mortar = smoothstep_clamped(min_dist / b.mortar_smooth);
    }
}

}  // namespace coherent::shader
