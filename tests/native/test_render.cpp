// Renderer tests: energy conservation (white furnace), ray types per scene
// features, self-intersection at every scene scale, NaN guard, passes,
// render border, determinism, progress and cancellation.
#include <gtest/gtest.h>

#include <condition_variable>
#include <cstdio>
#include <cmath>
#include <limits>
#include <mutex>
#include <thread>

#include "render/renderer.h"
#include "test_render_helpers.h"

using namespace coherent;
using namespace coherent::test;

namespace {

RenderSettings furnace_settings(int size, int spp) {
    RenderSettings rs;
    rs.width = rs.height = size;
    rs.spp = spp;
    rs.max_bounces = 128;
    rs.diffuse_bounces = 128;
    rs.glossy_bounces = 128;
    rs.transmission_bounces = 128;
    rs.threads = 2;
    return rs;
}

// Mean of the red channel over pixels whose first hit is geometry, with its
// standard error computed from the per-pixel spread.
MeanVar furnace_mean(const Scene& scene, const RenderSettings& rs, RenderStats* stats = nullptr) {
    Renderer r(scene, rs);
    EXPECT_TRUE(r.render());
    if (stats) *stats = r.stats();
    const auto rgba = r.film().resolve(PassType::Combined);
    const auto depth = r.film().resolve(PassType::Depth);
    std::vector<double> values;
    for (size_t i = 0; i < depth.size(); ++i)
        if (depth[i] < 1e9f) values.push_back(rgba[4 * i]);
    EXPECT_GT(values.size(), depth.size() / 4);
    return mean_var(values);
}

Scene furnace_scene(const Material& m) {
    Scene s;
    const uint32_t id = s.add_material(m);
    add_sphere(s, {0, 0, 0}, 1.0f, id);
    s.world_color = Vec3f(1.0f);
    s.camera = perspective_camera({0, 0, 4}, {0, 0, 0}, 0.3f);
    s.finalize();
    return s;
}


TEST(RenderFurnace, WhiteDiffuseSphereReturnsOne) {
    const Scene s = furnace_scene(principled(1.0f, 0.0f, 0.5f, 0.0f, 0.0f));
    const MeanVar mv = furnace_mean(s, furnace_settings(32, 16));
    EXPECT_NEAR(mv.mean, 1.0, 4.0 * mv.stderr_of_mean() + 0.005) << "stderr " << mv.stderr_of_mean();
}

TEST(RenderFurnace, WhiteRoughMetalSphereIsNearOneWithoutGain) {
    const Scene s = furnace_scene(principled(1.0f, 1.0f, 0.5f, 0.5f, 0.0f));
    const MeanVar mv = furnace_mean(s, furnace_settings(32, 16));
    // Single-scattering GGX loses energy at grazing angles, never gains.
    EXPECT_LT(mv.mean, 1.0 + 4.0 * mv.stderr_of_mean());
    EXPECT_GT(mv.mean, 0.85);
}

TEST(RenderFurnace, SmoothGlassSphereConservesEnergy) {
    const Scene s = furnace_scene(principled(1.0f, 0.0f, 0.0f, 0.5f, 1.0f, 1.5f));
    RenderStats st;
    const MeanVar mv = furnace_mean(s, furnace_settings(32, 16), &st);
    // Smooth white glass is lossless: every path carries weight exactly 1.
    EXPECT_NEAR(mv.mean, 1.0, 4.0 * mv.stderr_of_mean() + 0.005) << "stderr " << mv.stderr_of_mean();
    EXPECT_GT(st.rays[size_t(RayType::Refraction)], 0u);
}

TEST(RenderFurnace, RoughGlassSphereLosesLittleAndNeverGains) {
    const Scene s = furnace_scene(principled(1.0f, 0.0f, 0.3f, 0.5f, 1.0f, 1.5f));
    const MeanVar mv = furnace_mean(s, furnace_settings(32, 16));
    EXPECT_LT(mv.mean, 1.0 + 4.0 * mv.stderr_of_mean() + 0.005);
    EXPECT_GT(mv.mean, 0.85);
}

TEST(RenderFeatures, RayTypesFollowSceneFeatures) {
    // Diffuse floor and a mirror, lit by a point light: no refraction rays.
    Scene s;
    const uint32_t floor = s.add_material(principled(0.8f, 0.0f, 0.5f, 0.0f, 0.0f));
    const uint32_t mirror = s.add_material(principled(1.0f, 1.0f, 0.0f, 0.5f, 0.0f));
    add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 10, 10, floor);
    add_sphere(s, {0, 0, 1}, 1.0f, mirror, 16, 32);
    Light l;
    l.type = LightType::Point;
    l.position = {2, 2, 4};
    l.power = 500;
    s.lights.push_back(l);
    s.camera = perspective_camera({0, -6, 3}, {0, 0, 0.5f}, 0.5f);
    s.finalize();
    EXPECT_FALSE(s.features.glass);
    EXPECT_TRUE(s.features.specular);

