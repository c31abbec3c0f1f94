// A Sky Texture as the world (Background <- Sky Texture): the world radiance
// is exactly the sky's (EnvironmentMap::sky, evaluated per direction like
// Cycles' background shader), while an equirectangular bake of it gives the
// importance-sampling distribution (render/world_sampling.h), just as for an
// HDRI. The bake resolves the sun disc: texels near it average a grid of
// samples instead of taking their centre, so a disc smaller than a texel
// still carries its power into the distribution (and the sampler's 3x3
// dilation then covers the disc), which is what makes a sky-lit scene
// converge like an HDRI-lit one. The pdf stays the bake's, so estimates are
// unbiased whatever the bake's error.
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
