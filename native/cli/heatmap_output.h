// The heatmap images of `coherent render --heatmaps`: for each diagnostic
// film pass (BVH node visits per camera sample, SIMD lane utilisation), the
// raw values as a one-channel float EXR and a false-colour PNG an artist can
// read at a glance (viridis: dark blue = low, yellow = high).
#pragma once

#include <string>
#include <vector>

#include "film/film.h"

namespace coherent::cli {

// Perceptually uniform colour map (matplotlib's viridis, 17 samples,
// linearly interpolated): t in [0, 1] -> display (sRGB-encoded) RGB in
// [0, 1]. t outside [0, 1] is clamped, NaN maps to 0.
void viridis(float t, float rgb[3]);

// One heatmap pass as written to disk.
struct HeatmapImage {
    PassType pass;
    std::string exr_path, png_path;
    // The PNG's colour scale: lo maps to the darkest colour, hi to the
    // brightest; values beyond are clamped (they stay exact in the EXR).
    float lo = 0.0f, hi = 1.0f;
    float min = 0.0f, max = 0.0f, mean = 0.0f;  // of the pass's values
};

// "dir/render.exr" + "bvh_visits" + ".png" -> "dir/render.bvh_visits.png".
std::string heatmap_path(const std::string& output, const std::string& suffix, const std::string& extension);

// Resolves the NodeVisits and SimdUtilisation passes of `film` and writes
// OUT_stem.bvh_visits.{exr,png} and OUT_stem.simd.{exr,png} next to
// `output`. Scales: visits [0, max visits] (at least [0, 1]), utilisation
// the fixed [0, 1] so that renders compare. Returns false with a one-line
// `error` naming the file if one cannot be written.
bool write_heatmaps(const std::string& output, const Film& film, std::vector<HeatmapImage>& written,
                    std::string& error);

}  // namespace coherent::cli
