// Dual-buffer NLM with feature weights (denoiser.h).
//
// The filter loops over window offsets d, and for each offset over a band
// of rows: the per-pixel colour distance of (p, p + d) in both guides, box
// filtered over the patch (running sums: O(1) per pixel whatever the
// patch), then the weights and their sums. Bands run in parallel (TBB);
// each writes only its own rows, so the result does not depend on the
// thread count.
#include "denoiser.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <thread>

namespace coherent {

namespace {

// Rousselle et al.'s colour tolerance and the feature tolerances (albedo in
// reflectance units, normal in unit-vector distance: 0.25 ~ 14 degrees).
constexpr float kColourK = 0.45f;
constexpr float kAlbedoSigma = 0.1f;
constexpr float kNormalSigma = 0.25f;
constexpr float kEpsilon = 1e-10f;
// Added to the albedo before dividing by it: black surfaces (albedo 0) stay
// finite and barely change what a textured or emissive one divides by.
constexpr float kAlbedoBias = 0.01f;
// Half side of the box over which the noisy per-pixel variances are averaged.
constexpr int kVarianceRadius = 2;
constexpr int kBandRows = 16;

// One pixel as the filter reads it.
struct Pixel {
    float a[3], b[3];          // demodulated means of the even (a) and odd (b) halves
    float va[3], vb[3];        // their estimated variances
    float albedo[3], normal[3];
    float albedo_var, normal_var;  // variance of the feature means, summed over channels
    float modulation[3];       // what demodulation divided by
    float n_even, n_odd;
    bool valid;                // has samples
};

struct Image {
    int width = 0, height = 0;
    std::vector<Pixel> px;
    const Pixel& at(int x, int y) const { return px[size_t(y) * size_t(width) + size_t(x)]; }
};

// Variance of a mean of n samples from the difference of its two halves'
// sums: |even mean - odd mean|^2 n_e n_o / n^2 (film.h), summed over channels.
float feature_variance(const float* sum, const float* sum_odd, uint32_t n, uint32_t n_odd) {
    const uint32_t n_even = n - n_odd;
    if (!n_odd || !n_even) return 0.0f;
    float v = 0.0f;
    for (int c = 0; c < 3; ++c) {
        const float d = (sum[c] - sum_odd[c]) / float(n_even) - sum_odd[c] / float(n_odd);
        v += d * d;
    }
    return v * float(n_even) * float(n_odd) / (float(n) * float(n));
}

// Reads pixel i of the film; false if it has samples but lacks a half.
// Each half is demodulated by its own albedo: a pixel's coverage of a bright
// emitter or a texture edge varies between the halves in colour and albedo
// alike, and the ratio cancels it.
bool read_pixel(const Film::Sums& s, size_t i, Pixel& p) {
    p = Pixel{};
    const uint32_t n = s.count[i], n_odd = s.count_odd[i], n_even = n - n_odd;
    p.valid = n > 0;
    if (!p.valid) return true;
    if (!n_odd || !n_even) return false;
    p.n_even = float(n_even), p.n_odd = float(n_odd);
    const float inv = 1.0f / float(n);
    for (int c = 0; c < 3; ++c) {
        float albedo = 1.0f, even_albedo = 1.0f, odd_albedo = 1.0f;
        if (s.albedo) {
            albedo = s.albedo[3 * i + c] * inv;
            odd_albedo = s.albedo_odd[3 * i + c] / float(n_odd);
            even_albedo = (s.albedo[3 * i + c] - s.albedo_odd[3 * i + c]) / float(n_even);
        }
        p.albedo[c] = albedo;
        p.normal[c] = s.normal ? s.normal[3 * i + c] * inv : 0.0f;
        p.modulation[c] = std::max(albedo, 0.0f) + kAlbedoBias;
        const float odd = s.rgb_odd[3 * i + c] / float(n_odd);
        const float even = (s.rgba[4 * i + c] - s.rgb_odd[3 * i + c]) / float(n_even);
        p.a[c] = even / (std::max(even_albedo, 0.0f) + kAlbedoBias);
        p.b[c] = odd / (std::max(odd_albedo, 0.0f) + kAlbedoBias);
    }
    if (s.albedo) {
        p.albedo_var = feature_variance(s.albedo + 3 * i, s.albedo_odd + 3 * i, n, n_odd);
        p.normal_var = feature_variance(s.normal + 3 * i, s.normal_odd + 3 * i, n, n_odd);
    }
    return true;
}

// Each half's variance: Var[even mean] = E[(even - odd)^2] n_o / n, with
// (even - odd)^2 averaged over a small box (one pixel's is a single
// chi-square draw, far too noisy to normalise distances by).
void estimate_variances(Image& img) {
    const int w = img.width, h = img.height;
    std::vector<float> diff2(size_t(w) * size_t(h) * 3, 0.0f);
    for (size_t i = 0; i < img.px.size(); ++i)
        for (int c = 0; c < 3; ++c) {
            const float d = img.px[i].a[c] - img.px[i].b[c];
            diff2[3 * i + c] = img.px[i].valid ? d * d : 0.0f;
        }
    tbb::parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            Pixel& p = img.px[size_t(y) * size_t(w) + size_t(x)];
            if (!p.valid) continue;
            float sum[3] = {0.0f, 0.0f, 0.0f};
            int count = 0;
            for (int yy = std::max(0, y - kVarianceRadius); yy <= std::min(h - 1, y + kVarianceRadius); ++yy)
                for (int xx = std::max(0, x - kVarianceRadius); xx <= std::min(w - 1, x + kVarianceRadius); ++xx) {
                    const size_t j = size_t(yy) * size_t(w) + size_t(xx);
                    if (!img.px[j].valid) continue;
                    for (int c = 0; c < 3; ++c) sum[c] += diff2[3 * j + c];
                    ++count;
                }
            const float n = p.n_even + p.n_odd;
            for (int c = 0; c < 3; ++c) {
                const float mean = sum[c] / float(count);
                p.va[c] = mean * p.n_odd / n;
                p.vb[c] = mean * p.n_even / n;
            }
        }
    });
}

