// A Sky Texture as the world (Background <- Sky Texture): the world radiance
// is exactly the sky's (EnvironmentMap::sky, evaluated per direction like
// Cycles' background shader), while an equirectangular bake of it gives the
// importance-sampling distribution (render/world_sampling.h), just as for an
// HDRI. The Nishita sun disc, smaller than a texel's neighbourhood, is left
// out of the bake and sampled as a cone instead (EnvironmentMap::sun_*, with
// its power measured over the disc), so a sky-lit scene converges like an
// HDRI-lit one. The pdf is the sampler's own, so estimates are unbiased
// whatever the bake's error.
#pragma once

#include <memory>

#include "../scene/world.h"
#include "sky_model.h"

namespace coherent {

// Sampling bake size: texels of 0.7 degrees. The sky without its disc
// changes slowly (its brightest gradient, the Mie glow around the sun, spans
// degrees), and the bake only shapes the pdf, so finer buys little and
// costs 4x the evaluations per halving.
constexpr int kSkyBakeWidth = 512;
constexpr int kSkyBakeHeight = 256;

// `rotation`: row-major world -> sky frame (the Mapping node), or null.
EnvironmentMap make_sky_environment(std::shared_ptr<const SkyTexture> sky, const float* rotation = nullptr,
                                    int width = kSkyBakeWidth, int height = kSkyBakeHeight);

}  // namespace coherent