    RenderSettings rs = furnace_settings(24, 4);
    rs.max_bounces = 4;
    RenderStats st;
    render_combined(s, rs, &st);
    EXPECT_EQ(st.rays[size_t(RayType::Refraction)], 0u);
    EXPECT_GT(st.rays[size_t(RayType::Reflection)], 0u);
    EXPECT_GT(st.rays[size_t(RayType::Shadow)], 0u);
    EXPECT_GT(st.rays[size_t(RayType::Diffuse)], 0u);
    EXPECT_EQ(st.rays[size_t(RayType::Camera)], 24u * 24u * 4u);

    // Same scene with a glass sphere: refraction rays appear.
    Scene g;
    const uint32_t gf = g.add_material(principled(0.8f, 0.0f, 0.5f, 0.0f, 0.0f));
    const uint32_t glass = g.add_material(principled(1.0f, 0.0f, 0.0f, 0.5f, 1.0f));
    add_quad(g, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 10, 10, gf);
    add_sphere(g, {0, 0, 1}, 1.0f, glass, 16, 32);
    g.lights = s.lights;
    g.camera = s.camera;
    g.finalize();
    EXPECT_TRUE(g.features.glass);
    RenderStats gs;
    render_combined(g, rs, &gs);
    EXPECT_GT(gs.rays[size_t(RayType::Refraction)], 0u);

    // No emitter at all: no shadow rays, and a black image.
    Scene dark;
    add_quad(dark, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 10, 10, 0);
    dark.camera = s.camera;
    dark.finalize();
    RenderStats ds;
    const auto img = render_combined(dark, rs, &ds);
    EXPECT_EQ(ds.rays[size_t(RayType::Shadow)], 0u);
    for (size_t i = 0; i < img.size(); i += 4) EXPECT_EQ(img[i], 0.0f);

    // Direct light only (max bounces 0) from a point light of radius 0: the
    // bounce ray of each camera hit could only collect emission, and nothing
    // can be hit, so it is not traced. With a radius the light can be hit,
    // and the same ray is traced for its MIS half.
    RenderSettings direct = rs;
    direct.max_bounces = 0;
    RenderStats point_stats;
    const auto point_img = render_combined(s, direct, &point_stats);
    EXPECT_FALSE(s.features.hittable_emitters);
    EXPECT_EQ(point_stats.total_rays(),
              point_stats.rays[size_t(RayType::Camera)] + point_stats.rays[size_t(RayType::Shadow)]);
    EXPECT_GT(point_stats.rays[size_t(RayType::Shadow)], 0u);
    Scene soft = s;
    soft.lights[0].radius = 0.1f;
    soft.finalize();
    EXPECT_TRUE(soft.features.hittable_emitters);
    RenderStats soft_stats;
    render_combined(soft, direct, &soft_stats);
    EXPECT_GT(soft_stats.total_rays(),
              soft_stats.rays[size_t(RayType::Camera)] + soft_stats.rays[size_t(RayType::Shadow)]);
    // Not tracing it changes no pixel: the same render with every feature
    // forced on traces it and must give the same image.
    RenderSettings direct_all = direct;
    direct_all.force_all_features = true;
    EXPECT_EQ(render_combined(s, direct_all), point_img);

    // Forcing all features changes the work, not the expected image: the
    // all-features kernel counts the same camera rays.
    RenderSettings all = rs;
    all.force_all_features = true;
    Renderer r(s, all);
    EXPECT_TRUE(r.active_features().glass);
    r.render();
    EXPECT_EQ(r.stats().rays[size_t(RayType::Camera)], 24u * 24u * 4u);
}

