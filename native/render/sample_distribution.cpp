// Per-pixel sample counts for a denoised render (sample_distribution.h).
#include "sample_distribution.h"

#include "../denoise/denoiser.h"

#include <algorithm>
#include <cmath>

namespace coherent {

namespace {

// Pixel i's mean radiance in channel c over its mean albedo, as the denoiser
// demodulates it. Needs samples and albedo.
double illumination(const Film::Sums& s, size_t i, int c) {
    const double n = s.count[i];
    return (s.rgba[4 * i + size_t(c)] / n) / (std::max(s.albedo[3 * i + size_t(c)] / n, 0.0) + kDenoiserAlbedoBias);
}

// Whether a pixel's samples fill both halves (even and odd passes).
bool has_halves(const Film::Sums& s, size_t i) { return s.count_odd[i] >= 1 && s.count[i] - s.count_odd[i] >= 1; }

// Per-sample variance of what the denoiser keeps of pixel i's noise
// (sample_distribution.h), 0 where the pixel lacks a half.
double kept_variance(const Film::Sums& s, size_t i) {
    if (!has_halves(s, i)) return 0.0;
    const double n = s.count[i], n_odd = s.count_odd[i];
    double v = 0.0;
    for (int c = 0; c < 3; ++c) {
        const double colour_variance =
            halves_mean_variance(s.rgba[4 * i + size_t(c)], s.rgb_odd[3 * i + size_t(c)], n, n_odd);
        double modulation = 0.0;
        if (s.albedo) {
            const double light = illumination(s, i, c);
            modulation =
                halves_mean_variance(s.albedo[3 * i + size_t(c)], s.albedo_odd[3 * i + size_t(c)], n, n_odd) * light *
                light;
        }
        v += modulation + colour_variance * SampleDistribution::kFilteredVarianceShare;
    }
    v *= n;
    return std::isfinite(v) ? v : 0.0;
}

// Calls visit(q) for each of pixel (x, y)'s 8 neighbours that has samples;
// returns how many it visited.
template <class Visit>
int for_each_neighbour(const Film::Sums& s, int w, int h, int x, int y, Visit&& visit) {
    int count = 0;
    for (int yy = std::max(0, y - 1); yy <= std::min(h - 1, y + 1); ++yy)
        for (int xx = std::max(0, x - 1); xx <= std::min(w - 1, x + 1); ++xx) {
            const size_t q = size_t(yy) * size_t(w) + size_t(xx);
            if ((xx == x && yy == y) || s.count[q] == 0) continue;
            visit(q);
            ++count;
        }
    return count;
}

// The smallest and largest value seen per channel.
struct ChannelRange {
    double lo[3] = {0.0, 0.0, 0.0}, hi[3] = {0.0, 0.0, 0.0};
    bool any[3] = {false, false, false};
    void add(int c, double v) {
        lo[c] = any[c] ? std::min(lo[c], v) : v;
        hi[c] = any[c] ? std::max(hi[c], v) : v;
        any[c] = true;
    }
    double range(int c) const { return hi[c] - lo[c]; }
};

// Per-sample variance of pixel (x, y) if an edge of the albedo crosses it,
// judged from its 8 neighbours only: sum over channels of (the range of
// their mean albedo x their mean illumination)^2. A pixel whose samples see
// a fraction f of one side and 1 - f of the other has f (1 - f) times that.
// kept_variance() misses it where the samples are stratified: each half's
// few samples then see the edge in nearly the same proportion, so along an
// axis-aligned edge the halves agree exactly in runs of pixels and
// estimate no variance there at all, while the pixel's mean still carries
// the coverage error that neither the denoiser (which takes the mixed
// albedo as the truth) nor the neighbours can remove.
double edge_variance(const Film::Sums& s, int w, int h, int x, int y) {
    ChannelRange albedo;
    double light[3] = {0.0, 0.0, 0.0};
    const int count = for_each_neighbour(s, w, h, x, y, [&](size_t q) {
        for (int c = 0; c < 3; ++c) {
            albedo.add(c, s.albedo[3 * q + size_t(c)] / s.count[q]);
            light[c] += illumination(s, q, c);
        }
    });
    double v = 0.0;
    for (int c = 0; c < 3 && count; ++c) {
        const double contrast = albedo.range(c) * light[c] / count;
        v += contrast * contrast;
    }
    return std::isfinite(v) ? v : 0.0;
}

// Per-sample variance of pixel (x, y) if the edge of a hard shadow crosses
// it, judged from its 8 neighbours only: sum over channels of the squared
// range of their mean direct light (PathOutput::direct), less the variance
// of those means that their halves show (what noise alone would spread them
// by). A sun's or a small lamp's shadow edge is no edge of the albedo, so
// edge_variance() does not see it, and where the samples are stratified the
// halves miss its coverage too; the denoiser filters the direct light apart
// but cannot tell how much of the pixel the shadow covers. Soft shadows and
// noisy direct light keep most of their range within the subtracted noise.
double shadow_edge_variance(const Film::Sums& s, int w, int h, int x, int y) {
    ChannelRange direct;
    double noise[3] = {0.0, 0.0, 0.0};
    const int count = for_each_neighbour(s, w, h, x, y, [&](size_t q) {
        const double n = s.count[q], n_odd = s.count_odd[q];
        for (int c = 0; c < 3; ++c) {
            const double sum = s.direct[3 * q + size_t(c)], odd = s.direct_odd[3 * q + size_t(c)];
            direct.add(c, sum / n);
            if (has_halves(s, q)) noise[c] += halves_mean_variance(sum, odd, n, n_odd);
        }
    });
    double v = 0.0;
    for (int c = 0; c < 3 && count; ++c) {
        const double range = direct.range(c);
        v += std::max(0.0, range * range - noise[c] / count);
    }
    return std::isfinite(v) ? v : 0.0;
}

}  // namespace

std::vector<uint32_t> SampleDistribution::targets(const Film& film, int spp) {
    const int w = film.width(), h = film.height();
    const size_t size = size_t(w) * size_t(h);
    const uint32_t limit = uint32_t(pass_limit(spp));
    std::vector<uint32_t> out(size, uint32_t(spp));
    if (size == 0) return out;
    const Film::Sums s = film.sums();
    std::vector<double> variance(size);
    for (size_t i = 0; i < size; ++i) variance[i] = kept_variance(s, i);
    const bool edges = s.albedo && std::min(w, h) >= kEdgeMinSide;
    // Each pixel judged by its neighbours only (the box, centre left out).
    std::vector<double> weight(size, 0.0);
    double total = 0.0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            double sum = 0.0;
            int count = 0;
            for (int yy = std::max(0, y - kRadius); yy <= std::min(h - 1, y + kRadius); ++yy)
                for (int xx = std::max(0, x - kRadius); xx <= std::min(w - 1, x + kRadius); ++xx)
                    if (xx != x || yy != y) sum += variance[size_t(yy) * size_t(w) + size_t(xx)], ++count;
            const size_t i = size_t(y) * size_t(w) + size_t(x);
            double v = count ? sum / count : 0.0;
            if (edges) v += kEdgeVarianceShare * edge_variance(s, w, h, x, y);
            if (edges && s.direct) v += kShadowEdgeVarianceShare * shadow_edge_variance(s, w, h, x, y);
            weight[i] = std::sqrt(v);
            total += weight[i];
        }
    if (!(total > 0.0) || !std::isfinite(total)) return out;
    // Extra samples proportional to the weight, capped per pixel; what the
    // caps cut goes to the uncapped pixels (a few rounds suffice).
    std::vector<uint32_t> have(size);
    double budget = 0.0;
    for (size_t i = 0; i < size; ++i) {
        have[i] = s.count[i];
        budget += double(spp) - double(have[i]);
    }
    if (!(budget > 0.0)) return std::vector<uint32_t>(have.begin(), have.end());
    const auto room = [&](size_t i) { return double(limit) - double(have[i]); };
    double scale = budget / total;
    for (int round = 0; round < 16; ++round) {
        double spent = 0.0, uncapped = 0.0;
        for (size_t i = 0; i < size; ++i) {
            const double extra = weight[i] * scale;
            if (extra >= room(i)) {
                spent += room(i);
            } else {
                spent += extra;
                uncapped += weight[i];
            }
        }
        if (spent >= budget * 0.999 || !(uncapped > 0.0)) break;
        scale += (budget - spent) / uncapped;
    }
    for (size_t i = 0; i < size; ++i) {
        const double extra = std::clamp(weight[i] * scale, 0.0, std::max(room(i), 0.0));
        out[i] = std::min(limit, have[i] + 2u * uint32_t(std::lround(extra / 2.0)));
    }
    return out;
}

}  // namespace coherent
