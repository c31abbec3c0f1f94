// Filtering an image that already lives in memory as one whole pixel buffer
// (handed over by Blender: packed, generated or edited images), computed the
// way Cycles 3.4's CPU kernel filters its images (kernel/device/cpu/image.h,
// TextureInterpolator<T>::interp): the same texel addressing (Blender's v runs
// bottom up, a texel's centre at (i + 0.5) / size), closest / linear / cubic
// B-spline weights and extension modes, and the same float operations in the
// same order, so a lookup equals Cycles' to the bit for bytes and floats.
//
// This is no loader and no cache: the pixels are the host's, already in RAM,
// or an image file OpenImageIO decoded (textures.h). One lookup
// takes no lock, allocates nothing and calls nothing virtual.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>

#include "../core/simd.h"
#include "textures.h"  // TextureLookup

namespace coherent {

// A view of pixels (memory_images.h's PixelBuffer): rows top to bottom,
// `channels` values per texel, uint8 read as value / 255 or float32.
struct ImagePixels {
    const void* data = nullptr;
    int width = 0, height = 0, channels = 0;
    bool is_float = false;
};

namespace image_filter {

// Cycles' frac(): whole part by truncation, one lower for negative x (also
// for a negative whole number, whose fraction is then 1: kept, so the same
// texels are chosen).
inline float frac(float x, int& ix) {
    const int i = int(x) - (x < 0.0f ? 1 : 0);
    ix = i;
    return x - float(i);
}

// Keeps the conversion to int defined (NaN and huge coordinates); no float
// beyond 2^30 has a fraction, so nothing within it changes.
inline float bounded(float x) {
    constexpr float kLimit = 1073741824.0f;
    return x >= -kLimit ? (x <= kLimit ? x : kLimit) : -kLimit;
}

inline int wrap_periodic(int x, int size) {
    if (unsigned(x) < unsigned(size)) return x;  // most taps: no division
    x %= size;
    return x < 0 ? x + size : x;
}

inline int wrap_clamp(int x, int size) { return x < 0 ? 0 : (x >= size ? size - 1 : x); }

inline float value(uint8_t v) { return float(v) * (1.0f / 255.0f); }
inline float value(float v) { return v; }

// Texels addressed as Cycles does: (x, y) with y counting rows from the bottom.
// An image without alpha (1 or 3 channels) gets one of 1 in every texel, as
// Cycles' float4 texels have, so a clipped image's alpha fades out with its
// colour; it is filtered as channel N (kValues = N + 1).
template <class T, int N>
struct Texels {
    static constexpr bool kOpaque = N == 1 || N == 3;
    static constexpr int kValues = N + (kOpaque ? 1 : 0);
    const T* data;
    int width, height, stride;