// A tessellated, tilted plane lit by a sun at a grazing angle and by a point
// light, rendered at scene scales from 1e-4 to 1e5 (geometry, light and camera
// scaled together). Every pixel must be close to the analytic radiance: a
// single self-shadowed sample would darken its pixel by 1/spp.
void check_no_acne(float scale, float sun_angle_deg, bool point_light) {
    const Vec3f n = normalize(Vec3f(0.1f, 0.2f, 1.0f));
    Vec3f t, b;
    make_basis(n, t, b);
    const Vec3f origin = Vec3f(0.3f, -0.2f, 0.7f) * scale;

    Scene s;
    const float albedo = 0.8f;
    const uint32_t white = s.add_material(principled(albedo, 0.0f, 0.5f, 0.0f, 0.0f));
    const int cells = 8;
    const float cell = 4.0f * scale / cells;
    for (int i = 0; i < cells; ++i)
        for (int j = 0; j < cells; ++j) {
            const Vec3f c = origin + t * ((i + 0.5f - cells / 2) * cell) + b * ((j + 0.5f - cells / 2) * cell);
            add_quad(s, c, t, b, cell, cell, white);
        }

    const float theta = sun_angle_deg * kPi / 180.0f;
    float expected_sun = 0.0f;
    if (!point_light) {
        Light sun;
        sun.type = LightType::Sun;
        sun.power = 2.0f;
        sun.direction = -(n * std::cos(theta) + t * std::sin(theta));
        s.lights.push_back(sun);
        expected_sun = albedo * kInvPi * sun.power * std::cos(theta);
    }
    Light pl;
    if (point_light) {
        pl.type = LightType::Point;
        // Low over the plane and beside it: every pixel sees it at 87-89 degrees.
        pl.position = origin + n * (0.1f * scale) + t * (6.0f * scale);
        pl.power = 100.0f * scale * scale;  // keep the radiance independent of scale
        s.lights.push_back(pl);
    }

    s.camera.projection = Projection::Orthographic;
    s.camera.position = origin + n * (3.0f * scale);
    s.camera.forward = -n;
    s.camera.right = t;
    s.camera.up = b;  // (t, b, n) right-handed: right x up = -forward
    s.camera.half_width = s.camera.half_height = 1.5f * scale;
    s.camera.clip_start = 1e-3f * scale;
    s.camera.clip_end = 1e3f * scale;
    s.finalize();

    RenderSettings rs;
    rs.width = rs.height = 32;
    rs.spp = 4;
    rs.max_bounces = 0;
    rs.threads = 2;
    Renderer r(s, rs);
    r.render();
    const auto img = r.film().resolve(PassType::Combined);
    int outliers = 0;
    for (int y = 0; y < rs.height; ++y)
        for (int x = 0; x < rs.width; ++x) {
            const float v = img[4 * (y * rs.width + x)];
            float expected = expected_sun;
            if (point_light) {
                // Analytic value at the pixel centre; the pixel average differs by
                // its curvature only, far less than the 10% we allow.
                const float sx = (2.0f * (x + 0.5f) / rs.width - 1.0f) * 1.5f * scale;
                const float sy = (1.0f - 2.0f * (y + 0.5f) / rs.height) * 1.5f * scale;
                const Vec3f p = origin + t * sx + b * sy;
                const Vec3f to = pl.position - p;
                const float d2 = length_squared(to);
                const float cos_i = dot(n, to) / std::sqrt(d2);
                expected = albedo * kInvPi * (pl.power / (4.0f * kPi)) * cos_i / d2;
            }
            if (!(std::fabs(v - expected) <= 0.1f * expected + 1e-6f)) ++outliers;
        }
    EXPECT_EQ(outliers, 0) << "scale " << scale << " angle " << sun_angle_deg << " point " << point_light;
}

TEST(RenderRobustness, NoSelfShadowingAcneAtAnyScale) {
    for (float scale : {1e-4f, 1e-2f, 1.0f, 1e3f, 1e5f}) {
        for (float angle : {80.0f, 85.0f, 89.0f}) check_no_acne(scale, angle, false);
        check_no_acne(scale, 0.0f, true);
    }
}

TEST(RenderRobustness, NanProneSetupsGiveFinitePasses) {
    Scene s;
    Material nan_mat = principled(0.5f, 0.0f, 0.5f, 0.5f, 0.0f);
    nan_mat.closures[0].base_color = Vec3f(std::numeric_limits<float>::quiet_NaN());
    const uint32_t bad = s.add_material(nan_mat);
    const uint32_t glass_ior1 = s.add_material(principled(1.0f, 0.0f, 0.0f, 0.5f, 1.0f, 1.0f));
    const uint32_t mirror = s.add_material(principled(1.0f, 1.0f, 0.0f, 0.5f, 0.0f));
    Material mix = principled(1.0f, 0.0f, 1.0f, 1.0f, 0.0f);
    mix.closure_count = 3;
    mix.closures[1] = principled(1.0f, 0.0f, 0.0f, 0.5f, 1.0f, 3.0f).closures[0];
    mix.closures[2] = principled(1.0f, 1.0f, 1e-7f, 0.5f, 0.0f).closures[0];
    mix.weights = {0.5f, 2.0f, 0.0f, 0.0f};  // an Add node plus a zero weight
    const uint32_t mixed = s.add_material(mix);
    add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 4, 4, bad);
    add_quad(s, {0, 0, 0.5f}, {1, 0, 0}, {0, 1, 0}, 1, 1, glass_ior1);
    add_sphere(s, {1, 1, 0.5f}, 0.5f, mirror, 8, 16);
    add_sphere(s, {-1, 1, 0.5f}, 0.5f, mixed, 8, 16);
    // Point light exactly on a surface, zero-size area light, sun straight down.
    Light on_surface;
    on_surface.type = LightType::Point;
    on_surface.position = {0.25f, 0.25f, 0.0f};
    s.lights.push_back(on_surface);
    Light flat;
    flat.type = LightType::Area;
    flat.size_u = 0.0f;
    s.lights.push_back(flat);
    Light spot;
    spot.type = LightType::Spot;
    spot.position = {0, 0, 0.5f};  // on the glass quad
    spot.radius = 0.1f;
    spot.spot_size = 0.0f;
    s.lights.push_back(spot);
    Light sun;
    sun.type = LightType::Sun;
    sun.sun_angle = kPi;
    s.lights.push_back(sun);
    // A front end passing a NaN world colour: camera rays that miss see it.
    s.world_color = {std::numeric_limits<float>::quiet_NaN(), 0.2f, 0.2f};
    s.camera = perspective_camera({0, -3, 3}, {0, 0, 0}, 0.8f);
    s.finalize();

    RenderSettings rs = furnace_settings(24, 4);
    Renderer r(s, rs);
    r.render();
    for (PassType p : {PassType::Combined, PassType::Depth, PassType::Normal})
        for (float v : r.film().resolve(p)) ASSERT_TRUE(std::isfinite(v));
    // The NaN world poisons the samples that see it: discarded and counted.
    EXPECT_GT(r.stats().nonfinite_samples, 0u);
    EXPECT_EQ(r.stats().samples + r.stats().nonfinite_samples, uint64_t(24 * 24 * 4));
}

