// The padded Owen-scrambled Sobol sequence (sample/owen_sobol.h) and the
// samplers built on it: net properties before and after scrambling, through
// the samplers' streams, uniformity of the scramble, unbiasedness of every
// sampler, the convergence slope on a smooth integrand, and the even/odd
// error estimate.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <vector>

#include "sample/coherent_samplers.h"
#include "sample/image_sampler.h"
#include "sample/owen_sobol.h"
#include "sample/sampler.h"
#include "test_render_helpers.h"

namespace coherent {
namespace {

// Whether the 2^m points (x, y) (32-bit fractions) form a (0,m,2)-net: every
// elementary interval of area 2^-m (2^k x 2^(m-k) boxes, all k) holds one.
bool is_02_net(const std::vector<std::pair<uint32_t, uint32_t>>& pts, uint32_t m) {
    for (uint32_t k = 0; k <= m; ++k) {
        std::vector<int> count(size_t(1) << m, 0);
        for (const auto& [x, y] : pts) {
            const uint32_t cx = k ? x >> (32 - k) : 0, cy = m - k ? y >> (32 - (m - k)) : 0;
            if (++count[(size_t(cx) << (m - k)) | cy] > 1) return false;
        }
    }
    return true;
}

using Point2 = std::function<std::pair<uint32_t, uint32_t>(uint32_t index)>;

// The first 2^m points, and aligned blocks of 2^m further on, are nets.
void expect_02_sequence(const Point2& point, const char* what, uint32_t max_m = 10) {
    for (uint32_t m = 0; m <= max_m; ++m)
        for (uint32_t block : {0u, 1u, 5u, 77u}) {
            std::vector<std::pair<uint32_t, uint32_t>> pts;
            for (uint32_t i = 0; i < (1u << m); ++i) pts.push_back(point((block << m) + i));
            ASSERT_TRUE(is_02_net(pts, m)) << what << ": m " << m << " block " << block;
        }
}

uint32_t to_u32(float v) { return uint32_t(double(v) * 4294967296.0); }

TEST(Sobol, FirstComponentIsVanDerCorputAndMatricesAreKnown) {
    for (uint32_t i : {0u, 1u, 2u, 3u, 6u, 1000u}) EXPECT_EQ(sobol_u32(i, 0), reverse_bits32(i));
    // Second dimension (x + 1, direction numbers 1/2, 3/4, 5/8): points 1..5
    // are 1/2, 3/4, 1/2 ^ 3/4 = 1/4, 5/8, 1/2 ^ 5/8 = 1/8 (XOR of binary fractions).
    const double expect[] = {0.0, 0.5, 0.75, 0.25, 0.625, 0.125};
    for (uint32_t i = 0; i < 6; ++i) EXPECT_EQ(sobol_u32(i, 1) * 0x1p-32, expect[i]) << i;
}

// The four-lane set draw that streams use is the scalar definition, bit for bit.
TEST(Sobol, FourLaneSetDrawEqualsTheScalarComponents) {
    uint32_t state = 12345u;
    for (int k = 0; k < 20000; ++k) {
        state = state * 1664525u + 1013904223u;
        const uint32_t seed = state ^ (state >> 7) * 0x9e3779b9u;
        state = state * 1664525u + 1013904223u;
        const uint32_t index = (k < 64 ? uint32_t(k) : state) & 0xffffffu;
        const uint32_t shuffled = shuffle_reversed_index(reverse_bits32(index), seed);
        float lanes[4];
        owen_sobol_set4(shuffled, seed, lanes);
        for (uint32_t c = 0; c < 4; ++c)
            ASSERT_EQ(lanes[c], float(owen_sobol_shuffled(shuffled, c, seed) >> 8) * 0x1p-24f)
                << "index " << index << " seed " << seed << " component " << c;
    }
}

// Whether the 2^m values (32-bit fractions) put one value in each [i/2^m, (i+1)/2^m).
bool is_stratified_1d(const std::vector<uint32_t>& v, uint32_t m) {
    std::vector<int> count(size_t(1) << m, 0);
    for (uint32_t x : v)
        if (++count[m ? x >> (32 - m) : 0] > 1) return false;
    return true;
}

void expect_01_sequence(const std::function<uint32_t(uint32_t)>& value, const char* what, uint32_t max_m = 10) {
    for (uint32_t m = 0; m <= max_m; ++m)
        for (uint32_t block : {0u, 1u, 5u, 77u}) {
            std::vector<uint32_t> v;
            for (uint32_t i = 0; i < (1u << m); ++i) v.push_back(value((block << m) + i));
            ASSERT_TRUE(is_stratified_1d(v, m)) << what << ": m " << m << " block " << block;
        }
}

TEST(Sobol, ComponentsZeroAndOneAreAZeroTwoSequenceBeforeAndAfterScrambling) {
    expect_02_sequence([](uint32_t i) { return std::pair{sobol_u32(i, 0), sobol_u32(i, 1)}; }, "sobol");
    for (uint32_t seed : {0u, 1u, 0xdeadbeefu})
        expect_02_sequence([seed](uint32_t i) { return std::pair{owen_sobol_u32(i, 0, seed), owen_sobol_u32(i, 1, seed)}; },
                           "owen sobol");
    // Every component is stratified in 1D (what 1D decisions rely on)...
    for (uint32_t c = 0; c < 4; ++c) {
        expect_01_sequence([c](uint32_t i) { return sobol_u32(i, c); }, "sobol 1D");
        expect_01_sequence([c](uint32_t i) { return owen_sobol_u32(i, c, 12345u); }, "owen sobol 1D");
    }
    // ...but no other pair is (0,2): why 2D decisions read components 0 and 1 only.
    for (uint32_t a = 0; a < 4; ++a)
        for (uint32_t b = a + 1; b < 4; ++b) {
            if (a == 0 && b == 1) continue;
            bool all_nets = true;
            for (uint32_t m = 1; m <= 6; ++m) {
                std::vector<std::pair<uint32_t, uint32_t>> pts;
                for (uint32_t i = 0; i < (1u << m); ++i) pts.push_back({sobol_u32(i, a), sobol_u32(i, b)});
                all_nets = all_nets && is_02_net(pts, m);
            }
            EXPECT_FALSE(all_nets) << a << "," << b;
        }
}

TEST(Sobol, ScrambleIsUniformPerPointAndDiffersPerSeed) {
    // Owen scrambling makes each point uniform over seeds (unbiasedness):
    // chi-square of 64 bins over 16384 seeds, 63 dof (mean 63, sd 11.2).
    for (uint32_t index : {0u, 3u, 1000u})
        for (uint32_t c = 0; c < 4; ++c) {
            std::vector<int> bins(64, 0);
            const int n = 16384;
            for (int s = 0; s < n; ++s) ++bins[owen_sobol_u32(index, c, uint32_t(s) * 2654435761u) >> 26];
            double chi2 = 0.0;
            for (int b : bins) chi2 += (b - n / 64.0) * (b - n / 64.0) / (n / 64.0);
            EXPECT_LT(chi2, 63.0 + 5 * 11.2) << "index " << index << " component " << c;
        }
}

// Sample `k`'s values for two dimensions of one pixel's stream.
template <class S>
std::pair<uint32_t, uint32_t> stream_pair(const S& s, uint32_t px, uint32_t py, uint32_t k, uint32_t dx, uint32_t dy) {
    const SampleStream st = s.stream(px, py, k);
    return {to_u32(st.get(dx)), to_u32(st.get(dy))};
}

TEST(Sobol, EachPixelsEvenAndOddSamplesAreNetsInEveryTwoDimensionalDecision) {
    // Pairs the integrators read as 2D points.
    using D = PathDims;
    const std::pair<uint32_t, uint32_t> decisions[] = {{D::kPixelX, D::kPixelY},
                                                       {D::kLensU, D::kLensV},
                                                       {D::bounce(0, D::kLightU), D::bounce(0, D::kLightV)},
                                                       {D::bounce(0, D::kBsdfU), D::bounce(0, D::kBsdfV)},
                                                       {D::bounce(3, D::kLightU), D::bounce(3, D::kLightV)},
                                                       {D::bounce(5, D::kBsdfU), D::bounce(5, D::kBsdfV)}};
    const uint32_t one_d[] = {D::kTime, D::bounce(0, D::kLightPick), D::bounce(2, D::kBsdfLobe),
                              D::bounce(4, D::kRoulette)};
    const SptSampler spt(7);
    const CptSampler cpt(7);
    for (uint32_t parity : {0u, 1u}) {
        // Sample 2i + parity is point i of the parity's sequence (floats
        // keep 24 bits, plenty for nets of up to 2^8 points).
        for (const auto& [dx, dy] : decisions) {
            expect_02_sequence([&](uint32_t i) { return stream_pair(spt, 3, 4, 2 * i + parity, dx, dy); }, "spt", 8);
            // CPT: the packet's shared sequence is a net for each of its pixels
            // (the pixels read identical numbers).
            expect_02_sequence([&](uint32_t i) { return stream_pair(cpt, 2, 1, 2 * i + parity, dx, dy); }, "cpt", 8);
            for (uint32_t i = 0; i < 16; ++i)
                ASSERT_EQ(stream_pair(cpt, 2, 1, i, dx, dy), stream_pair(cpt, 0, 3, i, dx, dy));
        }
        for (uint32_t d : one_d)
            expect_01_sequence([&](uint32_t i) { return to_u32(spt.stream(3, 4, 2 * i + parity).get(d)); }, "spt 1D", 8);
    }
    // Different pixels (SPT) and different parities draw different scrambles.
    EXPECT_NE(stream_pair(spt, 3, 4, 0, 4, 5), stream_pair(spt, 4, 4, 0, 4, 5));
    EXPECT_NE(stream_pair(spt, 3, 4, 0, 4, 5), stream_pair(spt, 3, 4, 1, 4, 5));
}

TEST(Sobol, SetsOfDifferentDecisionsAreUncorrelated) {
    // Padding: each decision's set is shuffled independently, so two sets
    // read at the same sample index are uncorrelated (a shared index without
    // shuffle would give identical values).
    const SptSampler spt(3);
    const int n = 1 << 14;
    double sxy = 0.0;
    for (int k = 0; k < n; ++k) {
        const SampleStream st = spt.stream(5, 5, uint32_t(k));
        sxy += (st.get(PathDims::bounce(0, PathDims::kBsdfU)) - 0.5) * (st.get(PathDims::bounce(1, PathDims::kBsdfU)) - 0.5);
    }
    // Correlation sd ~ 1/sqrt(n) = 0.008.
    EXPECT_NEAR(sxy / n * 12.0, 0.0, 0.04);
}

// ---- Renders -------------------------------------------------------------

// A diffuse plane under one square area light, seen from above by an
// orthographic camera: direct light only, a smooth integrand in every pixel.
Scene lit_plane_scene() {
    Scene s;
    const uint32_t white = s.add_material(test::diffuse_material(Vec3f(0.8f)));
    const uint32_t light = s.add_material(test::emission_material(Vec3f(5.0f)));
    test::add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 8.0f, 8.0f, white, "plane");
    test::add_quad(s, {0.7f, 0.4f, 2.0f}, {0, 1, 0}, {1, 0, 0}, 1.5f, 1.5f, light, "light");  // faces -z
    s.camera = test::ortho_camera_looking_down(1.5f, 2.0f);
    s.world_color = Vec3f(0.0f);
    s.finalize();
    return s;
}

RenderSettings settings(int res, int spp, SamplerType sampler, uint64_t seed, int max_bounces) {
    RenderSettings rs;
    rs.width = rs.height = res;
    rs.spp = spp;
    rs.sampler = sampler;
    rs.pattern = SampleSequence::OwenSobol;
    rs.error_estimate = ErrorEstimate::Exact;  // paired scrambles: what these tests measure
    rs.seed = seed;
    rs.max_bounces = max_bounces;
    rs.threads = 2;
    return rs;
}

double rmse(const std::vector<float>& a, const std::vector<float>& b) {
    double e2 = 0.0;
    size_t n = 0;
    for (size_t i = 0; i < a.size(); i += 4)
        for (int c = 0; c < 3; ++c, ++n) e2 += (double(a[i + c]) - b[i + c]) * (double(a[i + c]) - b[i + c]);
    return std::sqrt(e2 / double(n));
}

TEST(SobolRender, RmseFallsFasterThanWhiteNoiseOnASmoothIntegrand) {
    // Log-log slope of RMSE against spp, least squares over 4..256 spp, RMSE
    // over 6 seeds against a 4096-spp reference. White noise gives -0.5.
    const Scene scene = lit_plane_scene();
    constexpr int kRes = 16;
    const auto reference = test::render_combined(scene, settings(kRes, 4096, SamplerType::Spt, 999, 0));
    for (SamplerType st : {SamplerType::Spt, SamplerType::Cpt, SamplerType::Icpt}) {
        std::vector<double> xs, ys;
        for (int spp : {4, 16, 64, 256}) {
            double e2 = 0.0;
            constexpr int kSeeds = 6;
            for (int seed = 0; seed < kSeeds; ++seed) {
                const double e = rmse(test::render_combined(scene, settings(kRes, spp, st, 10 + seed, 0)), reference);
                e2 += e * e;
            }
            xs.push_back(std::log(double(spp)));
            ys.push_back(0.5 * std::log(e2 / kSeeds));
        }
        double mx = 0, my = 0;
        for (size_t i = 0; i < xs.size(); ++i) mx += xs[i] / xs.size(), my += ys[i] / ys.size();
        double sxy = 0, sxx = 0;
        for (size_t i = 0; i < xs.size(); ++i) sxy += (xs[i] - mx) * (ys[i] - my), sxx += (xs[i] - mx) * (xs[i] - mx);
        const double slope = sxy / sxx;
        std::printf("[sobol slope] %s: RMSE ~ spp^%.3f (4..256 spp)\n", sampler_type_name(st).data(), slope);
        if (st != SamplerType::Icpt) {
            EXPECT_LT(slope, -0.6) << sampler_type_name(st);
        } else {
            EXPECT_LT(slope, -0.4);  // ICPT mixes sequences per pixel: at least white noise's rate
        }
    }
}

TEST(SobolRender, EverySamplerIsUnbiased) {
    // Mean over seeds of low-spp renders against a high-spp reference, both
    // with their standard errors from the spread over seeds; 3 sigma. Image
    // means and four quadrant means (indirect light, soft shadows).
    const Scene scene = test::sphere_on_floor_scene();
    constexpr int kRes = 16;
    auto region_means = [](const std::vector<float>& img) {
        std::vector<double> m(5, 0.0);
        for (int y = 0; y < kRes; ++y)
            for (int x = 0; x < kRes; ++x) {
                const size_t i = 4 * size_t(y * kRes + x);
                const double v = (img[i] + img[i + 1] + img[i + 2]) / 3.0;
                m[0] += v / (kRes * kRes);
                m[1 + (y >= kRes / 2) * 2 + (x >= kRes / 2)] += v / (kRes * kRes / 4);
            }
        return m;
    };
    auto seeded_means = [&](SamplerType st, int spp, int seeds, uint64_t base) {
        std::vector<std::vector<double>> per_region(5);
        for (int s = 0; s < seeds; ++s) {
            const auto m = region_means(test::render_combined(scene, settings(kRes, spp, st, base + s, 4)));
            for (int r = 0; r < 5; ++r) per_region[r].push_back(m[r]);
        }
        std::vector<test::MeanVar> out;
        for (const auto& v : per_region) out.push_back(test::mean_var(v));
        return out;
    };
    const auto ref = seeded_means(SamplerType::Spt, 256, 8, 5000);
    for (SamplerType st : {SamplerType::Spt, SamplerType::Cpt, SamplerType::Icpt}) {
        const auto got = seeded_means(st, 8, 48, 100);
        for (int r = 0; r < 5; ++r) {
            const double sigma = std::hypot(got[r].stderr_of_mean(), ref[r].stderr_of_mean());
            EXPECT_LT(std::fabs(got[r].mean - ref[r].mean), 3.0 * sigma)
                << sampler_type_name(st) << " region " << r << ": " << got[r].mean << " vs " << ref[r].mean;
        }
    }
}

TEST(SobolRender, EvenOddErrorEstimateTracksTrueError) {
    // The even and odd passes come from independently scrambled sequences,
    // so the half-image difference estimates the error honestly: within 25 %
    // of the true error (as a root mean square over seeds), for every sampler.
    const Scene scene = test::sphere_on_floor_scene();
    constexpr int kRes = 32;
    Renderer ref(scene, settings(kRes, 2048, SamplerType::Spt, 4321, 4));
    ASSERT_TRUE(ref.render());
    const auto reference = ref.film().resolve(PassType::Combined);
    const double ref_err = ref.film().relative_rmse_estimate();
    for (SamplerType st : {SamplerType::Spt, SamplerType::Cpt, SamplerType::Icpt})
        for (int spp : {16, 64}) {
            double est2 = 0.0, true2 = 0.0;
            constexpr int kSeeds = 8;
            for (int seed = 0; seed < kSeeds; ++seed) {
                Renderer r(scene, settings(kRes, spp, st, 31 + 17 * uint64_t(seed), 4));
                ASSERT_TRUE(r.render());
                const auto img = r.film().resolve(PassType::Combined);
                const double rel = rmse(img, reference) / test::image_mean(reference);
                est2 += r.film().relative_rmse_estimate() * r.film().relative_rmse_estimate();
                true2 += rel * rel - ref_err * ref_err;
            }
            const double ratio = std::sqrt(est2 / std::max(true2, 1e-30));
            std::printf("[sobol error estimate] %s %d spp: estimate/true %.3f\n", sampler_type_name(st).data(), spp,
                        ratio);
            EXPECT_NEAR(ratio, 1.0, 0.25) << sampler_type_name(st) << " " << spp << " spp";
        }
}

}  // namespace
}  // namespace coherent
