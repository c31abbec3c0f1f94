// BSDF tests: sampling agrees with evaluation (two independent estimators of
// the directional albedo), energy bounds, reciprocity, and no leaks through
// shading normals.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "core/random.h"
#include "render/bsdf.h"
#include "render/microfacet.h"
#include "test_render_helpers.h"
#include "test_seed.h"

using namespace coherent;
using coherent::test::principled;

namespace {

Vec3f dir_from_angle(float theta) { return {std::sin(theta), 0.0f, std::cos(theta)}; }

// Albedo by importance sampling (mean of sample weights; delta lobes included).
double albedo_by_sampling(const Bsdf& b, int n, uint64_t seed) {
    Pcg32 rng(seed);
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
        BsdfSample s;
        if (b.sample(rng.next_float(), rng.next_float(), rng.next_float(), s)) sum += luminance(s.weight);
    }
    return sum / n;
}

// Albedo of the non-delta part by uniform sphere sampling of eval(): an
// estimator that shares nothing with sample().
double albedo_by_quadrature(const Bsdf& b, int n, uint64_t seed, double* pdf_integral) {
    Pcg32 rng(seed);
    double sum = 0.0, pdf_sum = 0.0;
    for (int i = 0; i < n; ++i) {
        const float z = 1.0f - 2.0f * rng.next_float();
        const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
        const float phi = 2.0f * kPi * rng.next_float();
        const Vec3f w{r * std::cos(phi), r * std::sin(phi), z};
        float pdf = 0.0f;
        sum += luminance(b.eval(w, pdf)) * 4.0 * kPi;
        pdf_sum += pdf * 4.0 * kPi;
    }
    if (pdf_integral) *pdf_integral = pdf_sum / n;
    return sum / n;
}

struct Case {
    const char* name;
    Material mat;
};

TEST(Bsdf, SamplingMatchesEvaluationAndConservesEnergy) {
    const Vec3f n{0, 0, 1};
    std::vector<Case> cases = {
        {"diffuse", principled(1.0f, 0.0f, 0.5f, 0.0f, 0.0f)},
        {"metal_r05", principled(1.0f, 1.0f, 0.5f, 0.5f, 0.0f)},
        {"metal_r02", principled(1.0f, 1.0f, 0.2f, 0.5f, 0.0f)},
        {"rough_glass", principled(1.0f, 0.0f, 0.4f, 0.5f, 1.0f)},
        {"plastic", principled(0.5f, 0.0f, 0.3f, 0.5f, 0.0f)},
    };
    Material mix = principled(1.0f, 0.0f, 0.5f, 0.0f, 0.0f);
    mix.closure_count = 2;
    mix.closures[1] = principled(1.0f, 1.0f, 0.3f, 0.5f, 0.0f).closures[0];
    mix.weights = {0.3f, 0.7f, 0.0f, 0.0f};
    cases.push_back({"mix", mix});

    for (const Case& c : cases) {
        for (float theta : {0.1f, 0.8f, 1.3f}) {
            const Vec3f wo = dir_from_angle(theta);
            const Bsdf b(c.mat, n, n, wo, true, true);
            ASSERT_FALSE(b.empty()) << c.name;
            double pdf_integral = 0.0;
            const double by_sampling = albedo_by_sampling(b, 200000, 1);
            const double by_quadrature = albedo_by_quadrature(b, 400000, 2, &pdf_integral);
            // The two estimators must agree: sample() draws from the density eval() reports.
            EXPECT_NEAR(by_sampling, by_quadrature, 0.02 + 0.02 * by_quadrature) << c.name << " theta " << theta;
            // White closures never create energy (Principled v1 adds diffuse
            // and specular, so only single-lobe white closures are bounded by 1).
            if (std::string(c.name) != "plastic") {
                EXPECT_LE(by_sampling, 1.01) << c.name << " theta " << theta;
            }
            // The pdf integrates to at most one (less where samples are rejected).
            EXPECT_LE(pdf_integral, 1.02) << c.name;
            EXPECT_GT(pdf_integral, 0.5) << c.name;
        }
    }
}

