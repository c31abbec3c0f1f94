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

namespace coherent {
namespace {


constexpr int kRes = 48;

const char* name_of(SamplerType t) { return sampler_type_name(t).data(); }  // literals: NUL-terminated


RenderSettings base_settings(int spp, SamplerType sampler, uint64_t seed) {
    RenderSettings rs;
    rs.width = rs.height = kRes;
    rs.spp = spp;
    rs.sampler = sampler;
    rs.seed = seed;
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
    double reference_error;  // the reference's own estimated relative error
};

void check_estimate_tracks_truth(SceneCase& sc) {
    // Reference: 2048 spp with SPT (every sampler is unbiased, so one serves all).
    Renderer ref(sc.scene, base_settings(2048, SamplerType::Spt, 1234));
    ASSERT_TRUE(ref.render());
    sc.reference = ref.film().resolve(PassType::Combined);
    sc.reference_error = ref.film().relative_rmse_estimate();
    ASSERT_GT(sc.reference_error, 0.0);

    // One realisation of a squared error over a path-traced image is itself
    // noisy (heavy-tailed light transport, and CPT correlates whole packets),
    // so the calibration is checked on the mean square over a few seeds:
    // sqrt(mean estimate^2) against sqrt(mean true^2).
    constexpr int kSeeds = 8;
    for (SamplerType st : {SamplerType::Spt, SamplerType::Cpt, SamplerType::Icpt}) {
        for (int spp : {32, 128}) {
            double est2 = 0.0, true2 = 0.0;
            for (int seed = 0; seed < kSeeds; ++seed) {
                Renderer r(sc.scene, base_settings(spp, st, 7 + 101 * uint64_t(seed)));
                ASSERT_TRUE(r.render());
                const double estimate = r.film().relative_rmse_estimate();
                EXPECT_DOUBLE_EQ(estimate, r.stats().error_estimate);
                // The measured error includes the reference's own (independent)
                // error; remove it in quadrature (about sqrt(spp/2048) of it).
                const double measured = true_relative_rmse(r.film().resolve(PassType::Combined), sc.reference);
                est2 += estimate * estimate;
                true2 += measured * measured - sc.reference_error * sc.reference_error;
                if (seed == 0) check_error_pass(r.film(), estimate);
            }
            const double estimate = std::sqrt(est2 / kSeeds), truth = std::sqrt(std::max(true2, 0.0) / kSeeds);
            std::printf("[error estimate] %-12s %-4s %3d spp: estimate %.4f  true %.4f  ratio %.3f\n", sc.name,
                        name_of(st), spp, estimate, truth, estimate / truth);
            EXPECT_NEAR(estimate / truth, 1.0, 0.25) << sc.name << " " << name_of(st) << " " << spp << " spp";
        }
    }
}

TEST(ErrorEstimate, TracksTrueErrorCornellBox) {
    SceneCase sc{"cornell_box", {}, {}, 0.0};
    ASSERT_TRUE(test::load_fixture("cornell_box.glb", sc.scene));
    sc.scene.finalize();
    check_estimate_tracks_truth(sc);
}

TEST(ErrorEstimate, TracksTrueErrorSphereScene) {
    SceneCase sc{"sphere_floor", test::sphere_on_floor_scene(), {}, 0.0};
    check_estimate_tracks_truth(sc);
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

TEST(ErrorEstimate, TargetErrorStopsAtFirstEvenPassBelowTarget) {
    const Scene scene = test::sphere_on_floor_scene();
    for (SamplerType st : {SamplerType::Spt, SamplerType::Cpt, SamplerType::Icpt}) {
        RenderSettings rs = base_settings(4096, st, 11);
        rs.target_error = 0.08;
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
        // No earlier even check met the target: it stopped within one batch.
        ASSERT_EQ(log.at.size(), size_t(taken));
        for (const auto& [n, p] : log.at)
            if (n < taken && n >= 2 && n % 2 == 0) {
                EXPECT_GT(p.error_estimate, rs.target_error) << n;
            }
        std::printf("[target error] %-4s stopped at %d spp, estimate %.4f\n", name_of(st), taken,
                    r.stats().error_estimate);
    }
}

TEST(ErrorEstimate, TimeLimitOverrunsByAtMostOnePass) {
    const Scene scene = test::sphere_on_floor_scene();
    RenderSettings rs = base_settings(1 << 20, SamplerType::Spt, 5);
    rs.time_limit = 0.3;
    Renderer r(scene, rs);
    PassLog log;
    ASSERT_TRUE(r.render(log.callback()));
    const int taken = r.stats().spp;
    ASSERT_GT(taken, 0);
    ASSERT_LT(taken, rs.spp);
    ASSERT_EQ(log.at.size(), size_t(taken));
    // Every pass but the last ended before the limit; the last one is the
    // first to end at or past it, so the overrun is at most that one pass.
    for (const auto& [n, p] : log.at) {
        if (n < taken) {
            EXPECT_LT(p.seconds, rs.time_limit) << n;
        } else {
            EXPECT_GE(p.seconds, rs.time_limit);
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
