// Sky Texture (shader/sky_model.h) and the sky world's sampling
// (shader/sky_world.h, render/world_sampling.h). Agreement with Cycles is
// tested pixel by pixel in tests/blender/test_sky.py; these tests check the
// properties that make the sky usable as a light: its importance sampling is
// unbiased with the sun disc sampled as a cone, and sample() and pdf() agree.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "core/random.h"
#include "render/world_sampling.h"
#include "shader/program.h"
#include "shader/sky_model.h"
#include "shader/sky_world.h"

using namespace coherent;

namespace {

SkyInputs nishita(float sun_size_deg) {
    SkyInputs in;
    in.type = SkyType::Nishita;
    in.sun_elevation = 0.5f;
    in.sun_rotation = 1.2f;
    in.sun_size = sun_size_deg * kPi / 180.0f;
    in.altitude = 500.0f;
    return in;
}

// A rotation about x by `a` (world -> sky frame).
void rotation_x(float a, float r[9]) {
    const float c = std::cos(a), s = std::sin(a);
    const float m[9] = {1, 0, 0, 0, c, -s, 0, s, c};
    std::copy(m, m + 9, r);
}

// Integral of luminance over the sphere: a fine midpoint rule for the sky
// without its disc, plus the disc integrated over its own cone (the disc is
// far smaller than the grid's cells, so it gets its own quadrature).
double reference_power(const SkyTexture& sky, const EnvironmentMap& map) {
    const int w = 2048, h = 1024;
    double sum = 0.0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const float v = (float(y) + 0.5f) / float(h);
            const Vec3f d = equirect_to_direction((float(x) + 0.5f) / float(w), v);
            sum += double(luminance(sky.eval(d, false))) * std::cos(kPi * (v - 0.5f));
        }
    sum *= 2.0 * kPi * kPi / (double(w) * double(h));
    Vec3f t, b;
    make_basis(map.sun_dir, t, b);
    const int rings = 200, sectors = 200;
    double disc = 0.0, behind = 0.0;
    for (int i = 0; i < rings; ++i)
        for (int j = 0; j < sectors; ++j) {
            const float omc = (float(i) + 0.5f) / float(rings) * map.sun_one_minus_cos;
            const float st = std::sqrt(omc * (2.0f - omc)), phi = 2.0f * kPi * (float(j) + 0.5f) / float(sectors);
            const Vec3f d = normalize((t * std::cos(phi) + b * std::sin(phi)) * st + map.sun_dir * (1.0f - omc));
            disc += double(luminance(sky.eval(d)));
            behind += double(luminance(sky.eval(d, false)));
        }
    // The disc replaces the sky behind it.
    return sum + (disc - behind) / double(rings * sectors) * 2.0 * kPi * double(map.sun_one_minus_cos);
}

}  // namespace

TEST(Sky, PackedEvaluationIsTheSame) {
    for (SkyType type : {SkyType::Preetham, SkyType::HosekWilkie, SkyType::Nishita}) {
        SkyInputs in = nishita(20.0f);
        in.type = type;
        in.sun_direction = Vec3f(0.2f, -0.4f, 0.5f);
        const SkyTexture sky = precompute_sky(in);
        const std::vector<float> packed = pack(sky);
        ASSERT_TRUE(packed_sky_valid(packed.data(), packed.size()));
        EXPECT_FALSE(packed_sky_valid(packed.data(), packed.size() - 1) && type == SkyType::Nishita);
        Pcg32 rng(7);
        for (int i = 0; i < 1000; ++i) {
            const Vec3f d = equirect_to_direction(rng.next_float(), rng.next_float());
            const Vec3f a = sky.eval(d), c = eval_packed_sky(packed.data(), d);
            ASSERT_TRUE(is_finite(a) && min_component(a) >= 0.0f);
            ASSERT_EQ(a.x, c.x);
            ASSERT_EQ(a.y, c.y);
            ASSERT_EQ(a.z, c.z);
        }
    }
}

TEST(Sky, NishitaSunIsBrightAndTheGroundFadesToBlack) {
    const SkyTexture sky = precompute_sky(nishita(0.545f));
    const float lon = sky.params.sun_rotation + 0.5f * kPi, el = sky.params.sun_elevation;
    const Vec3f sun{std::cos(el) * std::cos(lon), std::cos(el) * std::sin(lon), std::sin(el)};
    EXPECT_GT(luminance(sky.eval(sun)), 1000.0f * luminance(sky.eval(Vec3f(0.0f, 0.0f, 1.0f))));
    // Without its disc, the sky behind the sun is the (bright, but far dimmer) Mie glow.
    EXPECT_LT(100.0f * luminance(sky.eval(sun, false)), luminance(sky.eval(sun)));
    EXPECT_TRUE(is_black(sky.eval(normalize(Vec3f(0.3f, 0.1f, -0.9f)))));
}

TEST(Sky, SunSampledAsAConeKeepsTheWorldEstimateUnbiased) {
    auto sky = std::make_shared<SkyTexture>(precompute_sky(nishita(0.545f)));
    float r[9];
    rotation_x(0.3f, r);
    const EnvironmentMap map = make_sky_environment(sky, r, 256, 128);
    ASSERT_GT(map.sun_power, 0.0f);
    const EnvironmentSampler sampler(map);
    ASSERT_FALSE(sampler.empty());
    Pcg32 rng(11);
    const int n = 1 << 19;
    double sum = 0.0, sum_sq = 0.0;
    int in_sun = 0;
    for (int i = 0; i < n; ++i) {
        Vec3f d;
        float pdf;
        if (!sampler.sample(rng.next_float(), rng.next_float(), d, pdf)) continue;
        ASSERT_NEAR(pdf, sampler.pdf(d), 1e-4f * pdf);
        const double f = double(luminance(sampler.eval(d))) / double(pdf);
        sum += f;
        sum_sq += f * f;
        in_sun += 0.5f * length_squared(map.to_map(d) - map.sun_dir) <= map.sun_one_minus_cos ? 1 : 0;
    }
    const double mean = sum / n, sigma = std::sqrt((sum_sq / n - mean * mean) / n);
    const double reference = reference_power(*sky, map);
    EXPECT_NEAR(mean, reference, 4.0 * sigma + 2e-3 * reference) << "sigma " << sigma;
    // The sun carries most of the power here, and most samples go to it.
    EXPECT_GT(in_sun, n / 2);
}

TEST(Sky, ProgramValidationRejectsAMissingSkyTable) {
    ShaderProgram p;
    p.constants.assign(6, 0.0f);
    ShaderInstr in;
    in.op = ShaderOp::SkyTexture;
    in.in[0] = 0;
    in.out[0] = 3;
    in.data = 0;
    p.code.push_back(in);
    EXPECT_NE(p.validate(0, 0), "");
    const std::vector<float> packed = pack(precompute_sky(nishita(0.545f)));
    p.data = packed;
    EXPECT_EQ(p.validate(0, 0), "");
    p.data.resize(packed.size() - 3);
    EXPECT_NE(p.validate(0, 0), "");
}