TEST(Bsdf, WhiteDiffuseAlbedoIsOneAndRoughMetalLosesLittle) {
    const Vec3f n{0, 0, 1};
    const Bsdf diffuse(principled(1.0f, 0.0f, 0.5f, 0.0f, 0.0f), n, n, dir_from_angle(0.5f), true, true);
    EXPECT_NEAR(albedo_by_sampling(diffuse, 10000, 3), 1.0, 1e-5);  // weight is exactly the colour
    const Bsdf metal(principled(1.0f, 1.0f, 0.5f, 0.5f, 0.0f), n, n, dir_from_angle(0.5f), true, true);
    const double a = albedo_by_sampling(metal, 200000, 4);
    // Single-scattering GGX at alpha 0.25 loses a few percent to multiple scattering.
    EXPECT_GT(a, 0.9);
    EXPECT_LT(a, 1.0);
}

TEST(Bsdf, SmoothGlassSplitsEnergyByFresnel) {
    const Vec3f n{0, 0, 1};
    for (bool front : {true, false}) {
        for (float theta : {0.0f, 0.5f, 1.0f, 1.4f}) {
            const Vec3f wo = dir_from_angle(theta);
            const Bsdf b(principled(1.0f, 0.0f, 0.0f, 0.5f, 1.0f, 1.5f), n, n, wo, front, true);
            ASSERT_TRUE(b.has_non_delta() == false);
            Pcg32 rng(5);
            int reflected = 0, total = 20000;
            for (int i = 0; i < total; ++i) {
                BsdfSample s;
                ASSERT_TRUE(b.sample(rng.next_float(), rng.next_float(), rng.next_float(), s));
                EXPECT_TRUE(s.delta);
                EXPECT_NEAR(luminance(s.weight), 1.0f, 1e-5f);  // white glass: no gain, no loss
                if (s.type == RayType::Reflection) {
                    ++reflected;
                    EXPECT_NEAR(s.wi.z, wo.z, 1e-5f);
                } else {
                    EXPECT_EQ(s.type, RayType::Refraction);
                    EXPECT_LT(s.wi.z, 0.0f);
                    // Snell: eta_o sin_o = eta_t sin_t.
                    const float eta = front ? 1.5f : 1.0f / 1.5f;
                    const float sin_t = std::sqrt(std::max(0.0f, 1.0f - s.wi.z * s.wi.z));
                    EXPECT_NEAR(std::sin(theta), eta * sin_t, 1e-4f);
                }
            }
            const float fr = fresnel_dielectric(std::cos(theta), front ? 1.5f : 1.0f / 1.5f);
            const float sigma = std::sqrt(fr * (1 - fr) / total) + 1e-6f;
            EXPECT_NEAR(float(reflected) / total, fr, 5 * sigma + 1e-3f) << "front " << front << " theta " << theta;
        }
    }
    // Total internal reflection from inside beyond the critical angle (41.8 deg).
    EXPECT_EQ(fresnel_dielectric(std::cos(1.0f), 1.0f / 1.5f), 1.0f);
}

TEST(Bsdf, ReflectionIsReciprocal) {
    const Vec3f n{0, 0, 1};
    const Material m = principled(0.7f, 0.3f, 0.35f, 0.5f, 0.0f);
    Pcg32 rng(9);
    for (int i = 0; i < 100; ++i) {
        const Vec3f a = normalize(Vec3f(rng.next_float() - 0.5f, rng.next_float() - 0.5f, rng.next_float() + 0.05f));
        const Vec3f c = normalize(Vec3f(rng.next_float() - 0.5f, rng.next_float() - 0.5f, rng.next_float() + 0.05f));
        float pdf;
        const Vec3f fab = Bsdf(m, n, n, a, true, true).eval(c, pdf) / c.z;
        const Vec3f fba = Bsdf(m, n, n, c, true, true).eval(a, pdf) / a.z;
        EXPECT_NEAR(fab.x, fba.x, 1e-4f * std::max(1.0f, fab.x));
        EXPECT_NEAR(fab.y, fba.y, 1e-4f * std::max(1.0f, fab.y));
    }
}

