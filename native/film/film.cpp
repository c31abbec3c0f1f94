// Film accumulation and pass resolution.
#include "film.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace coherent {

// Cycles writes this depth where a pixel saw no geometry; we do the same so
// that no pass ever holds an infinity.
constexpr float kNoHitDepth = 1e10f;

const PassInfo& pass_info(PassType t) {
    static const PassInfo infos[] = {
        {PassType::Combined, "Combined", 4, "RGBA"},
        {PassType::Depth, "Depth", 1, "Z"},
        {PassType::Normal, "Normal", 3, "XYZ"},
        {PassType::Error, "Error", 1, "X"},
        {PassType::NodeVisits, "BVH Visits", 1, "X"},
        {PassType::SimdUtilisation, "SIMD Utilisation", 1, "X"},
        {PassType::DenoisingAlbedo, "Denoising Albedo", 3, "RGB"},
        {PassType::DenoisingNormal, "Denoising Normal", 3, "XYZ"},
        {PassType::NoisyImage, "Noisy Image", 4, "RGBA"},
        {PassType::DenoisingDepth, "Denoising Depth", 1, "Z"},
    };
    if (is_render_pass(t)) {
        // Built once from passes.h's table.
        static const auto render_infos = [] {
            std::vector<PassInfo> v;
            for (int i = 0; i < kRenderPassCount; ++i) {
                const RenderPassInfo& r = render_pass_info(RenderPass(i));
                v.push_back({pass_type(RenderPass(i)), r.name, r.channels, r.chan_id});
            }
            return v;
        }();
        return render_infos[size_t(render_pass(t))];
    }
    return infos[size_t(t)];
}

Film::Film(int width, int height) : width_(std::max(width, 0)), height_(std::max(height, 0)) { clear(); }

void Film::clear() {
    const size_t n = size_t(width_) * size_t(height_);
    rgba_.assign(4 * n, 0.0f);
    depth_.assign(n, 0.0f);
    normal_.assign(3 * n, 0.0f);
    count_.assign(n, 0);
    hits_.assign(n, 0);
    rgb_odd_.assign(3 * n, 0.0f);
    count_odd_.assign(n, 0);
    heat_.clear();
    heat_count_.clear();
    const bool features = has_denoising_features();
    albedo_.clear(), albedo_odd_.clear(), dnormal_.clear(), dnormal_odd_.clear(), ddepth_.clear();
    direct_.clear(), direct_odd_.clear();
    if (features) enable_denoising_features();
    denoised_.clear();
    const PassMask passes = passes_;
    passes_ = 0;
    enable_passes(passes);
    const uint32_t crypto = crypto_types_;
    crypto_types_ = 0;
    enable_cryptomatte(crypto, crypto_slots_);
}

void Film::enable_cryptomatte(uint32_t types, int levels) {
    crypto_types_ = types;
    crypto_slots_ = types ? cryptomatte_slots(levels) : 0;
    const size_t n = size_t(width_) * size_t(height_);
    for (int t = 0; t < kCryptoTypeCount; ++t) {
        if (types & (1u << t)) crypto_[t].assign(n * size_t(crypto_slots_) * 2, 0.0f);
        else crypto_[t].clear();
    }
}

void Film::resolve_cryptomatte(CryptoType t, int layer, float* out) const {
    const size_t n = size_t(width_) * size_t(height_);
    const std::vector<float>& b = crypto_[int(t)];
    std::vector<std::pair<float, float>> ranked(static_cast<size_t>(crypto_slots_));
    for (size_t i = 0; i < n; ++i) {
        float* o = out + 4 * i;
        std::fill(o, o + 4, 0.0f);
        if (b.empty() || count_[i] == 0 || 2 * layer + 1 >= crypto_slots_) continue;
        const float* slots = &b[i * size_t(crypto_slots_) * 2];
        for (int k = 0; k < crypto_slots_; ++k) ranked[size_t(k)] = {slots[2 * k], slots[2 * k + 1]};
        // By coverage, highest first (Cycles' film_cryptomatte_post); ties keep slot order.
        std::stable_sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& c) { return a.second > c.second; });
        const float inv = 1.0f / float(count_[i]);
        for (int r = 0; r < 2; ++r) {
            o[2 * r] = ranked[size_t(2 * layer + r)].first;
            o[2 * r + 1] = ranked[size_t(2 * layer + r)].second * inv;
        }
    }
}


PassMask Film::stored_passes(PassMask mask) {
    constexpr int kLobes[3] = {int(RenderPass::DiffuseDirect), int(RenderPass::GlossyDirect),
                               int(RenderPass::TransmissionDirect)};
    for (int first : kLobes)
        if (mask & ((PassMask(1) << first) | (PassMask(1) << (first + 1)))) mask |= PassMask(1) << (first + 2);
    return mask & ((PassMask(1) << kRenderPassCount) - 1);  // pass bits only
}

