// NLM-guided first-order regression (denoiser.h).
//
// Every filter runs over bands of rows in parallel (TBB). Per band it first
// stores the weights of every (pixel, window offset) pair: for each offset,
// the per-pixel colour distances of (p, p + d) in both guides, box filtered
// over the patch (running sums: O(1) per pixel whatever the patch). Then it
// runs row by row over all offsets, so that one row's normal equations stay
// in cache. Each band writes only its own rows, so the result does not
// depend on the thread count.
#include "denoiser.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <thread>

namespace coherent {

namespace {

// The colour tolerance of the weights (NFOR's larger candidate, k = 1: a
// regression tolerates wider windows than a weighted mean) and the normals'
// tolerance (unit-vector distance: 0.25 ~ 14 degrees).
constexpr float kColourK = 1.0f;
constexpr float kNormalSigma = 0.25f;
constexpr float kEpsilon = 1e-10f;
// Half side of the box over which the noisy per-pixel variances are averaged.
constexpr int kVarianceRadius = 2;
constexpr int kBandRows = 8;
// The log depth of a pixel no sample hit (the world): log(1e10), Cycles'
// depth there, so that it never weighs with a surface.
constexpr float kNoHitLogDepth = 23.0f;
// Tolerance of the weights for log-depth differences: a neighbour 20 %
// nearer or farther than the centre weighs exp(-1) x its colour and normal
// weight. An object's silhouette over the surface behind it differs by far
// more, while a floor seen at a grazing angle changes by a few % a pixel.
// Depth separates surfaces that share normal and albedo (a box face in
// front of a parallel wall), which the colour patches see only once the
// noise is below their difference.
constexpr float kDepthSigma = 0.2f;
// Window radius of the first pass (non-local means), whose output only
// guides the regressions' weights: 3 x 3. Wider guides (7 x 7, the window
// of the regressions) made the weights too selective at 128 x 128 (the
// Cornell box at 16 spp 0.060 against 0.050, docs/results/denoise.md) and
// cost more; no guide at all (the raw halves) lost small highlights (the
// glass and many-lights scenes).
constexpr int kGuideWindowRadius = 1;
// Half side of the box over which the candidates' estimated errors are summed.
constexpr int kSelectionRadius = 1;

// The filter's inputs as planes (one float per pixel each), so the inner
// loops over a row run over contiguous floats and vectorise.
enum Plane : int {
    kA,                  // demodulated mean of the even half, 3 planes (RGB)
    kB = kA + 3,         // of the odd half
    kVarA = kB + 3,      // estimated variance of kA's means
    kVarB = kVarA + 3,
    kAlbedo = kVarB + 3,
    kNormal = kAlbedo + 3,
    kNormalVar = kNormal + 3,  // variance of the normal's mean, summed over channels
    kDepth,              // log of the mean depth of the samples that hit (kNoHitLogDepth if none)
    kValid,              // 1 where the pixel has samples, else 0
    kGuideA,             // what the weights compare: the halves, then the first pass's output
    kGuideB = kGuideA + 3,
    kGuideVarA = kGuideB + 3,
    kGuideVarB = kGuideVarA + 3,
    kPlaneCount = kGuideVarB + 3
};

struct Image {
    int width = 0, height = 0;
    std::vector<float> planes[kPlaneCount];
    std::vector<float> modulation;        // 3 a pixel: what the full mean is remodulated with
    std::vector<float> n_even, n_odd;     // samples per half
    float* plane(int p) { return planes[p].data(); }
    const float* plane(int p) const { return planes[p].data(); }
};

// exp(x) for x <= 0 to ~1e-4 relative: 2^(x log2 e) from the exponent bits
// and a cubic for the fraction. Unlike std::exp it vectorises, and weights
// need no more precision.
inline float exp_negative(float x) {
    const float t = std::max(x, -80.0f) * 1.44269504f;
    const float whole = std::floor(t), f = t - whole;
    const float p = 1.0f + f * (0.69606564f + f * (0.22449434f + f * 0.07944024f));
    return p * std::bit_cast<float>((int32_t(whole) + 127) << 23);
}

// Variance of a mean of n samples (a feature's or the radiance's) from its
// two halves' sums (film.h, halves_mean_variance), summed over channels; 0
// where a half is empty.
float halves_variance(const float* sum, const float* sum_odd, uint32_t n, uint32_t n_odd) {
    if (!n_odd || n_odd >= n) return 0.0f;
    double v = 0.0;
    for (int c = 0; c < 3; ++c) v += halves_mean_variance(sum[c], sum_odd[c], n, n_odd);
    return float(v);
}

// Reads pixel i of the film; false if it has samples but lacks a half.
// Each half is demodulated by its own albedo: a pixel's coverage of a bright
// emitter or a texture edge varies between the halves in colour and albedo
// alike, and the ratio cancels it.
// The demodulated halves (kA, kB) of pixel i, which has samples in both.
void read_halves(const Film::Sums& s, size_t i, Image& img) {
    const uint32_t n_odd = s.count_odd[i], n_even = s.count[i] - n_odd;
    for (int c = 0; c < 3; ++c) {
        float even_albedo = 1.0f, odd_albedo = 1.0f;
        if (s.albedo) {
            odd_albedo = s.albedo_odd[3 * i + c] / float(n_odd);
            even_albedo = (s.albedo[3 * i + c] - s.albedo_odd[3 * i + c]) / float(n_even);
        }
        const float odd = s.rgb_odd[3 * i + c] / float(n_odd);
        const float even = (s.rgba[4 * i + c] - s.rgb_odd[3 * i + c]) / float(n_even);
        img.planes[kA + c][i] = even / (std::max(even_albedo, 0.0f) + kDenoiserAlbedoBias);
        img.planes[kB + c][i] = odd / (std::max(odd_albedo, 0.0f) + kDenoiserAlbedoBias);
    }
}

bool read_pixel(const Film::Sums& s, size_t i, Image& img) {
    const uint32_t n = s.count[i], n_odd = s.count_odd[i], n_even = n - n_odd;
    img.planes[kValid][i] = n > 0 ? 1.0f : 0.0f;
    if (n == 0) return true;
    if (!n_odd || !n_even) return false;
    img.n_even[i] = float(n_even), img.n_odd[i] = float(n_odd);
    const float inv = 1.0f / float(n);
    for (int c = 0; c < 3; ++c) {
        const float albedo = s.albedo ? s.albedo[3 * i + c] * inv : 1.0f;
        img.planes[kAlbedo + c][i] = albedo;
        img.planes[kNormal + c][i] = s.normal ? s.normal[3 * i + c] * inv : 0.0f;
        img.modulation[3 * i + c] = std::max(albedo, 0.0f) + kDenoiserAlbedoBias;
    }
    read_halves(s, i, img);
    img.planes[kDepth][i] =
        s.hits[i] ? std::log(std::max(s.depth[i] / float(s.hits[i]), 1e-6f)) : kNoHitLogDepth;
    if (s.albedo) {
        img.planes[kNormalVar][i] = halves_variance(s.normal + 3 * i, s.normal_odd + 3 * i, n, n_odd);
    }
    return true;
}

// Fireflies. Cross-filtering cannot see an outlier of one half in the other
// half's weights, so a rare bright sample would be spread over the whole
// window as a blotch. As Cycles' NLM denoiser did (filter_detect_outliers),
// a half's pixel brighter than kOutlierFactor x the level of its
// neighbourhood (both halves, 5 x 5, demodulated) is scaled down to that
// level: biased (it loses some of the rare paths' energy). Cycles used 2x;
// here that clipped the demodulated illumination of pixels on an emitter's
// edge next to a dim ceiling (relative RMSE 0.70 against 0.41 at 6x on the
// fixture's Cornell box at 16 spp, docs/results/denoise.md).
// The level is the neighbourhood's 75th percentile (Cycles') or its mean,
// whichever is larger. Where light is sparse (a dim vault that only rare
// paths bounced off a sun-lit floor reach) most halves are black and the
// percentile is 0: every half that caught a path was then clipped, to
// nothing where the other half caught none, and every pixel both halves
// caught one in was kept unfiltered as a feature. The mean is the level
// such light has (Sponza at 512 x 512, 16 spp: denoised 0.0438 -> 0.0403;
// the Cornell boxes 11-13 % lower; docs/results/denoise.md).
// That factor is for scenes with a mirror or glass lobe (DenoiseOptions::
// caustics): a caustic's paths (a diffuse bounce, then a mirror or glass
// one, then a small bright light) are the rarest and brightest, and at 9x
// they passed the level (the glass scene at 512 x 512, 16 spp: 0.154 ->
// 0.350). Without such lobes the rare bright paths are sparse diffuse light,
// which every clip biases, and the level is twice as high: Sponza 0.0403 ->
// 0.0384, the public Cornell box 0.0527 -> 0.0460 (20x: 0.0380 on Sponza;
// docs/results/denoise.md, twentieth session).
constexpr float kOutlierFactor = 6.0f;
constexpr float kSparseLightOutlierFactor = 12.0f;
// A pixel the other half also sees bright is a real feature (a highlight, a
// caustic, a small light seen directly), not an outlier: a half is clipped
// no lower than kAgreementFactor x the other half's value at that pixel.
constexpr float kAgreementFactor = 2.0f;
constexpr int kOutlierRadius = 2;

// In a scene without mirror or glass lobes only light that reached the
// camera after at most one scattering (Film::add_direct_light) can make a
// feature: a light seen directly, a highlight. There a pixel both halves
// see bright by indirect light is two rare diffuse paths that happened to
// fall into the same pixel, one in each half; kept unfiltered, it stood out
// as a white speck in the shade (Sponza at 512 x 512, 16 spp: 164 specks
// over 8x their neighbourhood's median carried 5 % of the squared error,
// docs/results/denoise.md). A pixel counts as lit directly where the direct
// light is at least this share of its radiance in both halves.
constexpr float kDirectFeatureShare = 0.5f;

// Per pixel, whether each half's direct light (Film::add_direct_light) is
// at least kDirectFeatureShare of its radiance, by luminance. Empty without
// a direct-light buffer: then every pixel may be a feature.
std::vector<uint8_t> lit_directly(const Film::Sums& s, size_t size) {
    std::vector<uint8_t> out;
    if (!s.direct) return out;
    out.assign(size, 0);
    const auto lum = [](const float* v) { return v[0] + v[1] + v[2]; };
    for (size_t i = 0; i < size; ++i) {
        const float odd = lum(s.rgb_odd + 3 * i), direct_odd = lum(s.direct_odd + 3 * i);
        const float even = lum(s.rgba + 4 * i) - odd, direct_even = lum(s.direct + 3 * i) - direct_odd;
        out[i] = direct_odd >= kDirectFeatureShare * odd && direct_even >= kDirectFeatureShare * even;
    }
    return out;
}

// find_outliers returns the pixels both halves see brighter than
// kOutlierFactor x the level (features): small features (a highlight, a
// caustic, a light seen directly) that no filter can predict from their
// neighbours, so keep_features leaves them unfiltered; and the factor
// apply_outliers scales each half's pixel by (1 where it is no outlier).
// Without caustics (DenoiseOptions::caustics) only pixels `direct` marks
// (lit_directly; all where it is empty) can be features or agree with the
// other half. Their feature level stays at kOutlierFactor where the
// clipping level is kSparseLightOutlierFactor: a highlight seen in both
// halves is a feature in any scene (at 12x, 16 noisy highlights recorded as
// direct light kept 0.61 of their light, at 6x 0.94: tests/native/
// test_denoise.cpp, SparseIndirectLightMakesNoFeaturesWithoutCaustics).
struct Outliers {
    std::vector<uint8_t> features;
    std::vector<float> scale[2];
};

Outliers find_outliers(const Image& img, bool caustics, const std::vector<uint8_t>& direct) {
    const float factor = caustics ? kOutlierFactor : kSparseLightOutlierFactor;
    const int w = img.width, h = img.height;
    const size_t size = size_t(w) * size_t(h);
    Outliers out;
    std::vector<uint8_t>& features = out.features;
    features.assign(size, 0);
    for (auto& s : out.scale) s.assign(size, 1.0f);
    std::vector<float> lum[2];
    for (int half = 0; half < 2; ++half) {
        const int g = half ? kB : kA;
        lum[half].resize(size);
        for (size_t i = 0; i < size; ++i)
            lum[half][i] = (img.planes[g][i] + img.planes[g + 1][i] + img.planes[g + 2][i]) * (1.0f / 3.0f);
    }
    tbb::parallel_for(0, h, [&](int y) {
        float values[2 * (2 * kOutlierRadius + 1) * (2 * kOutlierRadius + 1)];
        for (int x = 0; x < w; ++x) {
            const size_t i = size_t(y) * size_t(w) + size_t(x);
            if (img.planes[kValid][i] == 0.0f) continue;
            int n = 0;
            float sum = 0.0f;
            for (int yy = std::max(0, y - kOutlierRadius); yy <= std::min(h - 1, y + kOutlierRadius); ++yy)
                for (int xx = std::max(0, x - kOutlierRadius); xx <= std::min(w - 1, x + kOutlierRadius); ++xx) {
                    const size_t j = size_t(yy) * size_t(w) + size_t(xx);
                    if (img.planes[kValid][j] == 0.0f) continue;
                    values[n++] = lum[0][j];
                    values[n++] = lum[1][j];
                    sum += lum[0][j] + lum[1][j];
                }
            std::nth_element(values, values + (3 * n) / 4, values + n);
            const float level = std::max(values[(3 * n) / 4], sum / float(n)), local = factor * level;
            const bool may_agree = caustics || direct.empty() || direct[i];
            const float feature_level = kOutlierFactor * level;
            features[i] = may_agree && lum[0][i] > feature_level && lum[1][i] > feature_level;
            for (int half = 0; half < 2; ++half) {
                const float l = lum[half][i];
                const float limit = may_agree ? std::max(local, kAgreementFactor * lum[1 - half][i]) : local;
                if (l > limit) out.scale[half][i] = limit / l;
            }
        }
    });
    return out;
}

// Scales img's halves by the outliers' factors: those found in img itself,
// or in the radiance img is a part of (the parts lose what their sum's
// outliers lost).
void apply_outliers(const Outliers& o, Image& img) {
    const size_t size = o.features.size();
    for (int half = 0; half < 2; ++half)
        for (int c = 0; c < 3; ++c) {
            float* p = img.plane((half ? kB : kA) + c);
            for (size_t i = 0; i < size; ++i) p[i] *= o.scale[half][i];
        }
}

// Each half's variance, from the squared difference of halves a and b
// averaged over a small box (one pixel's is a single chi-square draw, far
// too noisy to normalise distances by). For the film's halves, Var[even
// mean] = E[(even - odd)^2] n_odd / n (by_counts); for two filtered halves
// of equal variance, half the squared difference.
void estimate_variances(Image& img, int a, int b, int var_a, int var_b, bool by_counts) {
    const int w = img.width, h = img.height;
    const size_t size = size_t(w) * size_t(h);
    std::vector<float> diff2(3 * size);
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < size; ++i) {
            const float d = img.planes[a + c][i] - img.planes[b + c][i];
            diff2[size_t(c) * size + i] = d * d;  // 0 where invalid: both halves are 0 there
        }
    tbb::parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            const size_t i = size_t(y) * size_t(w) + size_t(x);
            if (img.planes[kValid][i] == 0.0f) continue;
            float sum[3] = {0.0f, 0.0f, 0.0f}, count = 0.0f;
            for (int yy = std::max(0, y - kVarianceRadius); yy <= std::min(h - 1, y + kVarianceRadius); ++yy)
                for (int xx = std::max(0, x - kVarianceRadius); xx <= std::min(w - 1, x + kVarianceRadius); ++xx) {
                    const size_t j = size_t(yy) * size_t(w) + size_t(xx);
                    for (int c = 0; c < 3; ++c) sum[c] += diff2[size_t(c) * size + j];
                    count += img.planes[kValid][j];
                }
            const float n = img.n_even[i] + img.n_odd[i];
            const float scale_a = by_counts ? img.n_odd[i] / n : 0.5f, scale_b = by_counts ? img.n_even[i] / n : 0.5f;
            for (int c = 0; c < 3; ++c) {
                img.planes[var_a + c][i] = sum[c] / count * scale_a;
                img.planes[var_b + c][i] = sum[c] / count * scale_b;
            }
        }
    });
}

