#include "heatmap_output.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <memory>

#include "io/image.h"

namespace coherent::cli {
namespace {

// matplotlib's viridis at t = i / 16 (already sRGB-encoded display values).
// Interpolated linearly they stay within 5.4/255 (per channel) of
// matplotlib's 256-entry table: a diagnostic map needs the order and the
// perceptual evenness of the colours, not their last bit.
constexpr std::array<std::array<float, 3>, 17> kViridis = {{
    {0.2670f, 0.0049f, 0.3294f}, {0.2823f, 0.0950f, 0.4173f}, {0.2788f, 0.1755f, 0.4834f},
    {0.2590f, 0.2515f, 0.5247f}, {0.2297f, 0.3224f, 0.5457f}, {0.1994f, 0.3876f, 0.5546f},
    {0.1727f, 0.4488f, 0.5579f}, {0.1490f, 0.5081f, 0.5573f}, {0.1276f, 0.5669f, 0.5506f},
    {0.1206f, 0.6258f, 0.5335f}, {0.1579f, 0.6838f, 0.5017f}, {0.2461f, 0.7389f, 0.4520f},
    {0.3692f, 0.7889f, 0.3829f}, {0.5160f, 0.8312f, 0.2943f}, {0.6785f, 0.8637f, 0.1895f},
    {0.8456f, 0.8873f, 0.0997f}, {0.9932f, 0.9062f, 0.1439f},
}};


uint8_t to_byte(float v) { return uint8_t(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f)); }

bool write_one(const std::string& output, const Film& film, PassType pass, const char* suffix, bool fixed_unit_range,
               HeatmapImage& image, std::string& error) {
    const int w = film.width(), h = film.height();
    const size_t n = size_t(w) * size_t(h);
    std::vector<float> values = film.resolve(pass);  // one channel
    image.pass = pass;
    image.exr_path = heatmap_path(output, suffix, ".exr");
    image.png_path = heatmap_path(output, suffix, ".png");

    // The film keeps passes finite; should a non-finite value slip through,
    // it must not reach a file (or the scale): it becomes 0.
    double sum = 0.0;
    float lo = INFINITY, hi = -INFINITY;
    for (float& v : values) {
        if (!std::isfinite(v)) v = 0.0f;
        lo = std::min(lo, v);
        hi = std::max(hi, v);
        sum += v;
    }
    image.min = n ? lo : 0.0f;
    image.max = n ? hi : 0.0f;
    image.mean = n ? float(sum / double(n)) : 0.0f;
    image.lo = 0.0f;
    image.hi = fixed_unit_range ? 1.0f : std::max(1.0f, image.max);

    if (!write_value_exr(image.exr_path, w, h, values.data(), "Y", error)) return false;

    std::vector<uint8_t> rgb(n * 3);
    const float scale = 1.0f / (image.hi - image.lo);
    for (size_t i = 0; i < n; ++i) {
        float c[3];
        viridis((values[i] - image.lo) * scale, c);
        for (int k = 0; k < 3; ++k) rgb[i * 3 + size_t(k)] = to_byte(c[k]);
    }
    return write_rgb8_png(image.png_path, w, h, rgb.data(), error);
}

}  // namespace

void viridis(float t, float rgb[3]) {
    if (!(t > 0.0f)) t = 0.0f;  // also NaN
    t = std::min(t, 1.0f);
    const float x = t * float(kViridis.size() - 1);
    const size_t i = std::min(size_t(x), kViridis.size() - 2);
    const float f = x - float(i);
    for (int k = 0; k < 3; ++k) rgb[k] = kViridis[i][size_t(k)] * (1.0f - f) + kViridis[i + 1][size_t(k)] * f;
}

std::string heatmap_path(const std::string& output, const std::string& suffix, const std::string& extension) {
    std::filesystem::path p(output);
    p.replace_extension();
    return p.string() + "." + suffix + extension;
}

bool write_heatmaps(const std::string& output, const Film& film, std::vector<HeatmapImage>& written,
                    std::string& error) {
    HeatmapImage visits, simd;
    if (!write_one(output, film, PassType::NodeVisits, "bvh_visits", false, visits, error)) return false;
    written.push_back(visits);
    if (!write_one(output, film, PassType::SimdUtilisation, "simd", true, simd, error)) return false;
    written.push_back(simd);
    return true;
}

}  // namespace coherent::cli
