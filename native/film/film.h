// Accumulation buffers for every pass. Row 0 is the TOP row of the image;
// front ends flip if their convention differs (Blender's is bottom-up).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "../core/vec.h"
#include "cryptomatte.h"
#include "passes.h"

namespace coherent {

// NodeVisits and SimdUtilisation are diagnostic heatmap passes
// (RenderSettings::heatmaps): BVH node visits per camera sample (all rays of
// the sample's path), and the mean SIMD lane utilisation, in [0, 1], of the
// packets that traced the pixel's rays (1 for single rays, which waste no lane).
//
// Denoising (Cycles' names): DenoisingAlbedo, DenoisingNormal and
// DenoisingDepth are the feature buffers of denoise/denoising_features.h
// (zero unless enabled);
// NoisyImage is Combined as rendered. Combined itself is the denoised image
// once set_denoised() was called, and NoisyImage otherwise.
enum class PassType : uint8_t {
    Combined,
    Depth,
    Normal,
    Error,
    NodeVisits,
    SimdUtilisation,
    DenoisingAlbedo,
    DenoisingNormal,
    NoisyImage,
    DenoisingDepth,
    // Cycles' light and data passes follow, one per RenderPass in its order
    // (passes.h, the one list of them): pass_type() names them.
    FirstRenderPass
};
constexpr PassType pass_type(RenderPass p) { return PassType(int(PassType::FirstRenderPass) + int(p)); }
constexpr bool is_render_pass(PassType t) { return t >= PassType::FirstRenderPass; }
constexpr RenderPass render_pass(PassType t) { return RenderPass(int(t) - int(PassType::FirstRenderPass)); }
constexpr int kPassTypeCount = int(PassType::FirstRenderPass) + kRenderPassCount;

struct PassInfo {
    PassType type;
    const char* name;  // Blender pass name
    int channels;
    const char* chan_id;  // Blender channel ids
};

const PassInfo& pass_info(PassType t);

// d^2 of one channel (Film::pixel_error): the variance of a mean of n
// samples estimated from the sums over all of them (`sum`) and over the
// n_odd odd ones (`sum_odd`). Needs both halves: 0 < n_odd < n.
inline double halves_mean_variance(double sum, double sum_odd, double n, double n_odd) {
    const double n_even = n - n_odd;
    const double d = (sum - sum_odd) / n_even - sum_odd / n_odd;
    return d * d * (n_even * n_odd / (n * n));
}

class Film {
public:
    Film() = default;
    Film(int width, int height);

    int width() const { return width_; }
    int height() const { return height_; }

    // Adds one sample's values to pixel (x, y). The caller guarantees finite
    // values (the renderer guards and counts before calling).
    // `sample` is the sample (pass) index: odd passes also go to the odd
    // half-buffer behind the error estimate below.
    void add_sample(int x, int y, const Vec3f& radiance, float alpha, float depth, const Vec3f& normal,
                    uint32_t sample = 0);

    // Running error estimate without a reference, from two half-buffers: the
    // even and the odd sample passes. Why by pass: every pass draws its
    // random numbers from sequences independent of every other pass, while
    // within a pass CPT/ICPT correlate the samples of a packet. Splitting by
    // sample index therefore gives two independent groups (per-sample-index
    // batches), so the estimate stays honest for correlated samplers, which
    // a split by pixel or by neighbourhood would not be.
    //
    // Per pixel and channel, with E, O the means of the n_e even and n_o odd
    // samples and n = n_e + n_o, the full mean is (n_e E + n_o O) / n and
    //   Var[E - O] = s^2 (1/n_e + 1/n_o) = s^2 n / (n_e n_o),
    //   Var[mean]  = s^2 / n  =  Var[E - O] * n_e n_o / n^2,
    // so d = (E - O) sqrt(n_e n_o) / n is an unbiased-in-square estimate of
    // the error of the full mean ((E - O) / 2 for n_e = n_o).
    // pixel_error(x, y): sqrt of the mean over R, G, B of d^2 (absolute
    // radiance units; 0 until a pixel has both an even and an odd sample).
    float pixel_error(int x, int y) const;
    // Mean over R, G, B of pixel (x, y)'s radiance mean (0 without samples):
    // the scale adaptive sampling judges pixel_error() against.
    double pixel_mean(int x, int y) const;
    // Image relative RMSE estimate: sqrt(mean over pixels and RGB of d^2)
    // divided by the mean over pixels and RGB of the image. The normalisation
    // by the image mean (not per pixel) keeps dark pixels from dominating and
    // needs no epsilon; it matches the bench's relative RMSE. Returns a
    // negative value when no estimate exists yet (some pixel lacks an even or
    // odd sample, i.e. fewer than 2 passes), and 0 for an all-black image.
    double relative_rmse_estimate() const;

    // Resolved pass as interleaved floats, width*height*channels, top row first.
    // Depth/Normal are from the first hit averaged over samples; Depth is inf
    // where nothing was hit (as Cycles writes 1e10). Error is pixel_error().
    std::vector<float> resolve(PassType t) const;
    void resolve_into(PassType t, float* out) const;  // out has width*height*channels floats
    uint32_t samples_at(int x, int y) const { return count_[size_t(y) * width_ + x]; }

    // Heatmaps: enable_heatmaps() allocates them (before rendering: adding
    // is not synchronised beyond distinct pixels); add_heatmap_sample() adds
    // one sample's node visits and SIMD utilisation to pixel (x, y), resolved
    // as means over these samples. Precondition of adding: enabled.
    void enable_heatmaps();
    void add_heatmap_sample(int x, int y, float node_visits, float simd_utilisation);