// Scratch of one band and offset: per-pixel colour distances of rows
// [y0 - f, y1 + f) in both guides and how many pairs were valid, their
// horizontal box sums, and the patch means of rows [y0, y1).
struct PatchDistances {
    std::vector<float> raw_a, raw_b, raw_n, row_a, row_b, row_n, dist_a, dist_b;
};

// A pixel's term of a patch distance is capped: where the variance is 0 (a
// noise-free albedo, an emitter's inside) it would reach 1e10 and more, and
// patch_distances' running sums, which add and later subtract each term,
// would lose the small terms beside it to rounding (a patch of equal pixels
// then came out at a distance of -6 instead of 0). 1e4 still puts one
// differing pixel of a 7 x 7 patch at a distance of 200, a weight of 0,
// while the rounding stays below 1e-2.
constexpr float kMaxDistanceTerm = 1e4f;

// The colour distance of every pixel p of `row` to p + (dx, 0) of `row_q`
// over x in [x0, x1), in guide `g` (planes g..g+2, variances v..v+2).
void row_colour_distances(const Image& img, size_t row, size_t row_q, int x0, int x1, int dx, int g, int v, float k2,
                          float* out) {
    float* o = out;
    for (int x = x0; x < x1; ++x) o[x] = 0.0f;
    for (int c = 0; c < 3; ++c) {
        const float* gp = img.plane(g + c) + row;
        const float* gq = img.plane(g + c) + row_q + dx;
        const float* vp = img.plane(v + c) + row;
        const float* vq = img.plane(v + c) + row_q + dx;
        for (int x = x0; x < x1; ++x) {
            const float diff = gp[x] - gq[x], var = vp[x] + vq[x];
            o[x] += std::min((diff * diff - var) / (kEpsilon + k2 * var), kMaxDistanceTerm) * (1.0f / 3.0f);
        }
    }
}

