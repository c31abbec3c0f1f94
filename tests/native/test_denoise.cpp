// The denoiser (denoise/denoiser.h) on films whose exact image is known:
// samples of a checker albedo under a sharp shadow boundary with mean-one
// multiplicative noise, added pass by pass as the renderer adds them. The
// oracle is the exact image, not another render. Then the feature buffers
// and the denoiser inside real renders: nothing changes without denoising,
// the noisy image stays bit-identical with it.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "denoise/denoiser.h"
#include "test_render_helpers.h"

namespace coherent {
namespace {

using test::add_quad;
using test::ortho_camera_looking_down;
using test::principled;
using test::render_combined;
using test::sphere_on_floor_scene;

constexpr int kSize = 64;
constexpr int kChecker = 8;      // checker squares, pixels
constexpr int kShadowX = 37;     // illumination steps down at this column (not on a checker edge)

Vec3f exact_albedo(int x, int y) {
    return ((x / kChecker + y / kChecker) & 1) ? Vec3f(0.8f, 0.7f, 0.6f) : Vec3f(0.15f, 0.2f, 0.3f);
}
float exact_light(int x, int y) { return (x < kShadowX ? 1.0f : 0.2f) * (0.8f + 0.4f * float(y) / kSize); }
Vec3f exact_pixel(int x, int y) { return exact_albedo(x, y) * exact_light(x, y); }

// A side x side film of `spp` passes; each sample is exact(x, y) times a
// mean-one exponential draw (a heavy tail, like path-traced light), with
// exact features (albedo(x, y), one normal). With `counts` (one a pixel,
// row by row), a pixel takes samples only in its first counts[i] passes.
template <class Exact, class Albedo>
Film noisy_film(int side, int spp, uint32_t seed, Exact&& exact, Albedo&& albedo, const std::vector<int>& counts = {}) {
    Film film(side, side);
    film.enable_denoising_features();
    std::mt19937 rng(seed);
    std::exponential_distribution<float> noise(1.0f);
    for (int pass = 0; pass < spp; ++pass)
        for (int y = 0; y < side; ++y)
            for (int x = 0; x < side; ++x) {
                if (!counts.empty() && pass >= counts[size_t(y * side + x)]) continue;
                const Vec3f n(0.0f, 0.0f, -1.0f);
                film.add_sample(x, y, exact(x, y) * noise(rng), 1.0f, 1.0f, n, uint32_t(pass));
                film.add_denoising_features(x, y, albedo(x, y), n, 0.0f, uint32_t(pass));
            }
    return film;
}
// The checker under the shadow step.
Film noisy_film(int spp, uint32_t seed) { return noisy_film(kSize, spp, seed, exact_pixel, exact_albedo); }

std::vector<float> rgb_of(const std::vector<float>& rgba) {
    std::vector<float> rgb;
    for (size_t i = 0; i < rgba.size(); i += 4) rgb.insert(rgb.end(), rgba.begin() + long(i), rgba.begin() + long(i) + 3);
    return rgb;
}

// Pixels within one pixel of a checker edge or of the shadow boundary.
bool on_edge(int x, int y) {
    for (int d = -1; d <= 1; ++d) {
        const int xs = std::clamp(x + d, 0, kSize - 1), ys = std::clamp(y + d, 0, kSize - 1);
        if (exact_albedo(xs, y).x != exact_albedo(x, y).x || exact_albedo(x, ys).x != exact_albedo(x, y).x) return true;
        if ((xs < kShadowX) != (x < kShadowX)) return true;
    }
    return false;
}

// Relative RMSE of 3-channel side x side `img` against exact(x, y), over
// the pixels `keep` accepts, normalised by the whole exact image's mean.
template <class Exact, class Keep>
double relative_rmse(const std::vector<float>& img, int side, Exact&& exact, Keep&& keep) {
    double err2 = 0.0, mean = 0.0;
    size_t n = 0;
    for (int y = 0; y < side; ++y)
        for (int x = 0; x < side; ++x) {
            const Vec3f e = exact(x, y);
            const float ev[3] = {e.x, e.y, e.z};
            for (int c = 0; c < 3; ++c) mean += ev[c];
            if (!keep(x, y)) continue;
            for (int c = 0; c < 3; ++c) {
                const double d = double(img[3 * (size_t(y) * size_t(side) + size_t(x)) + size_t(c)]) - ev[c];
                err2 += d * d;
            }
            n += 3;
        }
    return std::sqrt(err2 / double(n)) / (mean / (3.0 * side * side));
}
// Against the checker under the shadow step.
template <class Keep>
double relative_rmse(const std::vector<float>& img, Keep&& keep) {
    return relative_rmse(img, kSize, exact_pixel, keep);
}
double relative_rmse(const std::vector<float>& img) {
    return relative_rmse(img, [](int, int) { return true; });
}

TEST(Denoise, SixteenSamplesDenoisedBeatTwoHundredFiftySixNoisy) {
    const Film f16 = noisy_film(16, 1), f256 = noisy_film(256, 2);
    const DenoiseResult d = denoise(f16);
    ASSERT_EQ(d.rgb.size(), size_t(3 * kSize * kSize));
    const double noisy16 = relative_rmse(rgb_of(f16.resolve(PassType::Combined)));
    const double noisy256 = relative_rmse(rgb_of(f256.resolve(PassType::Combined)));
    const double denoised16 = relative_rmse(d.rgb);
    std::printf("relative RMSE: noisy 16 spp %.4f, noisy 256 spp %.4f, denoised 16 spp %.4f\n", noisy16, noisy256,
                denoised16);
    EXPECT_LT(denoised16, noisy256);
}

// What a 9 x 9 regression leaves of smooth light is noise at scales of a few
// pixels to a few tens (docs/results/denoise.md, fourteenth session); the
// sparse ring (DenoiseOptions::ring_radius) reaches it. Light that varies
// slowly over a wall of one albedo, i.i.d. heavy-tailed noise, 16 spp: the
// exact image is the oracle.
TEST(Denoise, SparseRingAveragesSmoothLightBeyondTheDenseWindow) {
    constexpr int kSide = 192;  // the ring reaches 12 pixels from 192 x 192 up (ring_radius)
    const Vec3f albedo(0.6f, 0.5f, 0.4f);
    auto exact = [&](int x, int y) {
        return albedo * (1.0f + 0.3f * std::sin(float(x) * 0.08f) + 0.2f * std::cos(float(y) * 0.05f));
    };
    const Film film = noisy_film(kSide, 16, 17, exact, [&](int, int) { return albedo; });
    auto rmse = [&](const std::vector<float>& rgb) {
        return relative_rmse(rgb, kSide, exact, [](int, int) { return true; });
    };
    DenoiseOptions no_ring;
    no_ring.ring_radius = 0;
    const DenoiseResult dense = denoise(film, no_ring), ringed = denoise(film);
    ASSERT_EQ(ringed.rgb.size(), size_t(3 * kSide * kSide));
    const double noisy = rmse(rgb_of(film.resolve(PassType::Combined)));
    std::printf("relative RMSE: noisy 16 spp %.4f, 9 x 9 window %.4f, with the ring %.4f\n", noisy, rmse(dense.rgb),
                rmse(ringed.rgb));
    EXPECT_LT(rmse(ringed.rgb), 0.9 * rmse(dense.rgb));  // measured 0.0274 against 0.0350
}

TEST(Denoise, KeepsCheckerAndShadowEdges) {
    const Film f16 = noisy_film(16, 3);
    const DenoiseResult d = denoise(f16);
    const std::vector<float> noisy = rgb_of(f16.resolve(PassType::Combined));
    const double noisy_edges = relative_rmse(noisy, on_edge), denoised_edges = relative_rmse(d.rgb, on_edge);
    std::printf("relative RMSE on edges: noisy 16 spp %.4f, denoised %.4f\n", noisy_edges, denoised_edges);
    // Not merely "not worse": blurring a 0.15/0.8 checker or a 5:1 shadow
    // step by one pixel costs far more than the noise it removes.
    EXPECT_LT(denoised_edges, 0.5 * noisy_edges);
}

// The estimate from the filtered halves sees the filter's remaining noise,
// not its bias; on this film it is within a factor of 2 of the true error.
TEST(Denoise, ErrorEstimateWithinFactorTwoOfTrueError) {
    for (int spp : {8, 16, 64}) {
        const Film film = noisy_film(spp, 10 + uint32_t(spp));
        const DenoiseResult d = denoise(film);
        const double truth = relative_rmse(d.rgb);
        std::printf("%d spp: denoised estimate %.4f, true %.4f\n", spp, d.error_estimate, truth);
        EXPECT_GT(d.error_estimate, 0.5 * truth) << spp;
        EXPECT_LT(d.error_estimate, 2.0 * truth) << spp;
    }
}

// Isolated bright pixels seen in both halves (a highlight, a small light, a
// caustic) are features, not fireflies: no neighbour predicts them, so
// filtering or clipping them loses their energy (the glass scene's
// highlights lost 60 % before keep_features, docs/results/denoise.md).
// A film of dim light (kDim) with a highlight (kBright) on a 16-pixel grid,
// every sample exponentially distributed; `direct`: the highlights' samples
// are also recorded as direct light (Film::add_direct_light), as a
// renderer records a highlight or a light seen directly.
constexpr float kDim = 0.05f, kBright = 2.0f;
Film highlights_film(bool direct) {
    auto exact = [](int x, int y) { return (x % 16 == 8 && y % 16 == 8) ? kBright : kDim; };
    Film film(kSize, kSize);
    film.enable_denoising_features();
    std::mt19937 rng(21);
    std::exponential_distribution<float> noise(1.0f);
    const Vec3f n(0.0f, 0.0f, -1.0f), albedo(0.5f);
    for (int pass = 0; pass < 16; ++pass)
        for (int y = 0; y < kSize; ++y)
            for (int x = 0; x < kSize; ++x) {
                const Vec3f v(exact(x, y) * noise(rng));
                film.add_sample(x, y, v, 1.0f, 1.0f, n, uint32_t(pass));
                film.add_denoising_features(x, y, albedo, n, 0.0f, uint32_t(pass));
                if (direct) film.add_direct_light(x, y, exact(x, y) == kBright ? v : Vec3f(0.0f), uint32_t(pass));
            }
    return film;
}

// The highlights' mean denoised value over kBright.
double highlights_kept(const std::vector<float>& rgb) {
    double kept = 0.0;
    int highlights = 0;
    for (int y = 8; y < kSize; y += 16)
        for (int x = 8; x < kSize; x += 16, ++highlights) kept += rgb.at(3 * (size_t(y) * kSize + size_t(x))) / kBright;
    return kept / highlights;
}

TEST(Denoise, KeepsIsolatedHighlightsSeenInBothHalves) {
    const DenoiseResult d = denoise(highlights_film(false));
    ASSERT_EQ(d.rgb.size(), size_t(3 * kSize * kSize));
    const double kept = highlights_kept(d.rgb);
    std::printf("mean denoised / exact over 16 highlights: %.3f\n", kept);
    // 16 exponential samples: the mean's relative spread is 0.25, over 16
    // highlights 0.06. Filtered into their neighbours they keep a few %.
    EXPECT_GT(kept, 0.8);
    EXPECT_LT(kept, 1.2);
}

// Sparse light: most paths find nothing and 1 in 50 brings 50x the mean, as
// in a dim vault lit only by what a bright floor far away bounces into it.
// Most of a 5 x 5 neighbourhood's halves are then black, so its 75th
// percentile is 0: judged against that, every half that caught a path was
// an outlier, clipped to twice the other half (to nothing where that half
// caught none), and every pixel whose two halves both caught one was a
// feature, left unfiltered at 6x and more the mean. Judged against the
// neighbourhood's mean as well, the image keeps its light and no pixel
// stands out.
// A film of flat light of mean `mean` at kSpp samples a pixel, where one
// sample in `1 / hit` carries all of it (mean / hit) and the rest none.
constexpr int kSparseSpp = 16;
Film sparse_light_film(float mean, float hit, unsigned seed) {
    Film film(kSize, kSize);
    film.enable_denoising_features();
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    const Vec3f n(0.0f, 0.0f, -1.0f), albedo(0.5f);
    for (int pass = 0; pass < kSparseSpp; ++pass)
        for (int y = 0; y < kSize; ++y)
            for (int x = 0; x < kSize; ++x) {
                const float v = u(rng) < hit ? mean / hit : 0.0f;
                film.add_sample(x, y, Vec3f(v), 1.0f, 1.0f, n, uint32_t(pass));
                film.add_denoising_features(x, y, albedo, n, 0.0f, uint32_t(pass));
            }
    return film;
}

TEST(Denoise, SparseLightIsNeitherClippedAwayNorKeptAsFeatures) {
    constexpr float kMean = 0.1f, kHit = 1.0f / 50.0f;
    const Film film = sparse_light_film(kMean, kHit, 41);
    const DenoiseResult d = denoise(film);
    ASSERT_EQ(d.rgb.size(), size_t(3 * kSize * kSize));
    double sum = 0.0;
    int standing_out = 0;
    for (size_t i = 0; i < d.rgb.size(); i += 3) {
        ASSERT_TRUE(std::isfinite(d.rgb[i]));
        sum += d.rgb[i];
        standing_out += d.rgb[i] > 3.0f * kMean;
    }
    const double mean = sum / double(kSize * kSize);
    const auto exact = [](int, int) { return Vec3f(kMean); };
    const auto all = [](int, int) { return true; };
    const double noisy = relative_rmse(rgb_of(film.resolve(PassType::Combined)), kSize, exact, all),
                 denoised = relative_rmse(d.rgb, kSize, exact, all);
    std::printf("sparse light: denoised mean / exact %.3f, %d pixels above 3x the mean, relative RMSE %.3f "
                "(noisy %.3f)\n",
                mean / kMean, standing_out, denoised, noisy);
    EXPECT_GT(mean, 0.8 * kMean);
    EXPECT_LT(mean, 1.2 * kMean);
    // Both halves catch a path in 2 % of the pixels; some of those still
    // stand out against a neighbourhood that caught few.
    EXPECT_LT(standing_out, kSize * kSize / 80);
    EXPECT_LT(denoised, 0.5 * noisy);
}

// The outlier level depends on whether the scene can make caustics
// (DenoiseOptions::caustics: a mirror or glass lobe). Without, it is twice
// as high: sparse light (1 sample in 50 at 50x the mean) keeps more of its
// energy and comes closer to exact. With, a half 9x its neighbourhood's
// level, between the two levels, is clipped, as a caustic's fireflies must
// be (docs/results/denoise.md: the glass scene), and loses energy that it
// keeps without.
TEST(Denoise, OutlierLevelIsLowerWhereTheSceneCanMakeCaustics) {
    const auto denoised = [](const Film& film, bool caustics) {
        DenoiseOptions options;
        options.caustics = caustics;
        return denoise(film, options).rgb;
    };
    const auto all = [](int, int) { return true; };
    const auto flat = [](float v) { return [v](int, int) { return Vec3f(v); }; };
    const Film sparse = sparse_light_film(0.1f, 1.0f / 50.0f, 43);
    const double sparse_caustics = relative_rmse(denoised(sparse, true), kSize, flat(0.1f), all),
                 sparse_none = relative_rmse(denoised(sparse, false), kSize, flat(0.1f), all);
    // Flat light of 0.1 and one pixel whose even half is 0.9 (one sample of
    // 6.5): its level is about 0.12, the other half 0.1.
    Film firefly(kSize, kSize);
    firefly.enable_denoising_features();
    const Vec3f n(0.0f, 0.0f, -1.0f), albedo(0.5f);
    for (int pass = 0; pass < kSparseSpp; ++pass)
        for (int y = 0; y < kSize; ++y)
            for (int x = 0; x < kSize; ++x) {
                const bool bright = pass == 0 && x == kSize / 2 && y == kSize / 2;
                firefly.add_sample(x, y, Vec3f(bright ? 6.5f : 0.1f), 1.0f, 1.0f, n, uint32_t(pass));
                firefly.add_denoising_features(x, y, albedo, n, 0.0f, uint32_t(pass));
            }
    const auto excess = [&](bool caustics) {  // the light above 0.1 a pixel, summed over the image
        double sum = 0.0;
        const std::vector<float> d = denoised(firefly, caustics);
        for (size_t i = 0; i < d.size(); i += 3) sum += d[i] - 0.1;
        return sum;
    };
    const double exact_excess = (6.5 - 0.1) / kSparseSpp, excess_caustics = excess(true), excess_none = excess(false);
    std::printf("sparse light, relative RMSE with caustics / without: %.3f / %.3f; a 9x half's excess light "
                "%.3f / %.3f of %.3f\n",
                sparse_caustics, sparse_none, excess_caustics, excess_none, exact_excess);
    EXPECT_LT(sparse_none, 0.8 * sparse_caustics);
    EXPECT_LT(excess_caustics, 0.9 * exact_excess);
    EXPECT_NEAR(excess_none, exact_excess, 0.05 * exact_excess);
}

// Sparse light (sparse_light_film) in a scene that cannot make caustics
// (DenoiseOptions::caustics false): where both halves of a pixel caught one
// of its rare paths, the pixel is not a feature (no mirror or glass lobe
// can focus light into a caustic there, and the light is indirect: no
// highlight or light seen directly), so it is clipped and filtered like any
// outlier. Kept unfiltered, such pixels were white specks in the shade
// (Sponza, docs/results/denoise.md, twenty-second session). The same light
// recorded as direct light (Film::add_direct_light: a highlight, a light
// seen directly, which can be a feature in any scene) keeps them.
TEST(Denoise, SparseIndirectLightMakesNoFeaturesWithoutCaustics) {
    constexpr float kMean = 0.1f;
    DenoiseOptions options;
    options.caustics = false;
    for (const unsigned seed : {41u, 42u}) {
        const Film film = sparse_light_film(kMean, 1.0f / 50.0f, seed);
        const DenoiseResult d = denoise(film, options);
        ASSERT_EQ(d.rgb.size(), size_t(3 * kSize * kSize));
        int standing_out = 0;
        double sum = 0.0;
        for (size_t i = 0; i < d.rgb.size(); i += 3) {
            standing_out += d.rgb[i] > 3.0f * kMean;
            sum += d.rgb[i];
        }
        const double mean = sum / double(kSize * kSize);
        std::printf("sparse indirect light without caustics, seed %u: %d pixels above 3x the mean (a pixel "
                    "whose halves caught one path each is 6.25x), mean / exact %.3f\n",
                    seed, standing_out, mean / kMean);
        EXPECT_EQ(standing_out, 0);
        EXPECT_GT(mean, 0.8 * kMean);
        EXPECT_LT(mean, 1.2 * kMean);
    }
    const double kept = highlights_kept(denoise(highlights_film(true), options).rgb);
    std::printf("highlights recorded as direct light, without caustics: mean denoised / exact %.3f\n", kept);
    EXPECT_GT(kept, 0.8);
    EXPECT_LT(kept, 1.2);
}

// Direct light filtered apart. A surface whose direct light has detail at
// pixel scale (bump shading: every pixel its own value, no neighbour
// predicts it) and no noise, plus smooth indirect light carrying all the
// noise. Filtered whole, the detail keeps the colour weights from averaging
// the noise; filtered apart, the direct part stays exact and the indirect
// part averages over the whole window. The control film has the same
// samples without the direct light's sums, so the whole radiance is
// filtered (as a film of an older renderer would be).
//
// With direct_noise the parts swap roles: the direct light is smooth (it
// varies slowly, as under a large emitter) and carries all the noise, the
// indirect light has the pixel-scale detail and none.
struct SplitFilms {
    Film with_direct, without;
    std::vector<float> exact;  // 3 a pixel
    explicit SplitFilms(int side) : with_direct(side, side), without(side, side) {}
};

SplitFilms split_films(bool direct_noise, uint32_t seed, int side = kSize) {
    SplitFilms f(side);
    f.exact.resize(3 * size_t(side) * size_t(side));
    f.with_direct.enable_denoising_features();
    f.without.enable_denoising_features();
    std::mt19937 rng(seed);
    std::exponential_distribution<float> noise(1.0f);
    const Vec3f n(0.0f, 0.0f, -1.0f), albedo(0.6f, 0.5f, 0.4f);
    auto bump = [](int x, int y) { return 0.3f + 0.7f * float((x * 7919 + y * 104729) % 97) / 96.0f; };
    auto slow = [](int x, int y) { return 1.0f + 0.3f * std::sin(float(x) * 0.08f) + 0.2f * std::cos(float(y) * 0.05f); };
    // The parts' exact values; the noisy one is multiplied by a draw of mean 1.
    auto direct_of = [&](int x, int y) { return albedo * (direct_noise ? slow(x, y) : bump(x, y)); };
    auto indirect_of = [&](int x, int y) { return albedo * (direct_noise ? 0.5f * bump(x, y) : 0.3f); };
    for (int y = 0; y < side; ++y)
        for (int x = 0; x < side; ++x) {
            const Vec3f e = direct_of(x, y) + indirect_of(x, y);
            const size_t i = 3 * (size_t(y) * size_t(side) + size_t(x));
            f.exact[i] = e.x, f.exact[i + 1] = e.y, f.exact[i + 2] = e.z;
        }
    for (int pass = 0; pass < 16; ++pass)
        for (int y = 0; y < side; ++y)
            for (int x = 0; x < side; ++x) {
                const float u = noise(rng);
                const Vec3f direct = direct_of(x, y) * (direct_noise ? u : 1.0f);
                const Vec3f indirect = indirect_of(x, y) * (direct_noise ? 1.0f : u);
                for (Film* film : {&f.with_direct, &f.without}) {
                    film->add_sample(x, y, direct + indirect, 1.0f, 1.0f, n, uint32_t(pass));
                    film->add_denoising_features(x, y, albedo, n, 0.0f, uint32_t(pass));
                }
                f.with_direct.add_direct_light(x, y, direct, uint32_t(pass));
            }
    return f;
}

double relative_rmse_to(const std::vector<float>& img, const std::vector<float>& exact) {
    double err2 = 0.0, mean = 0.0;
    for (size_t k = 0; k < exact.size(); ++k) err2 += (img[k] - exact[k]) * (img[k] - exact[k]), mean += exact[k];
    return std::sqrt(err2 / double(exact.size())) / (mean / double(exact.size()));
}

TEST(Denoise, NoiseFreeDirectLightIsFilteredApart) {
    const SplitFilms f = split_films(false, 31);
    const DenoiseResult apart = denoise(f.with_direct), whole = denoise(f.without);
    ASSERT_EQ(apart.rgb.size(), f.exact.size());
    ASSERT_EQ(whole.rgb.size(), f.exact.size());
    const double noisy = relative_rmse_to(rgb_of(f.without.resolve(PassType::Combined)), f.exact);
    const double e_apart = relative_rmse_to(apart.rgb, f.exact), e_whole = relative_rmse_to(whole.rgb, f.exact);
    std::printf("relative RMSE: noisy 16 spp %.4f, denoised whole %.4f, direct light apart %.4f\n", noisy, e_whole,
                e_apart);
    EXPECT_LT(e_apart, 0.6 * e_whole);
    for (float v : apart.rgb) ASSERT_TRUE(std::isfinite(v));
}

// Where the direct light carries the noise (an emissive panel, an HDRI
// world), it is filtered apart too, and its part weighs the sparse ring:
// split, the indirect light's detail no longer narrows the weights that
// average the direct light's noise, and the ring reaches that noise's
// long wavelengths (docs/results/denoise.md, eighteenth session). 192 x 192:
// the ring's smallest image (ring_radius).
TEST(Denoise, NoisyDirectLightIsFilteredApartWithTheRing) {
    const SplitFilms f = split_films(true, 32, 192);
    DenoiseOptions no_ring;
    no_ring.ring_radius = 0;
    const DenoiseResult apart = denoise(f.with_direct), whole = denoise(f.without),
                        apart_dense = denoise(f.with_direct, no_ring);
    ASSERT_EQ(apart.rgb.size(), f.exact.size());
    const double noisy = relative_rmse_to(rgb_of(f.without.resolve(PassType::Combined)), f.exact);
    const double e_apart = relative_rmse_to(apart.rgb, f.exact), e_whole = relative_rmse_to(whole.rgb, f.exact);
    const double e_dense = relative_rmse_to(apart_dense.rgb, f.exact);
    std::printf("relative RMSE: noisy 16 spp %.4f, denoised whole %.4f, apart %.4f, apart without the ring %.4f\n",
                noisy, e_whole, e_apart, e_dense);
    EXPECT_LT(e_apart, 0.6 * e_whole);
    EXPECT_LT(e_apart, 0.9 * e_dense);
    for (float v : apart.rgb) ASSERT_TRUE(std::isfinite(v));
}

// The albedo's prefilter. Above row kEdge an emitter (radiance 4, and as in
// Cycles its emission is its albedo), below it a wall of albedo 0.5 with
// noisy light; every sample of row kEdge sees the one or the other by a coin
// flip, as a pixel straddling a light's outline does. The demodulated
// halves cancel the coin flips, but remodulating with the row's noisy mean
// albedo brought them back (the row's error was that of the noisy image);
// prefiltered, the albedo of pixels along the edge, equal within their
// noise, is averaged, while the rows beside it, noise-free, keep theirs.
TEST(Denoise, AlbedoNoisyAlongAnEdgeIsAveragedAlongIt) {
    constexpr int kEdge = 24;
    const Vec3f emitter(4.0f), wall_albedo(0.5f), wall_light(0.25f), n(0.0f, 0.0f, -1.0f);
    Film film(kSize, kSize);
    film.enable_denoising_features();
    std::mt19937 rng(41);
    std::exponential_distribution<float> noise(1.0f);
    std::bernoulli_distribution coin(0.5);
    for (int pass = 0; pass < 16; ++pass)
        for (int y = 0; y < kSize; ++y)
            for (int x = 0; x < kSize; ++x) {
                const bool on_emitter = y < kEdge || (y == kEdge && coin(rng));
                const Vec3f radiance = on_emitter ? emitter : wall_light * noise(rng);
                film.add_sample(x, y, radiance, 1.0f, 1.0f, n, uint32_t(pass));
                film.add_denoising_features(x, y, on_emitter ? emitter : wall_albedo, n, 0.0f, uint32_t(pass));
            }
    auto exact = [&](int y) { return y < kEdge ? emitter.x : y == kEdge ? 0.5f * (emitter.x + wall_light.x) : wall_light.x; };
    auto row_rmse = [&](const std::vector<float>& rgb, int y) {
        double err2 = 0.0;
        for (int x = 0; x < kSize; ++x)
            for (int c = 0; c < 3; ++c) {
                const double d = rgb[3 * (size_t(y) * kSize + size_t(x)) + size_t(c)] - exact(y);
                err2 += d * d;
            }
        return std::sqrt(err2 / (3.0 * kSize)) / exact(y);
    };
    const DenoiseResult d = denoise(film);
    ASSERT_EQ(d.rgb.size(), size_t(3 * kSize * kSize));
    const std::vector<float> noisy = rgb_of(film.resolve(PassType::Combined));
    const double e_noisy = row_rmse(noisy, kEdge), e_denoised = row_rmse(d.rgb, kEdge);
    std::printf("edge row relative RMSE: noisy 16 spp %.4f, denoised %.4f; emitter row %.2g\n", e_noisy, e_denoised,
                row_rmse(d.rgb, kEdge - 1));
    // Without the prefilter: 0.2188 against the noisy 0.2140; with it 0.0823.
    EXPECT_LT(e_denoised, 0.5 * e_noisy);
    EXPECT_LT(row_rmse(d.rgb, kEdge - 1), 0.01);  // the emitter's row beside it stays within 1 %
    for (float v : d.rgb) ASSERT_TRUE(std::isfinite(v));
}

// A column in shade in front of a sun-lit wall whose albedo is close to
// its own (0.5 against 0.6): a pixel on the silhouette is as bright as the
// share of its samples that see the wall, and only the pixel's mean albedo
// (and its depth, which cannot say how much) tells that share. The
// regression's albedo slope has to follow that small albedo difference.
TEST(Denoise, LowContrastAlbedoTellsTheCoverageOfASilhouettePixel) {
    const float column_albedo = 0.5f, wall_albedo = 0.6f, column_light = 0.4f, wall_light = 4.0f;
    auto edge_x = [](int y) { return 20.0f + 0.37f * float(y); };  // slanted: every coverage occurs
    auto coverage = [&](int x, int y) { return std::clamp(edge_x(y) - float(x), 0.0f, 1.0f); };  // the column's
    auto exact = [&](int x, int y) {
        const float f = coverage(x, y);
        return Vec3f(f * column_albedo * column_light + (1.0f - f) * wall_albedo * wall_light);
    };
    Film film(kSize, kSize);
    film.enable_denoising_features();
    std::mt19937 rng(43);
    std::exponential_distribution<float> noise(1.0f);
    std::uniform_real_distribution<float> jitter(0.0f, 1.0f);
    const Vec3f n(0.0f, 0.0f, -1.0f);
    for (int pass = 0; pass < 16; ++pass)
        for (int y = 0; y < kSize; ++y)
            for (int x = 0; x < kSize; ++x) {
                // Stratified, as the renderer's samples are: the coverage is
                // nearly exact, and the silhouette's error is the light's noise
                // and what the filter averages across the coverages.
                const bool column = float(x) + (float(pass) + jitter(rng)) / 16.0f < edge_x(y);
                const float albedo = column ? column_albedo : wall_albedo;
                const float light = column ? column_light : wall_light;
                film.add_sample(x, y, Vec3f(albedo * light * noise(rng)), 1.0f, 1.0f, n, uint32_t(pass));
                film.add_denoising_features(x, y, Vec3f(albedo), n, column ? 2.0f : 3.0f, uint32_t(pass));
            }
    auto on_silhouette = [&](int x, int y) { return coverage(x, y) > 0.0f && coverage(x, y) < 1.0f; };
    const DenoiseResult d = denoise(film);
    ASSERT_EQ(d.rgb.size(), size_t(3 * kSize * kSize));
    const std::vector<float> noisy = rgb_of(film.resolve(PassType::Combined));
    const double e_noisy = relative_rmse(noisy, kSize, exact, on_silhouette);
    const double e_denoised = relative_rmse(d.rgb, kSize, exact, on_silhouette);
    std::printf("silhouette relative RMSE: noisy 16 spp %.4f, denoised %.4f; whole image denoised %.4f\n", e_noisy,
                e_denoised, relative_rmse(d.rgb, kSize, exact, [](int, int) { return true; }));
    // Measured (seed 43 and 1-5): 0.36-0.45 x the noisy error; with the
    // albedo's ridge at the offsets' 0.1, 0.59-0.63 x (kAlbedoRidge).
    EXPECT_LT(e_denoised, 0.5 * e_noisy);
}

// Distribute Samples leaves pixels with unequal counts (sample_distribution.h).
// The checker under the shadow step with 8 samples in half of the pixels
// (picked at random) and 120 in the others, against the same with 64 in
// every pixel: the same samples in all. A fit that weighs each pixel's mean
// by its count (row_fit_weights) comes close to the variance of the total
// count; one that weighs the means alike has that of the mean of 1/n,
// 4.3 x higher.
Film counts_film(bool unequal, uint32_t seed) {
    if (!unequal) return noisy_film(64, seed);
    std::mt19937 pick(seed + 1);
    std::vector<int> counts(kSize * kSize);
    for (int& c : counts) c = (pick() & 1) ? 120 : 8;
    return noisy_film(kSize, 120, seed, exact_pixel, exact_albedo, counts);
}

TEST(Denoise, PixelsWeighByTheirSampleCounts) {
    for (const uint32_t seed : {5u, 6u}) {
        const Film uniform = counts_film(false, seed), unequal = counts_film(true, seed);
        const DenoiseResult du = denoise(uniform), dn = denoise(unequal);
        ASSERT_EQ(dn.rgb.size(), size_t(3 * kSize * kSize));
        const auto all = [](int, int) { return true; };
        const double e_uniform = relative_rmse(du.rgb, all), e_unequal = relative_rmse(dn.rgb, all);
        const double noisy_unequal = relative_rmse(rgb_of(unequal.resolve(PassType::Combined)), all);
        std::printf("seed %u: denoised relative RMSE, 64 samples everywhere %.4f, 8 or 120 %.4f (noisy %.4f)\n", seed,
                    e_uniform, e_unequal, noisy_unequal);
        // Measured 1.64 x and 1.58 x the uniform error (seeds 5, 6);
        // weighing the means alike, 2.35 x and 2.15 x.
        EXPECT_LT(e_unequal, 1.9 * e_uniform);
    }
}

// Depth as a feature: a square in front of a wall, both with the same
// albedo and normal, lit 1.0 and 0.6. At 16 spp the colour patches cannot
// tell the step from the noise, so only the depth keeps the windows on one
// side. The control film is the same with one depth everywhere (the same
// samples: same seed), so any gain is the depth's.
TEST(Denoise, DepthKeepsASilhouetteThatNormalAndAlbedoDoNotSee) {
    constexpr int kLo = 16, kHi = 48;
    auto inside = [](int x, int y) { return x >= kLo && x < kHi && y >= kLo && y < kHi; };
    auto exact = [&](int x, int y) { return inside(x, y) ? 1.0f : 0.6f; };
    auto film_with_depths = [&](float near, float far) {
        Film film(kSize, kSize);
        film.enable_denoising_features();
        std::mt19937 rng(31);
        std::exponential_distribution<float> noise(1.0f);
        const Vec3f n(0.0f, 0.0f, -1.0f), albedo(0.5f);
        for (int pass = 0; pass < 16; ++pass)
            for (int y = 0; y < kSize; ++y)
                for (int x = 0; x < kSize; ++x) {
                    const float depth = inside(x, y) ? near : far;
                    film.add_sample(x, y, Vec3f(exact(x, y) * noise(rng)), 1.0f, depth, n, uint32_t(pass));
                    film.add_denoising_features(x, y, albedo, n, 0.0f, uint32_t(pass));
                }
        return film;
    };
    // RMSE over the pixels next to the silhouette (either side), relative.
    auto silhouette_rmse = [&](const std::vector<float>& rgb) {
        double err2 = 0.0;
        int count = 0;
        for (int y = 0; y < kSize; ++y)
            for (int x = 0; x < kSize; ++x) {
                if (inside(x, y) == inside(x - 1, y) && inside(x, y) == inside(x + 1, y) &&
                    inside(x, y) == inside(x, y - 1) && inside(x, y) == inside(x, y + 1))
                    continue;
                const double d = rgb[3 * (size_t(y) * kSize + size_t(x))] - exact(x, y);
                err2 += d * d, ++count;
            }
        return std::sqrt(err2 / count) / 0.8;
    };
    const DenoiseResult with_depth = denoise(film_with_depths(1.0f, 2.0f));
    const DenoiseResult flat_depth = denoise(film_with_depths(1.0f, 1.0f));
    ASSERT_EQ(with_depth.rgb.size(), size_t(3 * kSize * kSize));
    ASSERT_EQ(flat_depth.rgb.size(), size_t(3 * kSize * kSize));
    const double e_depth = silhouette_rmse(with_depth.rgb), e_flat = silhouette_rmse(flat_depth.rgb);
    std::printf("silhouette relative RMSE: depth 1 / 2 %.4f, one depth %.4f\n", e_depth, e_flat);
    EXPECT_LT(e_depth, 0.7 * e_flat);
}

TEST(Denoise, BlackImageStaysBlackWithZeroError) {
    Film film(16, 12);
    film.enable_denoising_features();
    for (uint32_t pass = 0; pass < 4; ++pass)
        for (int y = 0; y < 12; ++y)
            for (int x = 0; x < 16; ++x) {
                film.add_sample(x, y, Vec3f(0.0f), 1.0f, kInf, Vec3f(0.0f), pass);
                film.add_denoising_features(x, y, Vec3f(0.0f), Vec3f(0.0f), 0.0f, pass);
            }
    const DenoiseResult d = denoise(film);
    ASSERT_EQ(d.rgb.size(), size_t(3 * 16 * 12));
    for (float v : d.rgb) EXPECT_EQ(v, 0.0f);
    EXPECT_EQ(d.error_estimate, 0.0);
}

// A noise-free image whose light is all direct (emitters seen directly, or
// a converged render) is split (split_direct_light: the direct light is a
// tenth of the light or more), with no variance to normalise distances by:
// it comes back as it went in, finite, with no error estimated.
TEST(Denoise, NoiseFreeDirectLightComesBackUnchanged) {
    constexpr int kW = 32, kH = 24;
    Film film(kW, kH);
    film.enable_denoising_features();
    auto value = [](int x, int y) {
        return Vec3f(0.2f + 0.02f * float(x), 0.5f + (x >= 16 ? 3.0f : 0.0f), 0.1f + 0.03f * float(y));
    };
    for (uint32_t pass = 0; pass < 4; ++pass)
        for (int y = 0; y < kH; ++y)
            for (int x = 0; x < kW; ++x) {
                film.add_sample(x, y, value(x, y), 1.0f, 1.0f, Vec3f(0.0f, 0.0f, -1.0f), pass);
                film.add_denoising_features(x, y, Vec3f(0.5f), Vec3f(0.0f, 0.0f, -1.0f), 1.0f, pass);
                film.add_direct_light(x, y, value(x, y), pass);
            }
    const DenoiseResult d = denoise(film);
    ASSERT_EQ(d.rgb.size(), size_t(3 * kW * kH));
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) {
            const Vec3f v = value(x, y);
            const float* out = &d.rgb[3 * (size_t(y) * kW + size_t(x))];
            EXPECT_NEAR(out[0], v.x, 1e-4f * v.x) << x << ", " << y;
            EXPECT_NEAR(out[1], v.y, 1e-4f * v.y) << x << ", " << y;
            EXPECT_NEAR(out[2], v.z, 1e-4f * v.z) << x << ", " << y;
        }
    EXPECT_EQ(d.error_estimate, 0.0);
}

TEST(Denoise, EmptyImageGivesZerosNotNaN) {
    const Film empty(16, 12);  // no pixel has a sample (e.g. all were discarded)
    const DenoiseResult d = denoise(empty);
    ASSERT_EQ(d.rgb.size(), size_t(3 * 16 * 12));
    for (float v : d.rgb) EXPECT_EQ(v, 0.0f);
    EXPECT_EQ(d.error_estimate, 0.0);
    EXPECT_TRUE(denoise(Film(0, 0)).rgb.empty());
}

TEST(Denoise, NeedsBothHalves) {
    Film film(8, 8);
    for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x) film.add_sample(x, y, Vec3f(1.0f), 1.0f, 1.0f, Vec3f(0.0f), 0);
    EXPECT_TRUE(denoise(film).rgb.empty());  // one pass: no odd half to cross-filter with
}