// The same emitter expressed twice, as an analytic area light and as an
// emissive quad of equal radiance (Cycles: area radiance = P / (4 A)), lights
// a glossy floor and a diffuse sphere. The two code paths (analytic light
// sampling + ray/light intersection versus triangle sampling + BVH hits) must
// give the same image within noise: this checks both MIS halves.
TEST(RenderLights, AreaLightMatchesEquivalentEmissiveQuad) {
    auto build = [](bool analytic) {
        Scene s;
        const uint32_t floor = s.add_material(principled(0.9f, 1.0f, 0.3f, 0.5f, 0.0f));
        const uint32_t ball = s.add_material(principled(0.8f, 0.0f, 0.5f, 0.0f, 0.0f));
        add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 8, 8, floor);
        add_sphere(s, {0.5f, 0.5f, 0.6f}, 0.6f, ball, 16, 32);
        const float size = 1.0f, power = 200.0f;
        if (analytic) {
            Light l;
            l.type = LightType::Area;
            l.position = {0, 0, 3};
            l.direction = {0, 0, -1};
            l.size_u = size;
            l.power = power;
            s.lights.push_back(l);
        } else {
            // Quad facing down (u x v = -z); the back is never seen.
            const uint32_t e = s.add_material(emission_material(Vec3f(power / (4.0f * size * size))));
            add_quad(s, {0, 0, 3}, {0, 1, 0}, {1, 0, 0}, size, size, e);
        }
        s.camera = perspective_camera({0, -5, 2}, {0, 0, 0.3f}, 0.45f);  // the emitter is out of frame
        s.finalize();
        return s;
    };
    // Per 4x4-pixel block: mean and seed-to-seed variance of each version over
    // 8 seeds, then a two-sample z score per block.
    const Scene analytic = build(true), mesh = build(false);
    RenderSettings rs = furnace_settings(24, 32);
    rs.max_bounces = 3;
    constexpr int kSeeds = 8, kBlocks = 36;
    std::vector<std::vector<double>> blocks_a(kBlocks), blocks_b(kBlocks);
    double total_a = 0.0, total_b = 0.0;
    for (int seed = 0; seed < kSeeds; ++seed) {
        rs.seed = uint64_t(seed);
        const auto a = render_combined(analytic, rs);
        const auto b = render_combined(mesh, rs);
        for (int k = 0; k < kBlocks; ++k) {
            double sa = 0, sb = 0;
            for (int y = 0; y < 4; ++y)
                for (int x = 0; x < 4; ++x) {
                    const size_t i = 4 * size_t(((k / 6) * 4 + y) * 24 + (k % 6) * 4 + x);
                    sa += a[i];
                    sb += b[i];
                }
            blocks_a[k].push_back(sa / 16);
            blocks_b[k].push_back(sb / 16);
            total_a += sa;
            total_b += sb;
        }
    }
    EXPECT_GT(total_a / (kSeeds * 24 * 24), 0.05);  // the scene is lit
    for (int k = 0; k < kBlocks; ++k) {
        const MeanVar ma = mean_var(blocks_a[k]), mb = mean_var(blocks_b[k]);
        const double se = std::sqrt(ma.var / kSeeds + mb.var / kSeeds);
        EXPECT_LE(std::fabs(ma.mean - mb.mean), 5.0 * se + 1e-3 * (ma.mean + mb.mean) + 1e-6)
            << "block " << k << " analytic " << ma.mean << " mesh " << mb.mean << " se " << se;
    }
    EXPECT_NEAR(total_a / total_b, 1.0, 0.02);
}