// Both guides' distances (dist_a, dist_b), or without `second_guide` guide
// A's alone (dist_b then 0).
void patch_distances(const Image& img, int y0, int y1, int dx, int dy, int f, float k2, PatchDistances& s,
                     bool second_guide = true) {
    const int w = img.width, h = img.height;
    const int r0 = std::max(0, y0 - f), r1 = std::min(h, y1 + f), rows = r1 - r0;
    const size_t n = size_t(rows) * size_t(w);
    for (auto* v : {&s.raw_a, &s.raw_b, &s.raw_n, &s.row_a, &s.row_b, &s.row_n}) v->assign(n, 0.0f);
    const int x0 = std::max(0, -dx), x1 = std::min(w, w - dx);
    const float* valid = img.plane(kValid);
    for (int y = r0; y < r1; ++y) {
        const int qy = y + dy;
        if (qy < 0 || qy >= h) continue;
        const size_t row = size_t(y) * size_t(w), row_q = size_t(qy) * size_t(w), base = size_t(y - r0) * size_t(w);
        row_colour_distances(img, row, row_q, x0, x1, dx, kGuideA, kGuideVarA, k2, s.raw_a.data() + base);
        if (second_guide) row_colour_distances(img, row, row_q, x0, x1, dx, kGuideB, kGuideVarB, k2, s.raw_b.data() + base);
        for (int x = x0; x < x1; ++x) {
            const float both = valid[row + size_t(x)] * valid[row_q + size_t(x + dx)];
            s.raw_a[base + size_t(x)] *= both, s.raw_b[base + size_t(x)] *= both, s.raw_n[base + size_t(x)] = both;
        }
    }
    // Horizontal, then vertical box sums (running sums), normalised by how
    // many patch pixels had both ends valid.
    for (int r = 0; r < rows; ++r) {
        const size_t base = size_t(r) * size_t(w);
        float ra = 0.0f, rb = 0.0f, rn = 0.0f;
        for (int x = 0; x < std::min(f, w); ++x) ra += s.raw_a[base + x], rb += s.raw_b[base + x], rn += s.raw_n[base + x];
        for (int x = 0; x < w; ++x) {
            if (x + f < w) ra += s.raw_a[base + x + f], rb += s.raw_b[base + x + f], rn += s.raw_n[base + x + f];
            if (x - f - 1 >= 0)
                ra -= s.raw_a[base + x - f - 1], rb -= s.raw_b[base + x - f - 1], rn -= s.raw_n[base + x - f - 1];
            s.row_a[base + x] = ra, s.row_b[base + x] = rb, s.row_n[base + x] = rn;
        }
    }
    const size_t out = size_t(y1 - y0) * size_t(w);
    s.dist_a.assign(out, 0.0f), s.dist_b.assign(out, 0.0f);
    std::vector<float>& count = s.raw_n;  // reused: raw_n is no longer needed
    for (int y = y0; y < y1; ++y) {
        const int lo = std::max(r0, y - f) - r0, hi = std::min(r1 - 1, y + f) - r0;
        float* da = s.dist_a.data() + size_t(y - y0) * size_t(w);
        float* db = s.dist_b.data() + size_t(y - y0) * size_t(w);
        float* cnt = count.data();  // first row of scratch as the per-column count
        for (int x = 0; x < w; ++x) cnt[x] = 0.0f;
        for (int r = lo; r <= hi; ++r) {
            const size_t base = size_t(r) * size_t(w);
            for (int x = 0; x < w; ++x) da[x] += s.row_a[base + x], db[x] += s.row_b[base + x], cnt[x] += s.row_n[base + x];
        }
        for (int x = 0; x < w; ++x) {
            const float inv = cnt[x] > 0.0f ? 1.0f / cnt[x] : 0.0f;
            da[x] *= inv, db[x] *= inv;
        }
    }
}

// The weights of pairs (p, p + (dx, dy)) over one row of `count` pixels,
// pointers advanced to the first pair: wa filters half a (guided by b's
// distance), wb half b. Besides the colour patches, the normals: their
// squared difference beyond their own noise, over a tolerance, keeps the
// windows on one side of a geometric edge; the log depths' squared
// difference over kDepthSigma^2, on one side of a silhouette. (No albedo
// term: the colour is demodulated and the regression fits against the
// albedo.) Plain restrict pointers, so that the loops vectorise.
void row_weights(const Image& img, ptrdiff_t p, ptrdiff_t q, const float* __restrict dist_a,
                 const float* __restrict dist_b, int count, float* __restrict wa, float* __restrict wb) {
    constexpr float kNormal2 = kNormalSigma * kNormalSigma;
    for (int x = 0; x < count; ++x) wa[x] = 0.0f;  // the normals' squared difference until the last loop
    for (int c = 0; c < 3; ++c) {
        const float* __restrict fp = img.plane(kNormal + c) + p;
        const float* __restrict fq = img.plane(kNormal + c) + q;
        for (int x = 0; x < count; ++x) wa[x] += (fp[x] - fq[x]) * (fp[x] - fq[x]);
    }
    const float* __restrict vp = img.plane(kNormalVar) + p;
    const float* __restrict vq = img.plane(kNormalVar) + q;
    const float* __restrict valid_p = img.plane(kValid) + p;
    const float* __restrict valid_q = img.plane(kValid) + q;
    const float* __restrict dp = img.plane(kDepth) + p;
    const float* __restrict dq = img.plane(kDepth) + q;
    constexpr float kDepthScale = 1.0f / (kDepthSigma * kDepthSigma);
    for (int x = 0; x < count; ++x) {
        const float v = vp[x] + vq[x];
        const float f = std::max(0.0f, wa[x] - v) / (kNormal2 + v) + kDepthScale * (dp[x] - dq[x]) * (dp[x] - dq[x]);
        const float both = valid_p[x] * valid_q[x];
        wb[x] = both * exp_negative(-(std::max(0.0f, dist_a[x]) + f));
        wa[x] = both * exp_negative(-(std::max(0.0f, dist_b[x]) + f));
    }
}

// --- first-order regression (NFOR) ---------------------------------------------
//
// For every pixel p (a window's centre), a weighted least-squares fit of the
// demodulated colour of its window's pixels q against their regressors
// relative to p's (Bitterli et al. 2016): 1, albedo_q - albedo_p and the
// screen offset over the window radius. A smooth gradient of light across
// the window is then fitted, not averaged into a blur, and the weights can
// be wider than a weighted mean's. The normals weigh (row_weights) but are
// no regressors: with them, 9 regressors instead of 6 cost 72 instead of 39
// accumulations per pair, and the 9 x 9 window they pay for beat the 7 x 7
// window with normals on 9 of 12 scenes at 128 x 128 (the dragon and the
// bunny lost 2 % and 0.5 %; docs/results/denoise.md).
// Each pair's weight in the fit is its NLM weight times q's sample count in
// that half: least squares weighted by the inverse of each mean's variance,
// as the noise of a mean of n samples is Var / n. Distribute Samples gives
// a pixel from a quarter of the mean count (at least 2) to 16 x it
// (sample_distribution.h), and a pixel with 200 samples on a shadow line
// or a silhouette then pulls its window's fit through its own, nearly
// exact mean instead of counting as much as a neighbour of 8. At 512 x
// 512, 16 spp it lowered the denoised error on 11 of 12 scenes (Sponza
// 0.0336 -> 0.0326, the public Cornell box -10 %) and raised the glass
// scene's 0.8 %; the counts' square root or power 1.5 did less, and
// weighing the evaluations (below) by the centre's count as well did worse
// (docs/results/denoise.md, twenty-fourth session). Uniformly sampled,
// every pair's count is the same: no change.
// Collaborative: every pixel's output is the weighted mean of the fits of
// all windows that contain it, each evaluated at that pixel. The weights
// are symmetric (w(p, q) = w(q, p): the patch and feature distances are),
// so the windows containing p are those of p's own offsets, and both steps
// run the same loop over offsets: first the normal equations of each
// centre, then (after every fit is solved) the evaluations.
constexpr int kAlbedoRegressors = 3;
constexpr int kRegressors = 1 + kAlbedoRegressors + 2;  // 1, albedo (3), dx / r, dy / r
constexpr int kMoments = kRegressors * (kRegressors + 1) / 2;
// Ridges on the slopes, relative to the sum of weights: a regressor that
// hardly varies over a window gets no slope from noise.
// The screen offsets span +-1 over the dense window whatever the image, and
// their slope is fitted to noisy light: 0.1.
// The albedo is (pre)filtered and nearly noise-free, but its differences
// within a window are small where they matter: a pixel on a silhouette
// whose samples see a column of albedo 0.5 and a sun-lit wall of 0.6 is as
// bright as its share of wall samples, and only its mean albedo, 0.5 to
// 0.6, says that share. A ridge of 0.1 (the moment of a 0.3 difference)
// took that slope away, and the regression averaged pixels of different
// coverage into a blur. Split into bias and variance (two seeds), 39 % of
// Sponza's denoised squared error at 512 x 512, 16 spp was the filter's
// bias, half of it on geometric edges; 1e-3 removes a third of that bias
// (tests/native/test_denoise.cpp, LowContrastAlbedoTellsTheCoverageOfA
// SilhouettePixel). At 512 x 512, 16 spp: Sponza 0.0352 -> 0.0336,
// the bunny -2.2 %, the others within 0.6 %; 1e-4 gained 0.3 % more on
// Sponza but lost 1-1.5 % on three scenes (docs/results/denoise.md,
// twenty-third session).
constexpr double kSlopeRidge = 0.1;
constexpr double kAlbedoRidge = 1e-3;

