// The native denoiser: dual-buffer non-local means with feature weights
// (Rousselle, Manzi and Zwicker 2012, "Adaptive rendering with non-local
// means filtering"; the feature term as in their 2013 "Robust denoising
// using feature and color information"), on albedo-demodulated radiance.
//
// Inputs are the film's two half-buffers (the even and the odd sample
// passes, independent by construction, film.h) and its feature buffers
// (Denoising Albedo and Normal, denoising_features.h):
//   1. Demodulate: each half's mean radiance is divided by the albedo, so
//      textures are never blurred (they come back with the albedo).
//   2. Cross-filter: each half is filtered with weights computed from the
//      OTHER half. The weights are then independent of the noise they
//      average, so the filter neither locks onto its own outliers nor hides
//      them, and the two filtered halves stay (nearly) independent.
//   3. Weights: a pixel q in the search window of p counts with
//        exp(-(max(0, patch distance of p, q in the guide half) + feature distance))
//      where the patch distance is the mean over a patch and RGB of
//        ((G_p - G_q)^2 - (v_p + v_q)) / (eps + k^2 (v_p + v_q))
//      (v: the guide's estimated variance, so pixels that differ only by
//      noise have distance ~0), and the feature distance adds albedo and
//      normal differences beyond their own noise, in units of fixed
//      tolerances (kernels stay on one side of object and texture edges).
//   4. Recombine the filtered halves as the film combines the raw ones, and
//      estimate the result's error from their difference exactly as
//      Film::relative_rmse_estimate() does for the raw image. That estimate
//      sees the filter's remaining noise, not its bias (blur): it is a lower
//      bound in spirit, measured against references in tests/.
#pragma once

#include <atomic>
#include <functional>
#include <vector>

#include "../film/film.h"

namespace coherent {

struct DenoiseOptions {
    // Scales the colour tolerance k: 0 keeps only pixels equal within noise.
    float strength = 1.0f;
    int window_radius = 4;  // regression window (2r+1)^2
    int patch_radius = 3;   // patch (2f+1)^2 of the colour distance
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

}  // namespace coherent
