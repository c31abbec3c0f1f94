// Object motion blur: the moving-triangle BVH against brute force, the
// blurred image against the analytic time coverage of a moving emitter,
// every traversal mode against single rays, and scenes that do not move
// against the same scene without motion data.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "accel/motion_bvh.h"
#include "accel/triangle.h"
#include "core/random.h"
#include "render/renderer.h"
#include "test_render_helpers.h"

using namespace coherent;
using namespace coherent::test;

namespace {

Transform translation(const Vec3f& t) {
    Transform x;
    x.m[0][3] = t.x;
    x.m[1][3] = t.y;
    x.m[2][3] = t.z;
    return x;
}

// An emissive square (side `size`, centred at the origin, in the plane
// z = height) that translates by `travel` along x over the shutter.
void add_moving_square(Scene& s, float size, float height, float travel, uint32_t material) {
    const float h = 0.5f * size;
    const float pos[] = {-h, -h, height, h, -h, height, h, h, height, -h, h, height};
    const uint32_t idx[] = {0, 1, 2, 0, 2, 3};
    MeshInput m;
    m.name = "mover";
    m.positions = pos;
    m.vertex_count = 4;
    m.indices = idx;
    m.triangle_count = 2;
    m.material_slots = {material};
    m.moves = true;
    m.object_to_world_close = translation({travel, 0.0f, 0.0f});
    s.add_mesh(m);
}

// Fraction of the shutter during which x is covered by [tau * travel - h, tau * travel + h].
double coverage(double x, double h, double travel) {
    const double lo = std::max(0.0, (x - h) / travel), hi = std::min(1.0, (x + h) / travel);
    return std::max(0.0, hi - lo);
}

}  // namespace

TEST(MotionBlur, MotionBvhMatchesBruteForceAtRandomTimes) {
    Pcg32 rng(3);
    std::vector<Vec3f> open, close;
    std::vector<uint32_t> moving;
    for (uint32_t t = 0; t < 300; ++t) {
        const Vec3f c{rng.next_float() * 10 - 5, rng.next_float() * 10 - 5, rng.next_float() * 10 - 5};
        const Vec3f travel{rng.next_float() * 2 - 1, rng.next_float() * 2 - 1, rng.next_float() * 2 - 1};
        for (int k = 0; k < 3; ++k) {
            const Vec3f v = c + Vec3f(rng.next_float(), rng.next_float(), rng.next_float());
            open.push_back(v);
            close.push_back(v + travel);
        }
        if (t % 3 != 0) moving.push_back(t);  // a third stays out, as static triangles would
    }
    MotionBvh bvh;
    bvh.build(open, close, moving);
    ASSERT_EQ(bvh.triangle_count(), moving.size());
    int hits = 0;
    for (int i = 0; i < 3000; ++i) {
        Ray r;
        r.o = {rng.next_float() * 14 - 7, rng.next_float() * 14 - 7, -9.0f};
        r.d = normalize(Vec3f(rng.next_float() - 0.5f, rng.next_float() - 0.5f, 1.0f));
        r.tmin = 0.0f;
        r.tmax = 30.0f;
        const float tau = rng.next_float();
        const WatertightRay wr(r.o, r.d);
        Hit expect;
        for (uint32_t t : moving) {
            TriangleHit th;
            if (intersect_triangle_watertight(wr, motion_vertex(open[3 * t], close[3 * t], tau),
                                              motion_vertex(open[3 * t + 1], close[3 * t + 1], tau),
                                              motion_vertex(open[3 * t + 2], close[3 * t + 2], tau), r.tmin,
                                              expect.t, th) &&
                (th.t < expect.t || t < expect.prim))
                expect = Hit{th.t, th.u, th.v, t};
        }
        Hit got;
        const bool found = bvh.intersect(r, tau, got);
        ASSERT_EQ(found, expect.valid()) << "ray " << i;
        if (found) {
            ++hits;
            EXPECT_EQ(got.prim, expect.prim);
            EXPECT_EQ(got.t, expect.t);
            EXPECT_EQ(got.u, expect.u);
        }
        EXPECT_EQ(bvh.occluded(r, tau), expect.valid());
        // An incoming closer hit is kept.
        Hit closer{1e-3f, 0, 0, 7};
        EXPECT_FALSE(bvh.intersect(r, tau, closer));
        EXPECT_EQ(closer.prim, 7u);
    }
    EXPECT_GT(hits, 100);
}