// Fireflies. Cross-filtering cannot see an outlier of one half in the other
// half's weights, so a rare bright sample would be spread over the whole
// window as a blotch. As Cycles' NLM denoiser did (filter_detect_outliers),
// a half's pixel brighter than kOutlierFactor x the 75th percentile of its
// neighbourhood (both halves, 5 x 5, demodulated) is scaled down to that
// level: biased (it loses some of the rare paths' energy). Cycles used 2x;
// here that clipped the demodulated illumination of pixels on an emitter's
// edge next to a dim ceiling (relative RMSE 0.70 against 0.41 at 6x on the
// fixture's Cornell box at 16 spp, docs/results/denoise.md).
constexpr float kOutlierFactor = 6.0f;
constexpr int kOutlierRadius = 2;

inline float mean3(const float* v) { return (v[0] + v[1] + v[2]) * (1.0f / 3.0f); }

void suppress_outliers(Image& img) {
    const int w = img.width, h = img.height;
    const std::vector<Pixel> before = img.px;
    tbb::parallel_for(0, h, [&](int y) {
        float values[2 * (2 * kOutlierRadius + 1) * (2 * kOutlierRadius + 1)];
        for (int x = 0; x < w; ++x) {
            Pixel& p = img.px[size_t(y) * size_t(w) + size_t(x)];
            if (!p.valid) continue;
            int n = 0;
            for (int yy = std::max(0, y - kOutlierRadius); yy <= std::min(h - 1, y + kOutlierRadius); ++yy)
                for (int xx = std::max(0, x - kOutlierRadius); xx <= std::min(w - 1, x + kOutlierRadius); ++xx) {
                    const Pixel& q = before[size_t(yy) * size_t(w) + size_t(xx)];
                    if (!q.valid) continue;
                    values[n++] = mean3(q.a);
                    values[n++] = mean3(q.b);
                }
            std::nth_element(values, values + (3 * n) / 4, values + n);
            const float limit = kOutlierFactor * values[(3 * n) / 4];
            for (float* half : {p.a, p.b}) {
                const float l = mean3(half);
                if (l > limit)
                    for (int c = 0; c < 3; ++c) half[c] *= limit / l;
            }
        }
    });
}

// Feature distance of p and q beyond their noise, in units of the tolerances.
inline float feature_distance(const Pixel& p, const Pixel& q) {
    float da = 0.0f, dn = 0.0f;
    for (int c = 0; c < 3; ++c) {
        const float a = p.albedo[c] - q.albedo[c], n = p.normal[c] - q.normal[c];
        da += a * a;
        dn += n * n;
    }
    const float va = p.albedo_var + q.albedo_var, vn = p.normal_var + q.normal_var;
    return std::max(0.0f, da - va) / (kAlbedoSigma * kAlbedoSigma + va) +
           std::max(0.0f, dn - vn) / (kNormalSigma * kNormalSigma + vn);
}

// Colour distance of p and q in one guide half (means g, variances v).
inline float colour_distance(const float* gp, const float* vp, const float* gq, const float* vq, float k2) {
    float d = 0.0f;
    for (int c = 0; c < 3; ++c) {
        const float diff = gp[c] - gq[c], v = vp[c] + vq[c];
        d += (diff * diff - v) / (kEpsilon + k2 * v);
    }
    return d * (1.0f / 3.0f);
}

