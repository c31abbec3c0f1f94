// Statistical tests of SPT / CPT / ICPT through the whole renderer on the
// generated Cornell box (tests/fixtures/make_gltf.py):
//  * unbiasedness: the mean over many independent renders (different seeds)
//    of CPT and ICPT agrees with SPT's, pixel by pixel and over a region,
//    within 4 standard errors estimated from the sample variances;
//  * structure: CPT's per-pixel errors are strongly correlated between
//    horizontal neighbours in a packet, ICPT's are not (they lie in one row,
//    so always in different Latin-hypercube subsets), SPT's are ~0, while
//    ICPT still correlates diagonal neighbours that share a subset.
// Thresholds were chosen from measurements (quoted next to each) with margin.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <utility>
#include <set>
#include <string>
#include <vector>

#include "render/renderer.h"
#include "sample/coherent_samplers.h"
#include "test_fixtures.h"
#include "test_render_helpers.h"

using namespace coherent;
using namespace coherent::test;

namespace {

struct Region {
    int x0, y0, x1, y1;
    int width() const { return x1 - x0; }
    int height() const { return y1 - y0; }
};

class SamplerStats : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        scene_ = new Scene();
        ASSERT_TRUE(load_fixture("cornell_box.glb", *scene_));
        scene_->finalize();
    }
    static void TearDownTestSuite() {
        delete scene_;
        scene_ = nullptr;
    }

    // Luminance (mean of RGB) of the pixels of `r` in a 64x64 frame.
    static std::vector<double> render(SamplerType type, uint64_t seed, int spp, const Region& r,
                                      SequenceScope scope = SequenceScope::Packet) {
        RenderSettings rs;
        rs.width = rs.height = 64;
        rs.border_x0 = r.x0;
        rs.border_y0 = r.y0;
        rs.border_x1 = r.x1;
        rs.border_y1 = r.y1;
        rs.spp = spp;
        rs.seed = seed;
        rs.sampler = type;
        rs.sequence_scope = scope;
        rs.max_bounces = 4;
        rs.threads = 2;
        const std::vector<float> rgba = render_combined(*scene_, rs);
        std::vector<double> lum(rgba.size() / 4);
        for (size_t i = 0; i < lum.size(); ++i) lum[i] = (double(rgba[4 * i]) + rgba[4 * i + 1] + rgba[4 * i + 2]) / 3.0;
        return lum;
    }

    static Scene* scene_;
};

Scene* SamplerStats::scene_ = nullptr;

// Correlation of e(x, y) and e(x + dx, y + dy) over pairs within the same
// 4x4 packet, pooled over several error images.
// The errors are winsorised at the 99th percentile of |e| first: the glossy
// Cornell box has rare fireflies (errors 30x the typical one) that would
// otherwise decide the coefficient on their own (measured on the Lambert-
// diffuse version of this scene: plain Pearson gave CPT 0.22, 0.82 after
// winsorising, on the same renders).
// across_packets = true: pairs that straddle a packet column boundary instead.
double neighbour_correlation(const std::vector<std::vector<double>>& errors, int w, int h, int dx, int dy,
                             bool across_packets = false) {
    std::vector<double> mags;
    for (const auto& e : errors)
        for (double v : e) mags.push_back(std::fabs(v));
    std::nth_element(mags.begin(), mags.begin() + mags.size() * 99 / 100, mags.end());
    const double q = mags[mags.size() * 99 / 100];
    double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
    size_t n = 0;
    for (const auto& e : errors)
        for (int y = 0; y + dy < h; ++y)
            for (int x = 0; x + dx < w; ++x) {
                if ((x % 4 + dx >= 4) != across_packets || y % 4 + dy >= 4) continue;
                const double a = std::clamp(e[size_t(y) * w + x], -q, q);
                const double b = std::clamp(e[size_t(y + dy) * w + x + dx], -q, q);
                sa += a, sb += b, saa += a * a, sbb += b * b, sab += a * b;
                ++n;
            }
    const double ma = sa / n, mb = sb / n;
    const double cov = sab / n - ma * mb, va = saa / n - ma * ma, vb = sbb / n - mb * mb;
    return cov / std::sqrt(va * vb);
}

}  // namespace

