// The sky world's sampling bake and sun cone. See sky_world.h.
#include "sky_world.h"

#include <algorithm>
#include <cmath>

#include "../render/world_sampling.h"

namespace coherent {

namespace {

// The Nishita sun's direction and angular radius in the sky's frame (false:
// no disc, or one entirely below the horizon, where the sky hides it).
bool sun_disc(const SkyParams& p, Vec3f& dir, float& radius) {
    if (SkyType(int(p.type)) != SkyType::Nishita || !(p.angular_diameter > 0.0f)) return false;
    radius = 0.5f * p.angular_diameter;
    if (!(p.sun_elevation + radius > 0.0f)) return false;
    const float lon = p.sun_rotation + 0.5f * kPi;
    dir = {std::cos(p.sun_elevation) * std::cos(lon), std::cos(p.sun_elevation) * std::sin(lon),
           std::sin(p.sun_elevation)};
    return true;
}

// Mean luminance x solid angle of the disc: a stratified grid over the cone
// (uniform in solid angle), so limb darkening and a horizon cut are included.
float disc_power(const SkyTexture& sky, const Vec3f& sun, float one_minus_cos) {
    Vec3f t, b;
    make_basis(sun, t, b);
    constexpr int kRings = 16, kSectors = 32;
    double sum = 0.0;
    for (int i = 0; i < kRings; ++i)
        for (int j = 0; j < kSectors; ++j) {
            const float omc = (float(i) + 0.5f) / float(kRings) * one_minus_cos;
            const float sin_theta = std::sqrt(omc * (2.0f - omc));
            const float phi = 2.0f * kPi * (float(j) + 0.5f) / float(kSectors);
            const Vec3f d = normalize((t * std::cos(phi) + b * std::sin(phi)) * sin_theta + sun * (1.0f - omc));
            sum += double(luminance(sky.eval(d)));
        }
    return float(sum / double(kRings * kSectors) * 2.0 * double(kPi) * double(one_minus_cos));
}

}  // namespace

EnvironmentMap make_sky_environment(std::shared_ptr<const SkyTexture> sky, const float* rotation, int width,
                                    int height) {
    EnvironmentMap map;
    if (rotation) std::copy(rotation, rotation + 9, map.rotation);
    map.width = width;
    map.height = height;
    map.rgb.assign(size_t(width) * size_t(height) * 3, 0.0f);
    // The disc goes to the cone; the map holds the sky around (and behind) it.
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const Vec3f d = equirect_to_direction((float(x) + 0.5f) / float(width), (float(y) + 0.5f) / float(height));
            const Vec3f c = sky->eval(d, false);
            float* out = &map.rgb[(size_t(y) * size_t(width) + size_t(x)) * 3];
            for (int k = 0; k < 3; ++k) out[k] = std::isfinite(c[k]) ? std::max(c[k], 0.0f) : 0.0f;
        }
    Vec3f sun;
    float radius = 0.0f;
    if (sun_disc(sky->params, sun, radius)) {
        const float s = std::sin(0.5f * radius);
        map.sun_dir = sun;
        map.sun_one_minus_cos = 2.0f * s * s;  // 1 - cos(radius) without cancellation
        const float power = disc_power(*sky, sun, map.sun_one_minus_cos);
        map.sun_power = std::isfinite(power) ? std::max(power, 0.0f) : 0.0f;
    }
    map.sky = std::move(sky);
    return map;
}

}  // namespace coherent
