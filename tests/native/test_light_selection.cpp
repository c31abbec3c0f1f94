// Light selection by importance (light_sampling.h) and the environment map
// sampler (world_sampling.h):
// - selection probabilities: a distribution, ordered by power, floored;
// - unbiasedness: the next-event estimate of irradiance, mean of li cos / pdf,
//   matches the analytic irradiance of every kind of emitter within 3 sigma;
// - pdf consistency: for every sample, the pdf functions the integrator uses
//   for MIS (hit_lights, escaped, triangle_pdf) give the sample's own pdf, so
//   the power heuristic of a sample against itself is exactly 1/2;
// - the environment map's pdf integrates to 1 over the sphere and its
//   importance-sampled estimate of the map's integral matches a uniform one.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "render/light_sampling.h"
#include "render/world_sampling.h"
#include "test_seed.h"

namespace coherent {
namespace {

class Uniform {
public:
    explicit Uniform(uint64_t seed) : gen_(test::test_seed(seed)) {}
    float operator()() { return std::min(dist_(gen_), 0.99999994f); }

private:
    std::mt19937_64 gen_;
    std::uniform_real_distribution<float> dist_{0.0f, 1.0f};
};

Vec3f uniform_sphere(float u1, float u2) {
    const float z = 1.0f - 2.0f * u1, r = std::sqrt(std::max(0.0f, 1.0f - z * z)), phi = 2.0f * kPi * u2;
    return {r * std::cos(phi), r * std::sin(phi), z};
}

// Mean and standard error of a stream of samples, per channel.
struct Stats {
    double sum[3] = {0, 0, 0}, sum2[3] = {0, 0, 0};
    size_t n = 0;
    void add(const Vec3f& v) {
        const float c[3] = {v.x, v.y, v.z};
        for (int i = 0; i < 3; ++i) sum[i] += c[i], sum2[i] += double(c[i]) * c[i];
        ++n;
    }
    double mean(int i) const { return sum[i] / double(n); }
    double error(int i) const { return std::sqrt(std::max(0.0, sum2[i] / double(n) - mean(i) * mean(i)) / double(n)); }
};

// A map with structure: a dim sky gradient, a black band and a bright blob.
EnvironmentMap structured_map(int w, int h) {
    EnvironmentMap m;
    m.width = w;
    m.height = h;
    m.rgb.resize(size_t(w) * size_t(h) * 3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            float* p = &m.rgb[(size_t(y) * size_t(w) + size_t(x)) * 3];
            const float v = (float(y) + 0.5f) / float(h);
            const float sky = v > 0.5f ? 0.2f + v : 0.05f;
            const bool black = x > w / 2 && x < w / 2 + w / 8;
            const float dx = float(x - w / 5), dy = float(y - 3 * h / 4);
            const float blob = dx * dx + dy * dy < 4.0f ? 200.0f : 0.0f;
            p[0] = black ? 0.0f : sky + blob;
            p[1] = black ? 0.0f : 0.8f * sky + blob;
            p[2] = black ? 0.0f : 1.2f * sky + 0.9f * blob;
        }
    return m;
}

TEST(EnvironmentSampler, EquirectMappingRoundTrips) {
    Uniform u(11);
    for (int i = 0; i < 1000; ++i) {
        const Vec3f d = uniform_sphere(u(), u());
        const Vec2f uv = direction_to_equirect(d);
        const Vec3f back = equirect_to_direction(uv.x, uv.y);
        EXPECT_NEAR(length(back - d), 0.0f, 1e-5f);
    }
    // Cycles: +X is the image's centre column, +Z its top row.
    EXPECT_NEAR(direction_to_equirect(Vec3f(1, 0, 0)).x, 0.5f, 1e-6f);
    EXPECT_NEAR(direction_to_equirect(Vec3f(0, 0, 1)).y, 1.0f, 1e-6f);
    EXPECT_NEAR(direction_to_equirect(Vec3f(0, 1, 0)).x, 0.25f, 1e-6f);
}

TEST(EnvironmentSampler, PdfIntegratesToOneOverTheSphere) {
    const EnvironmentMap map = structured_map(64, 32);
    const EnvironmentSampler env(map);
    ASSERT_FALSE(env.empty());
    Uniform u(12);
    Stats s;
    for (int i = 0; i < 400000; ++i) {
        const float p = env.pdf(uniform_sphere(u(), u())) * 4.0f * kPi;  // pdf / uniform pdf
        s.add(Vec3f(p));
    }
    EXPECT_NEAR(s.mean(0), 1.0, 3.0 * s.error(0)) << "+- " << s.error(0);
}

TEST(EnvironmentSampler, SamplePdfMatchesPdfAndLookup) {
    EnvironmentMap map = structured_map(64, 32);
    // A rotation (60 degrees about Z): sampling and lookup must share the frame.
    const float c = 0.5f, s = std::sqrt(3.0f) / 2.0f;
    const float rot[9] = {c, -s, 0, s, c, 0, 0, 0, 1};
    std::copy(rot, rot + 9, map.rotation);
    const EnvironmentSampler env(map);
    Uniform u(13);
    Stats importance, uniform;
    int mismatches = 0;
    const int n = 200000;
    for (int i = 0; i < n; ++i) {
        Vec3f d;
        float pdf;
        if (env.sample(u(), u(), d, pdf)) {
            EXPECT_NEAR(length(d), 1.0f, 1e-5f);
            const float again = env.pdf(d);
            if (!(std::fabs(again - pdf) <= 1e-3f * pdf)) ++mismatches;  // a texel border rounded the other way
            importance.add(env.eval(d) / pdf);
        } else {
            importance.add(Vec3f(0.0f));
        }
        uniform.add(env.eval(uniform_sphere(u(), u())) * (4.0f * kPi));
    }
    EXPECT_LE(mismatches, n / 1000);
    // Both estimate the integral of the bilinear lookup over the sphere: the
    // sampled directions follow pdf() (else this differs) and the lookup's
    // support is covered (a texel of weight 0 where the lookup is not black
    // would make the importance estimate low).
    for (int ch = 0; ch < 3; ++ch) {
        const double sigma = std::hypot(importance.error(ch), uniform.error(ch));
        EXPECT_NEAR(importance.mean(ch), uniform.mean(ch), 3.0 * sigma) << "channel " << ch;
        EXPECT_LT(importance.error(ch), 0.5 * uniform.error(ch)) << "importance sampling should beat uniform";
    }
}

// The pdf gives each texel the share of the map's power that the bilinear
// lookup puts there: the integral of its luminance over the texel, times the
// cosine of elevation. A wider distribution (each texel weighted by its
// brightest neighbour, as before) sends samples to dark texels beside bright
// ones and measured 1.25x Cycles' RMSE on an HDRI world, against 1.06x now.
// Oracle: the lookup integrated over each texel on an 8x8 midpoint grid
// (the two quadratures differ by 1.5 % at worst, in the polar rows). The
// brightest-neighbour weights were off by up to 40x; the tent without the
// cosine's slope across a polar row by up to 0.94x.
TEST(EnvironmentSampler, EachTexelIsSampledByItsShareOfTheMapsPower) {
    const int w = 64, h = 32, m = 8;
    const EnvironmentMap map = structured_map(w, h);
    const EnvironmentSampler env(map);
    std::vector<double> share(size_t(w * h));
    double total = 0.0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            double sum = 0.0;
            for (int j = 0; j < m; ++j)
                for (int i = 0; i < m; ++i) {
                    const float u = (float(x) + (float(i) + 0.5f) / float(m)) / float(w);
                    const float v = (float(y) + (float(j) + 0.5f) / float(m)) / float(h);
                    sum += double(luminance(env.eval(equirect_to_direction(u, v)))) * std::cos(kPi * (v - 0.5f));
                }
            share[size_t(y * w + x)] = sum;
            total += sum;
        }
    int off = 0;
    double worst = 0.0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const float v = (float(y) + 0.5f) / float(h);
            const Vec3f centre = equirect_to_direction((float(x) + 0.5f) / float(w), v);
            const double sampled = double(env.pdf(centre)) * std::cos(kPi * (v - 0.5f)) * 2.0 * kPi * kPi / (w * h);
            const double want = share[size_t(y * w + x)] / total;
            const double err = std::fabs(sampled - want);
            worst = std::max(worst, err / std::max(want, 1e-12));
            if (!(err <= 0.03 * want + 1e-9)) ++off;
        }
    EXPECT_EQ(off, 0) << "worst relative difference " << worst;
}