    // Out-of-bounds texels are transparent black, Cycles' read() (clip).
    bool inside(int x, int y) const { return x >= 0 && y >= 0 && x < width && y < height; }
    const T* at(int x, int y) const { return data + (size_t(height - 1 - y) * size_t(width) + size_t(x)) * stride; }
    void read(int x, int y, float out[kValues]) const {
        const T* t = at(x, y);
        for (int c = 0; c < N; ++c) out[c] = value(t[c]);
        if (kOpaque) out[N] = 1.0f;
    }
    // acc += w * texel, per value (skipped outside: w * 0 adds nothing).
    void add(float w, int x, int y, float acc[kValues]) const {
        if (!inside(x, y)) return;
        const T* t = at(x, y);
        if constexpr (N == 4) {  // RGBA in one SSE register: the same operations per channel
            const __m128 sum = _mm_add_ps(_mm_loadu_ps(acc), _mm_mul_ps(_mm_set1_ps(w), values4(t)));
            _mm_storeu_ps(acc, sum);
            return;
        }
        for (int c = 0; c < N; ++c) acc[c] += w * value(t[c]);
        if (kOpaque) acc[N] += w * 1.0f;
    }
    // value() of four channels at once: bytes widened and converted exactly,
    // then times 1/255 as value(uint8_t) rounds it.
    static __m128 values4(const float* t) { return _mm_loadu_ps(t); }
    static __m128 values4(const uint8_t* t) {
        int32_t bytes;
        std::memcpy(&bytes, t, sizeof(bytes));
        const __m128 whole = _mm_cvtepi32_ps(_mm_cvtepu8_epi32(_mm_cvtsi32_si128(bytes)));
        return _mm_mul_ps(whole, _mm_set1_ps(1.0f / 255.0f));
    }
};

template <class T, int N>
void closest(const Texels<T, N>& img, float x, float y, TextureLookup::Extension ext, float* out) {
    int ix, iy;
    frac(bounded(x * float(img.width)), ix);
    frac(bounded(y * float(img.height)), iy);
    if (ext == TextureLookup::Extension::Repeat) {
        ix = wrap_periodic(ix, img.width);
        iy = wrap_periodic(iy, img.height);
    } else {
        if (ext == TextureLookup::Extension::Clip && (x < 0.0f || y < 0.0f || x > 1.0f || y > 1.0f)) return;
        ix = wrap_clamp(ix, img.width);
        iy = wrap_clamp(iy, img.height);
    }
    img.read(ix, iy, out);
}

// The lower texel of a linear or cubic footprint and the fraction past its
// centre (the -0.5 centres the footprint on the sample point).
inline float footprint(float x, int size, int& i) { return frac(bounded(x * float(size) - 0.5f), i); }

// Texel indices i + offset, offset = -1 .. 2, by the extension (clip: unwrapped).
template <int Count>
void wrap_taps(int i, int first, int size, TextureLookup::Extension ext, int taps[Count]) {
    for (int k = 0; k < Count; ++k) {
        const int t = i + first + k;
        taps[k] = ext == TextureLookup::Extension::Repeat ? wrap_periodic(t, size)
                  : ext == TextureLookup::Extension::Extend ? wrap_clamp(t, size)
                                                            : t;
    }
}

template <class T, int N>
void linear(const Texels<T, N>& img, float x, float y, TextureLookup::Extension ext, float* out) {
    int ix, iy;
    const float tx = footprint(x, img.width, ix), ty = footprint(y, img.height, iy);
    int xs[2], ys[2];
    // Cycles wraps ix first and steps from the wrapped value; the same texels.
    wrap_taps<2>(ix, 0, img.width, ext, xs);
    wrap_taps<2>(iy, 0, img.height, ext, ys);
    // (1-ty)(1-tx) A + (1-ty) tx B + ty (1-tx) C + ty tx D, summed in this order.
    img.add((1.0f - ty) * (1.0f - tx), xs[0], ys[0], out);
    img.add((1.0f - ty) * tx, xs[1], ys[0], out);
    img.add(ty * (1.0f - tx), xs[0], ys[1], out);
    img.add(ty * tx, xs[1], ys[1], out);
}

// Cycles' SET_CUBIC_SPLINE_WEIGHTS: the uniform cubic B-spline.
inline void cubic_weights(float t, float w[4]) {
    w[0] = (((-1.0f / 6.0f) * t + 0.5f) * t - 0.5f) * t + (1.0f / 6.0f);
    w[1] = ((0.5f * t - 1.0f) * t) * t + (2.0f / 3.0f);
    w[2] = ((-0.5f * t + 0.5f) * t + 0.5f) * t + (1.0f / 6.0f);
    w[3] = (1.0f / 6.0f) * t * t * t;
}

template <class T, int N>
void cubic(const Texels<T, N>& img, float x, float y, TextureLookup::Extension ext, float* out) {
    int ix, iy;
    const float tx = footprint(x, img.width, ix), ty = footprint(y, img.height, iy);
    int xs[4], ys[4];
    wrap_taps<4>(ix, -1, img.width, ext, xs);
    wrap_taps<4>(iy, -1, img.height, ext, ys);
    float u[4], v[4];
    cubic_weights(tx, u);
    cubic_weights(ty, v);
    // Sum over rows of v[row] * (u0 D0 + u1 D1 + u2 D2 + u3 D3), Cycles' TERM(row).
    for (int row = 0; row < 4; ++row) {
        float term[Texels<T, N>::kValues] = {};
        for (int k = 0; k < 4; ++k) img.add(u[k], xs[k], ys[row], term);
        for (int c = 0; c < Texels<T, N>::kValues; ++c) out[c] += v[row] * term[c];
    }
}

template <class T, int N>
void filter(const ImagePixels& image, float u, float v, TextureLookup how, float out[4]) {
    const Texels<T, N> img{static_cast<const T*>(image.data), image.width, image.height, image.channels};
    float acc[Texels<T, N>::kValues] = {};
    switch (how.interp) {
        case TextureLookup::Interp::Closest: closest(img, u, v, how.extension, acc); break;
        case TextureLookup::Interp::Linear: linear(img, u, v, how.extension, acc); break;
        case TextureLookup::Interp::Cubic: cubic(img, u, v, how.extension, acc); break;
    }
    for (int c = 0; c < N; ++c) out[c] = acc[c];
    if (Texels<T, N>::kOpaque) out[3] = acc[N];
}

// Calls visit(p) for each texel of the footprint a lookup at (x, y) reads
// (closest: 1, linear: 2 x 2, cubic: 4 x 4), row by row, wrapped as the
// lookup wraps them; clipped taps are clamped into the image, so every p
// addresses a texel of it.
template <class T, int N, class Visit>
void footprint_rows(const Texels<T, N>& img, float x, float y, TextureLookup how, Visit&& visit) {
    int ix, iy, first = 0, count = 1;
    if (how.interp == TextureLookup::Interp::Closest) {
        frac(bounded(x * float(img.width)), ix);
        frac(bounded(y * float(img.height)), iy);
    } else {
        footprint(x, img.width, ix);
        footprint(y, img.height, iy);
        first = how.interp == TextureLookup::Interp::Cubic ? -1 : 0;
        count = how.interp == TextureLookup::Interp::Cubic ? 4 : 2;
    }
    const auto wrap = [&](int i, int size) {
        return how.extension == TextureLookup::Extension::Repeat ? wrap_periodic(i, size) : wrap_clamp(i, size);
    };
    for (int k = 0; k < count; ++k) {
        const int row = wrap(iy + first + k, img.height);
        for (int j = 0; j < count; ++j) visit(img.at(wrap(ix + first + j, img.width), row));
    }
}

}  // namespace image_filter

// The first min(channels, 4) filtered values of `image` at Blender's (u, v)
// go to out[0..]; for 1 or 3 channels, out[3] gets the filtered alpha of 1
// (the sum of the weights of the texels inside the image); the rest of out
// is left as it was. Precondition: data set, width, height, channels > 0.
inline void filter_image(const ImagePixels& image, float u, float v, TextureLookup how, float out[4]) {
    using namespace image_filter;
    const int n = image.channels < 4 ? image.channels : 4;
    if (image.is_float) {
        switch (n) {
            case 1: return filter<float, 1>(image, u, v, how, out);
            case 2: return filter<float, 2>(image, u, v, how, out);
            case 3: return filter<float, 3>(image, u, v, how, out);
            default: return filter<float, 4>(image, u, v, how, out);
        }
    }
    switch (n) {
        case 1: return filter<uint8_t, 1>(image, u, v, how, out);
        case 2: return filter<uint8_t, 2>(image, u, v, how, out);
        case 3: return filter<uint8_t, 3>(image, u, v, how, out);
        default: return filter<uint8_t, 4>(image, u, v, how, out);
    }
}

// Starts loading the texels filter_image(image, u, v, how) will read, so that
// a batch of lookups issues all its cache misses before it waits on any.
// Changes nothing a lookup returns.
inline void prefetch_image(const ImagePixels& image, float u, float v, TextureLookup how) {
    using namespace image_filter;
    const void* last = nullptr;  // neighbouring taps mostly share a line
    const auto line = [&](const void* p) {
        if (!last || ((reinterpret_cast<uintptr_t>(p) ^ reinterpret_cast<uintptr_t>(last)) >> 6) != 0)
            simd::prefetch(p);
        last = p;
    };
    // The texel size alone decides the addresses (channels only widen the stride).
    if (image.is_float)
        footprint_rows(Texels<float, 1>{static_cast<const float*>(image.data), image.width, image.height,
                                        image.channels},
                       u, v, how, line);
    else
        footprint_rows(Texels<uint8_t, 1>{static_cast<const uint8_t*>(image.data), image.width, image.height,
                                          image.channels},
                       u, v, how, line);
}

}  // namespace coherent
