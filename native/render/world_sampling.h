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
// is the largest luminance among the texel and its 8 neighbours (so the
// bilinear spill of a bright texel into dark neighbours is still sampled)
// times cos(elevation) at the row's centre. The solid-angle pdf is
//     pdf(d) = weight(texel of d) / mean(weight) / (2 pi^2 cos(elevation(d))).
// sample() and pdf() evaluate that same expression, so MIS weights agree.
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
    // map(d) for a world-space unit direction, bilinear (without strength).
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

    const EnvironmentMap* map_ = nullptr;
    std::vector<float> weight_;            // per texel, row-major
    std::vector<float> row_cdf_;           // height + 1 entries, 0 ... 1
    std::vector<float> column_cdf_;        // height x (width + 1), each row 0 ... 1
    float inv_mean_weight_ = 0.0f;
    float mean_luminance_ = 0.0f;
};

// Cycles' equirectangular mapping (map frame) and its inverse.
Vec2f direction_to_equirect(const Vec3f& d);
Vec3f equirect_to_direction(float u, float v);

}  // namespace coherent
