// The Image Texture node over the batch in SIMD rows, for the case real
// scenes mostly hand over: an in-memory byte RGBA image (packed, generated or
// edited in Blender), linear filtering, repeat or extend, alpha straight or
// ignored. Eight lanes compute their footprints together and fetch their
// sixteen texels with AVX2 gathers, which also puts all of a block's cache
// misses in flight at once (the scalar path needs a prefetch pass for that).
//
// Every lane's result is the scalar interpreter's bit for bit
// (image_filter::linear, TextureStore::lookup_by, eval.cpp image_texture):
// the same float operations in the same order, which the build never
// contracts; texel indices wrap with the scalar functions where any lane of a
// block needs wrapping.
#include <cstdint>

#include "../core/simd.h"
#include "../scene/scene.h"
#include "eval_batch_kernels.h"
#include "eval_registers.h"
#include "image_filter.h"
#include "node_color.h"
#include "program.h"

namespace coherent::eval_detail {

namespace {

using V = simd::vfloat8;
using VI = simd::vint8;

// image_filter::bounded, lane-wise (NaN goes to -limit, as there).
V bounded(V x) {
    const V limit(1073741824.0f), lowest(-1073741824.0f);
    return select(x >= lowest, select(x <= limit, x, limit), lowest);
}

// image_filter::footprint: the lower texel (truncation, one lower below 0)
// and the fraction past its centre.
V footprint(V x, int size, VI& lower) {
    const V t = bounded(x * V(float(size)) - V(0.5f));
    const __m256i whole = _mm256_cvttps_epi32(t.v);
    const __m256i below = _mm256_castps_si256((t < V(0.0f)).m);  // -1 where t < 0
    lower = VI(_mm256_add_epi32(whole, below));
    return t - V(_mm256_cvtepi32_ps(lower.v));
}

// Taps i and i + 1 of a block, wrapped as image_filter::wrap_taps<2> does.
void wrap_pair(VI lower, int size, bool repeat, VI& first, VI& second) {
    const __m256i one = _mm256_set1_epi32(1);
    const __m256i next = _mm256_add_epi32(lower.v, one);
    // Both taps inside [0, size): nothing to wrap (the common case).
    const __m256i last = _mm256_set1_epi32(size - 1);
    const __m256i outside = _mm256_or_si256(_mm256_cmpgt_epi32(_mm256_setzero_si256(), lower.v),
                                            _mm256_cmpgt_epi32(next, last));
    if (_mm256_testz_si256(outside, outside)) {
        first = lower;
        second = VI(next);
        return;
    }
    alignas(32) int32_t taps[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(taps), lower.v);
    alignas(32) int32_t a[8], b[8];
    for (int k = 0; k < 8; ++k) {
        int pair[2];
        image_filter::wrap_taps<2>(taps[k], 0, size,
                                   repeat ? TextureLookup::Extension::Repeat : TextureLookup::Extension::Extend, pair);
        a[k] = pair[0], b[k] = pair[1];
    }
    first = VI(_mm256_load_si256(reinterpret_cast<const __m256i*>(a)));
    second = VI(_mm256_load_si256(reinterpret_cast<const __m256i*>(b)));
}

struct Rgba {
    V r, g, b, a;
};

// Texels at 32-bit indices, each channel as value(uint8_t) reads it.
Rgba gather(const int32_t* texels, VI index) {
    const __m256i t = _mm256_i32gather_epi32(texels, index.v, 4);
    const __m256i byte = _mm256_set1_epi32(0xff);
    const V scale(1.0f / 255.0f);
    const auto channel = [&](int shift) {
        return V(_mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32(t, shift), byte))) * scale;
    };
    return {channel(0), channel(8), channel(16), channel(24)};
}

// acc + w * texel per channel, as Texels::add.
void add(Rgba& acc, V w, const Rgba& t) {
    acc.r = acc.r + w * t.r;
    acc.g = acc.g + w * t.g;
    acc.b = acc.b + w * t.b;
    acc.a = acc.a + w * t.a;
}

}  // namespace

bool image_texture_rows(const Scene& scene, const ShaderInstr& in, const BatchRegisters& b) {
    if (in.op != ShaderOp::ImageTexture || !scene.shading.textures) return false;
    const ImagePixels* image = scene.shading.textures->memory_pixels(in.data);
    if (!image || image->is_float || image->channels != 4) return false;
    // Gathers take 32-bit texel indices.
    if (int64_t(image->width) * int64_t(image->height) >= (int64_t(1) << 31)) return false;
    const TextureLookup how = image_lookup_of(in);
    if (how.interp != TextureLookup::Interp::Linear || how.extension == TextureLookup::Extension::Clip) return false;
    if (in.mode & (kImageUnassociate | kImagePremultiply)) return false;
    const bool repeat = how.extension == TextureLookup::Extension::Repeat;
    const int width = image->width, height = image->height;
    const auto* texels = static_cast<const int32_t*>(image->data);
    const VI row_length(width), top(height - 1);
    for (size_t l = 0; l < b.blocks * 8; l += 8) {
        const V u = V::loadu(b.row(in.in[0]) + l), v = V::loadu(b.row(uint16_t(in.in[0] + 1)) + l);
        VI ix, iy;
        const V tx = footprint(u, width, ix), ty = footprint(v, height, iy);
        VI x0, x1, y0, y1;
        wrap_pair(ix, width, repeat, x0, x1);
        wrap_pair(iy, height, repeat, y0, y1);
        // Texels::at: rows run top to bottom, y counts from the bottom.
        const auto row_start = [&](VI y) {
            return VI(_mm256_mullo_epi32(_mm256_sub_epi32(top.v, y.v), row_length.v));
        };
        const VI r0 = row_start(y0), r1 = row_start(y1);
        const auto at = [&](VI row, VI x) { return VI(_mm256_add_epi32(row.v, x.v)); };
        Rgba acc{V(0.0f), V(0.0f), V(0.0f), V(0.0f)};
        add(acc, (V(1.0f) - ty) * (V(1.0f) - tx), gather(texels, at(r0, x0)));
        add(acc, (V(1.0f) - ty) * tx, gather(texels, at(r0, x1)));
        add(acc, ty * (V(1.0f) - tx), gather(texels, at(r1, x0)));
        add(acc, ty * tx, gather(texels, at(r1, x1)));
        const V alpha = (in.mode & kImageIgnoreAlpha) ? V(1.0f) : acc.a;
        if (in.mode & kImageSrgb)
            acc = {shader::srgb_to_linear_image_lanes(acc.r), shader::srgb_to_linear_image_lanes(acc.g),
                   shader::srgb_to_linear_image_lanes(acc.b), acc.a};
        if (in.out[0] != kNoRegister) {
            simd::storeu(b.row(in.out[0]) + l, acc.r);
            simd::storeu(b.row(uint16_t(in.out[0] + 1)) + l, acc.g);
            simd::storeu(b.row(uint16_t(in.out[0] + 2)) + l, acc.b);
        }
        if (in.out[1] != kNoRegister) simd::storeu(b.row(in.out[1]) + l, alpha);
    }
    return true;
}

}  // namespace coherent::eval_detail