TEST(EnvironmentSampler, MeanLuminanceOfAConstantMapIsItsLuminance) {
    EnvironmentMap map;
    map.width = 32, map.height = 64;
    map.rgb.assign(size_t(32 * 64 * 3), 0.0f);
    for (size_t i = 0; i < map.rgb.size(); i += 3) map.rgb[i] = 2.0f, map.rgb[i + 1] = 1.0f, map.rgb[i + 2] = 0.5f;
    const EnvironmentSampler env(map);
    EXPECT_NEAR(env.mean_luminance(), luminance(Vec3f(2.0f, 1.0f, 0.5f)), 1e-3f);
    EXPECT_NEAR(env.eval(Vec3f(0.3f, -0.4f, 0.866f)).x, 2.0f, 1e-6f);
    EnvironmentMap black = map;
    std::fill(black.rgb.begin(), black.rgb.end(), 0.0f);
    EXPECT_TRUE(EnvironmentSampler(black).empty());
}

Light point_light(Vec3f pos, float power, float radius = 0.0f) {
    Light l;
    l.type = LightType::Point;
    l.position = pos;
    l.power = power;
    l.radius = radius;
    return l;
}

Light sun_light(Vec3f travel, float irradiance, float angle_deg) {
    Light l;
    l.type = LightType::Sun;
    l.direction = normalize(travel);
    l.power = irradiance;
    l.sun_angle = angle_deg * kPi / 180.0f;
    return l;
}

