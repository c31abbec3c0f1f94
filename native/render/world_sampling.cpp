// Environment map lookup and importance sampling. Conventions: world_sampling.h.
#include "world_sampling.h"

#include <algorithm>
#include <cmath>

#include "../shader/sky_model.h"

namespace coherent {

namespace {

int wrap(int i, int n) {
    const int r = i % n;
    return r < 0 ? r + n : r;
}

float row_cos_elevation(int y, int height) { return std::cos(kPi * ((float(y) + 0.5f) / float(height) - 0.5f)); }

// How much rows y - 1, y and y + 1 contribute to the integral over row y
// of the bilinear lookup times cos(elevation), with v in texel units: the
// lower half-row blends row y - 1 in with weight (centre - v), the upper half
// row y + 1 with (v - centre). Midpoint rule, 32 steps per half-row.
struct RowWeights {
    float below, here, above;
};

RowWeights row_weights(int y, int height) {
    constexpr int kSteps = 32;
    double below = 0.0, here = 0.0, above = 0.0;
    for (int i = 0; i < kSteps; ++i) {
        const double t = (double(i) + 0.5) / (2.0 * kSteps);  // distance from the row's centre, 0 ... 1/2
        const double c_low = std::cos(kPi * ((double(y) + 0.5 - t) / double(height) - 0.5));
        const double c_high = std::cos(kPi * ((double(y) + 0.5 + t) / double(height) - 0.5));
        below += t * c_low;
        above += t * c_high;
        here += (1.0 - t) * (c_low + c_high);
    }
    const double dv = 1.0 / (2.0 * kSteps);
    return {float(below * dv), float(here * dv), float(above * dv)};
}

// Inclusive prefix sums of w[0..n) into cdf[0..n], normalised to end at 1;
// returns the total. A zero total gives a uniform cdf (never sampled: its
// row or map has probability 0).
double build_cdf(const float* w, int n, float* cdf) {
    double sum = 0.0;
    std::vector<double> prefix(size_t(n) + 1, 0.0);
    for (int i = 0; i < n; ++i) prefix[size_t(i) + 1] = sum += double(w[i]);
    for (int i = 0; i <= n; ++i) cdf[i] = sum > 0.0 ? float(prefix[size_t(i)] / sum) : float(i) / float(n);
    cdf[n] = 1.0f;
    return sum;
}

// The bin of u in cdf[0..n] and u's position within it, in [0, 1).
int sample_cdf(const float* cdf, int n, float u, float& frac) {
    const int i = std::clamp(int(std::upper_bound(cdf, cdf + n + 1, u) - cdf) - 1, 0, n - 1);
    const float width = cdf[i + 1] - cdf[i];
    frac = width > 0.0f ? std::clamp((u - cdf[i]) / width, 0.0f, 0.99999994f) : 0.5f;
    return i;
}

}  // namespace

Vec2f direction_to_equirect(const Vec3f& d) {
    return {0.5f - std::atan2(d.y, d.x) / (2.0f * kPi),
            0.5f + std::atan2(d.z, std::sqrt(d.x * d.x + d.y * d.y)) / kPi};
}

Vec3f equirect_to_direction(float u, float v) {
    const float phi = 2.0f * kPi * (0.5f - u), elevation = kPi * (v - 0.5f);
    const float c = std::cos(elevation);
    return {c * std::cos(phi), c * std::sin(phi), std::sin(elevation)};
}

EnvironmentSampler::EnvironmentSampler(const EnvironmentMap& map) {
    if (map.empty()) return;
    const int w = map.width, h = map.height;
    std::vector<float> lum(size_t(w) * size_t(h));
    double integral = 0.0;  // of luminance over the sphere, / (2 pi^2 / (w h))
    for (int y = 0; y < h; ++y) {
        const double c = row_cos_elevation(y, h);
        for (int x = 0; x < w; ++x) {
            const float l = luminance(map.texel(x, y));
            lum[size_t(y) * size_t(w) + size_t(x)] = std::isfinite(l) ? std::max(l, 0.0f) : 0.0f;
            integral += c * double(lum[size_t(y) * size_t(w) + size_t(x)]);
        }
    }
    // weight = the integral over the texel of the bilinear lookup's luminance
    // times cos(elevation), in texel units: separable, a (1/8, 3/4, 1/8) tent
    // across columns and, down rows, the hat functions integrated against the
    // cosine (which at the poles weights the half-row towards the equator).
    weight_.assign(lum.size(), 0.0f);
    std::vector<float> across(lum.size());
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const float* row = &lum[size_t(y) * size_t(w)];
            across[size_t(y) * size_t(w) + size_t(x)] =
                0.125f * row[wrap(x - 1, w)] + 0.75f * row[x] + 0.125f * row[wrap(x + 1, w)];
        }
    for (int y = 0; y < h; ++y) {
        const RowWeights k = row_weights(y, h);
        const float* below = &across[size_t(wrap(y - 1, h)) * size_t(w)];
        const float* here = &across[size_t(y) * size_t(w)];
        const float* above = &across[size_t(wrap(y + 1, h)) * size_t(w)];
        for (int x = 0; x < w; ++x)
            weight_[size_t(y) * size_t(w) + size_t(x)] = k.below * below[x] + k.here * here[x] + k.above * above[x];
    }
    column_cdf_.resize(size_t(h) * size_t(w + 1));
    std::vector<float> row_sums(static_cast<size_t>(h));
    double total = 0.0;
    for (int y = 0; y < h; ++y) {
        row_sums[size_t(y)] = float(build_cdf(&weight_[size_t(y) * size_t(w)], w, &column_cdf_[size_t(y) * size_t(w + 1)]));
        total += row_sums[size_t(y)];
    }
    if (!(total > 0.0) || !std::isfinite(total)) return;  // black: nothing to sample
    row_cdf_.resize(size_t(h) + 1);
    build_cdf(row_sums.data(), h, row_cdf_.data());
    inv_mean_weight_ = float(double(w) * double(h) / total);
    mean_luminance_ = float(integral * (2.0 * kPi * kPi / (double(w) * double(h))) / (4.0 * kPi));
    map_ = &map;
    if (map.sun_power > 0.0f && map.sun_one_minus_cos > 0.0f) {
        const double map_power = integral * (2.0 * kPi * kPi / (double(w) * double(h)));
        sun_share_ = float(double(map.sun_power) / (double(map.sun_power) + map_power));
        sun_cone_pdf_ = 1.0f / (2.0f * kPi * map.sun_one_minus_cos);
        make_basis(map.sun_dir, sun_t_, sun_b_);
        mean_luminance_ += float(double(map.sun_power) / (4.0 * kPi));
    }
}