// Camera inside a closed sphere whose walls have albedo rho and emit Le:
// the radiance after light bounced k times off the walls is Le rho^k, so a
// render with bounce limit N must give Le * sum_{k=0}^{N+1} rho^k (Blender's
// convention: 0 bounces still shows direct light). Exact for any closed
// enclosure, so the tessellation does not matter.
TEST(RenderBounces, LimitsFollowBlenderSemanticsInsideAGlowingSphere) {
    Scene s;
    Material wall = principled(0.5f, 0.0f, 0.5f, 0.0f, 0.0f);
    wall.emission = Vec3f(1.0f);
    const uint32_t id = s.add_material(wall);
    add_sphere(s, {0, 0, 0}, 2.0f, id, 16, 32);
    s.camera = perspective_camera({0, 0, 0}, {0, 1, 0}, 0.7f);
    s.finalize();
    auto expect = [](int n) {
        double sum = 0, term = 1;
        for (int k = 0; k <= n + 1; ++k, term *= 0.5) sum += term;
        return sum;
    };
    struct Case {
        int max_bounces, diffuse_bounces;
        double expected;
    };
    for (const Case& c : {Case{0, 4, expect(0)}, Case{12, 0, expect(0)}, Case{12, 2, expect(2)}, Case{1, 12, expect(1)},
                          Case{64, 64, 2.0}}) {
        RenderSettings rs = furnace_settings(16, 16);
        rs.max_bounces = c.max_bounces;
        rs.diffuse_bounces = c.diffuse_bounces;
        rs.rr_min_bounces = 2;  // roulette must not bias the sum
        Renderer r(s, rs);
        r.render();
        const auto img = r.film().resolve(PassType::Combined);
        std::vector<double> v;
        for (size_t i = 0; i < img.size(); i += 4) v.push_back(img[i]);
        const MeanVar mv = mean_var(v);
        EXPECT_NEAR(mv.mean, c.expected, 4.0 * mv.stderr_of_mean() + 0.003)
            << "max " << c.max_bounces << " diffuse " << c.diffuse_bounces;
    }
}

TEST(RenderFilm, EmptySceneShowsTheWorldAndEmptyBorderRendersNothing) {
    Scene s;
    s.world_color = {0.25f, 0.5f, 1.0f};
    s.finalize();
    RenderSettings rs = furnace_settings(8, 2);
    Renderer r(s, rs);
    EXPECT_TRUE(r.render());
    const auto img = r.film().resolve(PassType::Combined);
    for (size_t i = 0; i < img.size(); i += 4) {
        EXPECT_EQ(img[i + 0], 0.25f);
        EXPECT_EQ(img[i + 2], 1.0f);
        EXPECT_EQ(img[i + 3], 1.0f);
    }
    rs.border_x0 = 4;
    rs.border_x1 = 4;  // zero-width border
    Renderer e(s, rs);
    EXPECT_TRUE(e.render());
    EXPECT_EQ(e.film().width(), 0);
    EXPECT_EQ(e.stats().samples, 0u);
}

TEST(RenderClamp, DirectAndIndirectLimitsApplyPerContribution) {
    // Sun-lit white plane: the only light is one direct NEE contribution of
    // 0.8/pi * 3 * cos(30 deg) = 0.6616 per sample.
    Scene s;
    add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 20, 20, s.add_material(principled(0.8f, 0.0f, 0.5f, 0.0f, 0.0f)));
    Light sun;
    sun.type = LightType::Sun;
    sun.power = 3.0f;
    sun.direction = {0.0f, std::sin(kPi / 6.0f), -std::cos(kPi / 6.0f)};
    s.lights.push_back(sun);
    s.camera = ortho_camera_looking_down(5.0f, 2.0f);
    s.finalize();
    RenderSettings rs = furnace_settings(8, 4);
    rs.clamp_indirect = 0.01f;  // does not touch direct light
    for (size_t i = 0; i < 64; ++i) EXPECT_NEAR(render_combined(s, rs)[4 * i], 0.8f / kPi * 3.0f * std::cos(kPi / 6.0f), 1e-5f);
    rs.clamp_direct = 0.2f;
    const auto clamped = render_combined(s, rs);
    for (size_t i = 0; i < 64; ++i) EXPECT_NEAR(clamped[4 * i], 0.2f, 1e-6f);

    // Inside the glowing sphere (unclamped: 2.0), clamping indirect light
    // removes energy but keeps what the camera sees directly (1.0) and the
    // direct light at the first hit (0.5).
    Scene g;
    Material wall = principled(0.5f, 0.0f, 0.5f, 0.0f, 0.0f);
    wall.emission = Vec3f(1.0f);
    add_sphere(g, {0, 0, 0}, 2.0f, g.add_material(wall), 16, 32);
    g.camera = perspective_camera({0, 0, 0}, {0, 1, 0}, 0.7f);
    g.finalize();
    RenderSettings gs = furnace_settings(8, 16);
    gs.clamp_indirect = 0.01f;
    const auto img = render_combined(g, gs);
    double mean = 0;
    for (size_t i = 0; i < img.size(); i += 4) mean += img[i];
    mean /= double(img.size() / 4);
    EXPECT_GT(mean, 1.45);
    EXPECT_LT(mean, 1.75);
}