Light disk_light(Vec3f pos, float power, float diameter) {
    Light l;
    l.type = LightType::Area;
    l.shape = AreaShape::Disk;
    l.position = pos;
    l.direction = Vec3f(0, 0, -1);
    l.power = power;
    l.size_u = l.size_v = diameter;
    return l;
}

TEST(LightSelection, ProbabilitiesFollowPowerWithAUniformFloor) {
    Scene scene;
    scene.lights = {point_light({0, 0, 2}, 1.0f), point_light({1, 0, 2}, 10.0f), point_light({2, 0, 2}, 1000.0f),
                    sun_light({0, 0, -1}, 3.0f, 0.0f)};
    scene.world_color = Vec3f(0.01f);
    scene.world_map = structured_map(8, 4);  // a map, so the world is a unit beside the lights
    scene.finalize();
    const LightSet power(scene, LightSelection::Power);
    const LightSet uniform(scene, LightSelection::Uniform);
    ASSERT_EQ(power.light_count(), 4u);
    double sum = power.world_pick();
    for (size_t i = 0; i < 4; ++i) sum += power.light_pick(i);
    EXPECT_NEAR(sum, 1.0, 1e-6);
    const float floor = float(kUniformShare / 5.0);
    EXPECT_GE(power.light_pick(0), floor * 0.9999f);
    EXPECT_GE(power.world_pick(), floor * 0.9999f);
    EXPECT_LT(power.light_pick(0), power.light_pick(1));
    EXPECT_LT(power.light_pick(1), power.light_pick(2));
    EXPECT_GT(power.light_pick(2), 0.5f);
    // No geometry: cross-section pi; sun 3 W/m^2 -> 3 pi, world 0.01 x the
    // map's mean luminance m -> 0.01 m pi^2, point 1000 W.
    const double world = 0.01 * double(EnvironmentSampler(scene.world_map).mean_luminance()) * kPi * kPi;
    const double total = 1.0 + 10.0 + 1000.0 + 3.0 * kPi + world;
    EXPECT_NEAR(power.light_pick(2), 0.9 * 1000.0 / total + 0.02, 1e-5);
    EXPECT_NEAR(power.light_pick(3), 0.9 * 3.0 * kPi / total + 0.02, 1e-5);
    for (size_t i = 0; i < 4; ++i) EXPECT_EQ(uniform.light_pick(i), 0.2f);
    EXPECT_EQ(uniform.world_pick(), 0.2f);
}