TEST_F(SamplerStats, CptAndIcptAreUnbiasedAgainstSpt) {
    // An 8x8 region on the tall block's top edge and the back wall behind it
    // (frame 64x64), aligned with the 4x4 packets.
    const Region r{24, 24, 32, 32};
    const int renders = 300, spp = 4;
    const size_t pixels = size_t(r.width()) * r.height();
    constexpr int kVariants = 5;
    std::vector<std::vector<double>> per_pixel[kVariants];  // [variant][pixel][render]
    std::vector<double> region_mean[kVariants];
    const SamplerType types[kVariants] = {SamplerType::Spt, SamplerType::Cpt, SamplerType::Icpt, SamplerType::Cpt,
                                          SamplerType::Icpt};
    const SequenceScope scopes[kVariants] = {SequenceScope::Packet, SequenceScope::Packet, SequenceScope::Packet,
                                             SequenceScope::Image, SequenceScope::Image};
    for (int t = 0; t < kVariants; ++t) {
        per_pixel[t].assign(pixels, {});
        for (int k = 0; k < renders; ++k) {
            // Disjoint seeds per sampler: the three estimates are independent.
            const auto lum = render(types[t], uint64_t(1 + k + 100000 * t), spp, r, scopes[t]);
            double sum = 0;
            for (size_t i = 0; i < pixels; ++i) {
                per_pixel[t][i].push_back(lum[i]);
                sum += lum[i];
            }
            region_mean[t].push_back(sum / double(pixels));
        }
    }
    const MeanVar spt_region = mean_var(region_mean[0]);
    ASSERT_GT(spt_region.mean, 0.01);  // the region is lit
    for (int t = 1; t < kVariants; ++t) {
        const std::string name =
            std::string(sampler_type_name(types[t])) + "/" + std::string(sequence_scope_name(scopes[t]));
        // Whole region: for CPT the pixels' errors are correlated, so the
        // spread over renders (not over pixels) is the honest standard error.
        const MeanVar m = mean_var(region_mean[t]);
        const double se = std::sqrt(m.var / m.n + spt_region.var / spt_region.n);
        EXPECT_LT(std::fabs(m.mean - spt_region.mean), 4.0 * se)
            << name << " region mean " << m.mean << " vs SPT " << spt_region.mean << " (se " << se << ")";
        // Every pixel on its own.
        int failures = 0;
        double worst = 0;
        for (size_t i = 0; i < pixels; ++i) {
            const MeanVar a = mean_var(per_pixel[t][i]), b = mean_var(per_pixel[0][i]);
            const double s = std::sqrt(a.var / a.n + b.var / b.n);
            const double z = s > 0 ? std::fabs(a.mean - b.mean) / s : 0.0;
            worst = std::max(worst, z);
            if (z > 4.0) ++failures;
        }
        EXPECT_EQ(failures, 0) << name << ": worst pixel at " << worst << " standard errors";
    }
}

