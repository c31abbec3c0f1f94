// The direct filter of in-memory images (native/shader/image_filter.h):
// Cycles 3.4's CPU formulas, checked value by value on tiny images against
// hand-computed results, and against OpenImageIO's TextureSystem filtering the
// same buffer (TextureStore::lookup_through_oiio) for every interpolation and
// extension, bytes and floats, 1, 3 and 4 channels.
#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "shader/image_filter.h"
#include "shader/textures.h"

namespace coherent {
namespace {

using Interp = TextureLookup::Interp;
using Extension = TextureLookup::Extension;

constexpr Interp kInterps[] = {Interp::Closest, Interp::Linear, Interp::Cubic};
constexpr Extension kExtensions[] = {Extension::Repeat, Extension::Extend, Extension::Clip};

TextureLookup how(Interp interp, Extension extension) {
    TextureLookup h;
    h.interp = interp;
    h.extension = extension;
    return h;
}

std::string name(TextureLookup h) {
    static const char* interps[] = {"linear", "closest", "cubic"};
    static const char* extensions[] = {"repeat", "extend", "clip"};
    return std::string(interps[int(h.interp)]) + "/" + extensions[int(h.extension)];
}

// One channel of a float image, first row at the TOP; filtered value at (u, v).
float filter1(const std::vector<float>& pixels, int width, int height, float u, float v, TextureLookup h) {
    const ImagePixels image{pixels.data(), width, height, 1, true};
    float out[4] = {-1.0f, -1.0f, -1.0f, -1.0f};
    filter_image(image, u, v, h, out);
    EXPECT_EQ(out[1], -1.0f) << "wrote past the image's channels";
    return out[0];
}

// 2 x 2, rows top down: a b / c d. Cycles' (x, y) puts row y = 0 at the bottom: c d.
const std::vector<float> k2x2 = {1.0f, 2.0f,    // top: a b
                                 4.0f, 8.0f};   // bottom: c d

TEST(ImageFilter, ClosestPicksTheTexelUnderThePointBottomRowFirst) {
    const TextureLookup closest = how(Interp::Closest, Extension::Repeat);
    EXPECT_EQ(filter1(k2x2, 2, 2, 0.25f, 0.25f, closest), 4.0f);  // bottom left: c
    EXPECT_EQ(filter1(k2x2, 2, 2, 0.75f, 0.25f, closest), 8.0f);
    EXPECT_EQ(filter1(k2x2, 2, 2, 0.25f, 0.75f, closest), 1.0f);  // top left: a
    // Repeat: u = -0.25 is texel x = -1, wrapped to 1; u = 1.3 is x = 2 -> 0.
    EXPECT_EQ(filter1(k2x2, 2, 2, -0.25f, 0.25f, closest), 8.0f);
    EXPECT_EQ(filter1(k2x2, 2, 2, 1.3f, 0.75f, closest), 1.0f);
    // Extend: clamped to the edge.
    EXPECT_EQ(filter1(k2x2, 2, 2, -3.0f, 7.0f, how(Interp::Closest, Extension::Extend)), 1.0f);
    // Clip: nothing outside [0, 1]; u = 1 itself clamps to the last texel (Cycles 3.4).
    const TextureLookup clip = how(Interp::Closest, Extension::Clip);
    EXPECT_EQ(filter1(k2x2, 2, 2, -0.01f, 0.5f, clip), 0.0f);
    EXPECT_EQ(filter1(k2x2, 2, 2, 0.5f, 1.01f, clip), 0.0f);
    EXPECT_EQ(filter1(k2x2, 2, 2, 1.0f, 0.0f, clip), 8.0f);
}

TEST(ImageFilter, LinearWeighsTheFourTexelsAroundThePoint) {
    // (0.5, 0.5): x * 2 - 0.5 = 0.5 between texel centres 0 and 1 both ways.
    const TextureLookup repeat = how(Interp::Linear, Extension::Repeat);
    EXPECT_EQ(filter1(k2x2, 2, 2, 0.5f, 0.5f, repeat), 0.25f * 4.0f + 0.25f * 8.0f + 0.25f * 1.0f + 0.25f * 2.0f);
    // u = 0.375: x = 0.25 -> tx = 0.25; v = 0.25: texel centre of the bottom row, ty = 0.
    EXPECT_EQ(filter1(k2x2, 2, 2, 0.375f, 0.25f, repeat), 0.75f * 4.0f + 0.25f * 8.0f);
    // u = 0.125: x = -0.25 -> ix = -1, tx = 0.75. Repeat wraps -1 to 1, extend clamps it to 0.
    EXPECT_EQ(filter1(k2x2, 2, 2, 0.125f, 0.25f, repeat), 0.25f * 8.0f + 0.75f * 4.0f);
    EXPECT_EQ(filter1(k2x2, 2, 2, 0.125f, 0.25f, how(Interp::Linear, Extension::Extend)), 0.25f * 4.0f + 0.75f * 4.0f);
    // Clip: texels outside are black, so the image fades out over the half
    // texel past its edge: u = 1.125 -> x = 1.75, ix = 1, tx = 0.75.
    const TextureLookup clip = how(Interp::Linear, Extension::Clip);
    EXPECT_EQ(filter1(k2x2, 2, 2, 1.125f, 0.25f, clip), 0.25f * 8.0f);
    EXPECT_EQ(filter1(k2x2, 2, 2, 0.125f, 0.25f, clip), 0.75f * 4.0f);
    EXPECT_EQ(filter1(k2x2, 2, 2, 1.3f, 0.25f, clip), 0.0f);
}

// The uniform cubic B-spline basis, written independently of Cycles' Horner form.
double bspline(int k, double t) {
    switch (k) {
        case 0: return (1 - t) * (1 - t) * (1 - t) / 6;
        case 1: return (3 * t * t * t - 6 * t * t + 4) / 6;
        case 2: return (-3 * t * t * t + 3 * t * t + 3 * t + 1) / 6;
        default: return t * t * t / 6;
    }
}

TEST(ImageFilter, CubicWeightsAreTheUniformBSpline) {
    for (float t : {0.0f, 0.1f, 0.25f, 0.5f, 0.8f, 0.999f}) {
        float w[4];
        image_filter::cubic_weights(t, w);
        for (int k = 0; k < 4; ++k) EXPECT_NEAR(w[k], bspline(k, t), 1e-7) << t << " " << k;
    }
}

// A 4 x 3 float image; the cubic value is sum over 4 x 4 texels of B-spline weights.
TEST(ImageFilter, CubicSumsSixteenTexelsWithBSplineWeights) {
    const int w = 4, h = 3;
    std::vector<float> pixels(w * h);
    for (int i = 0; i < w * h; ++i) pixels[i] = float((i * 7) % 11) - 3.0f;
    auto texel = [&](int x, int y, Extension e) -> double {  // Cycles' (x, y), y from the bottom
        if (e == Extension::Repeat) x = (x % w + w) % w, y = (y % h + h) % h;
        if (e == Extension::Extend) x = std::clamp(x, 0, w - 1), y = std::clamp(y, 0, h - 1);
        if (x < 0 || y < 0 || x >= w || y >= h) return 0.0;
        return pixels[(h - 1 - y) * w + x];
    };
    for (Extension e : kExtensions)
        for (auto [u, v] : {std::pair{0.3f, 0.6f}, std::pair{0.01f, 0.95f}, std::pair{1.05f, -0.1f}}) {
            const double x = double(u) * w - 0.5, y = double(v) * h - 0.5;
            const int ix = int(std::floor(x)), iy = int(std::floor(y));
            double expected = 0.0;
            for (int j = 0; j < 4; ++j)
                for (int i = 0; i < 4; ++i)
                    expected += bspline(j, y - iy) * bspline(i, x - ix) * texel(ix - 1 + i, iy - 1 + j, e);
            EXPECT_NEAR(filter1(pixels, w, h, u, v, how(Interp::Cubic, e)), expected, 1e-5)
                << name(how(Interp::Cubic, e)) << " at " << u << "," << v;
        }
}

TEST(ImageFilter, BytesReadAsValueOver255AndChannelsStayApart) {
    const std::vector<uint8_t> rgba = {255, 0, 51, 128};  // 1 x 1
    const ImagePixels image{rgba.data(), 1, 1, 4, false};
    float out[4];
    filter_image(image, 0.3f, 0.7f, how(Interp::Linear, Extension::Repeat), out);
    // Four taps on the one texel: weights (1-ty)(1-tx) ... summed, each texel value / 255.
    for (int c = 0; c < 4; ++c) EXPECT_NEAR(out[c], rgba[c] / 255.0, 2.4e-7) << c;  // weights sum to 1 +- an ulp
    filter_image(image, 0.3f, 0.7f, how(Interp::Closest, Extension::Repeat), out);
    for (int c = 0; c < 4; ++c) EXPECT_EQ(out[c], float(rgba[c]) * (1.0f / 255.0f)) << c;
}

// Cycles' texels of an image without alpha have alpha 1, filtered like the
// colour: a clipped image fades out in alpha too.
TEST(ImageFilter, AnImageWithoutAlphaFadesOutAtAClippedEdge) {
    const std::vector<float> rgb = {0.5f, 0.25f, 1.0f, 0.5f, 0.25f, 1.0f};  // 2 x 1
    const ImagePixels image{rgb.data(), 2, 1, 3, true};
    float out[4];
    filter_image(image, 1.125f, 0.5f, how(Interp::Linear, Extension::Clip), out);  // tx = 0.75 past texel 1
    EXPECT_EQ(out[0], 0.25f * 0.5f);
    EXPECT_EQ(out[3], 0.25f);
    filter_image(image, 0.5f, 0.5f, how(Interp::Linear, Extension::Clip), out);
    EXPECT_EQ(out[3], 1.0f);
    filter_image(image, 1.125f, 0.5f, how(Interp::Closest, Extension::Clip), out);
    EXPECT_EQ(out[3], 0.0f);
    filter_image(image, 0.9f, 0.5f, how(Interp::Closest, Extension::Clip), out);
    EXPECT_EQ(out[3], 1.0f);
    TextureStore store(64);
    const uint32_t grey = store.add_pixels("grey", 2, 1, 1, rgb.data());
    float rgba[4];
    store.lookup(grey, 1.125f, 0.5f, how(Interp::Linear, Extension::Clip), rgba);
    EXPECT_EQ(rgba[0], 0.25f * 0.25f);
    EXPECT_EQ(rgba[2], 0.25f * 0.25f);
    EXPECT_EQ(rgba[3], 0.25f);
}

TEST(ImageFilter, NaNAndHugeCoordinatesStayInsideTheImage) {
    for (Interp i : kInterps)
        for (Extension e : kExtensions)
            for (float u : {NAN, INFINITY, -INFINITY, 3e9f, -3e9f}) {
                const float value = filter1(k2x2, 2, 2, u, 0.5f, how(i, e));
                EXPECT_TRUE(value >= 0.0f && value <= 8.0f) << name(how(i, e)) << " " << u << ": " << value;
            }
}

// Pixels with a pattern (rows top down) as bytes or floats.
std::vector<uint8_t> pattern_bytes(int w, int h, int channels) {
    std::vector<uint8_t> b(size_t(w) * h * channels);
    for (size_t i = 0; i < b.size(); ++i) b[i] = uint8_t((i * 37 + (i / channels) * 11) % 256);
    return b;
}

// Points of many kinds: random inside and outside [0, 1], the edges, texel centres.
std::vector<std::pair<float, float>> sample_points(int w, int h) {
    std::mt19937 rng(12345);
    std::uniform_real_distribution<float> wide(-1.5f, 2.5f), unit(0.0f, 1.0f);
    std::vector<std::pair<float, float>> points;
    for (int i = 0; i < 400; ++i) points.push_back({wide(rng), wide(rng)});
    for (int i = 0; i < 200; ++i) points.push_back({unit(rng), unit(rng)});
    for (float edge : {0.0f, 1.0f})
        for (float texels : {0.0f, -0.5f, 0.5f, -0.25f, 0.25f, -1.5f, 1.5f})
            for (int i = 0; i < 10; ++i) {
                points.push_back({edge + texels / w, unit(rng)});
                points.push_back({unit(rng), edge + texels / h});
            }
    for (int x = 0; x < w; x += 3) points.push_back({(x + 0.5f) / w, (x % h + 0.5f) / h});
    return points;
}

// A batch of lookups first prefetches every lane's footprint
// (prefetch_image, through image_filter::footprint_rows), so each lane's
// cache misses overlap the others'. The oracle for what a lookup reads is the
// filter itself: a texel is read where setting it alone to 1 changes the
// result. Every such texel's cache line must be among the visited ones, and
// every visited address must be a texel of the image, at any coordinate.
TEST(ImageFilter, PrefetchVisitsEveryCacheLineALookupReadsAndNothingOutside) {
    const int w = 64, h = 6, channels = 4;  // float RGBA: 16-byte texels, four to a 64-byte line
    std::vector<float> pixels(size_t(w) * h * channels, 0.0f);
    const ImagePixels image{pixels.data(), w, h, channels, true};
    const auto line_of = [](const void* p) { return reinterpret_cast<uintptr_t>(p) >> 6; };
    auto points = sample_points(w, h);
    for (float u : {NAN, INFINITY, -INFINITY, 3e9f, -3e9f}) points.push_back({u, 0.5f}), points.push_back({0.5f, u});
    size_t read = 0;
    for (Interp i : kInterps)
        for (Extension e : kExtensions)
            for (const auto& [u, v] : points) {
                std::vector<uintptr_t> visited;
                image_filter::footprint_rows(image_filter::Texels<float, 1>{pixels.data(), w, h, channels}, u, v,
                                             how(i, e), [&](const void* p) {
                                                 const auto* f = static_cast<const float*>(p);
                                                 ASSERT_TRUE(f >= pixels.data() && f < pixels.data() + pixels.size())
                                                     << name(how(i, e)) << " at " << u << ", " << v;
                                                 visited.push_back(line_of(p));
                                             });
                if (!std::isfinite(u) || !std::isfinite(v) || std::fabs(u) > 1e6f || std::fabs(v) > 1e6f) continue;
                for (size_t t = 0; t < size_t(w) * h; ++t) {
                    pixels[t * channels] = 1.0f;
                    float out[4] = {0.0f, 0.0f, 0.0f, 0.0f};
                    filter_image(image, u, v, how(i, e), out);
                    pixels[t * channels] = 0.0f;
                    if (out[0] == 0.0f) continue;
                    ++read;
                    EXPECT_NE(std::find(visited.begin(), visited.end(), line_of(&pixels[t * channels])), visited.end())
                        << name(how(i, e)) << " at " << u << ", " << v << " reads texel " << t % w << ", " << t / w
                        << " whose line was not prefetched";
                }
            }
    EXPECT_GT(read, 10000u);
}

// Writes `pixels` (rows top down, `channels` values of `type` a texel) as
// an image file at `path` (its extension picks the format).
void write_image(const std::string& path, int w, int h, int channels, OIIO::TypeDesc type, const void* pixels) {
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out) << path;
    OIIO::ImageSpec spec(w, h, channels, type);
    spec.attribute("oiio:UnassociatedAlpha", 1);  // the values as given, not divided by alpha into a PNG
    ASSERT_TRUE(out->open(path, spec)) << out->geterror();
    ASSERT_TRUE(out->write_image(type, pixels)) << out->geterror();
    out->close();
}

std::string temp_image_path(const std::string& name) {
    return (std::filesystem::temp_directory_path() / ("coherent_" + std::to_string(getpid()) + "_" + name)).string();
}

// Where the OIIO path is not Cycles and the direct filter is (both asserted
// above): closest at a texel boundary may pick either texel (OIIO is given
// t = 1 - v, whose rounding can land across it; at v = 0 exactly it reads the
// top row); a clipped image is black outside [0, 1] through OIIO, where linear
// and cubic fade out over the texels past the edge; and OIIO's alpha of an
// image without alpha is 1, Cycles' fades out at a clipped edge.
bool comparable(float u, float v, int w, int h, int channels, TextureLookup h_, int c) {
    auto near_whole = [](float x) { return std::fabs(x - std::round(x)) < 1e-3f; };
    if (h_.interp == Interp::Closest && (near_whole(u * w) || near_whole(v * h))) return false;
    if (h_.extension != Extension::Clip) return true;
    const bool outside = u < 0.0f || u > 1.0f || v < 0.0f || v > 1.0f;
    if (outside && h_.interp != Interp::Closest) return false;
    return !(c == 3 && (channels == 1 || channels == 3));
}

// Compares lookup `a` of an image with lookup `b` (the reference) at every
// interpolation, extension and sample point where both are Cycles'; returns
// how many values it compared (stops at the first that differs).
template <class A, class B>
size_t compare_everywhere(int w, int h, int channels, const std::string& what, A&& a, B&& b) {
    size_t compared = 0;
    for (Interp i : kInterps)
        for (Extension e : kExtensions)
            for (auto [u, v] : sample_points(w, h)) {
                float x[4], y[4];
                a(u, v, how(i, e), x);
                b(u, v, how(i, e), y);
                for (int c = 0; c < 4; ++c) {
                    if (!comparable(u, v, w, h, channels, how(i, e), c)) continue;
                    ++compared;
                    if (std::fabs(x[c] - y[c]) > 2e-5f * (1.0f + std::fabs(y[c]))) {
                        ADD_FAILURE() << what << ", " << name(how(i, e)) << " at (" << u << ", " << v << ") channel "
                                      << c << ": " << x[c] << " against " << y[c];
                        return compared;
                    }
                }
            }
    return compared;
}

TEST(ImageFilter, DirectFilterEqualsOiioOnTheSameBuffer) {
    const int w = 13, h = 7;  // odd sizes: wrapping is not a power-of-two mask
    size_t compared = 0;
    for (bool is_float : {false, true})
        for (int channels : {1, 3, 4}) {
            TextureStore store(64);
            const std::vector<uint8_t> bytes = pattern_bytes(w, h, channels);
            std::vector<float> floats;
            for (uint8_t b : bytes) floats.push_back(float(b) / 64.0f - 1.0f);  // negative and over 1 too
            const uint32_t id = is_float ? store.add_pixels("f", w, h, channels, floats.data())
                                         : store.add_bytes("b", w, h, channels, bytes.data());
            compared += compare_everywhere(
                w, h, channels, (is_float ? "float " : "byte ") + std::to_string(channels) + " channels",
                [&](float u, float v, TextureLookup h_, float* out) { store.lookup(id, u, v, h_, out); },
                [&](float u, float v, TextureLookup h_, float* out) { store.lookup_through_oiio(id, u, v, h_, out); });
        }
    EXPECT_GT(compared, size_t(6 * 9 * 600 * 3));  // most points of every case
}

// Image files are decoded whole into memory (TextureStore::add_file) and
// filtered directly; the oracle is OpenImageIO's TextureSystem reading the
// same file itself (a store with decode_files false). Grey, grey + alpha,
// RGB and RGBA 8-bit PNGs, a 16-bit PNG and a float EXR, odd sizes.
TEST(ImageFiles, DecodedFilesLookUpAsTheTextureSystemReadsThem) {
    const int w = 13, h = 7;
    struct Case {
        const char* name;
        int channels;
        OIIO::TypeDesc type;
    };
    const Case cases[] = {{"grey.png", 1, OIIO::TypeDesc::UINT8},  {"grey_alpha.png", 2, OIIO::TypeDesc::UINT8},
                          {"rgb.png", 3, OIIO::TypeDesc::UINT8},   {"rgba.png", 4, OIIO::TypeDesc::UINT8},
                          {"rgb16.png", 3, OIIO::TypeDesc::UINT16}, {"rgba.exr", 4, OIIO::TypeDesc::FLOAT}};
    size_t compared = 0;
    for (const Case& c : cases) {
        const std::string path = temp_image_path(c.name);
        const std::vector<uint8_t> bytes = pattern_bytes(w, h, c.channels);
        std::vector<uint16_t> shorts;
        std::vector<float> floats;
        for (uint8_t b : bytes) shorts.push_back(uint16_t(b * 257 + (b % 7)));
        for (uint8_t b : bytes) floats.push_back(float(b) / 64.0f - 1.0f);
        const void* data = c.type == OIIO::TypeDesc::UINT8    ? static_cast<const void*>(bytes.data())
                           : c.type == OIIO::TypeDesc::UINT16 ? static_cast<const void*>(shorts.data())
                                                              : static_cast<const void*>(floats.data());
        write_image(path, w, h, c.channels, c.type, data);
        TextureStore decoded(64), reference(64, false);
        const uint32_t id = decoded.add_file(path, c.name), ref = reference.add_file(path, c.name);
        ASSERT_NE(decoded.memory_pixels(id), nullptr) << c.name << " was not decoded";
        EXPECT_EQ(reference.memory_pixels(ref), nullptr);
        EXPECT_TRUE(decoded.warnings().empty()) << decoded.warnings()[0];
        compared += compare_everywhere(
            w, h, c.channels == 2 ? 4 : c.channels, c.name,
            [&](float u, float v, TextureLookup h_, float* out) { decoded.lookup(id, u, v, h_, out); },
            [&](float u, float v, TextureLookup h_, float* out) { reference.lookup(ref, u, v, h_, out); });
        std::remove(path.c_str());
    }
    EXPECT_GT(compared, size_t(6 * 9 * 600 * 3));
}

// A file is decoded once per process while it is unchanged: a later store
// (a re-render) reuses the pixels; NaN texels of a float file become 0 with
// a warning, as for in-memory images (and as Cycles loads them).
TEST(ImageFiles, AnUnchangedFileIsDecodedOnceAndItsNaNTexelsAreZero) {
    const std::string path = temp_image_path("nan.exr");
    std::vector<float> px(4 * 4 * 4, 0.5f);
    px[5 * 4 + 1] = std::numeric_limits<float>::quiet_NaN();
    write_image(path, 4, 4, 4, OIIO::TypeDesc::FLOAT, px.data());
    for (size_t render = 0; render < 2; ++render) {
        TextureStore store(64);
        const uint32_t id = store.add_file(path, "Material 'm', node 'n'");
        EXPECT_EQ(store.reused(), render);
        ASSERT_EQ(store.warnings().size(), 1u);
        EXPECT_NE(store.warnings()[0].find("NaN"), std::string::npos) << store.warnings()[0];
        float c[4];
        TextureLookup closest;
        closest.interp = Interp::Closest;
        store.lookup(id, 1.5f / 4, 2.5f / 4, closest, c);  // texel (1, 1) from the top: row 2 from the bottom
        EXPECT_EQ(c[1], 0.0f);
        EXPECT_EQ(c[0], 0.5f);
    }
    std::remove(path.c_str());
}

// The store's memory limit bounds the decoded pixels: a file that would pass
// it is read through the TextureSystem's tiles instead, and looks the same.
TEST(ImageFiles, AFileBeyondTheMemoryLimitGoesThroughTheTextureCache) {
    const int w = 700, h = 400;  // 1.12 MB as RGBA bytes, past a 1 MB limit
    const std::string big = temp_image_path("big.png"), small = temp_image_path("small.png");
    const std::vector<uint8_t> bytes = pattern_bytes(w, h, 3);
    write_image(big, w, h, 3, OIIO::TypeDesc::UINT8, bytes.data());
    write_image(small, 16, 16, 3, OIIO::TypeDesc::UINT8, bytes.data());
    TextureStore limited(1), roomy(64);
    const uint32_t small_id = limited.add_file(small, "small"), big_id = limited.add_file(big, "big");
    const uint32_t decoded_id = roomy.add_file(big, "big");
    EXPECT_NE(limited.memory_pixels(small_id), nullptr);
    EXPECT_EQ(limited.memory_pixels(big_id), nullptr);
    ASSERT_NE(roomy.memory_pixels(decoded_id), nullptr);
    EXPECT_LE(limited.buffer_bytes(), size_t(1) << 20);
    for (auto [u, v] : sample_points(w, h)) {
        float a[4], b[4];
        limited.lookup(big_id, u, v, how(Interp::Linear, Extension::Repeat), a);
        roomy.lookup(decoded_id, u, v, how(Interp::Linear, Extension::Repeat), b);
        // OIIO is given 1 - v: across 400 rows its rounding moves a weight by ~1e-5.
        for (int k = 0; k < 4; ++k) ASSERT_NEAR(a[k], b[k], 1e-4f) << "at (" << u << ", " << v << ")";
    }
    EXPECT_GT(limited.memory_bytes(), 0u);  // the big file's tiles
    std::remove(big.c_str());
    std::remove(small.c_str());
}

// A straight byte colour file is associated as Cycles associates it on load
// (c * a / 255 in integers, truncated), every texel, when asked to, and so
// are the same bytes handed over as pixels; alpha stays as stored.
TEST(ImageFiles, AStraightColourFileIsAssociatedAsCyclesLoadsIt) {
    const int w = 9, h = 5;
    const std::string path = temp_image_path("straight.png");
    const std::vector<uint8_t> bytes = pattern_bytes(w, h, 4);
    write_image(path, w, h, 4, OIIO::TypeDesc::UINT8, bytes.data());
    TextureStore store(64);
    const uint32_t associated = store.add_file(path, "associated", true), straight = store.add_file(path, "straight");
    const uint32_t handed_over = store.add_bytes("pixels", w, h, 4, bytes.data(), "", true);  // Blender's pixels
    TextureLookup closest;
    closest.interp = Interp::Closest;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const uint8_t* t = &bytes[(size_t(y) * w + x) * 4];  // row y from the top
            const float u = (x + 0.5f) / w, v = (h - 1 - y + 0.5f) / h;
            float a[4], s[4], p[4];
            store.lookup(associated, u, v, closest, a);
            store.lookup(straight, u, v, closest, s);
            store.lookup(handed_over, u, v, closest, p);
            for (int c = 0; c < 4; ++c) EXPECT_EQ(p[c], a[c]) << x << ", " << y << " channel " << c;
            for (int c = 0; c < 3; ++c) {
                EXPECT_FLOAT_EQ(a[c], float((unsigned(t[c]) * t[3]) / 255u) / 255.0f) << x << ", " << y << " channel " << c;
                EXPECT_FLOAT_EQ(s[c], float(t[c]) / 255.0f);
            }
            EXPECT_FLOAT_EQ(a[3], float(t[3]) / 255.0f);
        }
    std::remove(path.c_str());
}

}  // namespace
}  // namespace coherent
