#include "image.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <vector>

#include <OpenImageIO/imageio.h>

#include "../film/film.h"

namespace coherent {
namespace {

std::string lower_extension(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}

// OIIO messages may span lines; errors here are one line.
std::string one_line(std::string s) {
    for (char& c : s)
        if (c == '\n' || c == '\r') c = ' ';
    while (!s.empty() && s.back() == ' ') s.pop_back();
    return s;
}

bool write_with_oiio(const std::string& path, const OIIO::ImageSpec& spec, OIIO::TypeDesc type, const void* pixels,
                     std::string& error) {
    auto out = OIIO::ImageOutput::create(path);
    if (!out) {
        error = path + ": cannot create image writer: " + one_line(OIIO::geterror());
        return false;
    }
    if (!out->open(path, spec)) {
        error = path + ": cannot open for writing: " + one_line(out->geterror());
        return false;
    }
    const bool wrote = out->write_image(type, pixels);
    const std::string write_error = wrote ? std::string() : one_line(out->geterror());
    const bool closed = out->close();
    if (!wrote || !closed) {
        error = path + ": write failed: " + (wrote ? one_line(out->geterror()) : write_error);
        return false;
    }
    return true;
}

bool write_exr(const std::string& path, const ImagePasses& p, std::string& error) {
    std::vector<std::string> names = {"R", "G", "B", "A"};
    if (p.depth) names.push_back("Z");
    if (p.normal) names.insert(names.end(), {"N.X", "N.Y", "N.Z"});
    for (const ImagePasses::Layer& layer : p.layers)
        for (char c : layer.channel_ids) names.push_back(layer.name + "." + c);
    const int nch = int(names.size());

    OIIO::ImageSpec spec(p.width, p.height, nch, OIIO::TypeDesc::FLOAT);
    spec.channelnames = names;
    spec.alpha_channel = 3;
    spec.z_channel = p.depth ? 4 : -1;
    spec.attribute("compression", "zip");
    spec.attribute("oiio:ColorSpace", "Linear");

    const size_t n = size_t(p.width) * size_t(p.height);
    std::vector<float> pixels(n * size_t(nch));
    for (size_t i = 0; i < n; ++i) {
        float* dst = &pixels[i * size_t(nch)];
        for (int c = 0; c < 4; ++c) *dst++ = p.combined[i * 4 + size_t(c)];
        if (p.depth) *dst++ = p.depth[i];
        if (p.normal)
            for (int c = 0; c < 3; ++c) *dst++ = p.normal[i * 3 + size_t(c)];
        for (const ImagePasses::Layer& layer : p.layers) {
            const size_t k = layer.channel_ids.size();
            for (size_t c = 0; c < k; ++c) *dst++ = layer.pixels[i * k + c];
        }
    }
    return write_with_oiio(path, spec, OIIO::TypeDesc::FLOAT, pixels.data(), error);
}

uint8_t quantize(float v) {
    // NaN fails both comparisons and becomes 0.
    if (!(v > 0.0f)) return 0;
    if (!(v < 1.0f)) return 255;
    return uint8_t(std::lround(v * 255.0f));
}

bool write_png(const std::string& path, const ImagePasses& p, std::string& error) {
    const size_t n = size_t(p.width) * size_t(p.height);
    std::vector<uint8_t> pixels(n * 4);
    for (size_t i = 0; i < n; ++i) {
        const float* src = &p.combined[i * 4];
        const float alpha = std::clamp(std::isfinite(src[3]) ? src[3] : 0.0f, 0.0f, 1.0f);
        // Straight alpha: Combined is premultiplied, PNG is not.
        const float inv_alpha = alpha > 1e-6f ? 1.0f / alpha : 1.0f;
        for (int c = 0; c < 3; ++c) pixels[i * 4 + size_t(c)] = quantize(linear_to_srgb(src[c] * inv_alpha));
        pixels[i * 4 + 3] = quantize(alpha);
    }
    OIIO::ImageSpec spec(p.width, p.height, 4, OIIO::TypeDesc::UINT8);
    spec.alpha_channel = 3;
    // The data is already un-premultiplied: stop OIIO from doing it again.
    spec.attribute("oiio:UnassociatedAlpha", 1);
    spec.attribute("oiio:ColorSpace", "sRGB");
    return write_with_oiio(path, spec, OIIO::TypeDesc::UINT8, pixels.data(), error);
}

}  // namespace

bool write_value_exr(const std::string& path, int width, int height, const float* values, const char* channel,
                     std::string& error) {
    OIIO::ImageSpec spec(width, height, 1, OIIO::TypeDesc::FLOAT);
    spec.channelnames = {channel};
    spec.attribute("compression", "zip");
    spec.attribute("oiio:ColorSpace", "Linear");
    return write_with_oiio(path, spec, OIIO::TypeDesc::FLOAT, values, error);
}

bool write_rgb8_png(const std::string& path, int width, int height, const uint8_t* rgb, std::string& error) {
    OIIO::ImageSpec spec(width, height, 3, OIIO::TypeDesc::UINT8);
    spec.attribute("oiio:ColorSpace", "sRGB");
    return write_with_oiio(path, spec, OIIO::TypeDesc::UINT8, rgb, error);
}

ImageFormat image_format_for(const std::string& path) {
    const std::string ext = lower_extension(path);
    if (ext == ".exr") return ImageFormat::Exr;
    if (ext == ".png") return ImageFormat::Png;
    return ImageFormat::Unknown;
}

float linear_to_srgb(float x) {
    if (!(x > 0.0f)) return 0.0f;
    if (x >= 1.0f) return 1.0f;
    return x <= 0.0031308f ? 12.92f * x : 1.055f * std::pow(x, 1.0f / 2.4f) - 0.055f;
}

bool write_image(const std::string& path, const ImagePasses& passes, std::string& error) {
    if (passes.width <= 0 || passes.height <= 0 || !passes.combined) {
        error = path + ": nothing to write (empty image)";
        return false;
    }
    switch (image_format_for(path)) {
        case ImageFormat::Exr: return write_exr(path, passes, error);
        case ImageFormat::Png: return write_png(path, passes, error);
        case ImageFormat::Unknown: break;
    }
    error = path + ": unknown image format '" + lower_extension(path) + "' (use .exr or .png)";
    return false;
}

bool write_film(const std::string& path, const Film& film, std::string& error) {
    const std::vector<float> combined = film.resolve(PassType::Combined);
    const std::vector<float> depth = film.resolve(PassType::Depth);
    const std::vector<float> normal = film.resolve(PassType::Normal);
    ImagePasses passes;
    passes.width = film.width();
    passes.height = film.height();
    passes.combined = combined.data();
    passes.depth = depth.data();
    passes.normal = normal.data();
    std::vector<std::vector<float>> resolved;
    resolved.reserve(kPassTypeCount);
    const auto add_layer = [&](PassType t) {
        const PassInfo& info = pass_info(t);
        resolved.push_back(film.resolve(t));
        passes.layers.push_back({info.name, info.chan_id, resolved.back().data()});
    };
    for (int i = 0; i < kRenderPassCount; ++i)
        if (film.passes() & pass_bit(RenderPass(i))) add_layer(pass_type(RenderPass(i)));
    // What denoising kept (--denoise, --denoising-data), under Cycles' names.
    if (film.has_denoising_features())
        for (PassType t : {PassType::DenoisingNormal, PassType::DenoisingAlbedo, PassType::DenoisingDepth}) add_layer(t);
    if (film.denoised()) add_layer(PassType::NoisyImage);
    return write_image(path, passes, error);
}

}  // namespace coherent