TEST(Denoise, CancelledByProgress) {
    const Film film = noisy_film(4, 5);
    int calls = 0;
    const DenoiseResult d = denoise(film, {}, [&](double f) {
        EXPECT_GE(f, 0.0);
        EXPECT_LE(f, 1.0);
        ++calls;
        return false;
    });
    EXPECT_TRUE(d.rgb.empty());
    EXPECT_GE(calls, 1);
}

TEST(Denoise, CancelledByFlag) {
    const std::atomic<bool> stop{true};
    DenoiseOptions options;
    options.cancel = &stop;
    EXPECT_TRUE(denoise(noisy_film(4, 6), options).rgb.empty());
}

// --- inside the renderer -------------------------------------------------------

RenderSettings small_settings(bool denoise) {
    RenderSettings rs;
    rs.width = rs.height = 24;
    rs.spp = 4;
    rs.denoise = denoise;
    // Denoising always renders with paired scrambles (it filters each half
    // with the other's weights); the plain render must draw the same samples.
    rs.error_estimate = ErrorEstimate::Exact;
    return rs;
}

TEST(DenoiseRender, NothingAllocatedOrChangedWithoutDenoising) {
    const Scene scene = sphere_on_floor_scene();
    Renderer r(scene, small_settings(false));
    r.render();
    EXPECT_FALSE(r.film().has_denoising_features());
    EXPECT_FALSE(r.film().denoised());
    EXPECT_LT(r.stats().denoised_error_estimate, 0.0);
    EXPECT_EQ(r.film().resolve(PassType::Combined), r.film().resolve(PassType::NoisyImage));
    for (float v : r.film().resolve(PassType::DenoisingAlbedo)) EXPECT_EQ(v, 0.0f);
}