// Per band: the normal equations of each half (planes of the band's pixels):
// sum w z_i z_j (i >= j) and sum w z_i y_c.
struct NormalEquations {
    std::vector<float> moments[2][kMoments], targets[2][3 * kRegressors];
};

// Per band and offset: the regressors of one row's pairs and the weights.
struct RowScratch {
    std::vector<float> z[kRegressors];
    const float* weight[2] = {nullptr, nullptr};  // into the band's stored weights
    std::vector<float> fit_weight[2];             // weight x q's count in the half (row_fit_weights)
    void resize(int w) {
        for (auto& v : z) v.resize(size_t(w));
        for (auto& v : fit_weight) v.resize(size_t(w));
    }
};

// z of the pairs (p, q) of one row, pointers advanced to the first pair.
void row_regressors(const Image& img, ptrdiff_t p, ptrdiff_t q, int count, float sx, float sy, RowScratch& s) {
    for (int x = 0; x < count; ++x) s.z[0][size_t(x)] = 1.0f;
    for (int i = 0; i < kAlbedoRegressors; ++i) {
        const float* __restrict fp = img.plane(kAlbedo + i) + p;
        const float* __restrict fq = img.plane(kAlbedo + i) + q;
        float* __restrict z = s.z[1 + i].data();
        for (int x = 0; x < count; ++x) z[x] = fq[x] - fp[x];
    }
    std::fill_n(s.z[1 + kAlbedoRegressors].data(), count, sx);
    std::fill_n(s.z[2 + kAlbedoRegressors].data(), count, sy);
}

// The pairs' weights in the fits: each half's NLM weight times q's count
// of samples in that half (the even half is kA, the odd kB).
void row_fit_weights(const Image& img, ptrdiff_t q, int count, RowScratch& s) {
    for (int half = 0; half < 2; ++half) {
        const float* __restrict w = s.weight[half];
        const float* __restrict n = (half ? img.n_odd : img.n_even).data() + q;
        float* __restrict out = s.fit_weight[half].data();
        for (int x = 0; x < count; ++x) out[x] = w[x] * n[x];
    }
}

void accumulate_row(const float* const* colour, ptrdiff_t q, ptrdiff_t o, int count, const RowScratch& s, int half,
                    NormalEquations& eq) {
    const float* __restrict w = s.fit_weight[half].data();
    int m = 0;
    for (int i = 0; i < kRegressors; ++i)
        for (int j = 0; j <= i; ++j, ++m) {
            const float* __restrict zi = s.z[i].data();
            const float* __restrict zj = s.z[j].data();
            float* __restrict acc = eq.moments[half][m].data() + o;
            for (int x = 0; x < count; ++x) acc[x] += w[x] * zi[x] * zj[x];
        }
    for (int c = 0; c < 3; ++c) {
        const float* __restrict y = colour[c] + q;
        for (int i = 0; i < kRegressors; ++i) {
            const float* __restrict zi = s.z[i].data();
            float* __restrict acc = eq.targets[half][c * kRegressors + i].data() + o;
            for (int x = 0; x < count; ++x) acc[x] += w[x] * zi[x] * y[x];
        }
    }
}

// Solves one pixel's normal equations (Cholesky, in double) into beta
// (3 x kRegressors); without a solution, the weighted mean.
void solve_fit(const NormalEquations& eq, int half, size_t i, float* beta) {
    double a[kRegressors][kRegressors], b[3][kRegressors];
    int m = 0;
    for (int r = 0; r < kRegressors; ++r)
        for (int c = 0; c <= r; ++c, ++m) a[r][c] = a[c][r] = eq.moments[half][m][i];
    for (int c = 0; c < 3; ++c)
        for (int r = 0; r < kRegressors; ++r) b[c][r] = eq.targets[half][c * kRegressors + r][i];
    const double sum_w = a[0][0];
    for (int r = 1; r < kRegressors; ++r) a[r][r] += (r <= kAlbedoRegressors ? kAlbedoRidge : kSlopeRidge) * sum_w;
    bool ok = sum_w > 0.0;
    for (int r = 0; r < kRegressors && ok; ++r) {  // a = L L^T in the lower triangle
        for (int c = 0; c <= r; ++c) {
            double s = a[r][c];
            for (int k = 0; k < c; ++k) s -= a[r][k] * a[c][k];
            if (c < r) a[r][c] = s / a[c][c];
            else if (s > 1e-12 * sum_w) a[r][r] = std::sqrt(s);
            else ok = false;
        }
    }
    for (int c = 0; c < 3; ++c) {
        float* out = beta + c * kRegressors;
        if (!ok) {
            out[0] = sum_w > 0.0 ? float(b[c][0] / sum_w) : 0.0f;
            std::fill_n(out + 1, kRegressors - 1, 0.0f);
            continue;
        }
        double y[kRegressors];
        for (int r = 0; r < kRegressors; ++r) {
            double s = b[c][r];
            for (int k = 0; k < r; ++k) s -= a[r][k] * y[k];
            y[r] = s / a[r][r];
        }
        for (int r = kRegressors - 1; r >= 0; --r) {
            double s = y[r];
            for (int k = r + 1; k < kRegressors; ++k) s -= a[k][r] * out[k];
            out[r] = float(s / a[r][r]);
        }
    }
}

// Adds the fits of the windows centred at q = p + d, evaluated at p, to the
// band's sums (3 colour planes and the weight, per half).
void evaluate_row(const std::vector<float>& beta, ptrdiff_t q, ptrdiff_t o, int count, const RowScratch& s, int half,
                  std::vector<float>* sums, size_t size) {
    const float* __restrict w = s.weight[half];
    for (int c = 0; c < 3; ++c) {
        float* __restrict acc = sums[c].data() + o;
        const float* __restrict b0 = beta.data() + size_t(c * kRegressors) * size + q;
        for (int x = 0; x < count; ++x) acc[x] += w[x] * b0[x];
        for (int i = 1; i < kRegressors; ++i) {
            // p relative to the centre q is -z.
            const float* __restrict bi = beta.data() + size_t(c * kRegressors + i) * size + q;
            const float* __restrict zi = s.z[i].data();
            for (int x = 0; x < count; ++x) acc[x] -= w[x] * bi[x] * zi[x];
        }
    }
    float* __restrict sum_w = sums[3].data() + o;
    for (int x = 0; x < count; ++x) sum_w[x] += w[x];
}

// A window offset d: the pair (p, p + d).
struct Offset {
    int dx, dy;
};

// The offsets beyond the dense window are those whose coordinates are both
// multiples of this (window_offsets).
constexpr int kRingStride = 4;

// Every offset of the dense (2 window + 1)^2 square and, beyond it out to
// `ring`, those on the kRingStride grid: with window 4 and ring 12, 81 + 40
// pairs where a dense 25 x 25 window would weigh 625.
std::vector<Offset> window_offsets(int window, int ring) {
    const int reach = std::max(window, ring);
    std::vector<Offset> offsets;
    for (int dy = -reach; dy <= reach; ++dy)
        for (int dx = -reach; dx <= reach; ++dx) {
            const bool dense = std::abs(dx) <= window && std::abs(dy) <= window;
            if (dense || (dx % kRingStride == 0 && dy % kRingStride == 0)) offsets.push_back({dx, dy});
        }
    return offsets;
}

struct FilterParams {
    float k;      // colour tolerance
    int window;   // radius of the dense window
    int patch;    // radius
    int ring;     // radius of the sparse ring (no ring where <= window)
    std::vector<Offset> offsets;  // window_offsets(window, ring)
    int reach;    // the largest |dx| or |dy| of offsets

