// The sky world's sampling bake. See sky_world.h.
#include "sky_world.h"

#include <algorithm>
#include <cmath>

#include "../render/world_sampling.h"

namespace coherent {

namespace {

// The Nishita sun's direction and angular radius in the sky's frame (false:
// no disc), as sky_model.cpp evaluates it.
bool sun_disc(const SkyParams& p, Vec3f& dir, float& radius) {
    if (SkyType(int(p.type)) != SkyType::Nishita || !(p.angular_diameter > 0.0f)) return false;
    const float lon = p.sun_rotation + 0.5f * kPi;
    dir = {std::cos(p.sun_elevation) * std::cos(lon), std::cos(p.sun_elevation) * std::sin(lon),
           std::sin(p.sun_elevation)};
    radius = 0.5f * p.angular_diameter;
    return true;
}

// Mean of the sky over texel (x, y) from an n x n grid of sample points.
Vec3f texel_mean(const SkyTexture& sky, int x, int y, int w, int h, int n) {
    Vec3f sum(0.0f);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const float u = (float(x) + (float(i) + 0.5f) / float(n)) / float(w);
            const float v = (float(y) + (float(j) + 0.5f) / float(n)) / float(h);
            sum += sky.eval(equirect_to_direction(u, v));
        }
    return sum / float(n * n);
}

}  // namespace

EnvironmentMap make_sky_environment(std::shared_ptr<const SkyTexture> sky, const float* rotation, int width,
                                    int height) {
    EnvironmentMap map;
    if (rotation) std::copy(rotation, rotation + 9, map.rotation);
    map.width = width;
    map.height = height;
    map.rgb.assign(size_t(width) * size_t(height) * 3, 0.0f);
    Vec3f sun;
    float sun_radius = 0.0f;
    const bool has_sun = sun_disc(sky->params, sun, sun_radius);
    // A texel's centre is within this angle of every point of the texel.
    const float texel_reach = std::sqrt(std::pow(kPi / float(height), 2.0f) + std::pow(2.0f * kPi / float(width), 2.0f));
    const float cos_near = std::cos(std::min(sun_radius + texel_reach, kPi));
    // Enough samples across a texel that a disc of the sun's size is hit by several.
    const int n = std::clamp(int(std::ceil(4.0f * texel_reach / std::max(sun_radius, 1e-4f))), 4, 64);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const Vec3f d = equirect_to_direction((float(x) + 0.5f) / float(width), (float(y) + 0.5f) / float(height));
            const Vec3f c = has_sun && dot(d, sun) >= cos_near ? texel_mean(*sky, x, y, width, height, n)
                                                               : sky->eval(d);
            float* out = &map.rgb[(size_t(y) * size_t(width) + size_t(x)) * 3];
            for (int k = 0; k < 3; ++k) out[k] = std::isfinite(c[k]) ? std::max(c[k], 0.0f) : 0.0f;
        }
    map.sky = std::move(sky);
    return map;
}

}  // namespace coherent
