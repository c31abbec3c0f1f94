// The BVH Visits heatmap against a case with a known answer: one triangle,
// so the BVH is a single leaf. An orthographic camera looks straight down
// on it; the triangle's bounding box covers whole pixels in the middle of
// the frame. Where a camera ray misses (outside the box, or inside it but
// beside the triangle) it is the sample's only ray, so the pixel's mean is
// exact; where it hits, the path goes on (its MIS ray is traced even at max
// bounces 0) and only adds visits.
//   Wide BVHs (4, 8): the root is an interior node whose one child is the
//   leaf; the root is always visited, the leaf when the ray enters its box:
//   2 visits per sample inside the box, 1 outside.
//   Binary BVH: the root is the leaf, entered only when its box is hit:
//   1 inside, 0 outside.
// "Inside the box" includes the half of the square the triangle does not
// cover: visits count boxes entered, not triangles hit.
#include <gtest/gtest.h>

#include <string>

#include "test_render_helpers.h"

namespace coherent {
namespace {

constexpr int kRes = 16;  // pixel = 0.25 m at the plane (half extent 2 m)

Scene one_triangle_scene() {
    Scene s;
    // Corners at +-1.1 m: the box edges lie inside pixels 3 and 12.
    const float pos[] = {-1.1f, -1.1f, 0.0f, 1.1f, -1.1f, 0.0f, -1.1f, 1.1f, 0.0f};
    const uint32_t idx[] = {0, 1, 2};
    MeshInput m;
    m.name = "triangle";
    m.positions = pos;
    m.vertex_count = 3;
    m.indices = idx;
    m.triangle_count = 1;
    m.material_slots = {s.add_material(test::diffuse_material(Vec3f(0.5f)))};
    s.add_mesh(m);
    s.camera = test::ortho_camera_looking_down(5.0f, 2.0f);
    s.finalize();
    return s;
}

TEST(HeatmapValues, OneLeafBvhGivesExactVisitsPerPixel) {
    const Scene scene = one_triangle_scene();
    for (int width : {2, 4, 8}) {
        RenderSettings rs;
        rs.width = rs.height = kRes;
        rs.spp = 8;
        rs.max_bounces = 0;
        rs.threads = 2;
        rs.heatmaps = true;
        rs.traversal = Traversal::Single;
        rs.bvh_width = width;
        Renderer r(scene, rs);
        ASSERT_EQ(r.bvh().build_stats().leaves, 1u);
        ASSERT_TRUE(r.render());
        const auto visits = r.film().resolve(PassType::NodeVisits);
        const float inside = width == 2 ? 1.0f : 2.0f, outside = width == 2 ? 0.0f : 1.0f;
        // Pixel (x, y) spans world X in [-2 + x / 4, -2 + (x + 1) / 4], Y in
        // [2 - (y + 1) / 4, 2 - y / 4]; the triangle is X + Y < 0 in the box.
        auto in = [](int i) { return i >= 4 && i <= 11; };   // wholly inside [-1.1, 1.1]
        auto out = [](int i) { return i <= 2 || i >= 13; };  // wholly outside
        int missed_in_box = 0, hit = 0, outside_box = 0;
        for (int y = 0; y < kRes; ++y)
            for (int x = 0; x < kRes; ++x) {
                const float v = visits[size_t(y) * kRes + x];
                const std::string where = "width " + std::to_string(width) + " pixel " + std::to_string(x) + "," +
                                          std::to_string(y);
                if (out(x) || out(y)) {
                    EXPECT_EQ(v, outside) << where;
                    ++outside_box;
                } else if (in(x) && in(y) && x - y >= 2) {  // X + Y > 0 over the whole pixel
                    EXPECT_EQ(v, inside) << where;
                    ++missed_in_box;
                } else if (in(x) && in(y) && y - x >= 2) {  // X + Y < 0: every camera ray hits
                    EXPECT_GE(v, inside) << where;
                    ++hit;
                }
            }
        EXPECT_EQ(outside_box, kRes * kRes - 10 * 10);
        EXPECT_EQ(missed_in_box, 21);
        EXPECT_EQ(hit, 21);
        EXPECT_EQ(r.stats().rays[size_t(RayType::Camera)], uint64_t(kRes * kRes * rs.spp));
        // The pass and the statistics count the same visits.
        double total = 0.0;
        for (float v : visits) total += v;
        EXPECT_DOUBLE_EQ(total * rs.spp, double(r.stats().traversal.node_visits)) << "width " << width;
    }
}

}  // namespace
}  // namespace coherent