// A constant world beside other emitters is left to BSDF rays (Cycles 3.4):
// no shadow ray goes to it, and a BSDF ray that escapes collects all of its
// radiance whatever its pdf. Alone, it is next-event estimated as before.
TEST(LightSelection, AConstantWorldBesideLightsIsLeftToBsdfRays) {
    for (LightSelection sel : {LightSelection::Power, LightSelection::Uniform}) {
        Scene scene;
        scene.lights = {sun_light({0.3f, 0.2f, -1.0f}, 10.0f, 1.0f)};
        scene.world_color = Vec3f(0.05f, 0.1f, 0.2f);
        scene.finalize();
        const LightSet lights(scene, sel);
        EXPECT_EQ(lights.world_pick(), 0.0f);
        EXPECT_EQ(lights.light_pick(0), 1.0f);
        Uniform u(41);
        const Vec3f n(0, 0, 1);
        for (int i = 0; i < 1000; ++i) {
            LightSample ls;
            ASSERT_TRUE(lights.sample(Vec3f(0.0f), n, false, u(), u(), u(), ls));
            EXPECT_NEAR(dot(ls.wi, normalize(Vec3f(-0.3f, -0.2f, 1.0f))), 1.0f, 1e-3f);  // always the sun
        }
        const Vec3f up_side = normalize(Vec3f(1, 0, 1));
        const Vec3f got = lights.escaped(up_side, n, false, up_side.z / kPi);
        EXPECT_FLOAT_EQ(got.x, 0.05f);
        EXPECT_FLOAT_EQ(got.z, 0.2f);

        Scene alone;
        alone.world_color = Vec3f(0.5f);
        alone.finalize();
        EXPECT_EQ(LightSet(alone, sel).world_pick(), 1.0f);
    }
}

// Irradiance at the origin on an upward surface from a set of lights, next-event
// estimated: every term is an unbiased estimate on its own (sample() covers
// each emitter's support), so the mean must match the analytic sum.
void expect_nee_irradiance(const Scene& scene, const Vec3f& expected, uint64_t seed) {
    for (LightSelection sel : {LightSelection::Power, LightSelection::Uniform}) {
        const LightSet lights(scene, sel);
        Uniform u(seed);
        Stats s;
        const Vec3f p(0.0f), n(0, 0, 1);
        for (int i = 0; i < 300000; ++i) {
            LightSample ls;
            Vec3f e(0.0f);
            if (lights.sample(p, n, false, u(), u(), u(), ls)) e = ls.li * (std::max(0.0f, dot(ls.wi, n)) / ls.pdf);
            s.add(e);
        }
        const float want[3] = {expected.x, expected.y, expected.z};
        for (int ch = 0; ch < 3; ++ch)
            EXPECT_NEAR(s.mean(ch), want[ch], 3.0 * s.error(ch) + 1e-6 * want[ch])
                << (sel == LightSelection::Power ? "power" : "uniform") << " selection, channel " << ch;
    }
}