uint64_t Film::bytes_per_pixel(bool heatmaps, bool denoising_features, bool denoised, PassMask passes,
                               uint32_t cryptomatte_types, int cryptomatte_levels) {
    // RGBA, depth, normal, count, hits, odd-pass RGB and count.
    uint64_t floats = 4 + 1 + 3 + 1 + 1 + 3 + 1;
    if (heatmaps) floats += 2 + 1;
    if (denoising_features) floats += 6 * 3 + 1;  // albedo, normal, direct (each with its odd half), depth
    if (denoised) floats += 3;
    const PassMask stored = stored_passes(passes);
    for (int p = 0; p < kRenderPassCount; ++p)
        if (stored & pass_bit(RenderPass(p))) floats += uint64_t(render_pass_info(RenderPass(p)).channels);
    for (int t = 0; t < kCryptoTypeCount; ++t)
        if (cryptomatte_types & (1u << t)) floats += 2 * uint64_t(cryptomatte_slots(cryptomatte_levels));
    static_assert(sizeof(float) == sizeof(uint32_t));
    return floats * sizeof(float);
}

uint64_t Film::bytes() const {
    uint64_t floats = rgba_.size() + depth_.size() + normal_.size() + count_.size() + hits_.size() + rgb_odd_.size() +
                      count_odd_.size() + heat_.size() + heat_count_.size() + denoised_.size();
    for (const std::vector<float>* b : {&albedo_, &albedo_odd_, &dnormal_, &dnormal_odd_, &ddepth_, &direct_, &direct_odd_})
        floats += b->size();
    for (const std::vector<float>& b : pass_sums_) floats += b.size();
    for (const std::vector<float>& b : crypto_) floats += b.size();
    return floats * sizeof(float);
}

void Film::enable_passes(PassMask mask) {
    mask = stored_passes(mask);
    const size_t n = size_t(width_) * size_t(height_);
    for (int p = 0; p < kRenderPassCount; ++p)
        if ((mask & pass_bit(RenderPass(p))) && !(passes_ & pass_bit(RenderPass(p))))
            pass_sums_[p].assign(n * size_t(render_pass_info(RenderPass(p)).channels), 0.0f);
    passes_ |= mask;
}

void Film::add_passes(int x, int y, const PassSample& values, uint32_t sample) {
    const size_t i = size_t(y) * size_t(width_) + size_t(x);
    for (int p = 0; p < kRenderPassCount; ++p) {
        if (!(passes_ & pass_bit(RenderPass(p)))) continue;
        const RenderPassInfo& info = render_pass_info(RenderPass(p));
        const float* v = values.v + info.offset;
        float* d = &pass_sums_[p][i * size_t(info.channels)];
        if (RenderPass(p) >= RenderPass::Position && RenderPass(p) <= RenderPass::IndexMA) {
            // Sample 0 only (Cycles): an average of positions or indices means nothing.
            if (sample == 0)
                for (int c = 0; c < info.channels; ++c) d[c] = v[c];
            continue;
        }
        for (int c = 0; c < info.channels; ++c) d[c] += v[c];
    }
    for (int t = 0; t < kCryptoTypeCount; ++t) {
        const float id = values.crypto_id[t];
        if (!(crypto_types_ & (1u << t)) || id == 0.0f) continue;
        float* slots = &crypto_[t][i * size_t(crypto_slots_) * 2];
        for (int k = 0; k < crypto_slots_; ++k) {
            // The first free slot or this id's; a pixel with more ids drops the rest, as Cycles does.
            if (slots[2 * k] == 0.0f) slots[2 * k] = id;
            if (slots[2 * k] == id) {
                slots[2 * k + 1] += 1.0f;
                break;
            }
        }
    }
}

void Film::resolve_render_pass(PassType t, size_t i, float* out) const {
    const RenderPass p = render_pass(t);
    const int channels = render_pass_info(p).channels;
    const std::vector<float>& sums = pass_sums_[int(p)];
    if (sums.empty()) {
        for (int c = 0; c < channels; ++c) out[c] = 0.0f;
        return;
    }
    const float* s = &sums[i * size_t(channels)];
    const float inv = count_[i] ? 1.0f / float(count_[i]) : 0.0f;
    switch (p) {
        case RenderPass::DiffuseDirect:
        case RenderPass::DiffuseIndirect:
        case RenderPass::GlossyDirect:
        case RenderPass::GlossyIndirect:
        case RenderPass::TransmissionDirect:
        case RenderPass::TransmissionIndirect: {
            // Divided by the lobe's Col (both sums over the same samples), 0 where Col is.
            const int color = (int(p) / 3) * 3 + 2;
            const float* col = &pass_sums_[color][3 * i];
            for (int c = 0; c < 3; ++c) out[c] = col[c] != 0.0f ? s[c] / col[c] : 0.0f;
            break;
        }
        case RenderPass::Mist:
            // Accumulated as 1 - mist (0 for the world), as Cycles does.
            out[0] = count_[i] ? 1.0f - s[0] * inv : 0.0f;
            break;
        case RenderPass::Vector: {
            // Cycles divides by its motion weight: the samples that hit something.
            const float hit_inv = hits_[i] ? 1.0f / float(hits_[i]) : 0.0f;
            for (int c = 0; c < 4; ++c) out[c] = s[c] * hit_inv;
            break;
        }
        case RenderPass::Position:
        case RenderPass::IndexOB:
        case RenderPass::IndexMA:
            for (int c = 0; c < channels; ++c) out[c] = s[c];
            break;
        default:
            for (int c = 0; c < channels; ++c) out[c] = s[c] * inv;
            break;
    }
}

