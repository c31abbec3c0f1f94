// Where a denoised render of a fixed sample count spends its samples
// (RenderSettings::distribute_samples).
//
// The denoiser removes most of the noise of smooth lighting, but not what it
// cannot see from a pixel's neighbours: the sub-pixel coverage of an
// emitter's or an object's edge, texture detail finer than a pixel, hard
// shadow edges, small highlights. Its remodulating albedo is a mean of the
// pixel's own samples, so that error falls only as the pixel takes more
// samples. Measured on the glTF scenes at 512 x 512 and 16 spp, 1 % of the
// pixels carried 54-92 % of the denoised image's squared error
// (docs/results/denoise.md), so a render of a fixed budget takes a part of
// it in every pixel (uniform_passes: a quarter, or half where the scene can
// make caustics) and gives the rest where the error the denoiser will leave
// is highest, the same number of samples in all (Rousselle et al. 2012 and
// most adaptive denoising renderers work this way).
//
// After the uniform passes each pixel's per-sample variance of what the
// filter keeps is estimated from its even and odd halves:
//   sum over channels of  Var[albedo] (colour / albedo)^2   (remodulation)
//                       + Var[colour] x kFilteredVarianceShare  (what the filter leaves of the rest)
// and a pixel's extra samples are proportional to the square root of that
// variance averaged over the pixels of the 5 x 5 box around it, itself left
// out, plus kEdgeVarianceShare x the variance an edge would give it:
//   sum over channels of (range of the albedo over its 8 neighbours
//                         x their mean illumination)^2
// and kShadowEdgeVarianceShare x the variance the edge of a hard shadow
// would give it:
//   sum over channels of (range of the direct light over its 8 neighbours)^2
//                        less their means' variance
// (the halves' difference misses an edge's coverage where the samples are
// stratified: sample_distribution.cpp, edge_variance and
// shadow_edge_variance). The allocation that
// minimises the sum of per-pixel variances is proportional to their
// standard deviations (Neyman). Leaving the pixel's own samples out of its
// count keeps the count independent of them, so the pixel's mean stays
// unbiased (as adaptive sampling, settings.h); that needs
// pixels whose random numbers are independent: SPT only.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include "../film/film.h"

namespace coherent {

struct SampleDistribution {
    // Passes every pixel takes before the decision, rounded down to an even
    // count (both halves equal), at least 2: a quarter of the budget, or
    // half where the scene can make caustics (SceneFeatures::
    // can_make_caustics). At 512 x 512 and 16 spp a quarter lowered the
    // denoised error of the ten scenes without a mirror or glass lobe by
    // 0-11 % (Sponza 0.0384 -> 0.0360, the bunny 0.0190 -> 0.0170), but a
    // caustic's fireflies, seen in 4 samples a pixel, drew the samples
    // after them: the glass scene 0.154 -> 0.510, the fixture's Cornell box
    // +9 % (docs/results/denoise.md, twenty-first session).
    static int uniform_passes(int spp, bool caustics) { return std::max(2, (spp / (caustics ? 2 : 4)) & ~1); }
    // No pixel takes more than this many times the budget: the passes run
    // until the largest count, and the error of a pixel falls little past it.
    static constexpr int kMaxFactor = 16;
    static int pass_limit(int spp) { return spp > (1 << 24) / kMaxFactor ? spp : spp * kMaxFactor; }
    // The share of a pixel's colour variance the filter leaves (1/16: the
    // variance reduction of its 9 x 9 regression on smooth lighting).
    static constexpr double kFilteredVarianceShare = 1.0 / 16.0;
    // The share of an edge's variance (edge_variance: coverage f (1 - f) of
    // the range between its neighbours, at most 1/4) counted for a pixel
    // next to one. At 512 x 512 and 16 spp the error was flat from 0.02 to
    // 0.1; from 0.25 on, smooth light lost too many samples (Sponza, the
    // HDRI world: docs/results/denoise.md, seventeenth session).
    static constexpr double kEdgeVarianceShare = 0.05;
    // The share of a hard shadow's edge variance (shadow_edge_variance: the
    // range of the neighbours' direct light beyond their noise) counted for
    // a pixel next to one. Sponza's sun-lit floor at 512 x 512 and 16 spp,
    // seeds 7 and 8: denoised error 0.0503 / 0.0497 without it, 0.0438 /
    // 0.0436 with 0.1; 0.05 and 0.25 gave 0.0449 and 0.0440 (seed 7), but
    // 0.25 cost the bunny and the dragon 4 and 3 % (docs/results/denoise.md,
    // nineteenth session).
    static constexpr double kShadowEdgeVarianceShare = 0.1;
    // No edge terms on images with a shorter side below this: the 3-pixel
    // band they raise along every edge is then a large share of the image.
    // On the fixture's Cornell box (seeds 7-9, 16 spp) it lowered the
    // denoised error by 7-14 % at 128 x 128 but changed it by +3, +12 and
    // -2 % at 64 x 64.
    static constexpr int kEdgeMinSide = 128;
    // Half side of the box whose pixels (the centre left out) judge a pixel.
    static constexpr int kRadius = 2;

    // Per film pixel (row-major), the sample count each should reach: even,
    // at least the count it has, at most pass_limit(spp), summing to about
    // spp x pixels (within rounding to even counts). Called after
    // uniform_passes(spp, ...) passes over the whole film. Where no pixel
    // has any variance to spend on (a black image), every pixel gets spp.
    static std::vector<uint32_t> targets(const Film& film, int spp);
};

}  // namespace coherent