TEST_F(SamplerStats, CptNoiseIsStructuredAndIcptBreaksItUp) {
    const Region r{8, 16, 32, 48};  // 24x32 pixels: the tall block, red wall, back wall, floor
    const int w = r.width(), h = r.height();
    const std::vector<double> reference = render(SamplerType::Spt, 777, 1024, r);
    auto errors_of = [&](SamplerType t, SequenceScope scope = SequenceScope::Packet) {
        std::vector<std::vector<double>> errors;
        for (uint64_t seed = 1; seed <= 12; ++seed) {
            auto lum = render(t, seed, 4, r, scope);
            for (size_t i = 0; i < lum.size(); ++i) lum[i] -= reference[i];
            errors.push_back(std::move(lum));
        }
        return errors;
    };
    const auto spt = errors_of(SamplerType::Spt), cpt = errors_of(SamplerType::Cpt), icpt = errors_of(SamplerType::Icpt);
    const double c_spt = neighbour_correlation(spt, w, h, 1, 0);
    const double c_cpt = neighbour_correlation(cpt, w, h, 1, 0);
    const double c_icpt = neighbour_correlation(icpt, w, h, 1, 0);
    const double d_cpt = neighbour_correlation(cpt, w, h, 1, 1);
    const double d_icpt = neighbour_correlation(icpt, w, h, 1, 1);
    RecordProperty("corr_spt", std::to_string(c_spt));
    RecordProperty("corr_cpt", std::to_string(c_cpt));
    RecordProperty("corr_icpt", std::to_string(c_icpt));
    std::printf("horizontal error correlation: SPT %+.3f CPT %+.3f ICPT %+.3f; diagonal: CPT %+.3f ICPT %+.3f\n", c_spt,
                c_cpt, c_icpt, d_cpt, d_icpt);
    // Measured (this region, seeds 1-12, packet scope): SPT -0.018, CPT +0.544, ICPT +0.016.
    EXPECT_GT(c_cpt, 0.4);
    EXPECT_LT(c_icpt, 0.5 * c_cpt);
    EXPECT_LT(std::fabs(c_icpt), 0.15);
    EXPECT_LT(std::fabs(c_spt), 0.15);
    // Diagonal neighbours of a block share an ICPT subset in some of the
    // random Latin squares, so part of the structure remains there.
    // For a uniformly random Latin square of order 4 the probability is
    // exactly 1/3. Measured with uniform light selection: CPT +0.462, ICPT
    // +0.179 (0.39 of CPT); with selection by power and Sobol samples CPT's
    // diagonal structure is weaker, CPT +0.254, ICPT +0.153 (0.60), which sat
    // on the old 0.6 bound. ICPT must still remove a clear share of it.
    EXPECT_GT(d_icpt, 0.1 * d_cpt);
    EXPECT_LT(d_icpt, 0.75 * d_cpt);

    // Image-wide sequences: the same structure within a packet, and CPT's
    // errors are also correlated across packet boundaries (x mod 4 == 3).
    // Measured: CPT +0.615, ICPT -0.014; across edges CPT packet -0.019, image +0.727
    // with uniform light selection; +0.42 with selection by power, where the
    // image-wide shared choice of light no longer dominates the error.
    const auto cpt_image = errors_of(SamplerType::Cpt, SequenceScope::Image);
    const auto icpt_image = errors_of(SamplerType::Icpt, SequenceScope::Image);
    const double c_cpt_image = neighbour_correlation(cpt_image, w, h, 1, 0);
    const double c_icpt_image = neighbour_correlation(icpt_image, w, h, 1, 0);
    const double across_cpt = neighbour_correlation(cpt, w, h, 1, 0, true);
    const double across_cpt_image = neighbour_correlation(cpt_image, w, h, 1, 0, true);
    std::printf("image scope: CPT %+.3f ICPT %+.3f; across packet edges: CPT packet %+.3f, CPT image %+.3f\n",
                c_cpt_image, c_icpt_image, across_cpt, across_cpt_image);
    EXPECT_GT(c_cpt_image, 0.4);
    EXPECT_LT(std::fabs(c_icpt_image), 0.15);
    EXPECT_LT(std::fabs(across_cpt), 0.15);  // independent packets
    EXPECT_GT(across_cpt_image, 0.3);
}

TEST_F(SamplerStats, CoherentSamplersAreDeterministicAcrossThreadCounts) {
    for (SamplerType t : {SamplerType::Cpt, SamplerType::Icpt})
    for (SequenceScope scope : {SequenceScope::Packet, SequenceScope::Image}) {
        RenderSettings rs;
        rs.sequence_scope = scope;
        rs.width = rs.height = 24;
        rs.spp = 3;
        rs.seed = 5;
        rs.sampler = t;
        rs.tile_size = 7;
        rs.threads = 1;
        const auto a = render_combined(*scene_, rs);
        rs.threads = 2;
        rs.tile_size = 16;
        const auto b = render_combined(*scene_, rs);
        EXPECT_EQ(a, b) << sampler_type_name(t);
    }
}

