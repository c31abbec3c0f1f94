// The Vector pass (film/passes.h, Cycles' primitive_motion_vector): on
// quads whose motion one frame away is a known translation, every covered
// pixel holds (previous - now, now - next) of its raster position, in
// pixels with y up, for world-space triangles and instances alike, and for
// camera motion through both projections; world pixels hold 0.
#include <gtest/gtest.h>

#include "test_render_helpers.h"

namespace coherent::test {
namespace {

Transform translation(float x, float y, float z) {
    Transform t;
    t.m[0][3] = x, t.m[1][3] = y, t.m[2][3] = z;
    return t;
}

// Left half (x in [-2, 0], y in [-1.5, 1.5], z = 0): world-space triangles;
// right half (x in [0, 2], z = -2): an instance of a prototype. Each with
// the given transforms one frame earlier and later.
Scene two_moving_quads(const Transform left_frames[2], const Transform right_frames[2]) {
    Scene s;
    const uint32_t m = s.add_material(diffuse_material(Vec3f(0.5f), "grey"));
    const float pos[] = {-1, -1.5f, 0, 1, -1.5f, 0, 1, 1.5f, 0, -1, 1.5f, 0};
    const uint32_t idx[] = {0, 1, 2, 0, 2, 3};
    MeshInput in;
    in.name = "left";
    in.positions = pos;
    in.vertex_count = 4;
    in.indices = idx;
    in.triangle_count = 2;
    in.material_slots = {m};
    in.object_to_world = translation(-1, 0, 0);
    in.frame_transforms = left_frames;
    s.add_mesh(in);
    in.name = "right";
    in.frame_transforms = nullptr;
    const uint32_t proto = s.add_prototype(in);
    const Transform place = translation(1, 0, -2);
    EXPECT_EQ(s.add_instances(proto, &place, 1, {m}, "right", nullptr, right_frames), 1u);
    return s;
}

// Resolved Vector pass of a 16 x 16 render.
std::vector<float> render_vector(Scene& s) {
    s.finalize();
    RenderSettings rs;
    rs.width = rs.height = 16;
    rs.spp = 4;
    rs.threads = 2;
    rs.passes = pass_bit(RenderPass::Vector);
    Renderer r(s, rs);
    r.render();
    return r.film().resolve(pass_type(RenderPass::Vector));
}

void expect_vector(const std::vector<float>& v, int x, int y, const float want[4], float tol) {
    const float* p = &v[4 * size_t(y * 16 + x)];
    for (int c = 0; c < 4; ++c) EXPECT_NEAR(p[c], want[c], tol) << "pixel " << x << "," << y << " channel " << c;
}

// Orthographic, 4 pixels per unit. Left: one frame earlier 0.5 to the
// left, one later 0.25 right and 0.5 up. Right: earlier 1 up, later 0.5
// right (a prototype's instance carries its own motion).
TEST(VectorPass, ObjectMotionInPixelsForTrianglesAndInstances) {
    const Transform left[2] = {translation(-1.5f, 0, 0), translation(-0.75f, 0.5f, 0)};
    const Transform right[2] = {translation(1, 1, -2), translation(1.5f, 0, -2)};
    Scene s = two_moving_quads(left, right);
    s.camera = ortho_camera_looking_down(10.0f, 2.0f);
    const auto v = render_vector(s);
    const float want_left[4] = {-2, 0, -1, -2}, want_right[4] = {0, 4, -2, 0}, world[4] = {0, 0, 0, 0};
    for (int y = 3; y < 13; ++y) {
        expect_vector(v, 2, y, want_left, 1e-4f);
        expect_vector(v, 13, y, want_right, 1e-4f);
    }
    // Rows 0 and 15 see only the world (the quads end 2 pixels from the edges).
    for (int x = 0; x < 16; ++x) expect_vector(v, x, 0, world, 0.0f), expect_vector(v, x, 15, world, 0.0f);
}

// Perspective camera 10 above the left quad (12 above the right one), half
// extent 0.2 at distance 1: one frame later it is 0.5 further up (+y), so a
// still point at depth z is seen 0.5 / z / 0.2 * 8 pixels lower then; one
// frame earlier it was 1 to the right, 1 / z / 0.2 * 8 pixels further left.
TEST(VectorPass, CameraMotionThroughThePerspectiveProjection) {
    Scene s = two_moving_quads(nullptr, nullptr);
    s.camera = ortho_camera_looking_down(10.0f, 0.2f);
    s.camera.projection = Projection::Perspective;
    DataPassInputs& d = s.data_passes;
    d.camera_moves = true;
    d.camera_previous = {s.camera.position + Vec3f(1, 0, 0), s.camera.right, s.camera.up, s.camera.forward};
    d.camera_next = {s.camera.position + Vec3f(0, 0.5f, 0), s.camera.right, s.camera.up, s.camera.forward};
    const auto v = render_vector(s);
    for (const float z : {10.0f, 12.0f}) {
        const float want[4] = {-40.0f / z, 0, 0, 20.0f / z};
        for (int y = 6; y < 10; ++y) expect_vector(v, z == 10.0f ? 5 : 10, y, want, 1e-3f);
    }
}

}  // namespace
}  // namespace coherent::test