// A closed, tessellated box with every light outside: no path may get in
// through shared edges or vertices, so the inside must be exactly black.
TEST(RenderRobustness, NoLightLeaksIntoAClosedBox) {
    for (float scale : {1e-3f, 1.0f, 1e4f}) {
        Scene s;
        const uint32_t white = s.add_material(principled(0.9f, 0.0f, 0.5f, 0.0f, 0.0f));
        const uint32_t metal = s.add_material(principled(0.9f, 1.0f, 0.2f, 0.5f, 0.0f));
        const int n = 4;
        const float cell = 2.0f * scale / n;
        const Vec3f axes[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
        for (int a = 0; a < 3; ++a)
            for (float side : {-1.0f, 1.0f}) {
                const Vec3f nrm = axes[a] * side, u = axes[(a + 1) % 3], v = axes[(a + 2) % 3];
                for (int i = 0; i < n; ++i)
                    for (int j = 0; j < n; ++j) {
                        const Vec3f c = nrm * scale + u * ((i + 0.5f) * cell - scale) + v * ((j + 0.5f) * cell - scale);
                        add_quad(s, c, u, v, cell, cell, (i + j) % 2 ? white : metal);
                    }
            }
        const uint32_t e = s.add_material(emission_material(Vec3f(50.0f)));
        // An emitter resting just above the lid, outside.
        add_quad(s, Vec3f(0, 0, 1.0f + 1e-4f) * scale, {1, 0, 0}, {0, 1, 0}, scale, scale, e);
        Light sun;
        sun.type = LightType::Sun;
        sun.power = 20.0f;
        sun.sun_angle = 0.1f;
        sun.direction = normalize(Vec3f(-0.3f, -0.5f, -1.0f));
        s.lights.push_back(sun);
        Light point;
        point.type = LightType::Point;
        // Just outside a corner: shadow rays must run all the way to it (a
        // relative 1e-4 shortening let 950 of 1024 pixels see this light).
        point.position = Vec3f(1.0f, 1.0f, 1.0f) * (1.0f + 1e-4f) * scale;
        point.power = 1000.0f * scale * scale;
        s.lights.push_back(point);
        Light area;
        area.type = LightType::Area;
        area.position = Vec3f(0, 0, -1.001f) * scale;  // just below the floor, facing it
        area.direction = {0, 0, 1};
        area.size_u = 2.0f * scale;
        area.power = 1000.0f * scale * scale;
        s.lights.push_back(area);
        s.camera = perspective_camera(Vec3f(0.3f, 0.2f, -0.1f) * scale, Vec3f(-1, -1, -1) * scale, 1.2f);
        s.camera.clip_start = 1e-4f * scale;
        s.finalize();
        RenderSettings rs = furnace_settings(32, 8);
        rs.max_bounces = 8;
        RenderStats st;
        const auto img = render_combined(s, rs, &st);
        EXPECT_GT(st.rays[size_t(RayType::Shadow)], 0u);
        size_t lit = 0;
        for (size_t i = 0; i < img.size(); i += 4) lit += img[i] != 0.0f || img[i + 1] != 0.0f || img[i + 2] != 0.0f;
        EXPECT_EQ(lit, 0u) << "scale " << scale;
    }
}

Scene simple_lit_scene();

TEST(RenderControl, LongPassesReportProgressInBetween) {
    // Reports come at least every 0.25 s while a pass runs. One pass of
    // 2560 x 1440 paths of up to 4 bounces on 2 threads takes seconds (7 s
    // on the 2-core development machine; a machine 10x faster still needs
    // 0.7 s), so reports from inside the pass are certain, not a matter of a
    // fast or slow run: asserted unconditionally.
    const Scene s = simple_lit_scene();
    RenderSettings rs;
    rs.width = 2560;
    rs.height = 1440;
    rs.spp = 1;
    rs.max_bounces = 4;
    rs.threads = 2;
    Renderer r(s, rs);
    int within_pass = 0, after_pass = 0;
    double last_fraction = 0.0;
    EXPECT_TRUE(r.render([&](const Progress& p) {
        (p.samples_done == 0 ? within_pass : after_pass)++;
        if (p.samples_done == 0) {
            EXPECT_EQ(after_pass, 0) << "a within-pass report after the pass ended";
            EXPECT_GT(p.fraction, last_fraction);  // tiles done only grow
            EXPECT_LT(p.fraction, 1.0);
            last_fraction = p.fraction;
        }
        return true;
    }));
    EXPECT_EQ(after_pass, 1);
    EXPECT_GE(within_pass, 1) << "no progress report during a pass of " << r.stats().seconds << " s";
    std::printf("1 pass of 2560x1440 took %.2f s, %d reports during it\n", r.stats().seconds, within_pass);
}

Scene simple_lit_scene() {
    Scene s;
    const uint32_t m = s.add_material(principled(0.7f, 0.0f, 0.4f, 0.5f, 0.0f));
    add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 10, 10, m);
    add_sphere(s, {0, 0, 1}, 1.0f, m, 12, 24);
    Light l;
    l.type = LightType::Area;
    l.position = {0, 0, 4};
    l.power = 300;
    s.lights.push_back(l);
    s.world_color = {0.05f, 0.05f, 0.1f};
    s.camera = perspective_camera({0, -6, 3}, {0, 0, 0.5f}, 0.5f);
    s.finalize();
    return s;
}