// End to end: on a translation-invariant scene (an orthographic camera over a
// huge uniform diffuse plane, lit by a constant world), a path's value
// depends only on the random numbers it consumes. If every decision (pixel
// jitter, light choice, light sample, lobe, direction, roulette, at every
// bounce) reads the sampler at a pixel-independent dimension, CPT gives every
// pixel exactly the same value in a 1-spp render, and ICPT gives the same
// value to the pixels of one Latin-hypercube subset.
TEST(SamplerPaths, SharedSequencesGiveSharedPathsOnAUniformPlane) {
    Scene s;
    Material mat = diffuse_material(Vec3f(0.7f), "glossy");
    mat.closures[0].specular = 0.5f;  // a diffuse and a glossy lobe: the lobe choice is random too
    mat.closures[0].roughness = 0.4f;
    const uint32_t m = s.add_material(mat);
    add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1000.0f, 1000.0f, m);
    // Two translation-invariant lights to choose between: a soft sun and the world.
    Light sun;
    sun.type = LightType::Sun;
    sun.direction = normalize(Vec3f(0.3f, 0.2f, -1.0f));
    sun.power = 3.0f;
    sun.sun_angle = 0.3f;
    s.lights.push_back(sun);
    s.world_color = Vec3f(0.5f);
    s.camera = ortho_camera_looking_down(1.0f, 1.0f);
    s.finalize();
    RenderSettings rs;
    rs.width = rs.height = 16;
    rs.spp = 1;
    rs.seed = 3;
    rs.max_bounces = 8;
    rs.rr_min_bounces = 0;  // roulette from the first bounce: its dimension must be shared too
    rs.threads = 2;
    auto lum = [](const std::vector<float>& rgba, size_t i) { return rgba[4 * i] + rgba[4 * i + 1] + rgba[4 * i + 2]; };
    auto spread = [&](const std::vector<float>& rgba, const std::vector<size_t>& pixels) {
        float lo = 1e30f, hi = -1e30f;
        for (size_t i : pixels) lo = std::min(lo, lum(rgba, i)), hi = std::max(hi, lum(rgba, i));
        return hi - lo;
    };
    std::vector<size_t> all(256);
    for (size_t i = 0; i < all.size(); ++i) all[i] = i;

    rs.sampler = SamplerType::Spt;
    const auto spt = render_combined(s, rs);
    EXPECT_GT(spread(spt, all), 0.1f);  // independent paths differ

    // Pixels that share a sequence (same key) must have identical values;
    // different sequences give (almost surely) different values.
    auto check_groups = [&](SamplerType t, SequenceScope scope, auto key_of) {
        rs.sampler = t;
        rs.sequence_scope = scope;
        const auto img = render_combined(s, rs);
        std::map<std::pair<uint64_t, uint32_t>, std::vector<size_t>> groups;
        for (uint32_t y = 0; y < 16; ++y)
            for (uint32_t x = 0; x < 16; ++x) groups[key_of(x, y)].push_back(size_t(y) * 16 + x);
        std::set<int> distinct;
        float worst = 0.0f;
        for (const auto& [key, pixels] : groups) {
            worst = std::max(worst, spread(img, pixels) / lum(img, pixels[0]));
            distinct.insert(int(std::lround(lum(img, pixels[0]) * 1e4f)));
        }
        EXPECT_LT(worst, 1e-4f) << sampler_type_name(t) << "/" << sequence_scope_name(scope);
        EXPECT_GE(distinct.size() * 10, groups.size() * 9) << sampler_type_name(t) << "/" << sequence_scope_name(scope);
        return std::pair{groups.size(), worst};
    };
    for (SequenceScope scope : {SequenceScope::Image, SequenceScope::Packet}) {
        const CptSampler cpt(rs.seed, PathDims::count(rs.max_bounces), 0, 0, scope, 4, 4);
        const auto [cpt_groups, cpt_worst] =
            check_groups(SamplerType::Cpt, scope, [&](uint32_t x, uint32_t y) { return std::pair{cpt.region(x, y), 0u}; });
        const IcptSampler icpt(rs.seed, 4, PathDims::count(rs.max_bounces), 0, 0, scope);
        const auto [icpt_groups, icpt_worst] = check_groups(SamplerType::Icpt, scope, [&](uint32_t x, uint32_t y) {
            return std::pair{icpt.region(x, y), icpt.subset(x, y, 0)};
        });
        // Image: 1 CPT sequence, 4 ICPT ones; Packet: 16 packets, 4 regions x 4 subsets.
        EXPECT_EQ(cpt_groups, scope == SequenceScope::Image ? 1u : 16u);
        EXPECT_EQ(icpt_groups, scope == SequenceScope::Image ? 4u : 16u);
        std::printf("%s: %zu CPT groups (worst spread %.1e), %zu ICPT groups (%.1e)\n",
                    sequence_scope_name(scope).data(), cpt_groups, cpt_worst, icpt_groups, icpt_worst);
    }
    std::printf("spread of SPT pixel values: %.4f\n", spread(spt, all));
}
