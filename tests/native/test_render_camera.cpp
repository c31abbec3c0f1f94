// Primary rays: lens shift, clipping along the view axis, thin-lens focus,
// orthographic projection, and clipping in a full render.
#include <gtest/gtest.h>

#include "core/random.h"
#include "render/camera_rays.h"
#include "test_render_helpers.h"

using namespace coherent;
using namespace coherent::test;

namespace {

Camera wide_camera() {
    Camera c;  // looks down -z from (0, 0, 5); right +x, up +y
    c.half_width = 0.8f;
    c.half_height = 0.45f;  // 16:9
    return c;
}

TEST(CameraRays, ShiftIsInUnitsOfTheLargerFrameExtent) {
    Camera c = wide_camera();
    // Unshifted: the right edge of the frame (film x = width).
    const CameraRay edge = generate_camera_ray<false>(c, 160.0f, 45.0f, 160, 90, 0.5f, 0.5f);
    // Shift 0.5 moves the view by half the frame width: the centre pixel now
    // looks where the right edge looked.
    c.shift_x = 0.5f;
    const CameraRay shifted = generate_camera_ray<false>(c, 80.0f, 45.0f, 160, 90, 0.5f, 0.5f);
    EXPECT_NEAR(shifted.ray.d.x, edge.ray.d.x, 1e-6f);
    EXPECT_NEAR(shifted.ray.d.y, edge.ray.d.y, 1e-6f);
    // shift_y is also measured in widths (the larger extent), not heights.
    c.shift_x = 0.0f;
    c.shift_y = 0.25f;
    const CameraRay up = generate_camera_ray<false>(c, 80.0f, 45.0f, 160, 90, 0.5f, 0.5f);
    EXPECT_NEAR(up.ray.d.y / -up.ray.d.z, 0.25f * 2.0f * 0.8f, 1e-5f);
}

TEST(CameraRays, ClipDistancesAreAlongTheViewAxis) {
    Camera c = wide_camera();
    c.clip_start = 2.0f;
    c.clip_end = 7.0f;
    const CameraRay r = generate_camera_ray<false>(c, 0.0f, 0.0f, 160, 90, 0.5f, 0.5f);  // corner ray
    const float cos_axis = dot(r.ray.d, c.forward);
    EXPECT_LT(cos_axis, 0.9f);
    EXPECT_NEAR(r.ray.tmin * cos_axis, 2.0f, 1e-5f);
    EXPECT_NEAR(r.ray.tmax * cos_axis, 7.0f, 1e-4f);
    EXPECT_NEAR(r.depth_scale, cos_axis, 1e-6f);
    EXPECT_NEAR(length(r.ray.d), 1.0f, 1e-6f);
}

TEST(CameraRays, ThinLensRaysMeetAtTheFocusPlane) {
    Camera c = wide_camera();
    c.aperture_radius = 0.2f;
    c.focus_distance = 3.0f;
    const CameraRay pin = generate_camera_ray<false>(c, 30.0f, 70.0f, 160, 90, 0.5f, 0.5f);
    const Vec3f focus = pin.ray.o + pin.ray.d * (3.0f / dot(pin.ray.d, c.forward));
    Pcg32 rng(3);
    float spread = 0.0f;
    for (int i = 0; i < 100; ++i) {
        const CameraRay r = generate_camera_ray<true>(c, 30.0f, 70.0f, 160, 90, rng.next_float(), rng.next_float());
        // Origins lie on the lens disc...
        const Vec3f off = r.ray.o - c.position;
        EXPECT_NEAR(dot(off, c.forward), 0.0f, 1e-6f);
        EXPECT_LE(length(off), 0.2f + 1e-6f);
        spread = std::max(spread, length(off));
        // ...and every ray passes through the pinhole ray's focus point.
        const Vec3f at = r.ray.o + r.ray.d * ((3.0f - dot(off, c.forward)) / dot(r.ray.d, c.forward));
        EXPECT_NEAR(length(at - focus), 0.0f, 1e-5f);
    }
    EXPECT_GT(spread, 0.1f);
}

TEST(CameraRays, OrthographicRaysAreParallel) {
    Camera c = wide_camera();
    c.projection = Projection::Orthographic;
    c.half_width = 4.0f;
    c.half_height = 2.25f;
    const CameraRay a = generate_camera_ray<false>(c, 0.0f, 0.0f, 160, 90, 0.5f, 0.5f);
    const CameraRay b = generate_camera_ray<false>(c, 160.0f, 90.0f, 160, 90, 0.5f, 0.5f);
    EXPECT_EQ(a.ray.d.z, -1.0f);
    EXPECT_EQ(b.ray.d.z, -1.0f);
    EXPECT_NEAR(a.ray.o.x, -4.0f, 1e-6f);
    EXPECT_NEAR(a.ray.o.y, 2.25f, 1e-6f);  // film row 0 is the top
    EXPECT_NEAR(b.ray.o.x, 4.0f, 1e-6f);
    EXPECT_NEAR(b.ray.o.y, -2.25f, 1e-6f);
}

TEST(CameraRays, ClipStartHidesNearGeometryInARender) {
    Scene s;
    const uint32_t e = s.add_material(emission_material(Vec3f(1.0f)));
    add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 20, 20, 0);  // far plane, depth 5
    add_quad(s, {0, 0, 4}, {1, 0, 0}, {0, 1, 0}, 20, 20, e);  // near plane, depth 1
    s.camera = wide_camera();
    s.camera.clip_start = 2.0f;
    s.finalize();
    RenderSettings rs;
    rs.width = 16;
    rs.height = 9;
    rs.spp = 1;
    rs.max_bounces = 0;
    Renderer r(s, rs);
    r.render();
    for (float d : r.film().resolve(PassType::Depth)) EXPECT_NEAR(d, 5.0f, 1e-4f);
    s.camera.clip_start = 0.5f;
    s.camera.clip_end = 3.0f;
    Renderer r2(s, rs);
    r2.render();
    for (float d : r2.film().resolve(PassType::Depth)) EXPECT_NEAR(d, 1.0f, 1e-4f);
}

}  // namespace