    FilterParams(float k_, int window_, int patch_, int ring_ = 0)
        : k(k_), window(window_), patch(patch_), ring(ring_), offsets(window_offsets(window_, ring_)),
          reach(std::max(window_, ring_)) {}
};

// Shared by the bands of one denoise(): cancelling and the progress report.
struct Run {
    const DenoiseOptions& options;
    const DenoiseProgress& progress;
    int steps = 1;  // band-phases in all
    std::thread::id caller = std::this_thread::get_id();
    std::atomic<bool> cancelled{false};
    std::atomic<int> done{0};
    std::chrono::steady_clock::time_point last_report = std::chrono::steady_clock::now();

    bool stopped() const {
        return cancelled.load(std::memory_order_relaxed) ||
               (options.cancel && options.cancel->load(std::memory_order_relaxed));
    }
    // One band-phase done. Reports only from the calling thread (it takes
    // part in the loops), at most every 100 ms.
    void step() {
        const int d = done.fetch_add(1) + 1;
        const auto now = std::chrono::steady_clock::now();
        if (!progress || std::this_thread::get_id() != caller || now - last_report < std::chrono::milliseconds(100))
            return;
        last_report = now;
        if (!progress(std::min(1.0, double(d) / double(steps)))) cancelled.store(true);
    }
};

// The weights of every pair (p, p + d) of band [y0, y1) and window offset
// d = fp.offsets[k], both halves: weights[half][(k * rows + y - y0) * width
// + x], 0 where p + d is outside. Stored, so that the fits then run row by row
// over all offsets with one row's normal equations in cache.
bool band_weights(const Image& img, const FilterParams& fp, int y0, int y1, const Run& run,
                  std::vector<float>* weights) {
    const int w = img.width, h = img.height;
    const size_t rows = size_t(y1 - y0), plane = rows * size_t(w);
    for (int half = 0; half < 2; ++half) weights[half].assign(fp.offsets.size() * plane, 0.0f);
    PatchDistances dist;
    for (size_t k = 0; k < fp.offsets.size(); ++k) {
        if (run.stopped()) return false;
        const auto [dx, dy] = fp.offsets[k];
        patch_distances(img, y0, y1, dx, dy, fp.patch, fp.k * fp.k, dist);
        const int x0 = std::max(0, -dx), x1 = std::min(w, w - dx);
        for (int y = y0; y < y1; ++y) {
            if (y + dy < 0 || y + dy >= h) continue;
            const ptrdiff_t p = ptrdiff_t(y) * w + x0, q = ptrdiff_t(y + dy) * w + dx + x0;
            const ptrdiff_t o = ptrdiff_t(y - y0) * w + x0;
            row_weights(img, p, q, dist.dist_a.data() + o, dist.dist_b.data() + o, x1 - x0,
                        weights[0].data() + k * plane + size_t(o), weights[1].data() + k * plane + size_t(o));
        }
    }
    return true;
}

// Calls visit(q, x0, count, row) for every window offset d of row y once
// row.weight and row.z hold the pairs (p, p + d) for x in [x0, x0 + count):
// q is the image offset of the first p + d.
template <class Visit>
void for_each_offset(const Image& img, const FilterParams& fp, int y, int y0, int y1,
                     const std::vector<float>* weights, RowScratch& row, Visit&& visit) {
    const int w = img.width, h = img.height;
    const float inv_r = fp.reach > 0 ? 1.0f / float(fp.reach) : 0.0f;
    const size_t plane = size_t(y1 - y0) * size_t(w);
    for (size_t k = 0; k < fp.offsets.size(); ++k) {
        const auto [dx, dy] = fp.offsets[k];
        if (y + dy < 0 || y + dy >= h) continue;
        const int x0 = std::max(0, -dx), x1 = std::min(w, w - dx);
        const ptrdiff_t p = ptrdiff_t(y) * w + x0, q = ptrdiff_t(y + dy) * w + dx + x0;
        const size_t o = k * plane + size_t(y - y0) * size_t(w) + size_t(x0);
        row.weight[0] = weights[0].data() + o, row.weight[1] = weights[1].data() + o;
        row_regressors(img, p, q, x1 - x0, float(dx) * inv_r, float(dy) * inv_r, row);
        visit(q, x0, x1 - x0, row);
    }
}

// The fits of band [y0, y1), both halves, into beta[half] (3 x kRegressors
// planes of the whole image).
bool fit_band(const Image& img, const FilterParams& fp, int y0, int y1, const Run& run, std::vector<float>* beta) {
    const size_t w = size_t(img.width), size = w * size_t(img.height);
    std::vector<float> weights[2];
    if (!band_weights(img, fp, y0, y1, run, weights)) return false;
    const float* colour[2][3];
    for (int c = 0; c < 3; ++c) colour[0][c] = img.plane(kA + c), colour[1][c] = img.plane(kB + c);
    NormalEquations eq;  // of one row
    RowScratch row;
    row.resize(img.width);
    float fit[3 * kRegressors];
    for (int y = y0; y < y1; ++y) {
        for (int half = 0; half < 2; ++half) {
            for (auto& v : eq.moments[half]) v.assign(w, 0.0f);
            for (auto& v : eq.targets[half]) v.assign(w, 0.0f);
        }
        for_each_offset(img, fp, y, y0, y1, weights, row, [&](ptrdiff_t q, int x0, int count, RowScratch& r) {
            row_fit_weights(img, q, count, r);
            for (int half = 0; half < 2; ++half) accumulate_row(colour[half], q, x0, count, r, half, eq);
        });
        const size_t first = size_t(y) * w;
        for (int half = 0; half < 2; ++half)
            for (size_t x = 0; x < w; ++x) {
                solve_fit(eq, half, x, fit);
                for (int k = 0; k < 3 * kRegressors; ++k) beta[half][size_t(k) * size + first + x] = fit[k];
            }
    }
    return true;
}

// Band [y0, y1) of both filtered halves (demodulated), into out[half][c].
bool evaluate_band(const Image& img, const FilterParams& fp, int y0, int y1, const Run& run,
                   const std::vector<float>* beta, std::vector<float> (*out)[3]) {
    const size_t w = size_t(img.width), size = w * size_t(img.height);
    std::vector<float> weights[2];
    if (!band_weights(img, fp, y0, y1, run, weights)) return false;
    std::vector<float> sums[2][4];  // of one row
    RowScratch row;
    row.resize(img.width);
    for (int y = y0; y < y1; ++y) {
        for (auto& half : sums)
            for (auto& v : half) v.assign(w, 0.0f);
        for_each_offset(img, fp, y, y0, y1, weights, row, [&](ptrdiff_t q, int x0, int count, const RowScratch& r) {
            for (int half = 0; half < 2; ++half) evaluate_row(beta[half], q, x0, count, r, half, sums[half], size);
        });
        const size_t first = size_t(y) * w;
        for (int half = 0; half < 2; ++half)
            for (int c = 0; c < 3; ++c)
                for (size_t x = 0; x < w; ++x) {
                    // The centre pair always weighs 1 where valid: no division by 0.
                    const float wsum = sums[half][3][x];
                    out[half][c][first + x] = wsum > 0.0f ? sums[half][c][x] / wsum : 0.0f;
                }
    }
    return true;
}

// Band [y0, y1) of the weighted means (non-local means) of both halves,
// into out[half][c]: the regression's cheaper relative for the first pass,
// whose output only guides the second's weights.
bool mean_band(const Image& img, const FilterParams& fp, int y0, int y1, const Run& run,
               std::vector<float> (*out)[3]) {
    const size_t w = size_t(img.width);
    std::vector<float> weights[2];
    if (!band_weights(img, fp, y0, y1, run, weights)) return false;
    std::vector<float> sums[2][4];  // of one row
    const size_t plane = size_t(y1 - y0) * w;
    for (int y = y0; y < y1; ++y) {
        for (auto& half : sums)
            for (auto& v : half) v.assign(w, 0.0f);
        for (size_t k = 0; k < fp.offsets.size(); ++k) {
            const auto [dx, dy] = fp.offsets[k];
            if (y + dy < 0 || y + dy >= img.height) continue;
            const int x0 = std::max(0, -dx), count = std::min(img.width, img.width - dx) - x0;
            const ptrdiff_t q = ptrdiff_t(y + dy) * img.width + dx + x0;
            const size_t o = k * plane + size_t(y - y0) * w + size_t(x0);
            for (int half = 0; half < 2; ++half) {
                const float* __restrict wt = weights[half].data() + o;
                for (int c = 0; c < 3; ++c) {
                    const float* __restrict v = img.plane((half ? kB : kA) + c) + q;
                    float* __restrict acc = sums[half][c].data() + x0;
                    for (int x = 0; x < count; ++x) acc[x] += wt[x] * v[x];
                }
                float* __restrict acc = sums[half][3].data() + x0;
                for (int x = 0; x < count; ++x) acc[x] += wt[x];
            }
        }
        for (int half = 0; half < 2; ++half)
            for (int c = 0; c < 3; ++c)
                for (size_t x = 0; x < w; ++x) {
                    const float wsum = sums[half][3][x];
                    out[half][c][size_t(y) * w + x] = wsum > 0.0f ? sums[half][c][x] / wsum : 0.0f;
                }
    }
    return true;
}

