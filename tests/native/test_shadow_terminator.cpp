// Cycles' shadow terminator geometry offset (render/shadow_terminator.h):
// the lift's geometry on known surfaces, when it applies, and what it does
// to a low-poly smooth sphere lit at a grazing angle.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "render/renderer.h"
#include "render/shadow_terminator.h"
#include "test_render_helpers.h"

namespace coherent {
namespace {

using test::add_sphere;
using test::diffuse_material;
using test::perspective_camera;

// A triangle cut from a sphere of radius r, normals radial: the lift puts
// the centre between the flat triangle and the sphere, outwards.
TEST(ShadowTerminator, LiftTowardsTheSphereTheNormalsDescribe) {
    const float r = 2.0f;
    const Vec3f dirs[3] = {normalize(Vec3f(0.3f, 0.0f, 1.0f)), normalize(Vec3f(-0.15f, 0.26f, 1.0f)),
                           normalize(Vec3f(-0.15f, -0.26f, 1.0f))};
    Vec3f V[3], N[3];
    for (int k = 0; k < 3; ++k) V[k] = dirs[k] * r, N[k] = dirs[k];
    const Vec3f ng = normalize(cross(V[1] - V[0], V[2] - V[0]));
    ASSERT_GT(ng.z, 0.0f);
    const float third = 1.0f / 3.0f;
    const Vec3f flat = (V[0] + V[1] + V[2]) * third;
    const Vec3f lifted = flat + smooth_surface_lift(V, N, third, third, third, ng);
    // Cycles' parabola is conservative: at least the sphere's height over
    // the triangle there (the sagitta), and of its order.
    const float sagitta = r - length(flat);
    const float lift = length(lifted) - length(flat);
    EXPECT_GT(lift, 0.9f * sagitta);
    EXPECT_LT(lift, 3.0f * sagitta);
    EXPECT_GT(dot(lifted - flat, ng), 0.99f * lift);  // outwards, along the normal
    // At a corner the flat and the smooth surface meet: no lift.
    EXPECT_LT(length(smooth_surface_lift(V, N, 1.0f, 0.0f, 0.0f, ng)), 1e-5f);
    // Normals equal to the face normal describe the flat triangle itself.
    const Vec3f F[3] = {ng, ng, ng};
    EXPECT_LT(length(smooth_surface_lift(V, F, third, third, third, ng)), 1e-6f);
}

TEST(ShadowTerminator, AmountIsOneBelowTheSurfaceAndZeroWellAboveIt) {
    const Vec3f n{0.0f, 0.0f, 1.0f};
    Vec3f ng_light;
    float ng_dot_l = 0.0f;
    EXPECT_EQ(terminator_amount(0.1f, n, n, normalize(Vec3f(0.0f, 1.0f, 1.0f)), ng_light, ng_dot_l), 0.0f);
    // Light above the shading normal's horizon, below the geometric one's.
    const Vec3f tilted = normalize(Vec3f(0.0f, 0.3f, 1.0f));
    EXPECT_EQ(terminator_amount(0.1f, tilted, n, normalize(Vec3f(0.0f, 1.0f, -0.05f)), ng_light, ng_dot_l), 1.0f);
    EXPECT_LT(ng_dot_l, 0.0f);
    // Grazing both: partly.
    const float a = terminator_amount(0.1f, n, n, normalize(Vec3f(0.0f, 1.0f, 0.07f)), ng_light, ng_dot_l);
    EXPECT_GT(a, 0.0f);
    EXPECT_LT(a, 1.0f);
    // Light behind the shading normal (a transmission shadow ray): measured on the other side.
    terminator_amount(0.1f, n, n, normalize(Vec3f(0.0f, 1.0f, -1.0f)), ng_light, ng_dot_l);
    EXPECT_EQ(ng_light.z, -1.0f);
    EXPECT_GT(ng_dot_l, 0.0f);
}

// A low-poly smooth sphere lit by a sun from the side, direct light only.
// With interpolated normals, Lambert shading falls smoothly to 0 at the
// smooth terminator, but shadow rays leaving the flat triangles near it are
// blocked by their neighbours: dark triangles. Measured against the smooth
// shading the Normal pass implies, the offset must remove most of that.
struct TerminatorError {
    double dark_fraction;  // lit pixels (smooth n.l > 0.05) darker than half the smooth shading
};

TerminatorError grazing_sphere_error(float offset) {
    Scene s;
    const uint32_t white = s.add_material(diffuse_material(Vec3f(0.8f)));
    add_sphere(s, {0, 0, 0}, 1.0f, white, 6, 12);
    Light sun;
    sun.type = LightType::Sun;
    sun.direction = normalize(Vec3f(-1.0f, 0.3f, -0.1f));
    sun.power = 3.0f;
    s.lights.push_back(sun);
    s.world_color = {0.0f, 0.0f, 0.0f};
    s.camera = perspective_camera({0, -5, 0}, {0, 0, 0}, 0.25f);
    if (offset != kDefaultTerminatorOffset) s.object_terminator_offset.assign(s.object_names.size(), offset);
    s.finalize();
    RenderSettings rs;
    rs.width = rs.height = 96;
    rs.spp = 8;
    rs.max_bounces = 0;
    Renderer r(s, rs);
    r.render();
    const auto img = r.film().resolve(PassType::Combined);
    const auto nrm = r.film().resolve(PassType::Normal);
    const Vec3f l = -sun.direction;
    // Scale: the median of image / (n.l) over well-lit pixels.
    std::vector<double> scale;
    for (size_t i = 0; i < size_t(rs.width * rs.height); ++i) {
        const Vec3f n{nrm[3 * i], nrm[3 * i + 1], nrm[3 * i + 2]};
        const float nl = dot(n, l);
        if (length(n) > 0.99f && nl > 0.6f) scale.push_back(img[4 * i] / nl);
    }
    std::nth_element(scale.begin(), scale.begin() + scale.size() / 2, scale.end());
    const double k = scale[scale.size() / 2];
    size_t lit = 0, dark = 0;
    for (size_t i = 0; i < size_t(rs.width * rs.height); ++i) {
        const Vec3f n{nrm[3 * i], nrm[3 * i + 1], nrm[3 * i + 2]};
        const float nl = dot(n, l);
        if (length(n) < 0.99f || nl < 0.05f) continue;
        ++lit;
        dark += img[4 * i] < 0.5 * k * nl;
    }
    return {double(dark) / double(lit)};
}

TEST(ShadowTerminator, SmoothsTheFacetedTerminatorOfALowPolySphere) {
    const TerminatorError off = grazing_sphere_error(0.0f);
    const TerminatorError on = grazing_sphere_error(kDefaultTerminatorOffset);
    std::printf("dark lit pixels: offset 0 %.3f, offset 0.1 %.3f\n", off.dark_fraction, on.dark_fraction);
    EXPECT_GT(off.dark_fraction, 0.01);  // measured 0.018: a ring of dark triangles
    EXPECT_LT(on.dark_fraction, 0.25 * off.dark_fraction);
}

}  // namespace
}  // namespace coherent
