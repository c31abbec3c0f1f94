// Sky Texture precomputation and evaluation. See sky_model.h. The formulas
// follow Cycles 3.4 (scene/shader_nodes.cpp sky_texture_precompute_*,
// kernel/svm/sky.h; Apache-2.0, Copyright 2011-2022 Blender Foundation)
// operation for operation, in float where Cycles uses float, so that a sky
// agrees with Cycles' to float rounding.
#include "sky_model.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "sky_hosek.h"
#include "sky_nishita.h"

namespace coherent {

namespace {

constexpr float kHalfPi = 0.5f * kPi;
constexpr float kTwoPi = 2.0f * kPi;

// Cycles' XYZ -> scene linear for Blender's default OCIO configuration: the
// inverse of its srgb_to_xyz.spimtx (Rec.709 primaries, D65).
Vec3f xyz_to_rgb_clamped(const Vec3f& xyz) {
    const Vec3f rgb{3.240454836f * xyz.x - 1.5371388501f * xyz.y - 0.4985315469f * xyz.z,
                    -0.9692663899f * xyz.x + 1.8760109288f * xyz.y + 0.0415560823f * xyz.z,
                    0.0556434196f * xyz.x - 0.2040258543f * xyz.y + 1.0572251625f * xyz.z};
    return max(rgb, Vec3f(0.0f));
}

// (theta from +z, phi = atan2(x, y)): Cycles 3.4's direction_to_spherical.
Vec2f spherical(const Vec3f& d) { return {std::acos(std::clamp(d.z, -1.0f, 1.0f)), std::atan2(d.x, d.y)}; }

// ---------------------------------------------------------------- Preetham

float perez(const float* lam, float theta, float gamma) {
    const float ctheta = std::cos(theta), cgamma = std::cos(gamma);
    return (1.0f + lam[0] * std::exp(lam[1] / ctheta)) *
           (1.0f + lam[2] * std::exp(lam[3] * gamma) + lam[4] * cgamma * cgamma);
}

void precompute_preetham(SkyParams& p, const Vec3f& sun, float turbidity) {
    const float theta = std::acos(sun.z), phi = std::atan2(sun.x, sun.y);
    p.sun_theta = theta;
    p.sun_phi = phi;
    const float theta2 = theta * theta, theta3 = theta2 * theta;
    const float T = turbidity, T2 = T * T;
    const float chi = (4.0f / 9.0f - T / 120.0f) * (kPi - 2.0f * theta);
    // Zenith luminance Y (scaled) and chromaticity x, y.
    p.radiance[0] = ((4.0453f * T - 4.9710f) * std::tan(chi) - 0.2155f * T + 2.4192f) * 0.06f;
    p.radiance[1] = (0.00166f * theta3 - 0.00375f * theta2 + 0.00209f * theta) * T2 +
                    (-0.02903f * theta3 + 0.06377f * theta2 - 0.03202f * theta + 0.00394f) * T +
                    (0.11693f * theta3 - 0.21196f * theta2 + 0.06052f * theta + 0.25886f);
    p.radiance[2] = (0.00275f * theta3 - 0.00610f * theta2 + 0.00317f * theta) * T2 +
                    (-0.04214f * theta3 + 0.08970f * theta2 - 0.04153f * theta + 0.00516f) * T +
                    (0.15346f * theta3 - 0.26756f * theta2 + 0.06670f * theta + 0.26688f);
    const float perez_coefficients[3][5][2] = {
        {{0.1787f, -1.4630f}, {-0.3554f, 0.4275f}, {-0.0227f, 5.3251f}, {0.1206f, -2.5771f}, {-0.0670f, 0.3703f}},
        {{-0.0193f, -0.2592f}, {-0.0665f, 0.0008f}, {-0.0004f, 0.2125f}, {-0.0641f, -0.8989f}, {-0.0033f, 0.0452f}},
        {{-0.0167f, -0.2608f}, {-0.0950f, 0.0092f}, {-0.0079f, 0.2102f}, {-0.0441f, -1.6537f}, {-0.0109f, 0.0529f}}};
    for (int c = 0; c < 3; ++c) {
        for (int i = 0; i < 5; ++i) p.config[c][i] = perez_coefficients[c][i][0] * T + perez_coefficients[c][i][1];
        for (int i = 5; i < 9; ++i) p.config[c][i] = 0.0f;
        p.radiance[c] /= perez(p.config[c], 0.0f, theta);
    }
}

Vec3f xyY_to_xyz(float x, float y, float Y) {
    const float X = y != 0.0f ? (x / y) * Y : 0.0f;
    const float Z = (y != 0.0f && Y != 0.0f) ? (1.0f - x - y) / y * Y : 0.0f;
    return {X, Y, Z};
}

// --------------------------------------------------------- Hosek / Wilkie

void precompute_hosek(SkyParams& p, const Vec3f& sun, float turbidity, float ground_albedo) {
    const float theta = std::clamp(std::acos(sun.z), 0.0f, kHalfPi);
    p.sun_theta = theta;
    p.sun_phi = std::atan2(sun.x, sun.y);
    double config[3][9], radiance[3];
    // Cycles clamps to [0, 10]; below 1 the reference reads before its tables.
    hosek::xyz_configuration(double(std::clamp(turbidity, 1.0f, 10.0f)), double(ground_albedo),
                             double(kHalfPi - theta), config, radiance);
    for (int c = 0; c < 3; ++c) {
        for (int i = 0; i < 9; ++i) p.config[c][i] = float(config[c][i]);
        p.radiance[c] = float(radiance[c]);
    }
}

float hosek_radiance(const float* c, float theta, float gamma) {
    const float ctheta = std::cos(theta), cgamma = std::cos(gamma);
    const float expM = std::exp(c[4] * gamma);
    const float rayM = cgamma * cgamma;
    const float mieM = (1.0f + rayM) / std::pow((1.0f + c[8] * c[8] - 2.0f * c[8] * cgamma), 1.5f);
    const float zenith = std::sqrt(ctheta);
    return (1.0f + c[0] * std::exp(c[1] / (ctheta + 0.01f))) *
           (c[2] + c[3] * expM + c[5] * rayM + c[6] * mieM + c[7] * zenith);
}

// Preetham and Hosek share the geometry: theta from the zenith (clamped just
// above the horizon, so the ground repeats the horizon) and gamma from the sun.
Vec3f analytic_sky(const SkyParams& p, const Vec3f& dir) {
    const Vec2f s = spherical(dir);
    const float cospsi = std::sin(s.x) * std::sin(p.sun_theta) * std::cos(p.sun_phi - s.y) +
                         std::cos(s.x) * std::cos(p.sun_theta);
    const float gamma = std::acos(std::clamp(cospsi, -1.0f, 1.0f));
    const float theta = std::min(s.x, kHalfPi - 0.001f);
    if (SkyType(int(p.type)) == SkyType::Preetham) {
        const float x = p.radiance[1] * perez(p.config[1], theta, gamma);
        const float y = p.radiance[2] * perez(p.config[2], theta, gamma);
        const float Y = p.radiance[0] * perez(p.config[0], theta, gamma);
        return xyz_to_rgb_clamped(xyY_to_xyz(x, y, Y));
    }
    const Vec3f xyz{hosek_radiance(p.config[0], theta, gamma) * p.radiance[0],
                    hosek_radiance(p.config[1], theta, gamma) * p.radiance[1],
                    hosek_radiance(p.config[2], theta, gamma) * p.radiance[2]};
    return xyz_to_rgb_clamped(xyz) * (kTwoPi / 683);
}

// ----------------------------------------------------------------- Nishita

void precompute_nishita(SkyParams& p, std::vector<float>& image, const SkyInputs& in) {
    // Cycles: "below 1 m causes numerical issues and above 60 km is space";
    // and a minimum sun size against artifacts.
    const float altitude = std::clamp(in.altitude, 1.0f, 59999.0f);
    const float sun_size = std::max(in.sun_size, 0.0005f);
    nishita::precompute_sun(in.sun_elevation, sun_size, altitude, in.air_density, in.dust_density, p.pixel_bottom,
                            p.pixel_top);
    float rotation = std::fmod(in.sun_rotation, kTwoPi);
    if (rotation < 0.0f) rotation += kTwoPi;
    p.sun_rotation = kTwoPi - rotation;
    p.sun_elevation = in.sun_elevation;
    p.angular_diameter = in.sun_disc ? sun_size : -1.0f;
    p.sun_intensity = in.sun_intensity;
    p.image_width = float(nishita::kImageWidth);
    p.image_height = float(nishita::kImageHeight);
    image.assign(size_t(nishita::kImageWidth) * size_t(nishita::kImageHeight) * 3, 0.0f);
    nishita::precompute_texture(image.data(), nishita::kImageWidth, nishita::kImageHeight, in.sun_elevation,
                                altitude, in.air_density, in.dust_density, in.ozone_density);
}

// Cycles' CPU bilinear lookup with Extend: texel centres at (i + 0.5) / size,
// indices clamped at the borders.
Vec3f image_lookup(const float* image, int w, int h, float u, float v) {
    auto split = [](float x, int& i) {
        i = int(x) - (x < 0.0f ? 1 : 0);  // Cycles' frac(): differs from floor only at negative integers
        return x - float(i);
    };
    int ix, iy;
    const float tx = split(u * float(w) - 0.5f, ix), ty = split(v * float(h) - 0.5f, iy);
    const int x0 = std::clamp(ix, 0, w - 1), x1 = std::clamp(ix + 1, 0, w - 1);
    const int y0 = std::clamp(iy, 0, h - 1), y1 = std::clamp(iy + 1, 0, h - 1);
    auto texel = [&](int x, int y) {
        const float* t = image + (size_t(y) * size_t(w) + size_t(x)) * 3;
        return Vec3f{t[0], t[1], t[2]};
    };
    return (1.0f - ty) * (1.0f - tx) * texel(x0, y0) + (1.0f - ty) * tx * texel(x1, y0) +
           ty * (1.0f - tx) * texel(x0, y1) + ty * tx * texel(x1, y1);
}

Vec3f sun_disc_xyz(const SkyParams& p, float dir_elevation, float sun_dir_angle) {
    const Vec3f bottom{p.pixel_bottom[0], p.pixel_bottom[1], p.pixel_bottom[2]};
    const Vec3f top{p.pixel_top[0], p.pixel_top[1], p.pixel_top[2]};
    const float half_angular = p.angular_diameter / 2.0f;
    Vec3f xyz(0.0f);
    if (p.sun_elevation - half_angular > 0.0f) {
        const float y = ((dir_elevation - p.sun_elevation) / p.angular_diameter) + 0.5f;
        xyz = (bottom + y * (top - bottom)) * p.sun_intensity;
    } else if (p.sun_elevation + half_angular > 0.0f) {
        const float y = dir_elevation / (p.sun_elevation + half_angular);
        xyz = (bottom + y * (top - bottom)) * p.sun_intensity;
    }
    const float r = sun_dir_angle / half_angular;
    const float limb_darkening = 1.0f - 0.6f * (1.0f - std::sqrt(1.0f - r * r));
    return xyz * limb_darkening;
}

Vec3f nishita_sky(const SkyParams& p, const float* image, const Vec3f& dir, bool disc) {
    const int w = int(p.image_width), h = int(p.image_height);
    const Vec2f s = spherical(dir);
    float x = (s.y + kPi + p.sun_rotation) / kTwoPi;
    if (x > 1.0f) x -= 1.0f;
    if (dir.z >= 0.0f) {
        const float sun_lon = p.sun_rotation + kHalfPi;
        const Vec3f sun{std::cos(p.sun_elevation) * std::cos(sun_lon), std::cos(p.sun_elevation) * std::sin(sun_lon),
                        std::sin(p.sun_elevation)};
        // Cycles' precise_angle (Kahan's "Mangled Angles"): exact for tiny angles.
        const float sun_dir_angle = 2.0f * std::atan2(length(dir - sun), length(dir + sun));
        const float dir_elevation = kHalfPi - s.x;
        if (disc && p.angular_diameter >= 0.0f && sun_dir_angle < p.angular_diameter / 2.0f)
            return xyz_to_rgb_clamped(sun_disc_xyz(p, dir_elevation, sun_dir_angle));
        // The image's rows are spaced by the square of the elevation.
        const float y = std::sqrt(std::max(dir_elevation / kHalfPi, 0.0f));
        return xyz_to_rgb_clamped(image_lookup(image, w, h, x, y));
    }
    // Below the horizon: the horizon's colour fading to black at z = -0.4.
    if (dir.z < -0.4f) return Vec3f(0.0f);
    float fade = 1.0f + dir.z * 2.5f;
    fade = fade * fade * fade;
    return xyz_to_rgb_clamped(image_lookup(image, w, h, x, -0.5f) * fade);
}

Vec3f eval_sky(const SkyParams& p, const float* image, const Vec3f& dir, bool disc = true) {
    return SkyType(int(p.type)) == SkyType::Nishita ? nishita_sky(p, image, dir, disc) : analytic_sky(p, dir);
}

}  // namespace

SkyTexture precompute_sky(const SkyInputs& in) {
    SkyTexture sky;
    sky.params.type = float(int(in.type));
    const float len = length(in.sun_direction);
    const Vec3f sun = len > 0.0f ? in.sun_direction / len : Vec3f(0.0f, 0.0f, 1.0f);
    switch (in.type) {
        case SkyType::Preetham: precompute_preetham(sky.params, sun, in.turbidity); break;
        case SkyType::HosekWilkie: precompute_hosek(sky.params, sun, in.turbidity, in.ground_albedo); break;
        case SkyType::Nishita: precompute_nishita(sky.params, sky.image, in); break;
    }
    return sky;
}

Vec3f SkyTexture::eval(const Vec3f& dir, bool sun_disc) const { return eval_sky(params, image.data(), dir, sun_disc); }

std::vector<float> pack(const SkyTexture& sky) {
    std::vector<float> out(kSkyParamFloats + sky.image.size());
    std::memcpy(out.data(), &sky.params, sizeof(SkyParams));
    std::copy(sky.image.begin(), sky.image.end(), out.begin() + kSkyParamFloats);
    return out;
}

size_t packed_sky_floats(const float* packed) {
    SkyParams p;
    std::memcpy(static_cast<void*>(&p), packed, sizeof(SkyParams));
    return kSkyParamFloats + size_t(p.image_width) * size_t(p.image_height) * 3;
}

bool packed_sky_valid(const float* packed, size_t available) {
    if (available < kSkyParamFloats) return false;
    SkyParams p;
    std::memcpy(static_cast<void*>(&p), packed, sizeof(SkyParams));
    const bool known = p.type == 0.0f || p.type == 1.0f || p.type == 2.0f;
    auto dimension = [](float v) { return v >= 0.0f && v <= 4096.0f && v == std::floor(v); };
    if (!known || !dimension(p.image_width) || !dimension(p.image_height)) return false;
    if (SkyType(int(p.type)) == SkyType::Nishita && (p.image_width < 1.0f || p.image_height < 1.0f)) return false;
    return packed_sky_floats(packed) <= available;
}

Vec3f eval_packed_sky(const float* packed, const Vec3f& dir) {
    SkyParams p;
    std::memcpy(static_cast<void*>(&p), packed, sizeof(SkyParams));
    return eval_sky(p, packed + kSkyParamFloats, dir);
}

}  // namespace coherent