// Runs band_work(y0, y1) over all bands in parallel; false once cancelled.
template <class Work>
bool for_each_band(const Image& img, Run& run, Work&& band_work) {
    const int bands = (img.height + kBandRows - 1) / kBandRows;
    tbb::parallel_for(tbb::blocked_range<int>(0, bands, 1), [&](const tbb::blocked_range<int>& range) {
        for (int band = range.begin(); band != range.end(); ++band) {
            const int y0 = band * kBandRows, y1 = std::min(img.height, y0 + kBandRows);
            if (run.stopped() || !band_work(y0, y1)) return;
            run.step();
        }
    });
    return !run.stopped();
}

// --- the albedo's prefilter -----------------------------------------------------
//
// The albedo is noise-free inside a surface but not in a pixel whose samples
// see two (an emitter's outline, a silhouette, texture finer than a pixel):
// there its mean carries the same coverage noise as the radiance. Each half
// is demodulated by its own albedo, which cancels that noise in the filtered
// illumination (read_halves), but remodulating with the pixel's noisy mean
// albedo brought it back: on the emissive-mesh scene at 512 x 512, 16 spp,
// the one row of pixels on the ceiling light's edge held 38 % of the
// denoised image's squared error. So, as NFOR prefilters its features, the
// mean albedo is first filtered by non-local means in units of its own
// variance, and the regressions and the remodulation use the result: along
// an edge, pixels whose albedo differs only by noise are averaged, while a
// real difference (a texture, the other side of the edge) weighs
// exp(-difference^2 / variance). With an 11 x 11 window and 5 x 5 patches
// the emissive mesh's error fell by 15 %, the Cornell boxes' by 4-7 %, and
// no other scene of the 12 measured moved by more than 1.2 %, while 15 x 15
// windows or k = 2 blurred Sponza's textures (docs/results/denoise.md,
// fifteenth session).
constexpr int kAlbedoWindowRadius = 5;
constexpr int kAlbedoPatchRadius = 2;
constexpr float kAlbedoK = 1.0f;

// Whether each pixel has a pixel whose albedo varies between the halves
// within `radius`: elsewhere every weight of the prefilter would pick an
// equal albedo, so it is left exactly as it is.
std::vector<uint8_t> near_albedo_noise(const std::vector<uint8_t>& noisy, int w, int h, int radius) {
    // Summed-area table of the noisy pixels.
    std::vector<uint32_t> table(size_t(w + 1) * size_t(h + 1), 0);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            table[size_t(y + 1) * size_t(w + 1) + size_t(x + 1)] =
                noisy[size_t(y) * size_t(w) + size_t(x)] + table[size_t(y) * size_t(w + 1) + size_t(x + 1)] +
                table[size_t(y + 1) * size_t(w + 1) + size_t(x)] - table[size_t(y) * size_t(w + 1) + size_t(x)];
    std::vector<uint8_t> near(size_t(w) * size_t(h));
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const size_t y0 = size_t(std::max(0, y - radius)), y1 = size_t(std::min(h, y + radius + 1));
            const size_t x0 = size_t(std::max(0, x - radius)), x1 = size_t(std::min(w, x + radius + 1));
            const size_t row = size_t(w + 1);
            near[size_t(y) * size_t(w) + size_t(x)] =
                table[y1 * row + x1] + table[y0 * row + x0] > table[y0 * row + x1] + table[y1 * row + x0];
        }
    return near;
}

// Band [y0, y1) of the non-local means of guide A (the albedo) with weights
// from its own patches, into out[c] at the pixels marked in `near`.
bool albedo_band(const Image& img, const FilterParams& fp, const std::vector<uint8_t>& near, int y0, int y1,
                 const Run& run, std::vector<float>* out) {
    const int w = img.width, h = img.height, r = fp.window;
    const size_t first = size_t(y0) * size_t(w), count = size_t(y1 - y0) * size_t(w);
    if (std::none_of(near.begin() + ptrdiff_t(first), near.begin() + ptrdiff_t(first + count),
                     [](uint8_t v) { return v != 0; }))
        return true;
    std::vector<float> sums[4];
    for (auto& v : sums) v.assign(count, 0.0f);
    const float* valid = img.plane(kValid);
    PatchDistances dist;
    for (int dy = -r; dy <= r; ++dy) {
        if (run.stopped()) return false;
        for (int dx = -r; dx <= r; ++dx) {
            patch_distances(img, y0, y1, dx, dy, fp.patch, fp.k * fp.k, dist, false);
            const int x0 = std::max(0, -dx), x1 = std::min(w, w - dx);
            for (int y = std::max(y0, -dy); y < std::min(y1, h - dy); ++y) {
                const size_t o = size_t(y - y0) * size_t(w), p = size_t(y) * size_t(w);
                const size_t q = size_t(y + dy) * size_t(w);
                for (int x = x0; x < x1; ++x) {
                    const float wt = valid[p + size_t(x)] * valid[q + size_t(x + dx)] *
                                     exp_negative(-std::max(0.0f, dist.dist_a[o + size_t(x)]));
                    for (int c = 0; c < 3; ++c) sums[c][o + size_t(x)] += wt * img.planes[kGuideA + c][q + size_t(x + dx)];
                    sums[3][o + size_t(x)] += wt;
                }
            }
        }
    }
    for (size_t i = 0; i < count; ++i)
        if (near[first + i] && sums[3][i] > 0.0f)
            for (int c = 0; c < 3; ++c) out[c][first + i] = sums[c][i] / sums[3][i];
    return true;
}

// Replaces img's albedo (the regressors) and modulation by the prefiltered
// mean albedo. Uses the guide planes as scratch. False when cancelled.
bool prefilter_albedo(const Film::Sums& s, Image& img, Run& run) {
    if (!s.albedo) return true;
    const int w = img.width, h = img.height;
    const size_t size = size_t(w) * size_t(h);
    // Each channel's variance of the mean from its halves, then averaged
    // over 3 x 3: one pixel's is a single chi-square draw.
    std::vector<float> var(3 * size, 0.0f);
    std::vector<uint8_t> noisy(size, 0);
    for (size_t i = 0; i < size; ++i) {
        const uint32_t n = s.count[i], n_odd = s.count_odd[i];
        if (!n_odd || n_odd >= n) continue;
        const double scale = double(n - n_odd) * double(n_odd) / (double(n) * double(n));
        for (int c = 0; c < 3; ++c) {
            const double v = halves_mean_variance(s.albedo[3 * i + c], s.albedo_odd[3 * i + c], n, n_odd);
            var[size_t(c) * size + i] = float(v);
            // The halves' means differ by more than rounding (sums of equal
            // albedos over unequal counts differ by ~1e-7).
            const double tolerance = 1e-5 * std::abs(img.planes[kAlbedo + c][i]) + 1e-7;
            if (v > tolerance * tolerance * scale) noisy[i] = 1;
        }
    }
    if (std::none_of(noisy.begin(), noisy.end(), [](uint8_t v) { return v != 0; })) return true;
    for (int c = 0; c < 3; ++c) {
        img.planes[kGuideA + c] = img.planes[kAlbedo + c];
        float* out = img.plane(kGuideVarA + c);
        const float* in = var.data() + size_t(c) * size;
        tbb::parallel_for(0, h, [&](int y) {
            for (int x = 0; x < w; ++x) {
                float sum = 0.0f;
                int count = 0;
                for (int yy = std::max(0, y - 1); yy <= std::min(h - 1, y + 1); ++yy)
                    for (int xx = std::max(0, x - 1); xx <= std::min(w - 1, x + 1); ++xx, ++count)
                        sum += in[size_t(yy) * size_t(w) + size_t(xx)];
                out[size_t(y) * size_t(w) + size_t(x)] = sum / float(count);
            }
        });
    }
    const FilterParams fp{kAlbedoK, kAlbedoWindowRadius, kAlbedoPatchRadius};
    const std::vector<uint8_t> near = near_albedo_noise(noisy, w, h, fp.window + fp.patch + 1);
    std::vector<float> filtered[3];
    for (int c = 0; c < 3; ++c) filtered[c] = img.planes[kAlbedo + c];
    if (!for_each_band(img, run, [&](int y0, int y1) { return albedo_band(img, fp, near, y0, y1, run, filtered); }))
        return false;
    for (size_t i = 0; i < size; ++i) {
        if (!near[i]) continue;
        for (int c = 0; c < 3; ++c) {
            img.planes[kAlbedo + c][i] = filtered[c][i];
            img.modulation[3 * i + size_t(c)] = std::max(filtered[c][i], 0.0f) + kDenoiserAlbedoBias;
        }
    }
    return true;
}