Vec3f EnvironmentSampler::eval(const Vec3f& d) const {
    if (map_->sky) return map_->sky->eval(map_->to_map(d));
    const Vec2f uv = direction_to_equirect(map_->to_map(d));
    const int w = map_->width, h = map_->height;
    const float x = uv.x * float(w) - 0.5f, y = uv.y * float(h) - 0.5f;
    const float fx = std::floor(x), fy = std::floor(y);
    const float tx = x - fx, ty = y - fy;
    const int x0 = wrap(int(fx), w), y0 = wrap(int(fy), h);
    const int x1 = wrap(x0 + 1, w), y1 = wrap(y0 + 1, h);
    return (map_->texel(x0, y0) * (1.0f - tx) + map_->texel(x1, y0) * tx) * (1.0f - ty) +
           (map_->texel(x0, y1) * (1.0f - tx) + map_->texel(x1, y1) * tx) * ty;
}

float EnvironmentSampler::texel_pdf_uv(int x, int y) const {
    return weight_[size_t(y) * size_t(map_->width) + size_t(x)] * inv_mean_weight_;
}

bool EnvironmentSampler::sample(float u1, float u2, Vec3f& d, float& pdf) const {
    if (sun_share_ > 0.0f) return sample_with_sun(u1, u2, d, pdf);
    return sample_map(u1, u2, d, pdf);
}

// u1 picks the sun's cone (below sun_share_) or the map, then is stretched back to [0, 1).
bool EnvironmentSampler::sample_with_sun(float u1, float u2, Vec3f& d, float& pdf) const {
    if (u1 < sun_share_) {
        const float u = u1 / sun_share_;
        const float omc = u * map_->sun_one_minus_cos;  // 1 - cos(theta), uniform in solid angle
        const float sin_theta = std::sqrt(std::max(0.0f, omc * (2.0f - omc)));
        const float phi = 2.0f * kPi * u2;
        const Vec3f m = (sun_t_ * std::cos(phi) + sun_b_ * std::sin(phi)) * sin_theta + map_->sun_dir * (1.0f - omc);
        d = map_->from_map(normalize(m));
    } else {
        const float u = std::min((u1 - sun_share_) / (1.0f - sun_share_), 0.99999994f);
        if (!sample_map(u, u2, d, pdf)) return false;
    }
    pdf = this->pdf(d);
    return pdf > 0.0f && std::isfinite(pdf);
}

bool EnvironmentSampler::sample_map(float u1, float u2, Vec3f& d, float& pdf) const {
    const int w = map_->width, h = map_->height;
    float fy, fx;
    const int y = sample_cdf(row_cdf_.data(), h, u1, fy);
    const int x = sample_cdf(&column_cdf_[size_t(y) * size_t(w + 1)], w, u2, fx);
    const float u = (float(x) + fx) / float(w), v = (float(y) + fy) / float(h);
    const float cos_elevation = std::cos(kPi * (v - 0.5f));
    if (!(cos_elevation > 0.0f)) return false;
    d = map_->from_map(equirect_to_direction(u, v));
    pdf = texel_pdf_uv(x, y) / (2.0f * kPi * kPi * cos_elevation);
    return pdf > 0.0f && std::isfinite(pdf);
}

float EnvironmentSampler::pdf(const Vec3f& d) const {
    if (!(sun_share_ > 0.0f)) return map_pdf(d);
    // 1 - cos of the angle to the sun, without cancellation: |m - s|^2 / 2.
    const float omc = 0.5f * length_squared(map_->to_map(d) - map_->sun_dir);
    const float cone = omc <= map_->sun_one_minus_cos ? sun_cone_pdf_ : 0.0f;
    return (1.0f - sun_share_) * map_pdf(d) + sun_share_ * cone;
}

float EnvironmentSampler::map_pdf(const Vec3f& d) const {
    const Vec3f m = map_->to_map(d);
    const Vec2f uv = direction_to_equirect(m);
    const int w = map_->width, h = map_->height;
    const int x = std::clamp(int(uv.x * float(w)), 0, w - 1), y = std::clamp(int(uv.y * float(h)), 0, h - 1);
    const float cos_elevation = std::cos(kPi * (uv.y - 0.5f));
    if (!(cos_elevation > 0.0f)) return 0.0f;
    return texel_pdf_uv(x, y) / (2.0f * kPi * kPi * cos_elevation);
}

}  // namespace coherent