    // Denoising features: enable_denoising_features() allocates them (before
    // rendering, like the heatmaps); add_denoising_features() adds one
    // sample's albedo, camera-space normal and feature depth, the odd passes'
    // albedo and normal also to an odd half (the denoiser weighs feature
    // differences against their noise).
    void enable_denoising_features();
    bool has_denoising_features() const { return !albedo_.empty(); }
    void add_denoising_features(int x, int y, const Vec3f& albedo, const Vec3f& normal, float depth,
                                uint32_t sample);
    // With the features, the part of each sample's radiance that reached the
    // camera after at most one scattering (PathOutput::direct), over all
    // samples and the odd passes': the denoiser filters it apart from the
    // rest where it is a tenth of the light or more (denoiser.h).
    void add_direct_light(int x, int y, const Vec3f& direct, uint32_t sample);

    // The accumulation buffers as the denoiser reads them: per pixel i,
    // sums over all samples and over the odd passes' samples (rgba: 4 floats
    // a pixel, the others 3; albedo/normal null without features); depth:
    // the sum of the first hits' depths over the `hits` samples that hit.
    struct Sums {
        const float* rgba;
        const float* rgb_odd;
        const uint32_t* count;
        const uint32_t* count_odd;
        const float* albedo;
        const float* albedo_odd;
        const float* normal;
        const float* normal_odd;
        const float* depth;
        const uint32_t* hits;
        const float* direct;  // 3 a pixel, like albedo (null without features)
        const float* direct_odd;
    };
    Sums sums() const;

    // The denoised Combined RGB (3 floats a pixel, top row first), which
    // Combined resolves to from now on; clear() drops it.
    void set_denoised(std::vector<float> rgb);
    bool denoised() const { return !denoised_.empty(); }

    // Cycles' passes (passes.h): enable_passes() allocates the passes of
    // `mask` (before rendering, like the heatmaps; the others cost nothing);
    // add_passes() adds one sample's values to the enabled ones (Position,
    // IndexOB and IndexMA only from sample 0, as Cycles). A pass not
    // enabled resolves to zeros.
    void enable_passes(PassMask mask);
    PassMask passes() const { return passes_; }
    void add_passes(int x, int y, const PassSample& values, uint32_t sample);

    // Cryptomatte (cryptomatte.h): enable_cryptomatte() allocates the
    // types in `types` (bit per CryptoType) with `levels` ranks (rounded up
    // to even, at most 16); add_passes() adds each sample's ids.
    // resolve_cryptomatte() writes layer `layer` (ranks 2 layer, 2 layer + 1)
    // as RGBA per pixel, top row first; zeros for a type not enabled.
    void enable_cryptomatte(uint32_t types, int levels);
    uint32_t cryptomatte_types() const { return crypto_types_; }
    int cryptomatte_layers() const { return crypto_slots_ / 2; }
    void resolve_cryptomatte(CryptoType t, int layer, float* out) const;

    void clear();

    // What the film's buffers hold now, in bytes (every per-pixel array).
    uint64_t bytes() const;
    // What they will hold, per pixel, once enabled as given (the same rules
    // as enable_*; `denoised`: with the denoiser's result). The memory
    // check's estimate (render/memory_budget.h); tests compare it with bytes().
    static uint64_t bytes_per_pixel(bool heatmaps, bool denoising_features, bool denoised, PassMask passes,
                                    uint32_t cryptomatte_types, int cryptomatte_levels);

private:
    // Passes `mask` stores: Cycles divides Dir and Ind by Col, so a lobe's
    // Col comes with either of them.
    static PassMask stored_passes(PassMask mask);
    // (id, weight) slots per pixel and Cryptomatte type for `levels` ranks.
    static int cryptomatte_slots(int levels) { return 2 * ((std::clamp(levels, 1, 16) + 1) / 2); }

    // Resolves pass t (is_render_pass) of pixel i into out (its channels).
    void resolve_render_pass(PassType t, size_t i, float* out) const;

    int width_ = 0, height_ = 0;
    std::vector<float> rgba_;     // 4 per pixel, sums
    std::vector<float> depth_;    // sum of depths over samples that hit
    std::vector<float> normal_;   // 3 per pixel, sums
    std::vector<uint32_t> count_; // samples per pixel
    std::vector<uint32_t> hits_;  // samples that hit geometry
    std::vector<float> rgb_odd_;  // 3 per pixel, sums over odd passes only
    std::vector<uint32_t> count_odd_;  // odd-pass samples per pixel
    std::vector<float> heat_;     // 2 per pixel: sums of node visits, SIMD utilisation
    std::vector<uint32_t> heat_count_;  // heatmap samples per pixel
    // Denoising features, sums (3 per pixel; depth 1); empty unless enabled.
    std::vector<float> albedo_, albedo_odd_, dnormal_, dnormal_odd_, ddepth_, direct_, direct_odd_;
    std::vector<float> denoised_;  // 3 per pixel; empty until set_denoised()
    PassMask passes_ = 0;
    std::vector<float> pass_sums_[kRenderPassCount];  // channels per pixel; empty unless enabled
    uint32_t crypto_types_ = 0;
    int crypto_slots_ = 0;
    std::vector<float> crypto_[kCryptoTypeCount];  // per pixel crypto_slots_ (id, weight) pairs; id 0 = free
};

}  // namespace coherent