void allocate_halves(size_t size, std::vector<float> (*out)[3]) {
    for (int half = 0; half < 2; ++half)
        for (int c = 0; c < 3; ++c) out[half][c].assign(size, 0.0f);
}

// One regression filter of both halves with weights from the guide planes,
// into out[half][c] (demodulated). False when cancelled.
bool regression_filter(const Image& img, const FilterParams& fp, Run& run, std::vector<float> (*out)[3]) {
    const size_t size = size_t(img.width) * size_t(img.height);
    std::vector<float> beta[2];
    for (auto& b : beta) b.assign(size_t(3 * kRegressors) * size, 0.0f);
    allocate_halves(size, out);
    return for_each_band(img, run, [&](int y0, int y1) { return fit_band(img, fp, y0, y1, run, beta); }) &&
           for_each_band(img, run, [&](int y0, int y1) { return evaluate_band(img, fp, y0, y1, run, beta, out); });
}

// The filtered halves' combination and its relative RMSE estimate (film.h).
DenoiseResult combine(const Image& img, const std::vector<float>& fa, const std::vector<float>& fb) {
    DenoiseResult r;
    r.rgb.assign(fa.size(), 0.0f);
    double err2 = 0.0, mean = 0.0;
    const size_t size = size_t(img.width) * size_t(img.height);
    for (size_t i = 0; i < size; ++i) {
        if (img.planes[kValid][i] == 0.0f) continue;
        const double ne = img.n_even[i], no = img.n_odd[i], n = ne + no;
        const double scale = ne * no / (n * n);
        for (int c = 0; c < 3; ++c) {
            const double a = fa[3 * i + c], b = fb[3 * i + c];
            const double v = (ne * a + no * b) / n;
            r.rgb[3 * i + c] = std::isfinite(v) ? float(v) : 0.0f;
            err2 += (a - b) * (a - b) * scale;
            mean += v;
        }
    }
    const double count = 3.0 * double(size);
    mean /= count;
    r.error_estimate = mean > 0.0 ? std::sqrt(err2 / count) / mean : 0.0;
    if (!std::isfinite(r.error_estimate)) r.error_estimate = -1.0;
    return r;
}

// The guides of the next pass: the given halves (planes a..a+2, b..b+2).
void set_guides(Image& img, const std::vector<float> (*halves)[3]) {
    for (int c = 0; c < 3; ++c) img.planes[kGuideA + c] = halves[0][c], img.planes[kGuideB + c] = halves[1][c];
}

using Halves = std::vector<float>[2][3];

// Per-pixel selection between candidate filters (Bitterli et al.'s
// selection): each candidate's squared error is estimated from the other
// half, ((filtered a - raw b)^2 - Var b + (filtered b - raw a)^2 - Var a)
// in remodulated units, summed over a box (one pixel's is a single noisy
// draw); each pixel takes the candidate with the smallest sum.
void select_candidates(const Image& img, const std::vector<const Halves*>& candidates, Halves& out) {
    const int w = img.width, h = img.height;
    const size_t size = size_t(w) * size_t(h);
    std::vector<std::vector<float>> error(candidates.size(), std::vector<float>(size, 0.0f));
    for (size_t k = 0; k < candidates.size(); ++k) {
        const Halves& f = *candidates[k];
        for (size_t i = 0; i < size; ++i)
            for (int c = 0; c < 3; ++c) {
                const float m = img.modulation[3 * i + size_t(c)];
                const float da = f[0][c][i] - img.planes[kB + c][i], db = f[1][c][i] - img.planes[kA + c][i];
                error[k][i] += m * m * (da * da - img.planes[kVarB + c][i] + db * db - img.planes[kVarA + c][i]);
            }
    }
    allocate_halves(size, out);
    tbb::parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            size_t best = 0;
            double best_error = 0.0;
            for (size_t k = 0; k < candidates.size(); ++k) {
                double e = 0.0;
                for (int yy = std::max(0, y - kSelectionRadius); yy <= std::min(h - 1, y + kSelectionRadius); ++yy)
                    for (int xx = std::max(0, x - kSelectionRadius); xx <= std::min(w - 1, x + kSelectionRadius); ++xx)
                        e += error[k][size_t(yy) * size_t(w) + size_t(xx)];
                if (k == 0 || e < best_error) best = k, best_error = e;
            }
            const size_t i = size_t(y) * size_t(w) + size_t(x);
            for (int half = 0; half < 2; ++half)
                for (int c = 0; c < 3; ++c) out[half][c][i] = (*candidates[best])[half][c][i];
        }
    });
}

// The pixels find_outliers found bright in both halves take their own
// (clipped) halves: filtering would spread them over their neighbours.
void keep_features(const Image& img, const std::vector<uint8_t>& features, Halves& out) {
    for (size_t i = 0; i < features.size(); ++i)
        if (features[i])
            for (int c = 0; c < 3; ++c) out[0][c][i] = img.planes[kA + c][i], out[1][c][i] = img.planes[kB + c][i];
}

// The filtered halves (demodulated planes), remodulated and added to
// fa, fb (3 floats a pixel each).
void add_remodulated(const Image& img, const std::vector<float> (*halves)[3], std::vector<float>& fa,
                     std::vector<float>& fb) {
    const size_t size = size_t(img.width) * size_t(img.height);
    for (size_t i = 0; i < size; ++i) {
        if (img.planes[kValid][i] == 0.0f) continue;
        for (int c = 0; c < 3; ++c) {
            const float m = img.modulation[3 * i + size_t(c)];
            fa[3 * i + size_t(c)] += halves[0][c][i] * m, fb[3 * i + size_t(c)] += halves[1][c][i] * m;
        }
    }
}

// Replaces img's halves by those of `sums`, a part of the film img was read
// from (read_image): the features, counts and modulation stay.
void read_part_halves(const Film::Sums& sums, Image& img) {
    const size_t size = size_t(img.width) * size_t(img.height);
    for (size_t i = 0; i < size; ++i)
        if (img.planes[kValid][i] != 0.0f) read_halves(sums, i, img);
}

// Reads the film's sums into img; false if some pixel with samples lacks a half.
bool read_image(const Film::Sums& sums, int width, int height, Image& img) {
    img.width = width, img.height = height;
    const size_t size = size_t(width) * size_t(height);
    for (std::vector<float>& p : img.planes) p.assign(size, 0.0f);
    img.modulation.assign(3 * size, 1.0f);
    img.n_even.assign(size, 0.0f), img.n_odd.assign(size, 0.0f);
    for (size_t i = 0; i < size; ++i)
        if (!read_pixel(sums, i, img)) return false;
    return true;
}

// The whole filter on one signal (img, read_image): its outliers (found in
// it, or in the radiance it is a part of) scaled, the guide, the regressions
// (both candidates, or the larger patch's alone), their selection; the
// filtered halves remodulated and added to fa, fb. False when cancelled.
bool filter_signal(Image& img, const Outliers& outliers, const FilterParams& params, bool both_candidates, Run& run,
                   std::vector<float>& fa, std::vector<float>& fb) {
    const size_t size = size_t(img.width) * size_t(img.height);
    apply_outliers(outliers, img);
    const std::vector<uint8_t>& features = outliers.features;
    estimate_variances(img, kA, kB, kVarA, kVarB, true);
    for (int c = 0; c < 3; ++c) {
        img.planes[kGuideA + c] = img.planes[kA + c], img.planes[kGuideB + c] = img.planes[kB + c];
        img.planes[kGuideVarA + c] = img.planes[kVarA + c], img.planes[kGuideVarB + c] = img.planes[kVarB + c];
    }
    // First pass: non-local means over a 3 x 3 window. Its output only
    // guides the second pass's weights; there a regression first pass
    // measured no better (docs/results/denoise.md) at 3x the cost.
    Halves first, second, third, selected;
    allocate_halves(size, first);
    const FilterParams guide(params.k, std::min(params.window, kGuideWindowRadius), params.patch);
    if (!for_each_band(img, run, [&](int y0, int y1) { return mean_band(img, guide, y0, y1, run, first); }))
        return false;
    // Second pass: regressions of the raw halves, with weights from the
    // first pass's output, whose patches are far less noisy; two candidates
    // (patches 7 x 7 and 3 x 3: the smaller follows finer detail, the larger
    // averages more; both over params' ring where it has one), selected per
    // pixel, or the 7 x 7 alone.
    set_guides(img, first);
    estimate_variances(img, kGuideA, kGuideB, kGuideVarA, kGuideVarB, false);
    if (!regression_filter(img, params, run, second)) return false;
    if (both_candidates) {
        const FilterParams small_patch(params.k, params.window, std::min(params.patch, 1), params.ring);
        if (!regression_filter(img, small_patch, run, third)) return false;
        select_candidates(img, {&second, &third}, selected);
    } else {
        for (int half = 0; half < 2; ++half)
            for (int c = 0; c < 3; ++c) selected[half][c] = std::move(second[half][c]);
    }
    keep_features(img, features, selected);
    add_remodulated(img, selected, fa, fb);
    return true;
}