// Per band: weighted sums of each half and of the weights.
struct BandSums {
    std::vector<float> sum_a, sum_b, weight_a, weight_b;  // 3, 3, 1, 1 per pixel
};

// Patch-averaged colour distances of (p, p + (dx, dy)) for the pixels of rows
// [y0, y1): dist_a (guide a, weights for filtering b) and dist_b.
struct PatchDistances {
    std::vector<float> raw_a, raw_b, raw_n;  // per pixel of rows [y0 - f, y1 + f)
    std::vector<float> row_a, row_b, row_n;  // horizontal box sums
    std::vector<float> dist_a, dist_b;       // rows [y0, y1)
};

void patch_distances(const Image& img, int y0, int y1, int dx, int dy, int f, float k2, PatchDistances& s) {
    const int w = img.width, h = img.height;
    const int r0 = std::max(0, y0 - f), r1 = std::min(h, y1 + f), rows = r1 - r0;
    const size_t n = size_t(rows) * size_t(w);
    s.raw_a.assign(n, 0.0f), s.raw_b.assign(n, 0.0f), s.raw_n.assign(n, 0.0f);
    for (int y = r0; y < r1; ++y) {
        const int qy = y + dy;
        if (qy < 0 || qy >= h) continue;
        for (int x = std::max(0, -dx); x < std::min(w, w - dx); ++x) {
            const Pixel& p = img.at(x, y);
            const Pixel& q = img.at(x + dx, qy);
            if (!p.valid || !q.valid) continue;
            const size_t i = size_t(y - r0) * size_t(w) + size_t(x);
            s.raw_a[i] = colour_distance(p.a, p.va, q.a, q.va, k2);
            s.raw_b[i] = colour_distance(p.b, p.vb, q.b, q.vb, k2);
            s.raw_n[i] = 1.0f;
        }
    }
    // Horizontal then vertical box sums (running sums), normalised by how
    // many patch pixels had both ends in the image.
    s.row_a.assign(n, 0.0f), s.row_b.assign(n, 0.0f), s.row_n.assign(n, 0.0f);
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
    for (int y = y0; y < y1; ++y) {
        const int lo = std::max(r0, y - f) - r0, hi = std::min(r1 - 1, y + f) - r0;
        for (int x = 0; x < w; ++x) {
            float a = 0.0f, b = 0.0f, cnt = 0.0f;
            for (int r = lo; r <= hi; ++r) {
                const size_t i = size_t(r) * size_t(w) + size_t(x);
                a += s.row_a[i], b += s.row_b[i], cnt += s.row_n[i];
            }
            const size_t o = size_t(y - y0) * size_t(w) + size_t(x);
            s.dist_a[o] = cnt > 0.0f ? a / cnt : 0.0f;
            s.dist_b[o] = cnt > 0.0f ? b / cnt : 0.0f;
        }
    }
}

// Adds offset (dx, dy)'s contributions to the band's sums: half a is
// filtered with weights from guide b and vice versa.
void accumulate_offset(const Image& img, int y0, int y1, int dx, int dy, const PatchDistances& s, BandSums& sums) {
    const int w = img.width, h = img.height;
    for (int y = y0; y < y1; ++y) {
        const int qy = y + dy;
        if (qy < 0 || qy >= h) continue;
        for (int x = std::max(0, -dx); x < std::min(w, w - dx); ++x) {
            const Pixel& p = img.at(x, y);
            const Pixel& q = img.at(x + dx, qy);
            if (!p.valid || !q.valid) continue;
            const size_t o = size_t(y - y0) * size_t(w) + size_t(x);
            const float feature = feature_distance(p, q);
            const float wa = std::exp(-(std::max(0.0f, s.dist_b[o]) + feature));  // filters a, guided by b
            const float wb = std::exp(-(std::max(0.0f, s.dist_a[o]) + feature));
            for (int c = 0; c < 3; ++c) {
                sums.sum_a[3 * o + c] += wa * q.a[c];
                sums.sum_b[3 * o + c] += wb * q.b[c];
            }
            sums.weight_a[o] += wa;
            sums.weight_b[o] += wb;
        }
    }
}