void Film::enable_denoising_features() {
    const size_t n = size_t(width_) * size_t(height_);
    if (albedo_.size() == 3 * n && n > 0) return;
    for (std::vector<float>* b : {&albedo_, &albedo_odd_, &dnormal_, &dnormal_odd_, &direct_, &direct_odd_})
        b->assign(3 * n, 0.0f);
    ddepth_.assign(n, 0.0f);
}

void Film::add_denoising_features(int x, int y, const Vec3f& albedo, const Vec3f& normal, float depth,
                                  uint32_t sample) {
    const size_t pixel = size_t(y) * size_t(width_) + size_t(x), i = 3 * pixel;
    ddepth_[pixel] += depth;
    const float a[3] = {albedo.x, albedo.y, albedo.z}, nv[3] = {normal.x, normal.y, normal.z};
    for (int c = 0; c < 3; ++c) {
        albedo_[i + c] += a[c];
        dnormal_[i + c] += nv[c];
    }
    if (sample & 1u)
        for (int c = 0; c < 3; ++c) {
            albedo_odd_[i + c] += a[c];
            dnormal_odd_[i + c] += nv[c];
        }
}

void Film::add_direct_light(int x, int y, const Vec3f& direct, uint32_t sample) {
    const size_t i = 3 * (size_t(y) * size_t(width_) + size_t(x));
    const float d[3] = {direct.x, direct.y, direct.z};
    for (int c = 0; c < 3; ++c) direct_[i + c] += d[c];
    if (sample & 1u)
        for (int c = 0; c < 3; ++c) direct_odd_[i + c] += d[c];
}

Film::Sums Film::sums() const {
    const bool f = has_denoising_features();
    return {rgba_.data(),
            rgb_odd_.data(),
            count_.data(),
            count_odd_.data(),
            f ? albedo_.data() : nullptr,
            f ? albedo_odd_.data() : nullptr,
            f ? dnormal_.data() : nullptr,
            f ? dnormal_odd_.data() : nullptr,
            depth_.data(),
            hits_.data(),
            f ? direct_.data() : nullptr,
            f ? direct_odd_.data() : nullptr};
}

void Film::set_denoised(std::vector<float> rgb) {
    if (rgb.size() == 3 * size_t(width_) * size_t(height_)) denoised_ = std::move(rgb);
}

void Film::enable_heatmaps() {
    const size_t n = size_t(width_) * size_t(height_);
    if (heat_.size() == 2 * n) return;
    heat_.assign(2 * n, 0.0f);
    heat_count_.assign(n, 0);
}

void Film::add_heatmap_sample(int x, int y, float node_visits, float simd_utilisation) {
    const size_t i = size_t(y) * size_t(width_) + size_t(x);
    heat_[2 * i + 0] += node_visits;
    heat_[2 * i + 1] += simd_utilisation;
    ++heat_count_[i];
}

void Film::add_sample(int x, int y, const Vec3f& radiance, float alpha, float depth, const Vec3f& normal,
                      uint32_t sample) {
    const size_t i = size_t(y) * size_t(width_) + size_t(x);
    rgba_[4 * i + 0] += radiance.x;
    rgba_[4 * i + 1] += radiance.y;
    rgba_[4 * i + 2] += radiance.z;
    rgba_[4 * i + 3] += alpha;
    // depth < kInf marks a sample that hit geometry.
    if (depth < kInf) {
        depth_[i] += depth;
        ++hits_[i];
    }
    normal_[3 * i + 0] += normal.x;
    normal_[3 * i + 1] += normal.y;
    normal_[3 * i + 2] += normal.z;
    ++count_[i];
    if (sample & 1u) {
        rgb_odd_[3 * i + 0] += radiance.x;
        rgb_odd_[3 * i + 1] += radiance.y;
        rgb_odd_[3 * i + 2] += radiance.z;
        ++count_odd_[i];
    }
}