TEST(LightSelection, NextEventEstimateIsUnbiasedForEveryEmitterKind) {
    Scene scene;
    const float r = 0.3f, d = 3.0f;
    Light sphere = point_light({0, 0, d}, 50.0f, r);
    sphere.color = Vec3f(1.0f, 0.5f, 0.25f);
    const Light sun = sun_light({std::sin(0.5f), 0.0f, -std::cos(0.5f)}, 3.0f, 10.0f);
    const float disk_r = 0.5f, h = 2.0f;
    scene.lights = {point_light({0, 0, 2}, 100.0f), point_light({5, 0, 0.5f}, 0.5f), sphere, sun,
                    disk_light({0, 0, h}, 40.0f, 2.0f * disk_r)};
    scene.finalize();
    // Point: I cos / d^2, I = P / (4 pi). Sphere light: a disc facing the point,
    // I / (d^2 + r^2). Sun cone of half-angle b at angle t: E cos t (1 + cos b) / 2.
    // Disk straight above: L pi R^2 / (h^2 + R^2), L = P / (4 A). A constant
    // world, next-event estimated only when alone: pi L.
    Vec3f e = Vec3f(100.0f / (4.0f * kPi) / 4.0f);
    const float cos_far = 0.5f / std::sqrt(25.0f + 0.25f);
    e += Vec3f(0.5f / (4.0f * kPi) * cos_far / (25.0f + 0.25f));
    e += sphere.color * (50.0f / (4.0f * kPi) / (d * d + r * r));
    e += Vec3f(3.0f * std::cos(0.5f) * (1.0f + std::cos(5.0f * kPi / 180.0f)) / 2.0f);
    const float disk_area = kPi * disk_r * disk_r;
    e += Vec3f(40.0f / (4.0f * disk_area) * kPi * disk_r * disk_r / (h * h + disk_r * disk_r));
    expect_nee_irradiance(scene, e, 21);
    Scene world;
    world.world_color = Vec3f(0.02f, 0.03f, 0.04f);
    world.finalize();
    expect_nee_irradiance(world, world.world_color * kPi, 23);
}

TEST(LightSelection, NextEventEstimateIsUnbiasedForAnEnvironmentMap) {
    // Two halves in azimuth, (1, 2, 3) and (0.1, 0.2, 0.3) x strength 2: an
    // upward patch gets pi x strength x their average (the bilinear seam
    // keeps the azimuthal mean).
    Scene scene;
    EnvironmentMap& m = scene.world_map;
    m.width = 64, m.height = 32;
    m.rgb.resize(size_t(64 * 32 * 3));
    for (int y = 0; y < 32; ++y)
        for (int x = 0; x < 64; ++x)
            for (int ch = 0; ch < 3; ++ch)
                m.rgb[(size_t(y) * 64 + size_t(x)) * 3 + size_t(ch)] = float(ch + 1) * (x < 32 ? 1.0f : 0.1f);
    scene.world_color = Vec3f(2.0f);
    scene.lights = {point_light({0, 0, 2}, 30.0f)};
    scene.finalize();
    const Vec3f e = Vec3f(30.0f / (4.0f * kPi) / 4.0f) + Vec3f(1.0f, 2.0f, 3.0f) * (2.0f * kPi * 0.55f);
    expect_nee_irradiance(scene, e, 22);
}

// The pdf functions the integrator uses for MIS against a sample's own pdf:
// the power heuristic of equal pdfs is 1/2, so each function must return
// half the sample's radiance. Delta point lights of varied power make the
// selection probabilities differ between units. Allows a few samples on the
// rounding edge of an emitter (or a texel) to disagree.
struct PdfCheck {
    int checked = 0, mismatched = 0;
    void expect_half(const Vec3f& got, const Vec3f& li) {
        ++checked;
        const float want = 0.5f * luminance(li);
        if (!(std::fabs(luminance(got) - want) <= 2e-3f * want)) ++mismatched;
    }
};

Scene scene_with_points() {
    Scene scene;
    scene.lights = {point_light({3, 3, 0.5f}, 7.0f), point_light({-3, 3, 0.5f}, 300.0f)};
    return scene;
}

// An emitting mesh of `positions` (xyz per vertex) and triangle `indices`.
void add_emitter(Scene& scene, const std::vector<float>& positions, const std::vector<uint32_t>& indices,
                 const Vec3f& emission) {
    Material mat;
    mat.emission = emission;
    MeshInput mesh;
    mesh.name = "emitter";
    mesh.positions = positions.data();
    mesh.vertex_count = positions.size() / 3;
    mesh.indices = indices.data();
    mesh.triangle_count = indices.size() / 3;
    mesh.material_slots = {scene.add_material(mat)};
    scene.add_mesh(mesh);
}

void add_quad_emitter(Scene& scene, float z, float half, const Vec3f& emission) {
    add_emitter(scene, {-half, -half, z, half, -half, z, half, half, z, -half, half, z}, {0, 1, 2, 0, 2, 3}, emission);
}