TEST(Bsdf, SampledDirectionsNeverLeakThroughGeometry) {
    // Shading normal tilted 40 degrees from the geometric normal; grazing wo.
    const Vec3f ng{0, 0, 1};
    const Vec3f ns = normalize(Vec3f(std::sin(0.7f), 0, std::cos(0.7f)));
    const Vec3f wo = normalize(Vec3f(-0.2f, 0.0f, 0.98f));
    for (const Material& m : {principled(1.0f, 0.0f, 0.5f, 0.0f, 0.0f), principled(1.0f, 1.0f, 0.0f, 0.5f, 0.0f),
                              principled(1.0f, 1.0f, 0.3f, 0.5f, 0.0f)}) {
        const Bsdf b(m, ns, ng, wo, true, true);
        Pcg32 rng(11);
        for (int i = 0; i < 20000; ++i) {
            BsdfSample s;
            if (!b.sample(rng.next_float(), rng.next_float(), rng.next_float(), s)) continue;
            EXPECT_GT(dot(s.wi, ng), 0.0f);  // reflected light stays above the real surface
            EXPECT_TRUE(is_finite(s.weight));
        }
        // eval judges by the shading normal alone, as Cycles 3.4: light from
        // below the flat surface but above the smooth one shades the point
        // (its shadow ray, from the smooth surface, decides whether it
        // arrives: render/shadow_terminator.h); light below both does not.
        float pdf;
        const Vec3f below = normalize(Vec3f(0.9f, 0.0f, -0.1f));
        ASSERT_GT(dot(below, ns), 0.0f);
        if (b.has_non_delta()) {  // (a sharp mirror evaluates to black everywhere)
            EXPECT_FALSE(is_black(b.eval(below, pdf)));
            EXPECT_GT(pdf, 0.0f);
        }
        const Vec3f under_both = normalize(Vec3f(-0.3f, 0.0f, -1.0f));
        ASSERT_LT(dot(under_both, ns), 0.0f);
        EXPECT_TRUE(is_black(b.eval(under_both, pdf)));
    }
}

TEST(Microfacet, DistributionIsNormalised) {
    // integral of D(m) cos(m) dm = 1, by quadrature over the hemisphere.
    for (float alpha : {0.05f, 0.3f, 0.8f}) {
        Pcg32 rng(coherent::test::test_seed(13));
        double sum = 0.0;
        const int n = 400000;
        for (int i = 0; i < n; ++i) {
            const float z = rng.next_float();
            const float phi = 2.0f * kPi * rng.next_float();
            const float r = std::sqrt(1.0f - z * z);
            const Vec3f m{r * std::cos(phi), r * std::sin(phi), z};
            sum += ggx_d(m, alpha) * m.z * 2.0 * kPi;
        }
        EXPECT_NEAR(sum / n, 1.0, alpha < 0.1f ? 0.1 : 0.02) << alpha;
    }
}

// Upper quantile of the chi-square distribution with k degrees of freedom
// (Wilson-Hilferty; within 1 % of the exact value for k > 30).
double chi_square_quantile(int k, double z_upper) {
    const double a = 2.0 / (9.0 * k);
    const double c = 1.0 - a + z_upper * std::sqrt(a);
    return k * c * c * c;
}