TEST(DenoiseRender, NoisyImageIsTheUndenoisedRenderAndFeaturesAreFilled) {
    const Scene scene = sphere_on_floor_scene();
    const std::vector<float> plain = render_combined(scene, small_settings(false));
    // Uniform samples, as the plain render's (test_sample_distribution.cpp
    // covers the distributed ones).
    RenderSettings rs = small_settings(true);
    rs.distribute_samples = false;
    Renderer r(scene, rs);
    ASSERT_TRUE(r.render());
    EXPECT_EQ(r.film().resolve(PassType::NoisyImage), plain);
    EXPECT_TRUE(r.film().denoised());
    EXPECT_NE(r.film().resolve(PassType::Combined), plain);
    EXPECT_GE(r.stats().denoised_error_estimate, 0.0);
    EXPECT_LT(r.stats().denoised_error_estimate, r.stats().error_estimate);
    // Albedo: the floor (0.7 grey) and the red sphere (0.8, 0.2, 0.1), plus
    // the world (0.2) where nothing is hit; normals: unit vectors in camera
    // space facing the camera (z < 0) wherever the albedo came from a surface.
    const std::vector<float> albedo = r.film().resolve(PassType::DenoisingAlbedo);
    const std::vector<float> normal = r.film().resolve(PassType::DenoisingNormal);
    int red = 0, grey = 0;
    for (size_t i = 0; i < albedo.size(); i += 3) {
        if (std::fabs(albedo[i] - 0.8f) < 1e-4f && std::fabs(albedo[i + 1] - 0.2f) < 1e-4f) ++red;
        if (std::fabs(albedo[i] - 0.7f) < 1e-4f && std::fabs(albedo[i + 2] - 0.7f) < 1e-4f) {
            ++grey;
            const float len = std::sqrt(normal[i] * normal[i] + normal[i + 1] * normal[i + 1] + normal[i + 2] * normal[i + 2]);
            EXPECT_NEAR(len, 1.0f, 1e-3f);
            EXPECT_LT(normal[i + 2], 0.0f);
        }
    }
    EXPECT_GT(red, 20);
    EXPECT_GT(grey, 100);
    for (float v : r.film().resolve(PassType::Combined)) EXPECT_TRUE(std::isfinite(v));
}