PdfCheck check_pdfs(const Scene& scene, uint64_t seed) {
    const LightSet lights(scene, LightSelection::Power);
    Uniform u(seed);
    PdfCheck c;
    const Vec3f p(0.0f), n(0, 0, 1);
    for (int i = 0; i < 50000; ++i) {
        LightSample ls;
        if (!lights.sample(p, n, false, u(), u(), u(), ls) || ls.delta) continue;
        if (ls.on_surface) {
            // Which triangle holds p_light: one with the same pdf.
            bool found = false;
            for (uint32_t t : scene.emissive_triangles)
                found = found || std::fabs(lights.triangle_pdf(t, p, ls.p_light, ls.n_light) - ls.pdf) <= 1e-4f * ls.pdf;
            ++c.checked;
            if (!found) ++c.mismatched;
        } else if (std::isfinite(ls.dist)) {
            c.expect_half(lights.hit_lights(p, ls.wi, kInf, ls.pdf), ls.li);
        } else {
            c.expect_half(lights.escaped(ls.wi, n, false, ls.pdf), ls.li);
        }
    }
    return c;
}

TEST(LightSelection, PdfFunctionsAgreeWithSample) {
    {  // area lights (rectangle by solid angle, disk by area), a sphere light, emissive triangles
        Scene scene = scene_with_points();
        Light rect = disk_light({-2, 0, 2}, 80.0f, 1.0f);
        rect.shape = AreaShape::Rectangle;
        rect.size_v = 0.5f;
        scene.lights.push_back(rect);
        scene.lights.push_back(disk_light({2, 0, 2}, 20.0f, 0.8f));
        scene.lights.push_back(point_light({0, 2, 2}, 40.0f, 0.3f));
        add_quad_emitter(scene, 3.0f, 0.3f, Vec3f(5.0f));        // far: by area
        add_quad_emitter(scene, 0.25f, 0.4f, Vec3f(1.0f, 2.0f, 3.0f));  // near: by solid angle
        scene.finalize();
        const PdfCheck c = check_pdfs(scene, 31);
        EXPECT_GT(c.checked, 10000);
        EXPECT_LE(c.mismatched, c.checked / 500) << c.mismatched << " of " << c.checked;
    }
    {  // a sun with an angle, black world
        Scene scene = scene_with_points();
        scene.lights.push_back(sun_light({0.3f, 0.2f, -1.0f}, 4.0f, 3.0f));
        scene.finalize();
        const PdfCheck c = check_pdfs(scene, 32);
        EXPECT_GT(c.checked, 1000);
        EXPECT_LE(c.mismatched, c.checked / 500) << c.mismatched << " of " << c.checked;
    }
    for (bool map : {false, true}) {  // the world: constant (cosine-sampled, alone) or an environment map
        Scene scene = map ? scene_with_points() : Scene{};
        scene.world_color = Vec3f(0.5f);
        if (map) scene.world_map = structured_map(64, 32);
        scene.finalize();
        const PdfCheck c = check_pdfs(scene, 33);
        EXPECT_GT(c.checked, 1000);
        EXPECT_LE(c.mismatched, c.checked / 500) << (map ? "map: " : "constant: ") << c.mismatched << " of "
                                                 << c.checked;
    }
}

// Emissive triangles near the shading point are sampled by solid angle
// (spherical_triangle.h), far ones by area. Oracle: Lambert's formula for the
// irradiance from a polygon of constant radiance L onto a plane with normal n,
//     E = L / 2 |sum_i angle(a_i, a_i+1) n . normalize(a_i x a_i+1)|,
// a_i the unit directions to the vertices, in double.
double polygon_irradiance(const std::vector<Vec3f>& verts, const Vec3f& p, const Vec3f& n) {
    double sum = 0.0;
    for (size_t i = 0; i < verts.size(); ++i) {
        const Vec3f a = normalize(verts[i] - p), b = normalize(verts[(i + 1) % verts.size()] - p);
        const double ax = a.x, ay = a.y, az = a.z, bx = b.x, by = b.y, bz = b.z;
        const double cx = ay * bz - az * by, cy = az * bx - ax * bz, cz = ax * by - ay * bx;
        const double len = std::sqrt(cx * cx + cy * cy + cz * cz);
        const double angle = std::atan2(len, ax * bx + ay * by + az * bz);
        sum += angle * (n.x * cx + n.y * cy + n.z * cz) / len;
    }
    return 0.5 * std::fabs(sum);
}

