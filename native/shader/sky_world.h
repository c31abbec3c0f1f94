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

// Sampling bake size: 1024 x 512 texels of 0.35 degrees, finer than the
// default sun (0.545 degrees) and small enough to bake in milliseconds.
constexpr int kSkyBakeWidth = 1024;
constexpr int kSkyBakeHeight = 512;

// `rotation`: row-major world -> sky frame (the Mapping node), or null.
EnvironmentMap make_sky_environment(std::shared_ptr<const SkyTexture> sky, const float* rotation = nullptr,
                                    int width = kSkyBakeWidth, int height = kSkyBakeHeight);

}  // namespace coherent
