// Film accumulation and pass resolution.
#include "film.h"

#include <algorithm>
#include <cmath>

namespace coherent {

// Cycles writes this depth where a pixel saw no geometry; we do the same so
// that no pass ever holds an infinity.
constexpr float kNoHitDepth = 1e10f;

const PassInfo& pass_info(PassType t) {
    static const PassInfo infos[] = {
        {PassType::Combined, "Combined", 4, "RGBA"},
        {PassType::Depth, "Depth", 1, "Z"},
        {PassType::Normal, "Normal", 3, "XYZ"},
    };
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
}

void Film::add_sample(int x, int y, const Vec3f& radiance, float alpha, float depth, const Vec3f& normal) {
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
}

void Film::resolve_into(PassType t, float* out) const {
    const size_t n = size_t(width_) * size_t(height_);
    for (size_t i = 0; i < n; ++i) {
        const float inv = count_[i] ? 1.0f / float(count_[i]) : 0.0f;
        switch (t) {
            case PassType::Combined:
                for (int c = 0; c < 4; ++c) out[4 * i + c] = rgba_[4 * i + c] * inv;
                break;
            case PassType::Depth:
                out[i] = hits_[i] ? depth_[i] / float(hits_[i]) : kNoHitDepth;
                break;
            case PassType::Normal:
                for (int c = 0; c < 3; ++c) out[3 * i + c] = normal_[3 * i + c] * inv;
                break;
        }
    }
}

std::vector<float> Film::resolve(PassType t) const {
    std::vector<float> out(size_t(width_) * size_t(height_) * size_t(pass_info(t).channels));
    resolve_into(t, out.data());
    return out;
}

}  // namespace coherent
