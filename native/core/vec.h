// Small fixed-size vector types used everywhere in the engine.
//
// Invariant: plain aggregates (trivially copyable, no hidden padding beyond
// what the members need) so that arrays of them can be shared with numpy and
// SIMD code without conversion.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace coherent {

constexpr float kPi = 3.14159265358979323846f;
constexpr float kInvPi = 0.31830988618379067154f;
constexpr float kInf = INFINITY;

struct Vec2f {
    float x = 0, y = 0;
};

struct Vec3f {
    float x = 0, y = 0, z = 0;

    constexpr Vec3f() = default;
    constexpr Vec3f(float x_, float y_, float z_) : x(x_), y(y_), z(z_) {}
    constexpr explicit Vec3f(float s) : x(s), y(s), z(s) {}

    float operator[](int i) const { return (&x)[i]; }
    float& operator[](int i) { return (&x)[i]; }

    Vec3f operator-() const { return {-x, -y, -z}; }
    Vec3f& operator+=(const Vec3f& b) { x += b.x; y += b.y; z += b.z; return *this; }
    Vec3f& operator-=(const Vec3f& b) { x -= b.x; y -= b.y; z -= b.z; return *this; }
    Vec3f& operator*=(const Vec3f& b) { x *= b.x; y *= b.y; z *= b.z; return *this; }
    Vec3f& operator*=(float s) { x *= s; y *= s; z *= s; return *this; }
    Vec3f& operator/=(float s) { return *this *= 1.0f / s; }
};

inline Vec3f operator+(Vec3f a, const Vec3f& b) { return a += b; }
inline Vec3f operator-(Vec3f a, const Vec3f& b) { return a -= b; }
inline Vec3f operator*(Vec3f a, const Vec3f& b) { return a *= b; }
inline Vec3f operator*(Vec3f a, float s) { return a *= s; }
inline Vec3f operator*(float s, Vec3f a) { return a *= s; }
inline Vec3f operator/(Vec3f a, float s) { return a /= s; }
inline Vec3f operator/(const Vec3f& a, const Vec3f& b) { return {a.x / b.x, a.y / b.y, a.z / b.z}; }

inline float dot(const Vec3f& a, const Vec3f& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3f cross(const Vec3f& a, const Vec3f& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline float length_squared(const Vec3f& a) { return dot(a, a); }
inline float length(const Vec3f& a) { return std::sqrt(dot(a, a)); }
inline Vec3f normalize(const Vec3f& a) { return a / length(a); }
inline Vec3f abs(const Vec3f& a) { return {std::fabs(a.x), std::fabs(a.y), std::fabs(a.z)}; }
inline Vec3f min(const Vec3f& a, const Vec3f& b) {
    return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)};
}
inline Vec3f max(const Vec3f& a, const Vec3f& b) {
    return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)};
}
inline float max_component(const Vec3f& a) { return std::max(a.x, std::max(a.y, a.z)); }
inline float min_component(const Vec3f& a) { return std::min(a.x, std::min(a.y, a.z)); }
inline int max_dimension(const Vec3f& a) { return a.x > a.y ? (a.x > a.z ? 0 : 2) : (a.y > a.z ? 1 : 2); }
inline float luminance(const Vec3f& c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }
inline bool is_finite(const Vec3f& a) { return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z); }
inline bool is_black(const Vec3f& a) { return a.x == 0.0f && a.y == 0.0f && a.z == 0.0f; }
inline Vec3f lerp(float t, const Vec3f& a, const Vec3f& b) { return a * (1.0f - t) + b * t; }

// Orthonormal basis around a unit normal (Duff et al. 2017, branchless).
inline void make_basis(const Vec3f& n, Vec3f& t, Vec3f& b) {
    const float sign = std::copysign(1.0f, n.z);
    const float a = -1.0f / (sign + n.z);
    const float c = n.x * n.y * a;
    t = {1.0f + sign * n.x * n.x * a, sign * c, -sign * n.x};
    b = {c, sign + n.y * n.y * a, -n.y};
}

// Row-major affine 4x4 transform (last row implied 0 0 0 1 for points).
struct Transform {
    float m[4][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};

    Vec3f point(const Vec3f& p) const {
        return {m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + m[0][3],
                m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + m[1][3],
                m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + m[2][3]};
    }
    Vec3f vector(const Vec3f& v) const {
        return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
                m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
                m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
    }
    // Of the linear part: negative for a mirroring transform.
    float determinant() const {
        return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
               m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    }
};

}  // namespace coherent