TEST(RenderDeterminism, SameImageForAnyThreadCountAndTileSize) {
    const Scene s = simple_lit_scene();
    RenderSettings rs = furnace_settings(40, 3);
    rs.max_bounces = 4;
    rs.threads = 1;
    rs.tile_size = 16;
    const auto a = render_combined(s, rs);
    rs.threads = 2;
    rs.tile_size = 7;
    const auto b = render_combined(s, rs);
    ASSERT_EQ(a.size(), b.size());
    for (size_t i = 0; i < a.size(); ++i) ASSERT_EQ(a[i], b[i]) << i;
    rs.seed = 1;
    const auto c = render_combined(s, rs);
    size_t differ = 0;
    for (size_t i = 0; i < a.size(); ++i) differ += a[i] != c[i];
    EXPECT_GT(differ, a.size() / 4);  // another seed gives other noise
}

// Batches of passes (report_interval) change when the caller hears about
// progress, never the film: within a batch a tile may run passes ahead of
// another, but each pixel still takes its samples in order, so every
// traversal gives the image of a pass-by-pass render, bit for bit, at any
// thread count; and the batches end at even pass counts, growing by at most
// half the passes done.
TEST(RenderDeterminism, BatchesOfPassesGiveThePassByPassImage) {
    const Scene s = simple_lit_scene();
    for (Traversal t : {Traversal::Single, Traversal::Packet, Traversal::Stream, Traversal::Wavefront}) {
        RenderSettings rs = furnace_settings(40, 24);
        rs.max_bounces = 3;
        rs.sampler = SamplerType::Cpt;
        rs.traversal = t;
        rs.tile_size = 8;
        rs.threads = 1;
        rs.report_interval = 0.0;
        const auto by_pass = render_combined(s, rs);
        rs.threads = 3;
        rs.report_interval = 60.0;  // longer than the render: only the growth rule limits batches
        Renderer r(s, rs);
        std::vector<int> reported;
        ASSERT_TRUE(r.render([&](const Progress& p) {
            if (reported.empty() || p.samples_done != reported.back()) reported.push_back(p.samples_done);
            return true;
        }));
        const auto batched = r.film().resolve(PassType::Combined);
        ASSERT_EQ(by_pass.size(), batched.size());
        for (size_t i = 0; i < by_pass.size(); ++i) ASSERT_EQ(by_pass[i], batched[i]) << traversal_name(t) << " " << i;
        ASSERT_GE(reported.size(), 3u);
        EXPECT_EQ(reported[0], 1);
        EXPECT_EQ(reported[1], 2);
        EXPECT_EQ(reported.back(), 24);
        EXPECT_LT(reported.size(), 24u) << "no pass was batched";
        for (size_t i = 2; i < reported.size(); ++i) {
            EXPECT_EQ(reported[i] % 2, 0) << reported[i];
            EXPECT_LE(reported[i] - reported[i - 1], std::max(2, reported[i - 1] / 2)) << reported[i];
        }
    }
}

TEST(RenderFilm, BorderRendersTheSamePixelsAsTheFullFrame) {
    const Scene s = simple_lit_scene();
    RenderSettings rs = furnace_settings(32, 2);
    rs.max_bounces = 3;
    const auto full = render_combined(s, rs);
    rs.border_x0 = 8;
    rs.border_x1 = 27;
    rs.border_y0 = 4;
    rs.border_y1 = 20;
    Renderer r(s, rs);
    r.render();
    ASSERT_EQ(r.film().width(), 19);
    ASSERT_EQ(r.film().height(), 16);
    const auto part = r.film().resolve(PassType::Combined);
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 19; ++x)
            for (int c = 0; c < 4; ++c)
                ASSERT_EQ(part[4 * (y * 19 + x) + c], full[4 * ((y + 4) * 32 + x + 8) + c]);
}

