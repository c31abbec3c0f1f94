// The denoiser's feature buffers, Denoising Albedo, Normal and Depth, as
// Cycles 3.4 defines them (kernel/film/passes.h,
// film_write_denoising_features_surface):
//
//   Every hit while the path still looks for its features first adds the
//   length of the ray segment that reached it times the average of the
//   feature throughput to the depth: the camera distance of a diffuse first
//   hit, and through a mirror, the length of the whole reflected path.
//   At each hit while the path still looks for its features, every BSDF
//   closure adds its albedo (its weight; a Fresnel-weighted layer times its
//   Fresnel colour at the view angle) to the diffuse-like sum when its
//   roughness^2 (alpha) exceeds 0.075, else to the specular-like sum. If
//   more than a quarter of the sample weight is diffuse-like (or there is no
//   BSDF at all), the hit writes albedo = feature throughput x diffuse-like
//   sum and normal = its shading normal in camera space, and the search
//   ends. Otherwise the feature throughput is multiplied by the
//   specular-like sum and the search continues at the next hit: a mirror
//   shows the albedo of what it reflects.
//   Emission and the world seen while searching add feature throughput x
//   their radiance to the albedo (film_write_emission_or_background_pass).
//
// The features are nearly noise-free where radiance is noisy, and they
// change exactly at texture and geometry edges: the denoiser divides the
// radiance by the albedo (so textures are never blurred) and keeps its
// kernels on one side of albedo and normal edges.
#pragma once

#include <algorithm>
#include <cmath>

#include "../core/vec.h"
#include "../render/microfacet.h"
#include "../scene/camera.h"
#include "../scene/material.h"

namespace coherent {

// Per path: whether it still looks for its features, and the specular
// throughput collected on the way (Cycles' denoising_feature_throughput).
struct DenoisingFeatureState {
    bool pending = false;
    Vec3f throughput{1.0f};
};

// Cycles: a closure is diffuse-like when alpha_x alpha_y > 0.075^2, i.e.
// (with alpha = roughness^2) when roughness > sqrt(0.075).
constexpr float kFeatureDiffuseRoughness = 0.27386128f;

// One hit of a path whose features are pending: a surface with material
// `mat`, shading normal n (world, facing wo), cos_wo = dot(n, wo), reached
// by a ray segment of length `segment`. Adds to `depth`, adds to `albedo`
// and sets `normal` (camera space) when the search ends here.
inline void record_surface_features(const Material& mat, const Vec3f& n, float cos_wo, float segment,
                                    const Camera& camera, DenoisingFeatureState& f, Vec3f& albedo, Vec3f& normal,
                                    float& depth) {
    const float d = (f.throughput.x + f.throughput.y + f.throughput.z) / 3.0f * segment;
    if (std::isfinite(d)) depth += d;  // Cycles' ensure_finite: a non-finite write adds 0
    Vec3f diffuse_like(0.0f), specular_like(0.0f);
    float sum_weight = 0.0f, diffuse_weight = 0.0f;
    const auto add = [&](const Vec3f& closure_albedo, bool diffuse) {
        const float w = (closure_albedo.x + closure_albedo.y + closure_albedo.z) / 3.0f;
        sum_weight += w;
        if (diffuse) {
            diffuse_like += closure_albedo;
            diffuse_weight += w;
        } else {
            specular_like += closure_albedo;
        }
    };
    for (int c = 0; c < mat.closure_count && c < 4; ++c) {
        const float w = mat.weights[size_t(c)];
        if (!(w > 0.0f)) continue;
        const Closure& cl = mat.closures[size_t(c)];
        const ClosureLobes lobes = closure_lobes(cl);
        const bool rough = std::clamp(cl.roughness, 0.0f, 1.0f) > kFeatureDiffuseRoughness;
        if (lobes.diffuse > 0.0f) add(cl.base_color * (w * lobes.diffuse), true);
        if (lobes.specular > 0.0f) {
            // The Fresnel colour of the specular layer at the view angle (bsdf.h).
            const float metallic = std::clamp(cl.metallic, 0.0f, 1.0f);
            const float spec = std::clamp(cl.specular, 0.0f, 1.0f);
            const Vec3f f0 = Vec3f(0.08f * spec * (1.0f - metallic)) + cl.base_color * metallic;
            const float ior = 2.0f / (1.0f - std::sqrt(0.08f * spec)) - 1.0f;
            add(fresnel_interpolated(f0, cos_wo, ior, fresnel_dielectric(1.0f, ior)) * (w * lobes.specular), rough);
        }
        if (lobes.transmission > 0.0f) add(cl.base_color * (w * lobes.transmission), rough);
    }
    if (sum_weight > 0.0f && !(4.0f * diffuse_weight > sum_weight)) {
        f.throughput *= specular_like;  // mostly specular: look through it
        if (is_black(f.throughput)) f.pending = false;
        return;
    }
    albedo += f.throughput * diffuse_like;
    if (sum_weight > 0.0f) normal = Vec3f(dot(n, camera.right), dot(n, camera.up), dot(n, camera.forward));
    f.pending = false;
}

// Emission (or the world) of radiance `le` seen while the features are pending.
inline void record_emission_feature(const DenoisingFeatureState& f, const Vec3f& le, Vec3f& albedo) {
    if (f.pending) albedo += f.throughput * le;
}

}  // namespace coherent