void add_triangle_emitter(Scene& scene, const Vec3f& a, const Vec3f& b, const Vec3f& c, float emission) {
    add_emitter(scene, {a.x, a.y, a.z, b.x, b.y, b.z, c.x, c.y, c.z}, {0, 1, 2}, Vec3f(emission));
}

TEST(LightSelection, NextEventEstimateIsUnbiasedForNearAndFarEmissiveTriangles) {
    // From the origin facing up: a large triangle 0.1 above at a slant (solid
    // angle), the same seen nearly edge-on from beside its plane, and a
    // small far one (area).
    const Vec3f near[3] = {{-1.0f, -0.8f, 0.1f}, {1.2f, -0.5f, 0.3f}, {0.1f, 1.1f, 0.15f}};
    const Vec3f grazing[3] = {{0.5f, 0.02f, 0.05f}, {3.0f, 0.02f, 0.05f}, {1.5f, 0.3f, 2.0f}};
    const Vec3f far[3] = {{-4.0f, 3.0f, 5.0f}, {-3.6f, 3.0f, 5.2f}, {-3.8f, 3.5f, 5.1f}};
    const float emission[3] = {2.0f, 7.0f, 40.0f};
    Scene scene;
    double expected = 0.0;
    int k = 0;
    for (const Vec3f* t : {near, grazing, far}) {
        add_triangle_emitter(scene, t[0], t[1], t[2], emission[k]);
        expected += emission[k++] * polygon_irradiance({t[0], t[1], t[2]}, Vec3f(0.0f), Vec3f(0, 0, 1));
    }
    scene.finalize();
    expect_nee_irradiance(scene, Vec3f(float(expected)), 24);
}

// A constant emitter sampled by solid angle gives estimates L cos / pdf =
// L cos * solid angle / pick: bounded, where area sampling's d^2 / cos grows
// without bound towards a grazing edge. And the mapping is uniform: the mean
// of a non-constant function of direction over the spherical triangle matches
// its area-sampled integral.
TEST(SphericalTriangle, SamplesAreUniformInSolidAngleAndInsideTheTriangle) {
    const Vec3f v0(-1.0f, -0.8f, 0.1f), v1(1.2f, -0.5f, 0.3f), v2(0.1f, 1.1f, 0.15f), p(0.0f);
    SphericalTriangle st;
    ASSERT_TRUE(make_spherical_triangle(p, v0, v1, v2, st));
    const Vec3f n = normalize(cross(v1 - v0, v2 - v0));
    // Solid angle against the area integral of cos / d^2 (midpoint rule, 1000^2 cells).
    double area_integral = 0.0, weighted = 0.0;
    auto f = [](const Vec3f& d) { return double(d.x * d.x + 0.5f * d.y + 1.0f); };
    const int m = 1000;
    const double cell = 0.5 * double(length(cross(v1 - v0, v2 - v0))) / (double(m) * m);
    for (int i = 0; i < m; ++i)
        for (int j = 0; j < m - i; ++j)
            for (int up = 0; up < (j < m - i - 1 ? 2 : 1); ++up) {
                const float bu = (float(i) + (up ? 2.0f : 1.0f) / 3.0f) / float(m);
                const float bv = (float(j) + (up ? 2.0f : 1.0f) / 3.0f) / float(m);
                const Vec3f q = v0 + (v1 - v0) * bu + (v2 - v0) * bv;
                const Vec3f d = q - p;
                const double w = cell * std::fabs(double(dot(n, d))) / std::pow(double(length(d)), 3.0);
                area_integral += w;
                weighted += w * f(normalize(d));
            }
    EXPECT_NEAR(st.solid_angle, area_integral, 1e-3 * area_integral);
    Uniform u(25);
    Stats s;
    int outside = 0;
    for (int i = 0; i < 200000; ++i) {
        const Vec3f d = sample_spherical_triangle(st, u(), u());
        // Inside: on the same side of the three planes through p and an edge.
        const float s0 = dot(d, cross(v0 - p, v1 - p)), s1 = dot(d, cross(v1 - p, v2 - p)),
                    s2 = dot(d, cross(v2 - p, v0 - p));
        const float tol = -1e-5f;
        if (!((s0 >= tol && s1 >= tol && s2 >= tol) || (s0 <= -tol && s1 <= -tol && s2 <= -tol))) ++outside;
        s.add(Vec3f(float(f(d) * st.solid_angle)));
    }
    EXPECT_EQ(outside, 0);
    EXPECT_NEAR(s.mean(0), weighted, 3.0 * s.error(0) + 1e-4 * weighted);
}