// Sums of a film's part: `direct` (Film::add_direct_light) or the rest of
// the radiance, in the layout of Film::Sums (rgba 4 floats a pixel, alpha
// kept; rgb_odd 3).
struct PartSums {
    std::vector<float> rgba, rgb_odd;
    Film::Sums sums;
    PartSums(const Film::Sums& film, size_t size, bool direct) : rgba(4 * size), rgb_odd(3 * size), sums(film) {
        for (size_t i = 0; i < size; ++i) {
            rgba[4 * i + 3] = film.rgba[4 * i + 3];
            for (int c = 0; c < 3; ++c) {
                const float d = film.direct[3 * i + c], d_odd = film.direct_odd[3 * i + c];
                rgba[4 * i + c] = direct ? d : film.rgba[4 * i + c] - d;
                rgb_odd[3 * i + c] = direct ? d_odd : film.rgb_odd[3 * i + c] - d_odd;
            }
        }
        sums.rgba = rgba.data(), sums.rgb_odd = rgb_odd.data();
    }
};

// Direct light (Film::add_direct_light) and the rest of the radiance are
// filtered apart and added when the direct light is at least
// kSplitLightShare of the image's light. Where its noise is small, its
// detail (shadow edges, bump shading at pixel scale, an emitter's outline)
// is sharper than its noise, and filtered whole it stops the colour weights
// from averaging the indirect light's noise across that detail: on the
// Stanford bunny at 512 x 512, 16 spp, relative RMSE 0.032 -> 0.018
// (docs/results/denoise.md, fourteenth session).
//
// Where the direct light carries kDirectRingNoiseShare of the image's
// estimated variance or more, its smooth stretches need the ring
// (DenoiseOptions::ring_radius) as much as the indirect light does.
// Measured shares at 512 x 512, 16 spp: an HDRI world, many lamps and an
// emissive panel 0.73-0.79; the sky world and Sponza 0.23; the glass scene
// 0.11; the Cornell boxes, the sun-lit scene, the bunny and the dragon
// 0.009-0.023. Until the eighteenth session images whose share exceeded
// 0.5 were filtered whole, because split without the ring on the direct
// part they measured no better. Split with it (seeds 1 and 2): the HDRI
// world 0.0156 -> 0.0142, many lights 0.0303 -> 0.0292, the emissive panel
// (seeds 7 and 8) 0.0118 -> 0.0109, the sky world 0.0136 -> 0.0125, Sponza
// 0.0502 -> 0.0503. Below the share the direct part keeps the dense
// window: there the ring gained 0-2 % for a quarter more of the
// denoiser's time (the fixture's Cornell box at 64 spp: 7.7-8.2 ->
// 9.3-12.1 % of the render).
constexpr double kSplitLightShare = 0.1;
constexpr double kDirectRingNoiseShare = 0.15;

struct DirectSplit {
    bool apart = false;        // direct light and the rest filtered apart
    bool direct_ring = false;  // the direct part's regression weighs the ring too
};

DirectSplit split_direct_light(const Film::Sums& s, size_t size) {
    if (!s.direct) return {};
    double var_all = 0.0, var_direct = 0.0, light_all = 0.0, light_direct = 0.0;
    for (size_t i = 0; i < size; ++i) {
        const uint32_t n = s.count[i], n_odd = s.count_odd[i];
        if (!n) continue;
        var_all += halves_variance(s.rgba + 4 * i, s.rgb_odd + 3 * i, n, n_odd);
        var_direct += halves_variance(s.direct + 3 * i, s.direct_odd + 3 * i, n, n_odd);
        for (int c = 0; c < 3; ++c) {
            light_all += s.rgba[4 * i + c] / double(n);
            light_direct += s.direct[3 * i + c] / double(n);
        }
    }
    DirectSplit split;
    split.apart = light_all > 0.0 && light_direct >= kSplitLightShare * light_all;
    split.direct_ring = split.apart && var_direct >= kDirectRingNoiseShare * var_all;
    return split;
}

// DenoiseOptions::ring_radius, but at most a sixteenth of the shorter side:
// on a small image the ring spans a large part of the frame, where light is
// no longer smooth, and it measured no gain (the fixture's Cornell box at
// 64 x 64, 16 spp, three seeds: 0.1767 without, 0.1771 with a radius of 12),
// while the error estimate, which sees the noise and not the bias, fell
// further below the true error (0.086 against 0.172).
int ring_radius(int width, int height, const DenoiseOptions& options) {
    return std::min(std::max(0, options.ring_radius), std::min(width, height) / 16);
}

}  // namespace

DenoiseResult denoise(const Film& film, const DenoiseOptions& options, const DenoiseProgress& progress) {
    const int width = film.width(), height = film.height();
    const size_t size = size_t(width) * size_t(height);
    if (size == 0) return {{}, 0.0};
    const Film::Sums sums = film.sums();
    Image img;
    // Fewer than 2 passes: no halves to cross-filter.
    if (!read_image(sums, width, height, img)) return {};
    const DirectSplit split = split_direct_light(sums, size);
    const int bands = (height + kBandRows - 1) / kBandRows;
    Run run{options, progress};
    // Band-phases: the albedo's prefilter, then a mean and two regressions
    // of two phases; apart, a mean and one regression for each part.
    run.steps = (split.apart ? 7 : 6) * bands;
    const float k = kColourK * std::max(0.0f, options.strength);
    const int window = std::max(0, options.window_radius), patch = std::max(0, options.patch_radius);
    // The ring (DenoiseOptions::ring_radius) goes to the regressions that
    // average smooth light: both candidates of the whole radiance and,
    // filtered apart, the indirect rest, and the direct light where it
    // carries a large share of the noise (split_direct_light).
    const FilterParams dense(k, window, patch), wide(k, window, patch, ring_radius(width, height, options));
    std::vector<float> fa(3 * size, 0.0f), fb(3 * size, 0.0f);
    bool complete = false;
    tbb::task_arena arena(options.threads > 0 ? options.threads : tbb::task_arena::automatic);
    arena.execute([&] {
        if (!prefilter_albedo(sums, img, run)) return;
        // With caustics any pixel may be a feature: no direct-light test to make.
        const Outliers outliers =
            find_outliers(img, options.caustics, options.caustics ? std::vector<uint8_t>{} : lit_directly(sums, size));
        if (!split.apart) {
            complete = filter_signal(img, outliers, wide, true, run, fa, fb);
            return;
        }
        // The outliers are the radiance's (where its sum is a firefly), as
        // when it is filtered whole: a part's own, dimmer neighbourhood
        // would clip more of it (measured: 2.4 % of the light lost on the
        // fixture's Cornell box against 1.3 %). One candidate each: two
        // filters then cost what one of two candidates does, and measured
        // no worse (docs/results/denoise.md).
        for (const bool direct : {true, false}) {
            const PartSums part(sums, size, direct);
            read_part_halves(part.sums, img);
            const FilterParams& params = direct && !split.direct_ring ? dense : wide;
            if (!filter_signal(img, outliers, params, false, run, fa, fb)) return;
        }
        complete = true;
    });
    if (!complete || run.stopped() || (progress && !progress(1.0))) return {};
    return combine(img, fa, fb);
}

uint64_t denoise_working_bytes(int width, int height, const DenoiseOptions& options) {
    const uint64_t pixels = uint64_t(std::max(width, 0)) * uint64_t(std::max(height, 0));
    // Live at the peak, the second candidate's regression: the image's
    // planes, its modulation and sample counts (5), the filtered sums fa and
    // fb (6), the outliers' scales (2) and one part's sums (7) when filtered
    // apart, the first pass's and both candidates' halves (3 x 6), that
    // regression's fits (2 x 3 x kRegressors), and the result (3).
    constexpr uint64_t kFloatsPerPixel = kPlaneCount + 5 + 6 + 2 + 7 + 3 * 6 + 2 * 3 * kRegressors + 3;
    // Per thread, a band's weights for every window offset, both halves,
    // and its patch distances' scratch (8 rows of the band plus the patch's).
    const uint64_t offsets = window_offsets(std::max(0, options.window_radius), ring_radius(width, height, options)).size();
    const uint64_t band_floats =
        uint64_t(std::max(width, 0)) * (2 * offsets * kBandRows +
                                         8 * uint64_t(kBandRows + 2 * std::max(0, options.patch_radius)));
    const uint64_t threads =
        options.threads > 0 ? uint64_t(options.threads) : uint64_t(tbb::this_task_arena::max_concurrency());
    // A quarter more for the allocator's slack: measured, the peak came to
    // 0.92 of the sum (640 x 480 and 1024 x 768, 2 threads).
    return (pixels * kFloatsPerPixel + threads * band_floats) * sizeof(float) * 5 / 4 + pixels;  // + the outliers' flags
}

}  // namespace coherent