// Pearson's chi-square test of ggx_sample_vndf against ggx_vndf_pdf: the
// hemisphere is cut into solid-angle bins (theta bins even in
// atan(tan(theta) / alpha), which spreads GGX's mass over all of them, times
// even phi bins); each bin's expected count is N times the pdf integrated over
// the bin (midpoint rule on a fine sub-grid, sin(theta) d theta d phi).
// Bins expecting fewer than 5 samples are pooled. Significance 1e-4 per case.
// The same integration also checks that the pdf integrates to 1.
TEST(Microfacet, VndfSamplesFollowTheirPdf) {
    constexpr int kTheta = 16, kPhi = 16, kSub = 12, kSamples = 400000;
    constexpr double kZUpper = 3.719;  // one-sided normal quantile at 1e-4
    int case_index = 0;
    for (float alpha : {0.1f, 0.35f, 0.8f}) {
        for (float theta_o : {0.0f, 0.8f, 1.45f}) {
            const Vec3f wo = dir_from_angle(theta_o);
            // theta(t) for t in [0, 1]: tan(theta) = alpha tan(t pi / 2).
            auto theta_at = [&](double t) { return std::atan(alpha * std::tan(std::min(t, 0.999999) * kPi / 2)); };
            std::vector<double> expected(kTheta * kPhi, 0.0);
            double pdf_total = 0.0;
            for (int i = 0; i < kTheta; ++i)
                for (int j = 0; j < kPhi; ++j) {
                    const double t0 = theta_at(double(i) / kTheta), t1 = theta_at(double(i + 1) / kTheta);
                    double p = 0.0;
                    for (int a = 0; a < kSub; ++a)
                        for (int b = 0; b < kSub; ++b) {
                            const double th = t0 + (t1 - t0) * (a + 0.5) / kSub;
                            const double ph = 2.0 * kPi * (j + (b + 0.5) / kSub) / kPhi;
                            const Vec3f m{float(std::sin(th) * std::cos(ph)), float(std::sin(th) * std::sin(ph)),
                                          float(std::cos(th))};
                            p += ggx_vndf_pdf(wo, m, alpha) * std::sin(th);
                        }
                    p *= (t1 - t0) / kSub * (2.0 * kPi / kPhi) / kSub;
                    expected[i * kPhi + j] = p;
                    pdf_total += p;
                }
            EXPECT_NEAR(pdf_total, 1.0, 5e-3) << "alpha " << alpha << " theta_o " << theta_o;

            std::vector<double> observed(kTheta * kPhi, 0.0);
            Pcg32 rng(coherent::test::test_seed(101 + case_index++));
            for (int n = 0; n < kSamples; ++n) {
                const Vec3f m = ggx_sample_vndf(wo, alpha, rng.next_float(), rng.next_float());
                const double th = std::acos(std::clamp(double(m.z), -1.0, 1.0));
                double ph = std::atan2(double(m.y), double(m.x));
                if (ph < 0.0) ph += 2.0 * kPi;
                const double t = std::atan(std::tan(th) / alpha) / (kPi / 2);
                const int i = std::clamp(int(t * kTheta), 0, kTheta - 1);
                const int j = std::clamp(int(ph / (2.0 * kPi) * kPhi), 0, kPhi - 1);
                observed[i * kPhi + j] += 1.0;
            }
            double chi2 = 0.0, pooled_e = 0.0, pooled_o = 0.0;
            int bins = 0;
            for (size_t k = 0; k < expected.size(); ++k) {
                const double e = expected[k] * kSamples;
                if (e < 5.0) {
                    pooled_e += e;
                    pooled_o += observed[k];
                    continue;
                }
                chi2 += (observed[k] - e) * (observed[k] - e) / e;
                ++bins;
            }
            if (pooled_e >= 5.0) {
                chi2 += (pooled_o - pooled_e) * (pooled_o - pooled_e) / pooled_e;
                ++bins;
            } else {
                EXPECT_LE(pooled_o, 20.0) << "samples where the pdf is (almost) zero";
            }
            ASSERT_GT(bins, 100);
            const double limit = chi_square_quantile(bins - 1, kZUpper);
            EXPECT_LT(chi2, limit) << "alpha " << alpha << " theta_o " << theta_o << ", " << bins << " bins";
            std::printf("[vndf] alpha %.2f theta_o %.2f: chi2 %.1f over %d bins (limit %.1f)\n", alpha, theta_o,
                        chi2, bins, limit);
        }
    }
}

}  // namespace