TEST(MotionBlur, BlurredEmitterMatchesItsTimeCoverage) {
    // Orthographic view down the z axis of a square emitter sliding along x
    // over a black world: a pixel's value is the fraction of the shutter the
    // emitter covers it (averaged over the pixel).
    Scene s;
    const uint32_t light = s.add_material(emission_material(Vec3f(1.0f)));
    const float size = 1.0f, travel = 2.0f;
    add_moving_square(s, size, 0.0f, travel, light);
    s.camera = ortho_camera_looking_down(5.0f, 2.0f);
    s.finalize();
    ASSERT_TRUE(s.features.motion_blur);
    ASSERT_EQ(s.moving_triangles.size(), 2u);

    RenderSettings rs;
    rs.width = 64;
    rs.height = 8;  // only the row through y = 0 is checked
    rs.spp = 512;
    rs.threads = 2;
    rs.max_bounces = 0;
    Renderer r(s, rs);
    ASSERT_TRUE(r.render());
    const auto img = r.film().resolve(PassType::Combined);
    const int y = rs.height / 2;
    double worst = 0.0;
    for (int x = 0; x < rs.width; ++x) {
        // Pixel x covers world [x0, x1] along x (camera half extent 2, but
        // the horizontal extent follows the aspect: half_width is the
        // resolved world extent).
        const double half_w = s.camera.half_width;
        const double x0 = -half_w + 2.0 * half_w * x / rs.width, x1 = -half_w + 2.0 * half_w * (x + 1) / rs.width;
        double expect = 0.0;
        for (int k = 0; k < 64; ++k) expect += coverage(x0 + (x1 - x0) * (k + 0.5) / 64, 0.5 * size, travel) / 64;
        const double got = img[4 * (size_t(y) * rs.width + x)];
        // Binomial noise of 512 samples: sigma <= 0.5 / sqrt(512) = 0.022.
        EXPECT_NEAR(got, expect, 0.09) << "pixel " << x;
        worst = std::max(worst, std::fabs(got - expect));
    }
    EXPECT_LT(worst, 0.09);
}

TEST(MotionBlur, EveryTraversalGivesTheSingleRayImage) {
    // A moving red sphere-like box over a lit floor, with a moving occluder
    // casting a blurred shadow and a static one: shadows, bounces and AO all
    // see moving geometry.
    Scene s = sphere_on_floor_scene();
    Scene moving;
    const uint32_t white = moving.add_material(diffuse_material(Vec3f(0.7f)));
    const uint32_t red = moving.add_material(diffuse_material(Vec3f(0.8f, 0.2f, 0.1f)));
    const uint32_t light = moving.add_material(emission_material(Vec3f(4.0f)));
    add_quad(moving, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 6.0f, 6.0f, white, "floor");
    add_moving_square(moving, 1.0f, 1.0f, 1.5f, red);
    add_quad(moving, {1, 1, 4}, {0, 1, 0}, {1, 0, 0}, 2.5f, 2.5f, light, "light");
    moving.camera = s.camera;
    moving.world_color = Vec3f(0.2f);
    moving.finalize();
    ASSERT_TRUE(moving.features.motion_blur);
    for (Integrator integrator : {Integrator::PathTrace, Integrator::AmbientOcclusion}) {
        RenderSettings rs;
        rs.width = 36;
        rs.height = 30;
        rs.spp = 2;
        rs.threads = 2;
        rs.integrator = integrator;
        rs.sampler = SamplerType::Cpt;
        const auto single = render_combined(moving, rs);
        for (Traversal t : {Traversal::Packet, Traversal::Stream, Traversal::Wavefront}) {
            rs.traversal = t;
            const auto other = render_combined(moving, rs);
            EXPECT_EQ(single, other) << integrator_name(integrator) << " " << traversal_name(t);
        }
    }
}

TEST(MotionBlur, AMeshThatDoesNotMoveRendersAsWithoutMotion) {
    // The same square declared moving by zero: no moving triangles, no time
    // dimension drawn, the image of the static scene bit for bit.
    auto scene = [](bool declare_motion) {
        Scene s;
        const uint32_t white = s.add_material(diffuse_material(Vec3f(0.7f)));
        const uint32_t light = s.add_material(emission_material(Vec3f(2.0f)));
        add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 6.0f, 6.0f, white, "floor");
        if (declare_motion) add_moving_square(s, 1.0f, 2.0f, 0.0f, light);
        else add_quad(s, {0, 0, 2}, {1, 0, 0}, {0, 1, 0}, 1.0f, 1.0f, light, "still");
        s.camera = ortho_camera_looking_down(5.0f, 3.0f);
        s.finalize();
        return s;
    };
    const Scene still = scene(false), declared = scene(true);
    EXPECT_FALSE(declared.features.motion_blur);
    EXPECT_TRUE(declared.moving_triangles.empty());
    RenderSettings rs;
    rs.width = rs.height = 24;
    rs.spp = 4;
    EXPECT_EQ(render_combined(still, rs), render_combined(declared, rs));
}
