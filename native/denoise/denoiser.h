// The native denoiser: nonlinearly weighted first-order regression (Bitterli
// et al. 2016, "Nonlinearly weighted first-order regression for denoising
// Monte Carlo renderings", NFOR) on albedo-demodulated radiance, with
// dual-buffer non-local-means weights (Rousselle, Manzi and Zwicker 2012).
//
// Inputs are the film's two half-buffers (the even and the odd sample
// passes, independent by construction, film.h), its feature buffers
// (Denoising Albedo and Normal, denoising_features.h), its depth and its
// direct light:
//   1. Demodulate: each half's mean radiance is divided by its own albedo,
//      so textures are never blurred (they come back with the albedo).
//      The mean albedo that the regressions fit against and that step 5
//      remodulates with is first prefiltered by non-local means in units of
//      its own variance: where a pixel's samples see two surfaces (a light's
//      outline, a silhouette) it carries their coverage noise.
//   2. Cross-filter: each half is filtered with weights computed from the
//      OTHER half, so the weights are independent of the noise they average.
//      A weight is exp(-(colour patch distance + normal distance + depth
//      distance)), the colour and normal distances in units of their
//      estimated variance (pixels that differ only by noise have distance
//      ~0), the depth's as a relative difference over a tolerance.
//   3. First pass: non-local means (a weighted mean) over a 3 x 3 window.
//      Its output guides the second pass's weights: its patches are less
//      noisy than the raw halves'.
//   4. Second pass: per pixel, a weighted least-squares fit of the colour of
//      its 9 x 9 window against 1, albedo and screen offset; every pixel's
//      output averages the fits of all windows containing it (collaborative).
//      Two candidates (7 x 7 and 3 x 3 patches) are selected per pixel by
//      their error estimated from the other half. Both candidates, or the
//      indirect light when filtered apart (below), also weigh a sparse ring
//      of pixels out to 25 x 25 (DenoiseOptions::ring_radius), and so does
//      the direct light where it carries 15 % of the noise or more.
//   Where the direct light (the film's add_direct_light: what reached the
//   camera after at most one scattering) is a tenth of the light or more,
//   it and the rest of the radiance go through steps 1-4 apart (one
//   candidate each, with the outliers of their sum) and are added: its
//   sharp detail would otherwise keep the weights from averaging the
//   indirect noise.
//   5. Remodulate with the prefiltered albedo, recombine the filtered halves
//      as the film combines the raw ones, and estimate the result's error
//      from their difference exactly as
//      Film::relative_rmse_estimate() does for the raw image. That estimate
//      sees the filter's remaining noise, not its bias (blur): it is a lower
//      bound in spirit, measured against references in tests/.
#pragma once

#include <atomic>
#include <functional>
#include <vector>

#include "../film/film.h"

namespace coherent {

// Added to the albedo before the radiance is divided by it (demodulated):
// black surfaces (albedo 0) stay finite and barely change what a textured
// or emissive one divides by. Distribute Samples demodulates the same way
// (render/sample_distribution.cpp).
inline constexpr float kDenoiserAlbedoBias = 0.01f;

struct DenoiseOptions {
    // Scales the colour tolerance k: 0 keeps only pixels equal within noise.
    float strength = 1.0f;
    int window_radius = 4;  // regression window (2r+1)^2
    // Beyond that window, the regressions of smooth light also weigh the
    // pixels on a 4-pixel grid out to this radius (0 or <= window_radius:
    // none; at most a sixteenth of the image's shorter side). What the dense
    // window leaves is noise at scales of 4 to 32 pixels; a dense 25 x 25
    // window would cost 7.7x the 9 x 9 one, the ring 1.5x.
    int ring_radius = 12;
    int patch_radius = 3;   // patch (2f+1)^2 of the colour distance
    // Whether the scene has a mirror or glass lobe (SceneFeatures::
    // can_make_caustics), through which a path can reach a light as a caustic: the
    // rarest, brightest paths, clipped at a lower outlier level
    // (denoiser.cpp, find_outliers). Without them only direct light can make
    // a feature (a pixel kept unfiltered). True when unknown.
    bool caustics = true;
    int threads = 0;        // 0 = all cores
    // Polled while filtering (null: none): once set, denoise() stops within
    // a fraction of a second and returns an empty result.
    const std::atomic<bool>* cancel = nullptr;
};

struct DenoiseResult {
    std::vector<float> rgb;  // 3 floats a pixel, top row first; empty if cancelled or impossible
    // Relative RMSE estimate of `rgb` from its filtered halves (as
    // Film::relative_rmse_estimate); negative when there is none.
    double error_estimate = -1.0;
};

// Called on the calling thread with the fraction done; return false to cancel.
using DenoiseProgress = std::function<bool(double fraction)>;

// Denoises the film's Combined radiance. Needs an even and an odd sample in
// every pixel that has samples (2 passes); otherwise, or when cancelled,
// returns an empty result. Without feature buffers it filters colour only.
// Pixels without samples stay 0. Never produces NaN or Inf.
DenoiseResult denoise(const Film& film, const DenoiseOptions& options = {}, const DenoiseProgress& progress = {});

// The most denoise() holds at once beside the film, in bytes, for a film of
// width x height on `threads` threads (0: all cores): its planes per pixel
// and each thread's band of weights. The memory check's estimate
// (render/memory_budget.h); tests/native/test_memory_budget.cpp measures it
// against the peak of a real denoise.
uint64_t denoise_working_bytes(int width, int height, const DenoiseOptions& options = {});

}  // namespace coherent