// Denoising Depth as Cycles 3.4 writes it: every hit while the features are
// pending adds its ray segment's length times the average feature
// throughput. Orthographic camera 5 above the floor: a diffuse floor reads 5
// (less the near clip distance) in every pixel; a coloured mirror floor
// (metallic, roughness 0: its Fresnel colour at normal incidence is its base
// colour) passes the search on to a diffuse ceiling 8 above it, adding
// 8 x mean(base colour).
TEST(DenoiseRender, DenoisingDepthAddsEverySegmentWeightedByTheFeatureThroughput) {
    for (bool mirror : {false, true}) {
        Scene s;
        Material floor = principled(0.7f, mirror ? 1.0f : 0.0f, mirror ? 0.0f : 0.5f, 0.5f, 0.0f);
        if (mirror) floor.closures[0].base_color = {0.9f, 0.6f, 0.3f};
        add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 20, 20, s.add_material(floor), "floor");
        add_quad(s, {0, 0, 8}, {0, 1, 0}, {1, 0, 0}, 20, 20, s.add_material(principled(0.5f, 0.0f, 0.5f, 0.5f, 0.0f)),
                 "ceiling");  // faces down
        s.world_color = Vec3f(0.2f);
        s.camera = ortho_camera_looking_down(5.0f, 2.0f);
        s.finalize();
        RenderSettings rs = small_settings(false);
        rs.denoising_data = true;
        Renderer r(s, rs);
        ASSERT_TRUE(r.render());
        // Camera rays start at the near clip plane, as Cycles' do.
        const float first = 5.0f - s.camera.clip_start;
        const float expected = mirror ? first + 8.0f * (0.9f + 0.6f + 0.3f) / 3.0f : first;
        const std::vector<float> depth = r.film().resolve(PassType::DenoisingDepth);
        ASSERT_EQ(depth.size(), size_t(24 * 24));
        for (float d : depth) ASSERT_NEAR(d, expected, 1e-4f) << (mirror ? "mirror" : "diffuse");
    }
    // Without the features requested the pass costs nothing and reads 0.
    const Scene scene = sphere_on_floor_scene();
    Renderer plain(scene, small_settings(false));
    plain.render();
    for (float d : plain.film().resolve(PassType::DenoisingDepth)) EXPECT_EQ(d, 0.0f);
}

