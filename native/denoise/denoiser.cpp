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
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
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
constexpr int kBandRows = 32;

// The filter's inputs as planes (one float per pixel each), so the inner
// loops over a row run over contiguous floats and vectorise.
enum Plane : int {
    kA,                  // demodulated mean of the even half, 3 planes (RGB)
    kB = kA + 3,         // of the odd half
    kVarA = kB + 3,      // estimated variance of kA's means
    kVarB = kVarA + 3,
    kAlbedo = kVarB + 3,
    kNormal = kAlbedo + 3,
    kAlbedoVar,          // variance of the feature means, summed over channels
    kNormalVar,
    kValid,              // 1 where the pixel has samples, else 0
    kPlaneCount
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
bool read_pixel(const Film::Sums& s, size_t i, Image& img) {
    const uint32_t n = s.count[i], n_odd = s.count_odd[i], n_even = n - n_odd;
    img.planes[kValid][i] = n > 0 ? 1.0f : 0.0f;
    if (n == 0) return true;
    if (!n_odd || !n_even) return false;
    img.n_even[i] = float(n_even), img.n_odd[i] = float(n_odd);
    const float inv = 1.0f / float(n);
    for (int c = 0; c < 3; ++c) {
        float albedo = 1.0f, even_albedo = 1.0f, odd_albedo = 1.0f;
        if (s.albedo) {
            albedo = s.albedo[3 * i + c] * inv;
            odd_albedo = s.albedo_odd[3 * i + c] / float(n_odd);
            even_albedo = (s.albedo[3 * i + c] - s.albedo_odd[3 * i + c]) / float(n_even);
        }
        img.planes[kAlbedo + c][i] = albedo;
        img.planes[kNormal + c][i] = s.normal ? s.normal[3 * i + c] * inv : 0.0f;
        img.modulation[3 * i + c] = std::max(albedo, 0.0f) + kAlbedoBias;
        const float odd = s.rgb_odd[3 * i + c] / float(n_odd);
        const float even = (s.rgba[4 * i + c] - s.rgb_odd[3 * i + c]) / float(n_even);
        img.planes[kA + c][i] = even / (std::max(even_albedo, 0.0f) + kAlbedoBias);
        img.planes[kB + c][i] = odd / (std::max(odd_albedo, 0.0f) + kAlbedoBias);
    }
    if (s.albedo) {
        img.planes[kAlbedoVar][i] = feature_variance(s.albedo + 3 * i, s.albedo_odd + 3 * i, n, n_odd);
        img.planes[kNormalVar][i] = feature_variance(s.normal + 3 * i, s.normal_odd + 3 * i, n, n_odd);
    }
    return true;
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

void suppress_outliers(Image& img) {
    const int w = img.width, h = img.height;
    const size_t size = size_t(w) * size_t(h);
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
            for (int yy = std::max(0, y - kOutlierRadius); yy <= std::min(h - 1, y + kOutlierRadius); ++yy)
                for (int xx = std::max(0, x - kOutlierRadius); xx <= std::min(w - 1, x + kOutlierRadius); ++xx) {
                    const size_t j = size_t(yy) * size_t(w) + size_t(xx);
                    if (img.planes[kValid][j] == 0.0f) continue;
                    values[n++] = lum[0][j];
                    values[n++] = lum[1][j];
                }
            std::nth_element(values, values + (3 * n) / 4, values + n);
            const float limit = kOutlierFactor * values[(3 * n) / 4];
            for (int half = 0; half < 2; ++half) {
                const float l = lum[half][i];
                if (!(l > limit)) continue;
                for (int c = 0; c < 3; ++c) img.planes[(half ? kB : kA) + c][i] *= limit / l;
            }
        }
    });
}

// Each half's variance: Var[even mean] = E[(even - odd)^2] n_o / n, with
// (even - odd)^2 averaged over a small box (one pixel's is a single
// chi-square draw, far too noisy to normalise distances by).
void estimate_variances(Image& img) {
    const int w = img.width, h = img.height;
    const size_t size = size_t(w) * size_t(h);
    std::vector<float> diff2(3 * size);
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < size; ++i) {
            const float d = img.planes[kA + c][i] - img.planes[kB + c][i];
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
            for (int c = 0; c < 3; ++c) {
                const float mean = sum[c] / count;
                img.planes[kVarA + c][i] = mean * img.n_odd[i] / n;
                img.planes[kVarB + c][i] = mean * img.n_even[i] / n;
            }
        }
    });
}

