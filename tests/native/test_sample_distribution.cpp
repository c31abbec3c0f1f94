// Distributing a denoised render's samples (RenderSettings::distribute_samples,
// render/sample_distribution.h). The properties tested: the budget holds
// (spp samples per pixel on average, every pixel at least the uniform part,
// none past the cap, counts even); more samples go where the denoiser is
// predicted to leave error (the emitter's edge, not the black background);
// the noisy image stays unbiased (the counts are decided from each pixel's
// neighbours, never its own samples), over paired seeds against uniform
// renders; an edge whose stratified samples hide it from the halves still
// gets them, and so does a hard shadow's edge on a floor of one albedo; no
// NaN; and the setting is off wherever its conditions fail.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "../../native/render/sample_distribution.h"
#include "test_render_helpers.h"
#include "test_seed.h"

namespace coherent {
namespace {

constexpr int kRes = 16;

// The mean of rows [y0, y1) of a side x side image of sample counts.
double mean_of_rows(const std::vector<uint32_t>& counts, int side, int y0, int y1) {
    double sum = 0.0;
    for (int y = y0; y < y1; ++y)
        for (int x = 0; x < side; ++x) sum += counts[size_t(y) * size_t(side) + size_t(x)];
    return sum / double((y1 - y0) * side);
}

RenderSettings settings(bool distribute, int spp, uint64_t seed) {
    RenderSettings rs;
    rs.width = rs.height = kRes;
    rs.spp = spp;
    rs.seed = seed;
    rs.sampler = SamplerType::Auto;  // SPT when denoising
    rs.max_bounces = 4;
    rs.denoise = true;
    rs.distribute_samples = distribute;
    rs.threads = 2;
    return rs;
}

TEST(SampleDistribution, AppliesOnlyToFixedCountDenoisedSptRenders) {
    RenderSettings rs = settings(true, 16, 1);
    EXPECT_TRUE(RenderSettings{}.distribute_samples);  // on by default, acts only when denoising
    EXPECT_FALSE(RenderSettings{}.distributes_samples());
    EXPECT_TRUE(rs.distributes_samples());
    RenderSettings r = rs;
    r.denoise = false;
    EXPECT_FALSE(r.distributes_samples());
    r = rs, r.distribute_samples = false;
    EXPECT_FALSE(r.distributes_samples());
    r = rs, r.progressive_display = true;
    EXPECT_FALSE(r.distributes_samples());
    r = rs, r.target_error = 0.05;
    EXPECT_FALSE(r.distributes_samples());
    r = rs, r.time_limit = 10.0;
    EXPECT_FALSE(r.distributes_samples());
    r = rs, r.sampler = SamplerType::Cpt;  // shares numbers between neighbours: their samples would decide
    EXPECT_FALSE(r.distributes_samples());
    r = rs, r.spp = 2;
    EXPECT_FALSE(r.distributes_samples());
}

TEST(SampleDistribution, KeepsTheBudgetAndSamplesWhereTheDenoiserLeavesError) {
    const Scene scene = test::lobes_scene(false, 9.0f);
    RenderSettings rs = settings(true, 16, 7);
    rs.width = rs.height = 48;
    Renderer r(scene, rs);
    ASSERT_TRUE(r.render());
    const Film& film = r.film();
    const int w = film.width(), h = film.height();
    uint64_t total = 0;
    uint32_t most = 0, fewest = ~0u;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const uint32_t n = film.samples_at(x, y);
            total += n;
            most = std::max(most, n), fewest = std::min(fewest, n);
            EXPECT_EQ(n % 2, 0u) << "odd count at " << x << "," << y;
        }
    const double mean = double(total) / double(w * h);
    std::printf("distributed: mean %.3f spp, %u..%u per pixel, stats spp %d\n", mean, fewest, most, r.stats().spp);
    EXPECT_NEAR(mean, 16.0, 0.25);  // within the rounding of counts to even numbers
    EXPECT_EQ(r.stats().spp, 16);
    EXPECT_EQ(r.stats().samples, total);
    ASSERT_TRUE(r.active_features().can_make_caustics());  // glass and a mirror
    EXPECT_EQ(fewest, uint32_t(SampleDistribution::uniform_passes(16, true)));
    EXPECT_LE(most, uint32_t(SampleDistribution::pass_limit(16)));
    EXPECT_GT(most, 64u) << "no pixel got much more than the budget: nothing was distributed";
    // The brightest pixels (the light, highlights, the glass) must be sampled
    // more than the darkest, where nothing is left to denoise.
    const Film::Sums s = film.sums();
    double bright = 0.0, dark = 0.0;
    int bright_n = 0, dark_n = 0;
    std::vector<double> lum(size_t(w * h));
    for (size_t i = 0; i < lum.size(); ++i) lum[i] = (s.rgba[4 * i] + s.rgba[4 * i + 1] + s.rgba[4 * i + 2]) / s.count[i];
    std::vector<double> sorted = lum;
    std::sort(sorted.begin(), sorted.end());
    const double top = sorted[sorted.size() * 99 / 100], low = sorted[sorted.size() / 10];
    for (size_t i = 0; i < lum.size(); ++i) {
        if (lum[i] >= top) bright += s.count[i], ++bright_n;
        if (lum[i] <= low) dark += s.count[i], ++dark_n;
    }
    EXPECT_GT(bright / bright_n, 2.0 * dark / dark_n);
    const std::vector<float> img = film.resolve(PassType::Combined);
    for (float v : img) ASSERT_TRUE(std::isfinite(v));
}

// The decision comes after a quarter of the budget where no caustic can
// mislead it, after half where one can (uniform_passes); counts stay even.
TEST(SampleDistribution, DecidesAfterAQuarterOfTheBudgetWithoutCaustics) {
    EXPECT_EQ(SampleDistribution::uniform_passes(16, false), 4);
    EXPECT_EQ(SampleDistribution::uniform_passes(16, true), 8);
    EXPECT_EQ(SampleDistribution::uniform_passes(24, false), 6);
    EXPECT_EQ(SampleDistribution::uniform_passes(20, false), 4);  // 5, rounded down to even
    EXPECT_EQ(SampleDistribution::uniform_passes(4, false), 2);   // never fewer than both halves need
    EXPECT_EQ(SampleDistribution::uniform_passes(4, true), 2);
    // A diffuse scene: some pixels keep fewer samples than half the budget,
    // none fewer than a quarter.
    const Scene scene = test::sphere_on_floor_scene();
    RenderSettings rs = settings(true, 16, 5);
    rs.width = rs.height = 48;
    Renderer r(scene, rs);
    ASSERT_TRUE(r.render());
    ASSERT_FALSE(r.active_features().can_make_caustics());
    uint32_t fewest = ~0u;
    uint64_t total = 0;
    for (int y = 0; y < rs.height; ++y)
        for (int x = 0; x < rs.width; ++x) {
            fewest = std::min(fewest, r.film().samples_at(x, y));
            total += r.film().samples_at(x, y);
        }
    std::printf("diffuse scene: fewest %u, mean %.2f spp\n", fewest, double(total) / (rs.width * rs.height));
    EXPECT_EQ(fewest, 4u);
    EXPECT_NEAR(double(total) / (rs.width * rs.height), 16.0, 0.25);
}

// As the film's mean of each pixel is taken over a count decided by its
// neighbours' samples only, the Noisy Image (the undenoised mean) stays
// unbiased: over paired seeds its image mean and single pixels agree with
// uniform renders of the same spp within 4 standard errors.
TEST(SampleDistribution, NoisyImageUnbiasedAgainstUniformOverSeeds) {
    const Scene scene = test::sphere_on_floor_scene();
    constexpr int kSeeds = 200;
    // A lit floor pixel, one near the shadow, one on the sphere.
    test::PairedDifferences diff{kRes, {{2, 13}, {9, 10}, {8, 6}}};
    double spread = 0.0;
    for (int s = 0; s < kSeeds; ++s) {
        Renderer a(scene, settings(true, 8, test::test_seed(3000 + s)));
        Renderer b(scene, settings(false, 8, test::test_seed(3000 + s)));
        ASSERT_TRUE(a.render());
        ASSERT_TRUE(b.render());
        uint32_t most = 0;
        for (int y = 0; y < kRes; ++y)
            for (int x = 0; x < kRes; ++x) most = std::max(most, a.film().samples_at(x, y));
        spread += double(most) / kSeeds;
        diff.add(a.film().resolve(PassType::NoisyImage), b.film().resolve(PassType::NoisyImage));
    }
    std::printf("most sampled pixel: %.1f spp on average\n", spread);
    EXPECT_GT(spread, 16.0) << "the most sampled pixel should take several times the budget";
    diff.expect_zero_mean("distribution bias");
}

// An emitter's straight edge seen with stratified samples (on a film as
// small as the edge term applies to): each half of the
// edge row's pixels sees the emitter in exactly the same proportion, so the
// halves' difference estimates no variance there, as it does along runs of
// an axis-aligned edge in a real render (a Sobol pattern's 4 + 4 samples).
// The edge row must still be sampled more than the rows on either side of
// it (which the 5 x 5 box alone judges alike: their boxes hold the same
// rows) and far more than the smooth, noisy ceiling below.
TEST(SampleDistribution, StratifiedEdgeRowGetsMoreThanTheRowsBesideIt) {
    constexpr int kSide = SampleDistribution::kEdgeMinSide, kEdgeRow = 12, kPasses = 8;
    const Vec3f emitter(2.7f), ceiling_albedo(0.43f), n(0.0f, 0.0f, -1.0f);
    Film film(kSide, kSide);
    film.enable_denoising_features();
    std::mt19937 rng(5);
    std::exponential_distribution<float> noise(1.0f);
    for (int pass = 0; pass < kPasses; ++pass)
        for (int y = 0; y < kSide; ++y)
            for (int x = 0; x < kSide; ++x) {
                // Passes 0, 1 see the emitter, 2, 3 the ceiling, ...: 2 of each half's 4.
                const bool on_emitter = y < kEdgeRow || (y == kEdgeRow && (pass / 2) % 2 == 0);
                const Vec3f albedo = on_emitter ? emitter : ceiling_albedo;
                const Vec3f radiance = on_emitter ? emitter : ceiling_albedo * (0.6f * noise(rng));
                film.add_sample(x, y, radiance, 1.0f, 1.0f, n, uint32_t(pass));
                film.add_denoising_features(x, y, albedo, n, 1.0f, uint32_t(pass));
            }
    const std::vector<uint32_t> targets = SampleDistribution::targets(film, 2 * kPasses);
    const auto row_mean = [&](int y0, int y1) { return mean_of_rows(targets, kSide, y0, y1); };
    const double edge = row_mean(kEdgeRow, kEdgeRow + 1), above = row_mean(kEdgeRow - 1, kEdgeRow),
                 below = row_mean(kEdgeRow + 1, kEdgeRow + 2), ceiling = row_mean(kEdgeRow + 6, kSide);
    std::printf("mean target: edge row %.1f, above %.1f, below %.1f, ceiling %.1f, emitter %.1f\n", edge, above,
                below, ceiling, row_mean(0, kEdgeRow - 4));
    EXPECT_GT(edge, 1.3 * above);
    EXPECT_GT(edge, 1.3 * below);
    EXPECT_GT(edge, 3.0 * ceiling);
    EXPECT_NEAR(row_mean(0, kSide), 2.0 * kPasses, 0.25);  // the budget holds
}

// The edge of a sun's shadow across a floor of one albedo, seen with
// stratified samples: no albedo edge for edge_variance() to find, and the
// edge row's halves see the sun in the same proportion, so they show no
// variance there. The direct light's range over the neighbours must still
// give the edge row more samples than the rows beside it and far more than
// the noise-free sun-lit floor.
TEST(SampleDistribution, HardShadowEdgeRowGetsMoreThanTheRowsBesideIt) {
    constexpr int kSide = SampleDistribution::kEdgeMinSide, kEdgeRow = 40, kPasses = 8;
    const Vec3f albedo(0.5f), sun = albedo * 4.0f, n(0.0f, 0.0f, 1.0f);
    Film film(kSide, kSide);
    film.enable_denoising_features();
    std::mt19937 rng(11);
    std::exponential_distribution<float> noise(1.0f);
    for (int pass = 0; pass < kPasses; ++pass)
        for (int y = 0; y < kSide; ++y)
            for (int x = 0; x < kSide; ++x) {
                // Lit above the edge row; in it passes 0, 1 are lit, 2, 3 not, ...: 2 of each half's 4.
                const bool lit = y < kEdgeRow || (y == kEdgeRow && (pass / 2) % 2 == 0);
                const Vec3f direct = lit ? sun : Vec3f(0.0f);
                const Vec3f radiance = direct + albedo * (0.2f * noise(rng));  // noisy bounce light everywhere
                film.add_sample(x, y, radiance, 1.0f, 1.0f, n, uint32_t(pass));
                film.add_denoising_features(x, y, albedo, n, 1.0f, uint32_t(pass));
                film.add_direct_light(x, y, direct, uint32_t(pass));
            }
    const std::vector<uint32_t> targets = SampleDistribution::targets(film, 2 * kPasses);
    const auto row_mean = [&](int y0, int y1) { return mean_of_rows(targets, kSide, y0, y1); };
    const double edge = row_mean(kEdgeRow, kEdgeRow + 1), above = row_mean(kEdgeRow - 1, kEdgeRow),
                 below = row_mean(kEdgeRow + 1, kEdgeRow + 2), sunlit = row_mean(0, kEdgeRow - 4),
                 shade = row_mean(kEdgeRow + 4, kSide);
    std::printf("mean target: edge row %.1f, above %.1f, below %.1f, sun-lit %.1f, shadow %.1f\n", edge, above,
                below, sunlit, shade);
    EXPECT_GT(edge, 1.3 * above);
    EXPECT_GT(edge, 1.3 * below);
    EXPECT_GT(edge, 3.0 * sunlit);
    EXPECT_NEAR(row_mean(0, kSide), 2.0 * kPasses, 0.25);  // the budget holds
}

TEST(SampleDistribution, BlackImageGetsTheBudgetEverywhere) {
    Scene scene;  // no light and a black world: nothing to distribute by
    const uint32_t white = scene.add_material(test::diffuse_material(Vec3f(0.7f)));
    test::add_quad(scene, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 6.0f, 6.0f, white, "floor");
    test::add_sphere(scene, {0, 0, 1}, 1.0f, white, 16, 32);
    scene.camera = test::sphere_on_floor_scene().camera;
    scene.finalize();
    Renderer r(scene, settings(true, 8, 3));
    ASSERT_TRUE(r.render());
    for (int y = 0; y < kRes; ++y)
        for (int x = 0; x < kRes; ++x) EXPECT_EQ(r.film().samples_at(x, y), 8u);
    for (float v : r.film().resolve(PassType::Combined)) ASSERT_TRUE(std::isfinite(v));
}

}  // namespace
}  // namespace coherent
