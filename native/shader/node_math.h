// Math, Vector Math, Mapping and Clamp nodes with Cycles 3.4's formulas
// (intern/cycles/kernel/svm/math_util.h, mapping_util.h, util/math_*.h),
// including its "safe" conventions: division by zero gives 0, the
// logarithm of a non-positive number 0, and so on. Enum values are Blender's
// (NodeMathType / NodeVectorMathType), which the compiler passes through.
#pragma once

#include <cfloat>
#include <cmath>

#include "../core/vec.h"

namespace coherent::shader {

enum class MathOp : uint16_t {
    Add, Subtract, Multiply, Divide, Sine, Cosine, Tangent, Arcsine, Arccosine, Arctangent, Power, Logarithm,
    Minimum, Maximum, Round, LessThan, GreaterThan, Modulo, Absolute, Arctan2, Floor, Ceil, Fraction, Sqrt,
    InvSqrt, Sign, Exponent, Radians, Degrees, Sinh, Cosh, Tanh, Trunc, Snap, Wrap, Compare, MultiplyAdd,
    Pingpong, SmoothMin, SmoothMax, Count
};

enum class VectorMathOp : uint16_t {
    Add, Subtract, Multiply, Divide, CrossProduct, Project, Reflect, DotProduct, Distance, Length, Scale,
    Normalize, Snap, Floor, Ceil, Modulo, Fraction, Absolute, Minimum, Maximum, Wrap, Sine, Cosine, Tangent,
    Refract, Faceforward, MultiplyAdd, Count
};

inline float safe_divide(float a, float b) { return b != 0.0f ? a / b : 0.0f; }
inline Vec3f safe_divide(const Vec3f& a, const Vec3f& b) {
    return {safe_divide(a.x, b.x), safe_divide(a.y, b.y), safe_divide(a.z, b.z)};
}
inline float safe_modulo(float a, float b) { return b != 0.0f ? std::fmod(a, b) : 0.0f; }
inline float fractf(float a) { return a - std::floor(a); }

inline float compatible_powf(float x, float y) {
    if (y == 0.0f) return 1.0f;
    if (x < 0.0f) {
        if (std::fmod(-y, 2.0f) == 0.0f) return std::pow(-x, y);
        return -std::pow(-x, y);
    }
    if (x == 0.0f) return 0.0f;
    return std::pow(x, y);
}
inline float safe_powf(float a, float b) {
    if (a < 0.0f && b != float(int(b))) return 0.0f;
    return compatible_powf(a, b);
}
inline float safe_logf(float a, float b) {
    if (a <= 0.0f || b <= 0.0f) return 0.0f;
    return safe_divide(std::log(a), std::log(b));
}
inline float wrapf(float value, float max, float min) {
    const float range = max - min;
    return range != 0.0f ? value - range * std::floor((value - min) / range) : min;
}
inline float pingpongf(float a, float b) {
    return b != 0.0f ? std::fabs(fractf((a - b) / (b * 2.0f)) * b * 2.0f - b) : 0.0f;
}
inline float smoothminf(float a, float b, float k) {
    if (k != 0.0f) {
        const float h = std::fmax(k - std::fabs(a - b), 0.0f) / k;
        return std::fmin(a, b) - h * h * h * k * (1.0f / 6.0f);
    }
    return std::fmin(a, b);
}
inline float compatible_signf(float f) { return f == 0.0f ? 0.0f : (f > 0.0f ? 1.0f : -1.0f); }
inline float saturatef(float a) { return std::fmin(std::fmax(a, 0.0f), 1.0f); }

inline float svm_math(MathOp type, float a, float b, float c) {
    switch (type) {
        case MathOp::Add: return a + b;
        case MathOp::Subtract: return a - b;
        case MathOp::Multiply: return a * b;
        case MathOp::Divide: return safe_divide(a, b);
        case MathOp::Power: return safe_powf(a, b);
        case MathOp::Logarithm: return safe_logf(a, b);
        case MathOp::Sqrt: return std::sqrt(std::fmax(a, 0.0f));
        case MathOp::InvSqrt: return 1.0f / std::sqrt(a);
        case MathOp::Absolute: return std::fabs(a);
        case MathOp::Radians: return a * (float(M_PI) / 180.0f);
        case MathOp::Degrees: return a * (180.0f / float(M_PI));
        case MathOp::Minimum: return std::fmin(a, b);
        case MathOp::Maximum: return std::fmax(a, b);
        case MathOp::LessThan: return a < b ? 1.0f : 0.0f;
        case MathOp::GreaterThan: return a > b ? 1.0f : 0.0f;
        case MathOp::Round: return std::floor(a + 0.5f);
        case MathOp::Floor: return std::floor(a);
        case MathOp::Ceil: return std::ceil(a);
        case MathOp::Fraction: return a - std::floor(a);
        case MathOp::Modulo: return safe_modulo(a, b);
        case MathOp::Trunc: return a >= 0.0f ? std::floor(a) : std::ceil(a);
        case MathOp::Snap: return std::floor(safe_divide(a, b)) * b;
        case MathOp::Wrap: return wrapf(a, b, c);
        case MathOp::Pingpong: return pingpongf(a, b);
        case MathOp::Sine: return std::sin(a);
        case MathOp::Cosine: return std::cos(a);
        case MathOp::Tangent: return std::tan(a);
        case MathOp::Sinh: return std::sinh(a);
        case MathOp::Cosh: return std::cosh(a);
        case MathOp::Tanh: return std::tanh(a);
        case MathOp::Arcsine: return std::asin(std::fmin(std::fmax(a, -1.0f), 1.0f));
        case MathOp::Arccosine: return std::acos(std::fmin(std::fmax(a, -1.0f), 1.0f));
        case MathOp::Arctangent: return std::atan(a);
        case MathOp::Arctan2: return std::atan2(a, b);
        case MathOp::Sign: return compatible_signf(a);
        case MathOp::Exponent: return std::exp(a);
        case MathOp::Compare: return (a == b || std::fabs(a - b) <= std::fmax(c, FLT_EPSILON)) ? 1.0f : 0.0f;
        case MathOp::MultiplyAdd: return a * b + c;
        case MathOp::SmoothMin: return smoothminf(a, b, c);
        case MathOp::SmoothMax: return -smoothminf(-a, -b, c);
        case MathOp::Count: break;
    }
    return 0.0f;
}

inline Vec3f floor3(const Vec3f& a) { return {std::floor(a.x), std::floor(a.y), std::floor(a.z)}; }
inline Vec3f safe_normalize(const Vec3f& a) {
    const float len = length(a);
    return len != 0.0f ? a / len : a;
}
inline Vec3f project(const Vec3f& v, const Vec3f& onto) {
    const float len_sq = dot(onto, onto);
    return len_sq != 0.0f ? (dot(v, onto) / len_sq) * onto : Vec3f(0.0f);
}
inline Vec3f reflect(const Vec3f& incident, const Vec3f& normal) {
    const Vec3f n = normalize(normal);
    return incident - 2.0f * n * dot(incident, n);
}
inline Vec3f refract(const Vec3f& incident, const Vec3f& normal, float eta) {
    const float k = 1.0f - eta * eta * (1.0f - dot(normal, incident) * dot(normal, incident));
    if (k < 0.0f) return Vec3f(0.0f);
    return eta * incident - (eta * dot(normal, incident) + std::sqrt(k)) * normal;
}

// Vector Math: writes the vector result, or the float one for the dot
// product, distance and length (the other output is 0, as in Cycles).
inline void svm_vector_math(VectorMathOp type, const Vec3f& a, const Vec3f& b, const Vec3f& c, float param,
                            Vec3f& vector, float& value) {
    vector = Vec3f(0.0f);
    value = 0.0f;
    auto each = [&](auto f) { vector = {f(a.x, b.x, c.x), f(a.y, b.y, c.y), f(a.z, b.z, c.z)}; };
    switch (type) {
        case VectorMathOp::Add: vector = a + b; break;
        case VectorMathOp::Subtract: vector = a - b; break;
        case VectorMathOp::Multiply: vector = a * b; break;
        case VectorMathOp::Divide: vector = safe_divide(a, b); break;
        case VectorMathOp::CrossProduct: vector = cross(a, b); break;
        case VectorMathOp::Project: vector = project(a, b); break;
        case VectorMathOp::Reflect: vector = reflect(a, b); break;
        case VectorMathOp::Refract: vector = refract(a, safe_normalize(b), param); break;
        case VectorMathOp::Faceforward: vector = dot(c, b) < 0.0f ? a : -a; break;
        case VectorMathOp::MultiplyAdd: vector = a * b + c; break;
        case VectorMathOp::DotProduct: value = dot(a, b); break;
        case VectorMathOp::Distance: value = length(a - b); break;
        case VectorMathOp::Length: value = length(a); break;
        case VectorMathOp::Scale: vector = a * param; break;
        case VectorMathOp::Normalize: vector = safe_normalize(a); break;
        case VectorMathOp::Snap: vector = floor3(safe_divide(a, b)) * b; break;
        case VectorMathOp::Floor: vector = floor3(a); break;
        case VectorMathOp::Ceil: vector = {std::ceil(a.x), std::ceil(a.y), std::ceil(a.z)}; break;
        case VectorMathOp::Modulo: each([](float x, float y, float) { return safe_modulo(x, y); }); break;
        case VectorMathOp::Wrap: each([](float x, float y, float z) { return wrapf(x, y, z); }); break;
        case VectorMathOp::Fraction: vector = a - floor3(a); break;
        case VectorMathOp::Absolute: vector = abs(a); break;
        case VectorMathOp::Minimum: vector = min(a, b); break;
        case VectorMathOp::Maximum: vector = max(a, b); break;
        case VectorMathOp::Sine: vector = {std::sin(a.x), std::sin(a.y), std::sin(a.z)}; break;
        case VectorMathOp::Cosine: vector = {std::cos(a.x), std::cos(a.y), std::cos(a.z)}; break;
        case VectorMathOp::Tangent: vector = {std::tan(a.x), std::tan(a.y), std::tan(a.z)}; break;
        case VectorMathOp::Count: break;
    }
}

// Cycles' euler_to_transform (XYZ Euler), applied to a direction, and its transpose.
struct EulerRotation {
    Vec3f x, y, z;  // rows
    explicit EulerRotation(const Vec3f& e) {
        const float cx = std::cos(e.x), cy = std::cos(e.y), cz = std::cos(e.z);
        const float sx = std::sin(e.x), sy = std::sin(e.y), sz = std::sin(e.z);
        x = {cy * cz, sy * sx * cz - cx * sz, sy * cx * cz + sx * sz};
        y = {cy * sz, sy * sx * sz + cx * cz, sy * cx * sz - sx * cz};
        z = {-sy, cy * sx, cy * cx};
    }
    Vec3f apply(const Vec3f& a) const { return {dot(x, a), dot(y, a), dot(z, a)}; }
    Vec3f apply_transposed(const Vec3f& a) const {
        return {a.x * x.x + a.y * y.x + a.z * z.x, a.x * x.y + a.y * y.y + a.z * z.y, a.x * x.z + a.y * y.z + a.z * z.z};
    }
};

inline Vec3f svm_mapping(uint16_t type, const Vec3f& v, const Vec3f& location, const Vec3f& rotation,
                         const Vec3f& scale) {
    const EulerRotation r(rotation);
    switch (type) {
        case 0: return r.apply(v * scale) + location;                           // Point
        case 1: return safe_divide(r.apply_transposed(v - location), scale);   // Texture
        case 2: return r.apply(v * scale);                                      // Vector
        case 3: return safe_normalize(r.apply(safe_divide(v, scale)));         // Normal
        default: return Vec3f(0.0f);
    }
}

// Clamp node: min-max clamps to [a, b]; range also accepts a > b.
inline float svm_clamp(uint16_t type, float value, float lo, float hi) {
    if (type == 1 && lo > hi) return std::fmin(std::fmax(value, hi), lo);
    return std::fmin(std::fmax(value, lo), hi);
}

}  // namespace coherent::shader