TEST(RenderFilm, DepthNormalAlphaAndTransparentFilm) {
    Scene s;
    add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 2, 2, 0);  // covers the middle of the frame
    s.world_color = Vec3f(0.5f);
    s.camera = perspective_camera({0, 0, 5}, {0, 0, 0}, 0.4f);  // frame spans +-2 at the plane
    s.finalize();
    RenderSettings rs = furnace_settings(16, 4);
    rs.max_bounces = 0;
    Renderer r(s, rs);
    r.render();
    const auto depth = r.film().resolve(PassType::Depth);
    const auto normal = r.film().resolve(PassType::Normal);
    const auto rgba = r.film().resolve(PassType::Combined);
    // Pixel (8, 8) sees the plane at view-axis depth 5 (not the ray length);
    // the corner pixel sees only the world.
    const int centre = 8 * 16 + 8;
    EXPECT_NEAR(depth[centre], 5.0f, 1e-4f);
    EXPECT_NEAR(depth[9 * 16 + 10], 5.0f, 1e-4f);
    EXPECT_NEAR(normal[3 * centre + 2], 1.0f, 1e-5f);
    EXPECT_EQ(depth[0], 1e10f);
    EXPECT_EQ(rgba[3], 1.0f);  // opaque film: alpha 1 everywhere
    EXPECT_NEAR(rgba[0], 0.5f, 1e-6f);

    rs.transparent_film = true;
    Renderer t(s, rs);
    t.render();
    const auto trgba = t.film().resolve(PassType::Combined);
    EXPECT_EQ(trgba[3], 0.0f);   // world seen directly: transparent, no colour
    EXPECT_EQ(trgba[0], 0.0f);
    EXPECT_EQ(trgba[4 * centre + 3], 1.0f);
    EXPECT_GT(trgba[4 * centre], 0.0f);  // lit by the world
}

TEST(RenderControl, ProgressOnCallingThreadAndCancelByCallback) {
    const Scene s = simple_lit_scene();
    RenderSettings rs = furnace_settings(32, 6);
    rs.max_bounces = 2;
    rs.report_interval = 0.0;  // a report after every pass
    Renderer r(s, rs);
    const auto caller = std::this_thread::get_id();
    int calls = 0, last_done = 0;
    bool same_thread = true;
    EXPECT_TRUE(r.render([&](const Progress& p) {
        ++calls;
        same_thread &= std::this_thread::get_id() == caller;
        EXPECT_GE(p.samples_done, last_done);
        last_done = p.samples_done;
        EXPECT_LE(p.fraction, 1.0);
        return true;
    }));
    EXPECT_GE(calls, 6);
    EXPECT_EQ(last_done, 6);
    EXPECT_TRUE(same_thread);

    Renderer c(s, rs);
    int seen = 0;
    EXPECT_FALSE(c.render([&](const Progress& p) {
        seen = p.samples_done;
        return p.samples_done < 2;  // stop after the second pass
    }));
    EXPECT_EQ(seen, 2);
    EXPECT_TRUE(c.cancelled());
    EXPECT_EQ(c.film().samples_at(0, 0), 2u);
}

// Promptness of cancel() from another thread, as events rather than seconds:
// the first progress report (inside pass 0 of a 4K frame, or at its end)
// hands over to a canceller thread and waits until cancel() has returned
// there. From then on the renderer must not finish another pass nor report
// progress again, and render() returns false. Only tiles already in flight
// may complete: the samples traced stay below one more pass.
TEST(RenderControl, CancelFromAnotherThreadStopsWithinThePassInFlight) {
    const Scene s = simple_lit_scene();
    RenderSettings rs;
    rs.width = 3840;
    rs.height = 2160;
    rs.spp = 1000;
    rs.threads = 2;
    Renderer r(s, rs);
    std::mutex m;
    std::condition_variable cv;
    bool asked = false, cancelled = false;
    std::thread canceller([&] {
        std::unique_lock<std::mutex> lock(m);
        cv.wait(lock, [&] { return asked; });
        r.cancel();
        cancelled = true;
        cv.notify_all();
    });
    int reports = 0, reports_after_cancel = 0, done_at_cancel = -1;
    const bool finished = r.render([&](const Progress& p) {
        ++reports;
        if (done_at_cancel >= 0) {
            ++reports_after_cancel;
            return true;
        }
        done_at_cancel = p.samples_done;
        std::unique_lock<std::mutex> lock(m);
        asked = true;
        cv.notify_all();
        cv.wait(lock, [&] { return cancelled; });
        return true;  // the cancel comes from the other thread only
    });
    canceller.join();
    EXPECT_FALSE(finished);
    EXPECT_TRUE(r.cancelled());
    ASSERT_GE(done_at_cancel, 0) << "no progress report at all";
    EXPECT_EQ(reports_after_cancel, 0);
    EXPECT_EQ(r.stats().spp, done_at_cancel) << "a pass completed after cancel()";
    const uint64_t pixels = uint64_t(rs.width) * uint64_t(rs.height);
    EXPECT_LT(r.stats().samples, uint64_t(done_at_cancel + 1) * pixels);
    std::printf("cancelled at the report with %d passes done; %llu samples traced\n", done_at_cancel,
                (unsigned long long)r.stats().samples);
}

}  // namespace