// A rendered scene against a reference of 2 x 2048 spp (other seeds), the
// reference's own variance (a quarter of its renders' squared difference)
// subtracted from each mean squared error; over all pixels and over the
// smooth ones (no 4-neighbour differs by more than 20 % in the reference:
// away from the edges, whose sub-pixel coverage error no image filter
// can take back).
struct SceneErrors {
    double noisy16, noisy64, noisy256, denoised16, denoised64;
    double smooth_noisy16, smooth_noisy256, smooth_denoised16;
};

std::vector<bool> smooth_pixels(const std::vector<float>& ref, int size) {
    std::vector<bool> smooth(size_t(size) * size_t(size), true);
    const auto lum = [&](int x, int y) {
        const size_t i = 3 * (size_t(y) * size_t(size) + size_t(x));
        return ref[i] + ref[i + 1] + ref[i + 2];
    };
    for (int y = 0; y < size; ++y)
        for (int x = 0; x < size; ++x)
            for (const auto& [dx, dy] : {std::pair{1, 0}, std::pair{-1, 0}, std::pair{0, 1}, std::pair{0, -1}}) {
                const int xx = std::clamp(x + dx, 0, size - 1), yy = std::clamp(y + dy, 0, size - 1);
                const float a = lum(x, y), b = lum(xx, yy);
                if (std::fabs(a - b) > 0.2f * std::max(a, b)) smooth[size_t(y) * size_t(size) + size_t(x)] = false;
            }
    return smooth;
}

