// The reference-free error estimate (Film::relative_rmse_estimate, from the
// even/odd half-buffers) against the true error measured with a high-spp
// reference, for every sampler; and the stopping rules built on it.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "test_fixtures.h"
#include "test_render_helpers.h"
#include "test_seed.h"

namespace coherent {
namespace {


constexpr int kRes = 48;

const char* name_of(SamplerType t) { return sampler_type_name(t).data(); }  // literals: NUL-terminated


// Exact by default: these tests are about the unbiased estimate; Auto (one
// scramble, an upper bound) has its own test below.
RenderSettings base_settings(int spp, SamplerType sampler, uint64_t seed,
                             ErrorEstimate estimate = ErrorEstimate::Exact) {
    RenderSettings rs;
    rs.width = rs.height = kRes;
    rs.spp = spp;
    rs.sampler = sampler;
    rs.seed = seed;
    rs.error_estimate = estimate;
    return rs;
}

// sqrt(mean over pixels and RGB of (img - ref)^2) / mean over pixels and RGB
// of ref: the same normalisation as Film::relative_rmse_estimate.
double true_relative_rmse(const std::vector<float>& img, const std::vector<float>& ref) {
    double err2 = 0.0, mean = 0.0;
    size_t n = 0;
    for (size_t i = 0; i + 3 < img.size(); i += 4)
        for (int c = 0; c < 3; ++c) {
            const double d = double(img[i + c]) - double(ref[i + c]);
            err2 += d * d;
            mean += ref[i + c];
            ++n;
        }
    return std::sqrt(err2 / double(n)) / (mean / double(n));
}

// The Error pass: finite, non-negative, and its RMS over the image divided
// by the image mean is the relative estimate.
void check_error_pass(const Film& film, double estimate) {
    const std::vector<float> err = film.resolve(PassType::Error);
    ASSERT_EQ(err.size(), size_t(film.width()) * film.height());
    double err2 = 0.0;
    for (float e : err) {
        ASSERT_TRUE(std::isfinite(e));
        ASSERT_GE(e, 0.0f);
        err2 += double(e) * e;
    }
    const auto img = film.resolve(PassType::Combined);
    double mean = 0.0;
    for (size_t i = 0; i < img.size(); i += 4) mean += img[i] + img[i + 1] + img[i + 2];
    mean /= 3.0 * double(err.size());
    EXPECT_NEAR(std::sqrt(err2 / double(err.size())) / mean, estimate, 1e-3 * estimate);
}

struct SceneCase {
    const char* name;
    Scene scene;
    std::vector<float> reference;
    double reference_error2 = 0.0;  // the reference's own squared relative error, estimated independently
    int seeds = 32;                 // renders per sampler and spp (the standard error shrinks with them)
};

// The reference is the mean of two independent 1024-spp SPT renders A and B
// (every sampler is unbiased, so one serves all). Its own error is measured
// without the estimator under test: for independent A, B of the same
// expectation, E[(A - B)^2] = 2 Var[A] per pixel, and the mean (A + B) / 2 has
// variance Var[A] / 2 = E[(A - B)^2] / 4.
void render_reference(SceneCase& sc) {
    Renderer a(sc.scene, base_settings(1024, SamplerType::Spt, test::test_seed(1234)));
    Renderer b(sc.scene, base_settings(1024, SamplerType::Spt, test::test_seed(4321)));
    ASSERT_TRUE(a.render());
    ASSERT_TRUE(b.render());
    const auto ia = a.film().resolve(PassType::Combined), ib = b.film().resolve(PassType::Combined);
    sc.reference.resize(ia.size());
    for (size_t i = 0; i < ia.size(); ++i) sc.reference[i] = 0.5f * (ia[i] + ib[i]);
    const double ab = true_relative_rmse(ia, sc.reference);  // |A - ref| = |A - B| / 2
    // true_relative_rmse(A, ref)^2 = rel. mean of (A - B)^2 / 4: exactly the reference's squared error.
    sc.reference_error2 = ab * ab;
    ASSERT_GT(sc.reference_error2, 0.0);
}

// Calibration of the estimate, over seeds. One realisation of a squared
// error over a path-traced image is itself noisy (heavy-tailed light
// transport, and CPT correlates whole packets), so the test compares means
// of squares over kSeeds renders: per seed, the estimate e_i^2 and the true
// squared error t_i^2 (against the reference, less the reference's own
// squared error, which adds to it in expectation). The ratio
// R = mean(e^2) / mean(t^2) must be 1 within 5 standard errors, the
// standard error measured from the seeds themselves (delta method on the
// paired values: Var[R] ~ Var[e^2 - R t^2] / (k mean(t^2)^2)); 5, not 4.5:
// with heavy-tailed squared errors (the Cornell box's caustics) R is skewed
// and that standard error is itself uncertain (runs reached -3.6). So that a
// noisy case cannot pass by having a huge error bar, the bar itself must
// be below 1: small enough to catch a factor 2 in the square, e.g. the
// half-buffer difference taken as the error of the mean without its
// sqrt(n_e n_o) / n scaling. (Heavy tails and CPT's packet-correlated
// errors make the squared error of one image noisy: +-25 % in RMSE at
// 4.5 sigma would take ~150 seeds.)
void check_estimate_tracks_truth(SceneCase& sc) {
    render_reference(sc);
    if (::testing::Test::HasFatalFailure()) return;
    const int kSeeds = sc.seeds;
    for (SamplerType st : {SamplerType::Spt, SamplerType::Cpt, SamplerType::Icpt}) {
        for (int spp : {16, 64}) {
            std::vector<double> e2(kSeeds), t2(kSeeds);
            for (int k = 0; k < kSeeds; ++k) {
                Renderer r(sc.scene, base_settings(spp, st, test::test_seed(7 + 101 * uint64_t(k))));
                ASSERT_TRUE(r.render());
                const double estimate = r.film().relative_rmse_estimate();
                EXPECT_DOUBLE_EQ(estimate, r.stats().error_estimate);
                const double measured = true_relative_rmse(r.film().resolve(PassType::Combined), sc.reference);
                e2[k] = estimate * estimate;
                t2[k] = measured * measured - sc.reference_error2;
                if (k == 0) check_error_pass(r.film(), estimate);
            }
            double me = 0.0, mt = 0.0;
            for (int k = 0; k < kSeeds; ++k) me += e2[k] / kSeeds, mt += t2[k] / kSeeds;
            ASSERT_GT(mt, 0.0);
            const double ratio = me / mt;
            double var = 0.0;
            for (int k = 0; k < kSeeds; ++k) {
                const double d = e2[k] - ratio * t2[k];
                var += d * d / (kSeeds - 1);
            }
            const double se = std::sqrt(var / kSeeds) / mt;
            std::printf("[error estimate] %-12s %-4s %3d spp: estimate %.4f  true %.4f  R %.3f +- %.3f (%.1f sigma)\n",
                        sc.name, name_of(st), spp, std::sqrt(me), std::sqrt(mt), ratio, se, (ratio - 1.0) / se);
            EXPECT_LE(std::abs(ratio - 1.0), 5.0 * se) << sc.name << " " << name_of(st) << " " << spp << " spp";
            EXPECT_LT(5.0 * se, 1.0) << "too noisy to tell a factor 2: " << sc.name << " " << name_of(st);
        }
    }
}

TEST(ErrorEstimate, TracksTrueErrorCornellBox) {
    SceneCase sc{"cornell_box", {}, {}, 0.0, 24};  // slower per sample
    ASSERT_TRUE(test::load_fixture("cornell_box.glb", sc.scene));
    sc.scene.finalize();
    check_estimate_tracks_truth(sc);
}

TEST(ErrorEstimate, TracksTrueErrorSphereScene) {
    SceneCase sc{"sphere_floor", test::sphere_on_floor_scene(), {}, 0.0, 32};
    check_estimate_tracks_truth(sc);
}

// ErrorEstimate::Auto with nothing deciding by the estimate draws every Sobol
// sample from one scramble. Over seeds, against the same reference: its true
// squared error is below the paired scrambles' (the reason for it); it
// reports no estimate, because the film's even/odd difference would
// overstate its error (the halves are complementary strata), which the test
// also checks so that the rule stays justified.
TEST(ErrorEstimate, AutoTakesOneScrambleWithLessErrorAndNoEstimate) {
    SceneCase sc{"sphere_floor", test::sphere_on_floor_scene(), {}, 0.0, 24};
    render_reference(sc);
    if (HasFatalFailure()) return;
    for (SamplerType st : {SamplerType::Spt, SamplerType::Cpt}) {
        double e2[2] = {}, t2[2] = {};  // [exact, auto]: means over seeds
        for (int mode = 0; mode < 2; ++mode) {
            const ErrorEstimate estimate = mode == 0 ? ErrorEstimate::Exact : ErrorEstimate::Auto;
            for (int k = 0; k < sc.seeds; ++k) {
                Renderer r(sc.scene, base_settings(64, st, test::test_seed(7 + 101 * uint64_t(k)), estimate));
                ASSERT_TRUE(r.render());
                if (mode == 1) {
                    EXPECT_LT(r.stats().error_estimate, 0.0) << "Auto reports no estimate";
                }
                const double e = r.film().relative_rmse_estimate();
                const double t = true_relative_rmse(r.film().resolve(PassType::Combined), sc.reference);
                e2[mode] += e * e / sc.seeds;
                t2[mode] += (t * t - sc.reference_error2) / sc.seeds;
            }
        }
        std::printf("[error estimate] %s 64 spp: true exact %.4f auto %.4f; halves' estimate exact %.4f auto %.4f\n",
                    name_of(st), std::sqrt(t2[0]), std::sqrt(t2[1]), std::sqrt(e2[0]), std::sqrt(e2[1]));
        EXPECT_LT(t2[1], 0.9 * t2[0]) << name_of(st) << ": one scramble should have less error";
        EXPECT_GT(e2[1], 2.0 * t2[1]) << name_of(st) << ": one scramble's halves no longer measure its error";
    }
    // Anything that decides by the estimate gets the exact one.
    RenderSettings rs = base_settings(8, SamplerType::Spt, 1, ErrorEstimate::Auto);
    EXPECT_FALSE(rs.exact_error_estimate());
    RenderSettings t = rs;
    t.target_error = 0.05;
    RenderSettings a = rs;
    a.adaptive = true;
    RenderSettings d = rs;
    d.denoise = true;
    RenderSettings w = rs;
    w.pattern = SampleSequence::WhiteNoise;
    EXPECT_TRUE(t.exact_error_estimate());
    EXPECT_TRUE(a.exact_error_estimate());
    EXPECT_TRUE(d.exact_error_estimate());
    EXPECT_EQ(w.resolved_pattern(), SampleSequence::WhiteNoise);
}

TEST(ErrorEstimate, UnknownBeforeTwoPassesAndFiniteErrorPass) {
    const Scene scene = test::sphere_on_floor_scene();
    Renderer r(scene, base_settings(1, SamplerType::Spt, 3));
    ASSERT_TRUE(r.render());
    EXPECT_LT(r.film().relative_rmse_estimate(), 0.0);  // no odd pass yet
    EXPECT_LT(r.stats().error_estimate, 0.0);
    EXPECT_EQ(r.stats().spp, 1);
    for (float e : r.film().resolve(PassType::Error)) EXPECT_EQ(e, 0.0f);
}

// Pass-end progress reports: the first report carrying each samples_done
// (reports inside a pass repeat the previous pass's count).
struct PassLog {
    std::map<int, Progress> at;
    ProgressCallback callback() {
        return [this](const Progress& p) {
            if (p.samples_done > 0 && !at.count(p.samples_done)) at[p.samples_done] = p;
            return true;
        };
    }
};

// With report_interval 0 every pass reports, so the target is checked after
// every even pass count; with batches (the default) after every batch.
// Either way the render stops at the first check that meets it.
TEST(ErrorEstimate, TargetErrorStopsAtFirstEvenPassBelowTarget) {
    const Scene scene = test::sphere_on_floor_scene();
    for (double interval : {0.0, RenderSettings().report_interval})
        for (SamplerType st : {SamplerType::Spt, SamplerType::Cpt, SamplerType::Icpt}) {
            RenderSettings rs = base_settings(4096, st, test::test_seed(11));
            rs.target_error = 0.08;
            rs.report_interval = interval;
            Renderer r(scene, rs);
            PassLog log;
            ASSERT_TRUE(r.render(log.callback()));
            const int taken = r.stats().spp;
            ASSERT_GE(taken, 2);
            ASSERT_LT(taken, rs.spp) << "target never reached";
            EXPECT_EQ(taken % 2, 0);
            EXPECT_LE(r.stats().error_estimate, rs.target_error);
            EXPECT_DOUBLE_EQ(r.stats().error_estimate, r.film().relative_rmse_estimate());
            EXPECT_EQ(r.film().samples_at(0, 0), uint32_t(taken));
            if (interval == 0.0) {
                ASSERT_EQ(log.at.size(), size_t(taken));  // a report per pass
            }
            // No earlier check met the target.
            for (const auto& [n, p] : log.at)
                if (n < taken && n >= 2 && n % 2 == 0) {
                    EXPECT_GT(p.error_estimate, rs.target_error) << n;
                }
            std::printf("[target error] %-4s report interval %.2f s: stopped at %d spp after %zu reports, "
                        "estimate %.4f\n",
                        name_of(st), interval, taken, log.at.size(), r.stats().error_estimate);
        }
}

TEST(ErrorEstimate, TimeLimitOverrunsByAtMostOnePass) {
    const Scene scene = test::sphere_on_floor_scene();
    for (double interval : {0.0, RenderSettings().report_interval}) {
        RenderSettings rs = base_settings(1 << 20, SamplerType::Spt, 5);
        rs.time_limit = 0.3;
        rs.report_interval = interval;
        Renderer r(scene, rs);
        PassLog log;
        ASSERT_TRUE(r.render(log.callback()));
        const int taken = r.stats().spp;
        ASSERT_GT(taken, 0);
        ASSERT_LT(taken, rs.spp);
        if (interval == 0.0) {
            ASSERT_EQ(log.at.size(), size_t(taken));
        }
        // Every report but the last came before the limit; the last is the
        // first at or past it. Batches are cut to end by the limit at the
        // pace of the batch before, so the overrun is about one pass.
        for (const auto& [n, p] : log.at) {
            if (n < taken) {
                EXPECT_LT(p.seconds, rs.time_limit) << n;
            } else {
                EXPECT_GE(p.seconds, rs.time_limit);
            }
        }
    }
}

TEST(ErrorEstimate, NoStoppingRuleRendersAllSamples) {
    const Scene scene = test::sphere_on_floor_scene();
    Renderer r(scene, base_settings(6, SamplerType::Cpt, 2));
    ASSERT_TRUE(r.render());
    EXPECT_EQ(r.stats().spp, 6);
    EXPECT_GT(r.stats().error_estimate, 0.0);
}

}  // namespace
}  // namespace coherent
