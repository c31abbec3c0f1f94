// Adaptive sampling (RenderSettings::adaptive): pixels whose even/odd error
// estimate meets the threshold over their 3x3 neighbourhood stop early.
// The properties tested: it really stops a good share of pixels and traces
// fewer camera rays; converged pixels keep exactly the samples they had; and
// the image stays unbiased: over many seeds, the adaptive render's image
// mean (and a few pixels) agrees with the full render's within 4 standard
// errors of the paired differences.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "test_render_helpers.h"
#include "test_seed.h"

namespace coherent {
namespace {


constexpr int kRes = 16;
constexpr int kSpp = 64;


RenderSettings settings(bool adaptive, uint64_t seed) {
    RenderSettings rs;
    rs.width = rs.height = kRes;
    rs.spp = kSpp;
    rs.seed = seed;
    rs.sampler = SamplerType::Spt;
    rs.max_bounces = 4;
    rs.adaptive = adaptive;
    rs.adaptive_threshold = 0.1;
    rs.adaptive_min_samples = 8;
    return rs;
}

TEST(Adaptive, OffByDefaultConvergesNothing) {
    const Scene scene = test::sphere_on_floor_scene();
    RenderSettings rs = settings(false, 1);
    EXPECT_FALSE(RenderSettings{}.adaptive);
    Renderer r(scene, rs);
    ASSERT_TRUE(r.render());
    EXPECT_EQ(r.stats().converged_pixels, 0u);
    EXPECT_EQ(r.stats().pixels, uint64_t(kRes * kRes));
    EXPECT_EQ(r.stats().samples, uint64_t(kRes * kRes * kSpp));
}

// Converged pixels stop at an even count >= the minimum and below spp; the
// others get every pass; the stats count exactly the samples on the film.
TEST(Adaptive, ConvergedPixelsStopAtEvenCountsAndStatsAddUp) {
    const Scene scene = test::sphere_on_floor_scene();
    Renderer ad(scene, settings(true, 5));
    ASSERT_TRUE(ad.render());
    Renderer full(scene, settings(false, 5));
    ASSERT_TRUE(full.render());
    const RenderStats& st = ad.stats();
    uint64_t total = 0, converged = 0;
    for (int y = 0; y < kRes; ++y)
        for (int x = 0; x < kRes; ++x) {
            const uint32_t n = ad.film().samples_at(x, y);
            total += n;
            if (ad.pixel_converged(x, y)) {
                ++converged;
                EXPECT_EQ(n % 2, 0u);
                EXPECT_GE(n, 8u);
                EXPECT_LT(n, uint32_t(kSpp));
            } else {
                EXPECT_EQ(n, uint32_t(st.spp));
            }
        }
    EXPECT_EQ(converged, st.converged_pixels);
    EXPECT_EQ(total, st.samples);
    EXPECT_GT(st.converged_fraction(), 0.3);
    const uint64_t cam_ad = st.rays[size_t(RayType::Camera)];
    const uint64_t cam_full = full.stats().rays[size_t(RayType::Camera)];
    EXPECT_EQ(cam_full, uint64_t(kRes * kRes * kSpp));
    EXPECT_EQ(cam_ad, st.samples);  // one camera ray per sample
    EXPECT_LT(double(cam_ad), 0.85 * double(cam_full));
    // A pixel's samples use the same random numbers in every render with
    // this seed, so a converged pixel's value is exactly a full render's
    // with spp = its own count: nothing is lost or re-weighted.
    const auto img = ad.film().resolve(PassType::Combined);
    int checked = 0;
    for (int y = 0; y < kRes && checked < 2; ++y)
        for (int x = 0; x < kRes && checked < 2; ++x) {
            if (!ad.pixel_converged(x, y)) continue;
            RenderSettings rs = settings(false, 5);
            rs.spp = int(ad.film().samples_at(x, y));
            const auto ref = test::render_combined(scene, rs);
            const size_t i = 4 * (size_t(y) * kRes + size_t(x));
            for (int c = 0; c < 4; ++c) EXPECT_EQ(img[i + c], ref[i + c]) << x << "," << y;
            ++checked;
            x += 7;  // a second, different pixel
        }
    EXPECT_EQ(checked, 2);
    std::printf("adaptive: %.1f%% converged, camera rays %llu vs %llu\n", 100.0 * st.converged_fraction(),
                (unsigned long long)cam_ad, (unsigned long long)cam_full);
}

// A constant world has zero error everywhere: every pixel converges at the
// first decision (the minimum, rounded up to even) and the render ends there.
TEST(Adaptive, AllConvergedEndsRenderAtMinimumSamples) {
    Scene scene;
    scene.world_color = Vec3f(0.5f);
    scene.finalize();
    RenderSettings rs = settings(true, 3);
    rs.adaptive_min_samples = 7;  // rounded up to 8
    Renderer r(scene, rs);
    ASSERT_TRUE(r.render());
    EXPECT_EQ(r.stats().spp, 8);
    EXPECT_EQ(r.stats().converged_pixels, uint64_t(kRes * kRes));
    EXPECT_DOUBLE_EQ(r.stats().converged_fraction(), 1.0);
    EXPECT_EQ(r.stats().samples, uint64_t(kRes * kRes * 8));
    EXPECT_FLOAT_EQ(r.film().resolve(PassType::Combined)[0], 0.5f);
}

TEST(Adaptive, DeterministicAcrossThreadCounts) {
    const Scene scene = test::sphere_on_floor_scene();
    RenderSettings a = settings(true, 9), b = settings(true, 9);
    a.threads = 1;
    b.threads = 2;
    b.tile_size = 5;
    EXPECT_EQ(test::render_combined(scene, a), test::render_combined(scene, b));
}

// The unbiasedness test. Paired by seed: both renders draw the same random
// numbers for every sample they share, so the difference isolates what
// stopping early changes, with far less variance than two independent runs
// (a stricter test for the same number of seeds).
TEST(Adaptive, UnbiasedAgainstFullRenderOverSeeds) {
    const Scene scene = test::sphere_on_floor_scene();
    constexpr int kSeeds = 400;
    // A lit floor pixel, a pixel near the shadow, one on the sphere (a pixel
    // that never converged has identical samples in both: diff 0).
    test::PairedDifferences diff{kRes, {{2, 13}, {9, 10}, {8, 6}}};
    double converged_sum = 0.0, mean_full = 0.0;
    for (int s = 0; s < kSeeds; ++s) {
        RenderStats st;
        const auto ad = test::render_combined(scene, settings(true, test::test_seed(1000 + s)), &st);
        const auto full = test::render_combined(scene, settings(false, test::test_seed(1000 + s)));
        converged_sum += st.converged_fraction();
        mean_full += test::image_mean(full) / kSeeds;
        diff.add(ad, full);
    }
    const double converged = converged_sum / kSeeds;
    std::printf("adaptive: image mean %.5f, converged %.1f%%\n", mean_full, 100.0 * converged);
    EXPECT_GT(converged, 0.3) << "threshold too strict to test anything";
    diff.expect_zero_mean("adaptive bias");
}

// Adaptive sampling under every sampler and traversal. Each combination
// keeps the bookkeeping invariants (converged pixels stop at even counts
// >= the minimum and below spp, the others get every pass, the stats count
// the film's samples) and stays unbiased against the full render over
// paired seeds at 4.5 standard errors. Packets, streams and wavefronts
// trace the same hits as single rays, so for one sampler every traversal
// also makes the same convergence decisions and the same image.
struct Mode {
    SamplerType sampler;
    Traversal traversal;
};

std::string mode_name(const Mode& m) {
    return std::string(sampler_type_name(m.sampler)) + "/" + std::string(traversal_name(m.traversal));
}

RenderSettings mode_settings(const Mode& m, bool adaptive, uint64_t seed) {
    RenderSettings rs = settings(adaptive, seed);
    rs.sampler = m.sampler;
    rs.traversal = m.traversal;
    rs.threads = 2;
    return rs;
}

void expect_bookkeeping(const Renderer& r, const std::string& what) {
    const RenderStats& st = r.stats();
    uint64_t total = 0, converged = 0;
    for (int y = 0; y < kRes; ++y)
        for (int x = 0; x < kRes; ++x) {
            const uint32_t n = r.film().samples_at(x, y);
            total += n;
            if (r.pixel_converged(x, y)) {
                ++converged;
                EXPECT_EQ(n % 2, 0u) << what;
                EXPECT_GE(n, 8u) << what;
                EXPECT_LT(n, uint32_t(kSpp)) << what;
            } else {
                EXPECT_EQ(n, uint32_t(st.spp)) << what;
            }
        }
    EXPECT_EQ(converged, st.converged_pixels) << what;
    EXPECT_EQ(total, st.samples) << what;
    EXPECT_GT(st.converged_fraction(), 0.3) << what << ": nothing to test";
}

TEST(Adaptive, EverySamplerAndTraversalKeepsTheRules) {
    const Scene scene = test::sphere_on_floor_scene();
    for (SamplerType sampler : {SamplerType::Spt, SamplerType::Cpt, SamplerType::Icpt}) {
        std::vector<float> single_image;
        std::vector<uint32_t> single_counts;
        for (Traversal traversal : {Traversal::Single, Traversal::Packet, Traversal::Stream, Traversal::Wavefront}) {
            const Mode m{sampler, traversal};
            Renderer r(scene, mode_settings(m, true, test::test_seed(5)));
            ASSERT_TRUE(r.render());
            ASSERT_EQ(r.settings().traversal, traversal) << mode_name(m);
            expect_bookkeeping(r, mode_name(m));
            std::vector<uint32_t> counts;
            for (int y = 0; y < kRes; ++y)
                for (int x = 0; x < kRes; ++x) counts.push_back(r.film().samples_at(x, y));
            const auto img = r.film().resolve(PassType::Combined);
            if (traversal == Traversal::Single) {
                single_image = img;
                single_counts = counts;
            } else {
                EXPECT_EQ(counts, single_counts) << mode_name(m) << ": other convergence decisions than single rays";
                EXPECT_EQ(img, single_image) << mode_name(m) << ": another image than single rays";
            }
        }
    }
}

TEST(Adaptive, UnbiasedForEverySamplerOverSeeds) {
    const Scene scene = test::sphere_on_floor_scene();
    constexpr int kSeeds = 60;
    for (const Mode& m : {Mode{SamplerType::Cpt, Traversal::Packet}, Mode{SamplerType::Icpt, Traversal::Packet},
                          Mode{SamplerType::Spt, Traversal::Wavefront}}) {
        std::vector<double> d;
        for (int s = 0; s < kSeeds; ++s) {
            const uint64_t seed = test::test_seed(2000 + s);
            const auto ad = test::render_combined(scene, mode_settings(m, true, seed));
            const auto full = test::render_combined(scene, mode_settings(m, false, seed));
            d.push_back(test::image_mean(ad) - test::image_mean(full));
        }
        const test::MeanVar mv = test::mean_var(d);
        std::printf("adaptive bias %-15s: diff %.2e +- %.2e (%.2f sigma)\n", mode_name(m).c_str(), mv.mean,
                    mv.stderr_of_mean(), mv.mean / mv.stderr_of_mean());
        EXPECT_GT(mv.stderr_of_mean(), 0.0) << mode_name(m);
        EXPECT_LT(std::abs(mv.mean), 4.5 * mv.stderr_of_mean()) << mode_name(m);
    }
}

// Adaptive sampling together with a target error: whichever rule ends the
// render, it ends at an even pass; if the target ended it, the image
// estimate meets it there and at no earlier report; converged pixels
// still hold their own (even) counts.
TEST(Adaptive, WithTargetErrorStopsByEitherRule) {
    const Scene scene = test::sphere_on_floor_scene();
    for (SamplerType sampler : {SamplerType::Spt, SamplerType::Cpt, SamplerType::Icpt}) {
        RenderSettings rs = settings(true, test::test_seed(17));
        rs.sampler = sampler;
        rs.spp = 4096;
        rs.target_error = 0.05;
        Renderer r(scene, rs);
        std::vector<double> estimate_at(rs.spp + 1, -1.0);
        ASSERT_TRUE(r.render([&](const Progress& p) {
            if (p.samples_done > 0) estimate_at[p.samples_done] = p.error_estimate;
            return true;
        }));
        const RenderStats& st = r.stats();
        const std::string what = std::string(sampler_type_name(sampler));
        ASSERT_LT(st.spp, rs.spp) << what << ": neither rule stopped the render";
        EXPECT_EQ(st.spp % 2, 0) << what;
        EXPECT_GT(st.converged_pixels, 0u) << what << ": adaptive sampling never acted";
        const bool all_converged = st.converged_pixels == st.pixels;
        EXPECT_TRUE(all_converged || st.error_estimate <= rs.target_error) << what;
        // Every earlier report (one per batch of passes) still missed the target.
        for (int n = 2; n < st.spp; ++n)
            if (estimate_at[n] >= 0.0) {
                EXPECT_GT(estimate_at[n], rs.target_error) << what << " at " << n;
            }
        EXPECT_DOUBLE_EQ(st.error_estimate, r.film().relative_rmse_estimate()) << what;
        uint64_t total = 0;
        for (int y = 0; y < kRes; ++y)
            for (int x = 0; x < kRes; ++x) {
                const uint32_t n = r.film().samples_at(x, y);
                total += n;
                EXPECT_EQ(n % 2, 0u) << what;
                if (!r.pixel_converged(x, y)) {
                    EXPECT_EQ(n, uint32_t(st.spp)) << what;
                }
            }
        EXPECT_EQ(total, st.samples) << what;
        std::printf("adaptive + target %-4s: stopped at %d passes, estimate %.4f, %.0f%% converged\n", what.c_str(),
                    st.spp, st.error_estimate, 100.0 * st.converged_fraction());
    }
}

// The error estimate when pixels stop at different counts, per pixel: each
// pixel's Error-pass value is its own even/odd estimate at its own count,
// exactly the full render's at that count (its samples are the same).
TEST(Adaptive, PixelErrorIsTheEstimateAtThePixelsOwnCount) {
    const Scene scene = test::sphere_on_floor_scene();
    Renderer ad(scene, settings(true, test::test_seed(31)));
    ASSERT_TRUE(ad.render());
    const auto err = ad.film().resolve(PassType::Error);
    std::map<uint32_t, std::vector<float>> full_err;  // by spp
    for (int y = 0; y < kRes; ++y)
        for (int x = 0; x < kRes; ++x) {
            const uint32_t n = ad.film().samples_at(x, y);
            if (!full_err.count(n)) {
                RenderSettings rs = settings(false, test::test_seed(31));
                rs.spp = int(n);
                rs.error_estimate = ErrorEstimate::Exact;  // the paired scrambles adaptive sampling renders with
                Renderer f(scene, rs);
                ASSERT_TRUE(f.render());
                full_err[n] = f.film().resolve(PassType::Error);
            }
            EXPECT_EQ(err[size_t(y) * kRes + x], full_err[n][size_t(y) * kRes + x]) << x << "," << y << " n " << n;
        }
    EXPECT_GE(full_err.size(), 2u) << "every pixel stopped at the same count: nothing tested";
}

// The image estimate when pixels stop at different counts, calibrated
// against the true error over seeds as in test_error_estimate.cpp:
// R = mean(e^2) / mean(t^2) within 4.5 measured standard errors of 1. The
// truth comes from an independent reference, the mean of two 4096-spp
// renders whose own error is measured from their difference.
//
// This failed (R = 0.38 +- 0.04 over 100 seeds) while a pixel's stop read
// its own estimate: stopping when the estimate is small by chance selects
// optimistic estimates, and adaptive sampling plus a target error stopped at
// an RMSE about 1.6x the target. A stop decided from the neighbours' samples
// (Renderer::update_convergence) leaves each pixel's estimate unbiased.
TEST(Adaptive, ImageErrorEstimateCalibratedUnderAdaptiveStops) {
    const Scene scene = test::sphere_on_floor_scene();
    RenderSettings ref_rs = settings(false, test::test_seed(90001));
    ref_rs.spp = 4096;
    const auto ra = test::render_combined(scene, ref_rs);
    ref_rs.seed = test::test_seed(90002);
    const auto rb = test::render_combined(scene, ref_rs);
    std::vector<float> ref(ra.size());
    for (size_t i = 0; i < ra.size(); ++i) ref[i] = 0.5f * (ra[i] + rb[i]);
    auto mean_sq_diff = [](const std::vector<float>& a, const std::vector<float>& b) {
        double e2 = 0.0;
        for (size_t i = 0; i < a.size(); i += 4)
            for (int c = 0; c < 3; ++c) e2 += (double(a[i + c]) - b[i + c]) * (double(a[i + c]) - b[i + c]);
        return e2 / (3.0 * double(a.size() / 4));
    };
    const double ref_mean = test::image_mean(ref);
    const double ref_err2 = mean_sq_diff(ra, ref) / (ref_mean * ref_mean);  // (A - B)^2 / 4

    constexpr int kSeeds = 60;
    std::vector<double> e2, t2;
    for (int s = 0; s < kSeeds; ++s) {
        Renderer r(scene, settings(true, test::test_seed(300 + s)));
        ASSERT_TRUE(r.render());
        const double e = r.film().relative_rmse_estimate();
        e2.push_back(e * e);
        t2.push_back(mean_sq_diff(r.film().resolve(PassType::Combined), ref) / (ref_mean * ref_mean) - ref_err2);
    }
    double me = 0.0, mt = 0.0;
    for (int s = 0; s < kSeeds; ++s) me += e2[s] / kSeeds, mt += t2[s] / kSeeds;
    ASSERT_GT(mt, 0.0);
    const double ratio = me / mt;
    double var = 0.0;
    for (int s = 0; s < kSeeds; ++s) var += (e2[s] - ratio * t2[s]) * (e2[s] - ratio * t2[s]) / (kSeeds - 1);
    const double se = std::sqrt(var / kSeeds) / mt;
    std::printf("adaptive error estimate: estimate %.4f, true %.4f, R %.3f +- %.3f\n", std::sqrt(me),
                std::sqrt(mt), ratio, se);
    EXPECT_LT(4.5 * se, 1.0) << "too noisy to tell a factor 2";
    EXPECT_LE(std::abs(ratio - 1.0), 4.5 * se) << "the estimate is not calibrated under adaptive stops";
}

}  // namespace
}  // namespace coherent