TEST(LightSelection, SolidAngleSamplingBoundsANearEmittersEstimate) {
    const Vec3f v0(-1.0f, -0.8f, 0.1f), v1(1.2f, -0.5f, 0.3f), v2(0.1f, 1.1f, 0.15f), p(0.0f), n(0, 0, 1);
    Scene scene;
    add_triangle_emitter(scene, v0, v1, v2, 3.0f);
    scene.finalize();
    const LightSet lights(scene);
    SphericalTriangle st;
    ASSERT_TRUE(make_spherical_triangle(p, v0, v1, v2, st));
    Uniform u(26);
    float most = 0.0f;
    for (int i = 0; i < 100000; ++i) {
        LightSample ls;
        if (lights.sample(p, n, false, u(), u(), u(), ls)) most = std::max(most, ls.li.x * dot(ls.wi, n) / ls.pdf);
    }
    EXPECT_LE(most, 3.0f * st.solid_angle * 1.0001f);
    EXPECT_GT(most, 0.5f * 3.0f * st.solid_angle);
}

// Hard cases for solid-angle sampling: shading points on an emitter itself,
// in its plane beside it, on its edge and vertex, and a sliver triangle. Every
// sample is finite with a positive pdf, and so is the pdf MIS computes for it.
TEST(LightSelection, NearEmitterSamplingStaysFiniteInItsOwnPlane) {
    Scene scene;
    const Vec3f a(0.0f, 0.0f, 1.0f), b(1.0f, 0.0f, 1.0f), c(0.0f, 1.0f, 1.0f);
    add_triangle_emitter(scene, a, b, c, 5.0f);
    add_triangle_emitter(scene, Vec3f(3.0f, 0.0f, 1.0f), Vec3f(4.0f, 0.0f, 1.0f), Vec3f(3.5f, 1e-6f, 1.0f), 5.0f);
    scene.finalize();
    const LightSet lights(scene);
    const Vec3f points[] = {{0.25f, 0.25f, 1.0f},  {0.25f, 0.25f, 1.0f + 1e-7f}, {2.0f, 0.5f, 1.0f},
                            {0.5f, 0.0f, 1.0f},    {0.0f, 0.0f, 1.0f},           {3.5f, 0.0f, 1.0f},
                            {0.3f, 0.3f, 1.0001f}, {3.5f, 0.0f, 1.001f}};
    Uniform u(27);
    for (const Vec3f& p : points)
        for (const Vec3f& n : {Vec3f(0, 0, 1), Vec3f(0, 0, -1), Vec3f(1, 0, 0)}) {
            for (int i = 0; i < 2000; ++i) {
                LightSample ls;
                if (!lights.sample(p, n, false, u(), u(), u(), ls)) continue;
                ASSERT_TRUE(std::isfinite(ls.pdf) && ls.pdf > 0.0f) << p.x << " " << p.y << " " << p.z;
                ASSERT_TRUE(is_finite(ls.li) && is_finite(ls.wi) && std::isfinite(ls.dist));
                ASSERT_NEAR(length(ls.wi), 1.0f, 1e-4f);
                const float mis = std::max(lights.triangle_pdf(0, p, ls.p_light, ls.n_light),
                                           lights.triangle_pdf(1, p, ls.p_light, ls.n_light));
                ASSERT_TRUE(std::isfinite(mis));
            }
        }
}

}  // namespace
}  // namespace coherent
