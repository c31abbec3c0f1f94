// The world's emission beyond the constant colour: an equirectangular
// environment map (Blender's Environment Texture node), as linear RGB floats.
// The world radiance in direction d is Scene::world_color x map(R d), where
// world_color carries the Background node's strength (and any tint) and R
// the Mapping node's rotation. Sampling lives in render/world_sampling.h.
// A Sky Texture world (shader/sky_world.h) sets `sky`: the radiance is then
// the sky's, evaluated exactly, and `rgb` is only its bake for sampling.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

#include "../core/vec.h"

namespace coherent {

struct SkyTexture;

struct EnvironmentMap {
    int width = 0, height = 0;
    // width x height x 3 linear RGB, rows bottom to top as Blender stores
    // image pixels: row 0 holds v = 0 (straight down), column 0 holds u = 0.
    std::vector<float> rgb;
    // Row-major 3x3 rotation taking a world direction to the map's frame
    // (the Mapping node in front of the texture); identity by default.
    float rotation[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    // Sky world: radiance(d) = sky(R d); rgb is its sampling bake.
    std::shared_ptr<const SkyTexture> sky;
    // A sun disc sampled as a cone besides the map (render/world_sampling.h),
    // in the map's frame: its axis, 1 - cos(angular radius), and its power
    // (mean luminance x solid angle). sun_power == 0: none.
    Vec3f sun_dir{0.0f, 0.0f, 1.0f};
    float sun_one_minus_cos = 0.0f;
    float sun_power = 0.0f;

    bool empty() const { return width <= 0 || height <= 0 || rgb.size() != size_t(width) * size_t(height) * 3; }
    Vec3f texel(int x, int y) const {
        const float* p = &rgb[(size_t(y) * size_t(width) + size_t(x)) * 3];
        return {p[0], p[1], p[2]};
    }
    Vec3f to_map(const Vec3f& d) const {
        const float* r = rotation;
        return {r[0] * d.x + r[1] * d.y + r[2] * d.z, r[3] * d.x + r[4] * d.y + r[5] * d.z,
                r[6] * d.x + r[7] * d.y + r[8] * d.z};
    }
    Vec3f from_map(const Vec3f& d) const {  // the transpose: rotations are orthonormal
        const float* r = rotation;
        return {r[0] * d.x + r[3] * d.y + r[6] * d.z, r[1] * d.x + r[4] * d.y + r[7] * d.z,
                r[2] * d.x + r[5] * d.y + r[8] * d.z};
    }
};

}  // namespace coherent