// Filtered halves of the band's pixels, remodulated: 3 floats a pixel each.
void filter_band(const Image& img, const DenoiseOptions& o, int y0, int y1, float* out_a, float* out_b) {
    const int w = img.width, r = std::max(0, o.window_radius), f = std::max(0, o.patch_radius);
    const float k = kColourK * std::max(0.0f, o.strength);
    const size_t n = size_t(y1 - y0) * size_t(w);
    BandSums sums{std::vector<float>(3 * n, 0.0f), std::vector<float>(3 * n, 0.0f), std::vector<float>(n, 0.0f),
                  std::vector<float>(n, 0.0f)};
    PatchDistances scratch;
    for (int dy = -r; dy <= r; ++dy)
        for (int dx = -r; dx <= r; ++dx) {
            patch_distances(img, y0, y1, dx, dy, f, k * k, scratch);
            accumulate_offset(img, y0, y1, dx, dy, scratch, sums);
        }
    for (size_t i = 0; i < n; ++i) {
        const Pixel& p = img.px[size_t(y0) * size_t(w) + i];
        for (int c = 0; c < 3; ++c) {
            // The centre pixel always weighs 1 (distance <= 0): no division by 0.
            out_a[3 * i + c] = p.valid ? sums.sum_a[3 * i + c] / sums.weight_a[i] * p.modulation[c] : 0.0f;
            out_b[3 * i + c] = p.valid ? sums.sum_b[3 * i + c] / sums.weight_b[i] * p.modulation[c] : 0.0f;
        }
    }
}

// The filtered halves' combination and its relative RMSE estimate (film.h).
DenoiseResult combine(const Image& img, const std::vector<float>& fa, const std::vector<float>& fb) {
    DenoiseResult r;
    r.rgb.assign(fa.size(), 0.0f);
    double err2 = 0.0, mean = 0.0;
    for (size_t i = 0; i < img.px.size(); ++i) {
        const Pixel& p = img.px[i];
        if (!p.valid) continue;
        const double n = double(p.n_even) + double(p.n_odd);
        const double scale = double(p.n_even) * double(p.n_odd) / (n * n);
        for (int c = 0; c < 3; ++c) {
            const double a = fa[3 * i + c], b = fb[3 * i + c];
            const double v = (double(p.n_even) * a + double(p.n_odd) * b) / n;
            r.rgb[3 * i + c] = std::isfinite(v) ? float(v) : 0.0f;
            err2 += (a - b) * (a - b) * scale;
            mean += v;
        }
    }
    const double count = 3.0 * double(img.px.size());
    mean /= count;
    r.error_estimate = mean > 0.0 ? std::sqrt(err2 / count) / mean : 0.0;
    if (!std::isfinite(r.error_estimate)) r.error_estimate = -1.0;
    return r;
}

}  // namespace

DenoiseResult denoise(const Film& film, const DenoiseOptions& options, const DenoiseProgress& progress) {
    Image img;
    img.width = film.width(), img.height = film.height();
    img.px.resize(size_t(img.width) * size_t(img.height));
    const Film::Sums sums = film.sums();
    for (size_t i = 0; i < img.px.size(); ++i)
        if (!read_pixel(sums, i, img.px[i])) return {};  // fewer than 2 passes: no halves to cross-filter
    if (img.px.empty()) return {{}, 0.0};

    tbb::task_arena arena(options.threads > 0 ? options.threads : tbb::task_arena::automatic);
    const int bands = (img.height + kBandRows - 1) / kBandRows;
    std::vector<float> fa(3 * img.px.size()), fb(3 * img.px.size());
    std::atomic<int> bands_done{0};
    std::atomic<bool> cancelled{false};
    const auto caller = std::this_thread::get_id();
    auto last_report = std::chrono::steady_clock::now();
    arena.execute([&] {
        suppress_outliers(img);
        estimate_variances(img);
        tbb::parallel_for(tbb::blocked_range<int>(0, bands, 1), [&](const tbb::blocked_range<int>& range) {
            for (int band = range.begin(); band != range.end(); ++band) {
                if (cancelled.load(std::memory_order_relaxed)) return;
                const int y0 = band * kBandRows, y1 = std::min(img.height, y0 + kBandRows);
                const size_t first = 3 * size_t(y0) * size_t(img.width);
                filter_band(img, options, y0, y1, fa.data() + first, fb.data() + first);
                const int done = bands_done.fetch_add(1) + 1;
                // Reports only from the calling thread (it takes part in the loop).
                const auto now = std::chrono::steady_clock::now();
                if (progress && std::this_thread::get_id() == caller && now - last_report > std::chrono::milliseconds(100)) {
                    last_report = now;
                    if (!progress(double(done) / double(bands))) cancelled.store(true);
                }
            }
        });
    });
    if (cancelled.load() || (progress && !progress(1.0))) return {};
    return combine(img, fa, fb);
}

}  // namespace coherent