// Per band: weighted sums of each half and of the weights (planes of the
// band's pixels: 3 + 3 + 1 + 1).
struct BandSums {
    std::vector<float> sum_a[3], sum_b[3], weight_a, weight_b;
};

// Scratch of one band and offset: per-pixel colour distances of rows
// [y0 - f, y1 + f) in both guides and how many pairs were valid, their
// horizontal box sums, and the patch means of rows [y0, y1).
struct PatchDistances {
    std::vector<float> raw_a, raw_b, raw_n, row_a, row_b, row_n, dist_a, dist_b;
};

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
            o[x] += (diff * diff - var) / (kEpsilon + k2 * var) * (1.0f / 3.0f);
        }
    }
}

void patch_distances(const Image& img, int y0, int y1, int dx, int dy, int f, float k2, PatchDistances& s) {
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
        row_colour_distances(img, row, row_q, x0, x1, dx, kA, kVarA, k2, s.raw_a.data() + base);
        row_colour_distances(img, row, row_q, x0, x1, dx, kB, kVarB, k2, s.raw_b.data() + base);
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
// distance), wb half b. Plain restrict pointers, so that the loop vectorises.
void row_weights(const Image& img, ptrdiff_t p, ptrdiff_t q, const float* __restrict dist_a,
                 const float* __restrict dist_b, int count, float* __restrict wa, float* __restrict wb) {
    constexpr float kAlbedo2 = kAlbedoSigma * kAlbedoSigma, kNormal2 = kNormalSigma * kNormalSigma;
    float* __restrict feature = wb;  // wb holds the feature distance until the last loop
    for (int x = 0; x < count; ++x) feature[x] = 0.0f;
    for (int base : {int(kAlbedo), int(kNormal)}) {
        float* __restrict d2 = wa;  // squared feature difference, summed over channels
        for (int x = 0; x < count; ++x) d2[x] = 0.0f;
        for (int c = 0; c < 3; ++c) {
            const float* __restrict fp = img.plane(base + c) + p;
            const float* __restrict fq = img.plane(base + c) + q;
            for (int x = 0; x < count; ++x) d2[x] += (fp[x] - fq[x]) * (fp[x] - fq[x]);
        }
        // Beyond the features' own noise, in units of the tolerances.
        const int var_plane = base == kAlbedo ? kAlbedoVar : kNormalVar;
        const float tolerance = base == kAlbedo ? kAlbedo2 : kNormal2;
        const float* __restrict vp = img.plane(var_plane) + p;
        const float* __restrict vq = img.plane(var_plane) + q;
        for (int x = 0; x < count; ++x) {
            const float v = vp[x] + vq[x];
            feature[x] += std::max(0.0f, d2[x] - v) / (tolerance + v);
        }
    }
    const float* __restrict valid_p = img.plane(kValid) + p;
    const float* __restrict valid_q = img.plane(kValid) + q;
    for (int x = 0; x < count; ++x) {
        const float both = valid_p[x] * valid_q[x], f = feature[x];
        wa[x] = both * exp_negative(-(std::max(0.0f, dist_b[x]) + f));
        wb[x] = both * exp_negative(-(std::max(0.0f, dist_a[x]) + f));
    }
}

// Adds offset (dx, dy)'s contributions to the band's sums: half a is
// filtered with weights from guide b and vice versa.
void accumulate_offset(const Image& img, int y0, int y1, int dx, int dy, const PatchDistances& s, BandSums& sums,
                       std::vector<float>& wa, std::vector<float>& wb) {
    const int w = img.width, h = img.height;
    const int x0 = std::max(0, -dx), x1 = std::min(w, w - dx), count = x1 - x0;
    wa.resize(size_t(w)), wb.resize(size_t(w));
    for (int y = y0; y < y1; ++y) {
        const int qy = y + dy;
        if (qy < 0 || qy >= h) continue;
        // Row starts advanced to x0: the loops run over [0, count).
        const ptrdiff_t p = ptrdiff_t(y) * w + x0, q = ptrdiff_t(qy) * w + dx + x0, o = ptrdiff_t(y - y0) * w + x0;
        row_weights(img, p, q, s.dist_a.data() + o, s.dist_b.data() + o, count, wa.data(), wb.data());
        const float* __restrict wa_row = wa.data();
        const float* __restrict wb_row = wb.data();
        for (int c = 0; c < 3; ++c) {
            const float* __restrict a = img.plane(kA + c) + q;
            const float* __restrict b = img.plane(kB + c) + q;
            float* __restrict sa = sums.sum_a[c].data() + o;
            float* __restrict sb = sums.sum_b[c].data() + o;
            for (int x = 0; x < count; ++x) sa[x] += wa_row[x] * a[x], sb[x] += wb_row[x] * b[x];
        }
        float* __restrict sum_wa = sums.weight_a.data() + o;
        float* __restrict sum_wb = sums.weight_b.data() + o;
        for (int x = 0; x < count; ++x) sum_wa[x] += wa_row[x], sum_wb[x] += wb_row[x];
    }
}

// Filtered halves of the band's pixels, remodulated: 3 floats a pixel each.
// Returns early (output incomplete) once `cancelled` is set: checked per
// window row, so cancelling is prompt at any image width.
void filter_band(const Image& img, const DenoiseOptions& o, int y0, int y1, const std::atomic<bool>& cancelled,
                 float* out_a, float* out_b) {
    const int w = img.width, r = std::max(0, o.window_radius), f = std::max(0, o.patch_radius);
    const float k = kColourK * std::max(0.0f, o.strength);
    const size_t n = size_t(y1 - y0) * size_t(w);
    BandSums sums;
    for (int c = 0; c < 3; ++c) sums.sum_a[c].assign(n, 0.0f), sums.sum_b[c].assign(n, 0.0f);
    sums.weight_a.assign(n, 0.0f), sums.weight_b.assign(n, 0.0f);
    PatchDistances scratch;
    std::vector<float> wa, wb;
    for (int dy = -r; dy <= r; ++dy) {
        if (cancelled.load(std::memory_order_relaxed) || (o.cancel && o.cancel->load(std::memory_order_relaxed)))
            return;
        for (int dx = -r; dx <= r; ++dx) {
            patch_distances(img, y0, y1, dx, dy, f, k * k, scratch);
            accumulate_offset(img, y0, y1, dx, dy, scratch, sums, wa, wb);
        }
    }
    const size_t first = size_t(y0) * size_t(w);
    for (size_t i = 0; i < n; ++i) {
        const bool valid = img.planes[kValid][first + i] != 0.0f;
        for (int c = 0; c < 3; ++c) {
            // The centre pixel always weighs 1 (distance <= 0): no division by 0.
            const float m = img.modulation[3 * (first + i) + size_t(c)];
            out_a[3 * i + c] = valid ? sums.sum_a[c][i] / sums.weight_a[i] * m : 0.0f;
            out_b[3 * i + c] = valid ? sums.sum_b[c][i] / sums.weight_b[i] * m : 0.0f;
        }
    }
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

}  // namespace

DenoiseResult denoise(const Film& film, const DenoiseOptions& options, const DenoiseProgress& progress) {
    Image img;
    img.width = film.width(), img.height = film.height();
    const size_t size = size_t(img.width) * size_t(img.height);
    if (size == 0) return {{}, 0.0};
    for (std::vector<float>& p : img.planes) p.assign(size, 0.0f);
    img.modulation.assign(3 * size, 1.0f);
    img.n_even.assign(size, 0.0f), img.n_odd.assign(size, 0.0f);
    const Film::Sums sums = film.sums();
    for (size_t i = 0; i < size; ++i)
        if (!read_pixel(sums, i, img)) return {};  // fewer than 2 passes: no halves to cross-filter

    tbb::task_arena arena(options.threads > 0 ? options.threads : tbb::task_arena::automatic);
    const int bands = (img.height + kBandRows - 1) / kBandRows;
    std::vector<float> fa(3 * size), fb(3 * size);
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
                filter_band(img, options, y0, y1, cancelled, fa.data() + first, fb.data() + first);
                const int done = bands_done.fetch_add(1) + 1;
                // Reports only from the calling thread (it takes part in the loop).
                const auto now = std::chrono::steady_clock::now();
                if (progress && std::this_thread::get_id() == caller &&
                    now - last_report > std::chrono::milliseconds(100)) {
                    last_report = now;
                    if (!progress(double(done) / double(bands))) cancelled.store(true);
                }
            }
        });
    });
    if (cancelled.load() || (options.cancel && options.cancel->load()) || (progress && !progress(1.0))) return {};
    return combine(img, fa, fb);
}

}  // namespace coherent