namespace {

// Squared error estimate d^2 summed over R, G, B for pixel i (see film.h);
// false when the pixel lacks an even or an odd sample.
bool pixel_error_sq(const float* sum, const float* sum_odd, uint32_t n, uint32_t n_odd, double& out) {
    const uint32_t n_even = n - n_odd;
    out = 0.0;
    if (n_odd == 0 || n_even == 0) return false;
    for (int c = 0; c < 3; ++c) out += halves_mean_variance(sum[c], sum_odd[c], n, n_odd);
    return true;
}

}  // namespace

float Film::pixel_error(int x, int y) const {
    const size_t i = size_t(y) * size_t(width_) + size_t(x);
    double e2 = 0.0;
    pixel_error_sq(&rgba_[4 * i], &rgb_odd_[3 * i], count_[i], count_odd_[i], e2);
    const float e = float(std::sqrt(e2 / 3.0));
    return std::isfinite(e) ? e : 0.0f;
}

double Film::pixel_mean(int x, int y) const {
    const size_t i = size_t(y) * size_t(width_) + size_t(x);
    if (count_[i] == 0) return 0.0;
    return (double(rgba_[4 * i]) + double(rgba_[4 * i + 1]) + double(rgba_[4 * i + 2])) / (3.0 * double(count_[i]));
}

double Film::relative_rmse_estimate() const {
    const size_t n = size_t(width_) * size_t(height_);
    if (n == 0) return -1.0;
    double err2 = 0.0, mean = 0.0;
    for (size_t i = 0; i < n; ++i) {
        double e2 = 0.0;
        if (!pixel_error_sq(&rgba_[4 * i], &rgb_odd_[3 * i], count_[i], count_odd_[i], e2)) return -1.0;
        err2 += e2;
        const double inv = 1.0 / double(count_[i]);
        mean += (double(rgba_[4 * i]) + double(rgba_[4 * i + 1]) + double(rgba_[4 * i + 2])) * inv;
    }
    err2 /= double(3 * n);
    mean /= double(3 * n);
    if (!(mean > 0.0)) return 0.0;  // all black: every sample was 0 (radiance is non-negative)
    const double r = std::sqrt(err2) / mean;
    return std::isfinite(r) ? r : -1.0;
}

void Film::resolve_into(PassType t, float* out) const {
    const size_t n = size_t(width_) * size_t(height_);
    if (is_render_pass(t)) {
        const size_t channels = size_t(pass_info(t).channels);
        for (size_t i = 0; i < n; ++i) resolve_render_pass(t, i, out + channels * i);
        return;
    }
    for (size_t i = 0; i < n; ++i) {
        const float inv = count_[i] ? 1.0f / float(count_[i]) : 0.0f;
        switch (t) {
            case PassType::Combined:
                for (int c = 0; c < 4; ++c) out[4 * i + c] = rgba_[4 * i + c] * inv;
                if (!denoised_.empty())
                    for (int c = 0; c < 3; ++c) out[4 * i + c] = denoised_[3 * i + c];
                break;
            case PassType::NoisyImage:
                for (int c = 0; c < 4; ++c) out[4 * i + c] = rgba_[4 * i + c] * inv;
                break;
            case PassType::DenoisingAlbedo:
            case PassType::DenoisingNormal: {
                const std::vector<float>& b = t == PassType::DenoisingAlbedo ? albedo_ : dnormal_;
                for (int c = 0; c < 3; ++c) out[3 * i + c] = b.empty() ? 0.0f : b[3 * i + c] * inv;
                break;
            }
            case PassType::DenoisingDepth:
                out[i] = ddepth_.empty() ? 0.0f : ddepth_[i] * inv;
                break;
            case PassType::Depth:
                out[i] = hits_[i] ? depth_[i] / float(hits_[i]) : kNoHitDepth;
                break;
            case PassType::Normal:
                for (int c = 0; c < 3; ++c) out[3 * i + c] = normal_[3 * i + c] * inv;
                break;
            case PassType::Error:
                out[i] = pixel_error(int(i % size_t(width_)), int(i / size_t(width_)));
                break;
            case PassType::NodeVisits:
            case PassType::SimdUtilisation: {
                // Zero where no heatmap sample was taken (heatmaps off).
                const int c = t == PassType::NodeVisits ? 0 : 1;
                out[i] = heat_.empty() || heat_count_[i] == 0 ? 0.0f : heat_[2 * i + c] / float(heat_count_[i]);
                break;
            }
            default:
                break;  // render passes: above
        }
    }
}

std::vector<float> Film::resolve(PassType t) const {
    std::vector<float> out(size_t(width_) * size_t(height_) * size_t(pass_info(t).channels));
    resolve_into(t, out.data());
    return out;
}

}  // namespace coherent
