// Importance sampling of an equirectangular environment map (the HDRI world).
//
// Mapping (Cycles' direction_to_equirectangular, so an image looks the same
// in both renderers), for a direction d in the map's frame:
//     u = 0.5 - atan2(d.y, d.x) / (2 pi),   v = 0.5 + atan2(d.z, |d.xy|) / pi
// i.e. elevation = pi (v - 0.5) and the solid angle of du dv is
// 2 pi^2 cos(elevation) du dv.
//
// Lookup: bilinear between texel centres with periodic wrap in both axes,
// as Cycles' Linear interpolation with its default Repeat extension.
//
// Sampling: a piecewise-constant 2D distribution over the texels (marginal
// over rows, conditional over columns; pbrt's Distribution2D) whose weight
// is the integral over the texel of the bilinear lookup's luminance times
// cos(elevation): each texel's share of the map's power. It is positive
// wherever the lookup is (a bright texel's bilinear spill into dark
// neighbours is still sampled) without widening the distribution, as the
// brightest-neighbour weight it replaced did (1.25x -> 1.06x Cycles' RMSE on
// an HDRI world, docs/results/light_selection.md). The solid-angle pdf is
//     pdf(d) = weight(texel of d) / mean(weight) / (2 pi^2 cos(elevation(d))).
// sample() and pdf() evaluate that same expression, so MIS weights agree.
//
// A map with a sun (EnvironmentMap::sun_power > 0, the Nishita sky) mixes in
// uniform sampling of the sun's cone with probability
//     s = sun_power / (sun_power + power of the map),
// pdf(d) = (1 - s) map_pdf(d) + s cone_pdf(d): the disc, far smaller than a
// texel's neighbourhood, is then hit by every cone sample instead of a few
// map samples. The map of such a sky holds the sky without the disc.
#pragma once

#include <vector>

#include "../scene/world.h"

namespace coherent {

class EnvironmentSampler {
public:
    EnvironmentSampler() = default;
    explicit EnvironmentSampler(const EnvironmentMap& map);

    // Nothing to sample: no map, or one that is black everywhere.
    bool empty() const { return map_ == nullptr; }
    // map(d) for a world-space unit direction, bilinear (without strength);
    // for a sky world (EnvironmentMap::sky) the sky itself, exactly.
    Vec3f eval(const Vec3f& d) const;
    // A world-space unit direction with its solid-angle pdf; false for a
    // sample that landed where the pdf is 0 (a pole).
    bool sample(float u1, float u2, Vec3f& d, float& pdf) const;
    float pdf(const Vec3f& d) const;
    // Mean luminance of map over the sphere (per steradian): the world's
    // mean radiance, for light selection.
    float mean_luminance() const { return mean_luminance_; }

private:
    float texel_pdf_uv(int x, int y) const;
    bool sample_map(float u1, float u2, Vec3f& d, float& pdf) const;
    bool sample_with_sun(float u1, float u2, Vec3f& d, float& pdf) const;
    float map_pdf(const Vec3f& d) const;

    const EnvironmentMap* map_ = nullptr;
    std::vector<float> weight_;            // per texel, row-major
    std::vector<float> row_cdf_;           // height + 1 entries, 0 ... 1
    std::vector<float> column_cdf_;        // height x (width + 1), each row 0 ... 1
    float inv_mean_weight_ = 0.0f;
    float mean_luminance_ = 0.0f;
    // The sun's cone (map frame); sun_share_ == 0 when the map has no sun.
    float sun_share_ = 0.0f;
    float sun_cone_pdf_ = 0.0f;  // 1 / solid angle
    Vec3f sun_t_, sun_b_;        // basis around map_->sun_dir
};

// Cycles' equirectangular mapping (map frame) and its inverse.
Vec2f direction_to_equirect(const Vec3f& d);
Vec3f equirect_to_direction(float u, float v);

}  // namespace coherent