SceneErrors scene_errors(const Scene& scene, int size) {
    const auto render = [&](int spp, uint64_t seed, bool denoise) {
        RenderSettings rs;
        rs.width = rs.height = size;
        rs.spp = spp;
        rs.seed = seed;
        rs.denoise = denoise;
        Renderer r(scene, rs);
        r.render();
        return std::pair{rgb_of(r.film().resolve(PassType::NoisyImage)), rgb_of(r.film().resolve(PassType::Combined))};
    };
    const std::vector<float> ref_a = render(2048, 101, false).second, ref_b = render(2048, 202, false).second;
    double mean = 0.0;
    for (size_t i = 0; i < ref_a.size(); ++i) mean += 0.5 * (ref_a[i] + ref_b[i]);
    mean /= double(ref_a.size());
    std::vector<float> ref(ref_a.size());
    for (size_t i = 0; i < ref.size(); ++i) ref[i] = 0.5f * (ref_a[i] + ref_b[i]);
    const std::vector<bool> smooth = smooth_pixels(ref, size);
    const auto rmse = [&](const std::vector<float>& img, bool smooth_only = false) {
        double se = 0.0;
        size_t n = 0;
        for (size_t i = 0; i < img.size(); ++i) {
            if (smooth_only && !smooth[i / 3]) continue;
            const double ref_var = 0.25 * (ref_a[i] - ref_b[i]) * (ref_a[i] - ref_b[i]);
            se += (img[i] - ref[i]) * (img[i] - ref[i]) - ref_var;
            ++n;
        }
        return std::sqrt(std::max(se / double(std::max<size_t>(n, 1)), 0.0)) / mean;
    };
    const auto [noisy16, denoised16] = render(16, 7, true);
    const auto [noisy64, denoised64] = render(64, 7, true);
    const std::vector<float> noisy256 = render(256, 7, false).second;
    return {rmse(noisy16),       rmse(noisy64),          rmse(noisy256),
            rmse(denoised16),    rmse(denoised64),       rmse(noisy16, true),
            rmse(noisy256, true), rmse(denoised16, true)};
}

TEST(DenoiseRender, SphereOnFloorAgainstAReference) {
    const SceneErrors e = scene_errors(sphere_on_floor_scene(), 32);
    std::printf("relative RMSE: noisy 16 / 64 / 256 spp %.4f / %.4f / %.4f, denoised 16 / 64 spp %.4f / %.4f\n",
                e.noisy16, e.noisy64, e.noisy256, e.denoised16, e.denoised64);
    std::printf("smooth pixels: noisy 16 / 256 spp %.4f / %.4f, denoised 16 spp %.4f\n", e.smooth_noisy16,
                e.smooth_noisy256, e.smooth_denoised16);
    // The target (denoised 16 spp below noisy 256 spp) is not met
    // here: the sampler's 256 spp is 6x better than its 16 spp, not 4x,
    // and most of the error is the edges' coverage (docs/results/denoise.md).
    // What holds: the filter lowers the error, most on the smooth pixels.
    EXPECT_LT(e.denoised16, e.noisy16);
    EXPECT_LT(e.denoised64, e.noisy64);
    EXPECT_LT(e.smooth_denoised16, 0.8 * e.smooth_noisy16);
}

}  // namespace
}  // namespace coherent
