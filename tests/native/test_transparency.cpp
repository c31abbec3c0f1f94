// Transparent, Translucent and Holdout closures (render/transparency.h):
// closed-form checks on scenes lit by a sun straight down, seen by an
// orthographic camera looking down, with direct light only, so every
// pixel's value is known.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "test_render_helpers.h"

using namespace coherent;
using namespace coherent::test;

namespace {

constexpr int kSize = 12;

Material closure_material(ClosureKind kind, const Vec3f& color, const char* name) {
    Material m;
    m.name = name;
    m.closures[0].kind = kind;
    m.closures[0].base_color = color;
    return m;
}

Light sun_down(float irradiance) {
    Light l;
    l.type = LightType::Sun;
    l.direction = {0.0f, 0.0f, -1.0f};
    l.power = irradiance;
    return l;
}

RenderSettings direct_settings(int spp = 1, Traversal traversal = Traversal::Single) {
    RenderSettings rs;
    rs.width = rs.height = kSize;
    rs.spp = spp;
    rs.max_bounces = 0;
    rs.threads = 2;
    rs.traversal = traversal;
    return rs;
}

// A white Lambert floor at z = 0 under the sun; the camera at z = 2 sees only
// the floor. Quads at z > 2 shade the floor without being seen.
Scene floor_scene(const std::vector<uint32_t>& overhead_materials = {}, std::vector<Material> extra = {}) {
    Scene s;
    for (Material& m : extra) s.add_material(m);
    const uint32_t floor = s.add_material(diffuse_material(Vec3f(1.0f), "floor"));
    add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 8, 8, floor, "floor");
    float z = 3.0f;
    for (uint32_t m : overhead_materials) {
        add_quad(s, {0, 0, z}, {1, 0, 0}, {0, 1, 0}, 8, 8, m, "overhead");
        z += 0.5f;
    }
    s.lights.push_back(sun_down(3.0f));
    s.camera = ortho_camera_looking_down(2.0f, 1.0f);
    s.finalize();
    return s;
}

Vec3f mean_rgb(const std::vector<float>& rgba) {
    Vec3f m(0.0f);
    for (size_t i = 0; i < rgba.size(); i += 4) m += Vec3f{rgba[i], rgba[i + 1], rgba[i + 2]};
    return m / float(rgba.size() / 4);
}

}  // namespace

TEST(Transparency, TransparentSurfaceAttenuatesShadowRayByItsColour) {
    const Vec3f c{0.2f, 0.5f, 0.8f};
    const Scene open = floor_scene();
    Scene shaded = floor_scene({1}, {closure_material(ClosureKind::Transparent, c, "filter")});
    EXPECT_TRUE(shaded.features.transparent);
    EXPECT_FALSE(open.features.transparent);
    const Vec3f lit = mean_rgb(render_combined(open, direct_settings()));
    ASSERT_GT(lit.x, 0.5f);  // the sun's 3 W/m^2 on a white Lambert floor: 3 / pi
    EXPECT_NEAR(lit.x, 3.0f / kPi, 1e-4f);
    const Vec3f through = mean_rgb(render_combined(shaded, direct_settings()));
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(through[k], c[k] * lit[k], 1e-5f) << "channel " << k;
}

TEST(Transparency, ShadowRaysCrossAtMostTransparentMaxBouncesSurfaces) {
    const Vec3f c(0.5f);
    const Scene three = floor_scene({1, 1, 1}, {closure_material(ClosureKind::Transparent, c, "filter")});
    RenderSettings rs = direct_settings();
    rs.transparent_max_bounces = 3;
    EXPECT_NEAR(mean_rgb(render_combined(three, rs)).y, 0.125f * 3.0f / kPi, 1e-5f);
    rs.transparent_max_bounces = 2;  // the third filter blocks the light
    EXPECT_EQ(mean_rgb(render_combined(three, rs)).y, 0.0f);
}

TEST(Transparency, OpaqueSurfaceBehindTransparentOneStillBlocks) {
    Material opaque = diffuse_material(Vec3f(0.5f), "opaque");
    const Scene s = floor_scene({1, 2}, {closure_material(ClosureKind::Transparent, Vec3f(1.0f), "clear"), opaque});
    EXPECT_EQ(mean_rgb(render_combined(s, direct_settings())).x, 0.0f);
}

// The camera sees the floor through a coloured transparent quad: the floor's
// radiance, itself lit through the quad, times the colour again.
TEST(Transparency, CameraRaysPassThroughWithoutCountingABounce) {
    const Vec3f c{0.3f, 0.6f, 0.9f};
    Scene s;
    const uint32_t filter = s.add_material(closure_material(ClosureKind::Transparent, c, "filter"));
    const uint32_t floor = s.add_material(diffuse_material(Vec3f(1.0f), "floor"));
    add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 8, 8, floor, "floor");
    add_quad(s, {0, 0, 1}, {1, 0, 0}, {0, 1, 0}, 8, 8, filter, "filter");
    s.lights.push_back(sun_down(3.0f));
    s.camera = ortho_camera_looking_down(2.0f, 1.0f);
    s.finalize();
    const std::vector<float> single = render_combined(s, direct_settings(2));  // max_bounces 0 still sees the floor
    const Vec3f m = mean_rgb(single);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(m[k], c[k] * c[k] * 3.0f / kPi, 1e-5f) << "channel " << k;
    // Every traversal traces the same rays and shades them the same way.
    for (Traversal t : {Traversal::Packet, Traversal::Stream, Traversal::Wavefront})
        EXPECT_EQ(render_combined(s, direct_settings(2, t)), single) << "traversal " << int(t);
}

// A Principled-style surface at 50 % alpha (weights 0.5 diffuse, 0.5 white
// transparent) over the floor, both lit from above: the camera sees half
// the surface's radiance plus half the floor's, the floor half in shadow.
TEST(Transparency, StochasticAlphaConvergesToTheMix) {
    Scene s;
    Material half = diffuse_material(Vec3f(0.4f), "half");
    half.closures[1].kind = ClosureKind::Transparent;
    half.closures[1].base_color = Vec3f(1.0f);
    half.weights = {0.5f, 0.5f, 0.0f, 0.0f};
    half.closure_count = 2;
    const uint32_t leaf = s.add_material(half);
    const uint32_t floor = s.add_material(diffuse_material(Vec3f(1.0f), "floor"));
    add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 8, 8, floor, "floor");
    add_quad(s, {0, 0, 1}, {1, 0, 0}, {0, 1, 0}, 8, 8, leaf, "leaf");
    s.lights.push_back(sun_down(3.0f));
    s.camera = ortho_camera_looking_down(2.0f, 1.0f);
    s.finalize();
    const float e = 3.0f / kPi;
    const float expected = 0.5f * 0.4f * e + 0.5f * (0.5f * e);
    const std::vector<float> img = render_combined(s, direct_settings(256));
    EXPECT_NEAR(mean_rgb(img).x, expected, 0.01f * expected);
    for (Traversal t : {Traversal::Packet, Traversal::Stream, Traversal::Wavefront})
        EXPECT_EQ(render_combined(s, direct_settings(256, t)), img) << "traversal " << int(t);
}

// A translucent quad lit from behind shines on the camera's side like a
// Lambert surface of the same colour lit from the front.
TEST(Transparency, TranslucentLeafLitFromBehindMatchesLambertLitFromFront) {
    auto leaf_scene = [](ClosureKind kind, float sun_z) {
        Scene s;
        const uint32_t m = s.add_material(closure_material(kind, Vec3f(0.25f, 0.5f, 0.75f), "leaf"));
        add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 8, 8, m, "leaf");
        Light l = sun_down(2.0f);
        l.direction = normalize(Vec3f{0.0f, 0.6f, sun_z});
        s.lights.push_back(l);
        s.camera = ortho_camera_looking_down(2.0f, 1.0f);
        s.finalize();
        return s;
    };
    const Vec3f translucent = mean_rgb(render_combined(leaf_scene(ClosureKind::Translucent, 0.8f), direct_settings()));
    // Reference: a Lambert quad of the same colour lit from the camera's side.
    Scene ref;
    const uint32_t m = ref.add_material(diffuse_material(Vec3f(0.25f, 0.5f, 0.75f), "leaf"));
    add_quad(ref, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 8, 8, m, "leaf");
    Light l = sun_down(2.0f);
    l.direction = normalize(Vec3f{0.0f, 0.6f, -0.8f});
    ref.lights.push_back(l);
    ref.camera = ortho_camera_looking_down(2.0f, 1.0f);
    ref.finalize();
    const Vec3f front = mean_rgb(render_combined(ref, direct_settings()));
    ASSERT_GT(front.z, 0.0f);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(translucent[k], front[k], 1e-5f) << "channel " << k;
    // Lit from the camera's side, a translucent surface shows nothing.
    EXPECT_EQ(mean_rgb(render_combined(leaf_scene(ClosureKind::Translucent, -0.8f), direct_settings())).z, 0.0f);
}

// A holdout quad in the middle of the view: black with alpha 0 where seen
// directly, and through a 50 % transparent filter alpha 0.5.
TEST(Transparency, HoldoutCutsAlphaAndColour) {
    Scene s;
    const uint32_t hold = s.add_material(closure_material(ClosureKind::Holdout, Vec3f(1.0f), "holdout"));
    const uint32_t floor = s.add_material(diffuse_material(Vec3f(1.0f), "floor"));
    add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 8, 8, floor, "floor");
    add_quad(s, {-0.5f, 0, 0.5f}, {1, 0, 0}, {0, 1, 0}, 1, 4, hold, "holdout");  // the left half of the view
    s.lights.push_back(sun_down(3.0f));
    s.camera = ortho_camera_looking_down(2.0f, 1.0f);
    s.finalize();
    EXPECT_TRUE(s.features.holdout);
    const std::vector<float> img = render_combined(s, direct_settings());
    const int row = kSize / 2;
    const float* left = &img[4 * size_t(row * kSize + 2)];
    const float* right = &img[4 * size_t(row * kSize + kSize - 3)];
    EXPECT_EQ(left[3], 0.0f);
    EXPECT_EQ(left[0], 0.0f);
    EXPECT_EQ(right[3], 1.0f);
    EXPECT_GT(right[0], 0.0f);
}

// Shared geometry: the filter of CameraRaysPassThroughWithoutCountingABounce
// as two instances of one quad (one seen by the camera, one above it shading
// the floor): camera and shadow rays pass instances as they pass meshes.
TEST(Transparency, InstancedTransparentSurfacesPassCameraAndShadowRays) {
    const Vec3f c{0.3f, 0.6f, 0.9f};
    Scene s;
    const uint32_t filter = s.add_material(closure_material(ClosureKind::Transparent, c, "filter"));
    const uint32_t floor = s.add_material(diffuse_material(Vec3f(1.0f), "floor"));
    add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 8, 8, floor, "floor");
    const float pos[] = {-4, -4, 0, 4, -4, 0, 4, 4, 0, -4, 4, 0};
    const uint32_t idx[] = {0, 1, 2, 0, 2, 3};
    MeshInput quad;
    quad.name = "filter";
    quad.positions = pos;
    quad.vertex_count = 4;
    quad.indices = idx;
    quad.triangle_count = 2;
    const uint32_t proto = s.add_prototype(quad);
    Transform at[2];
    at[0].m[2][3] = 1.0f;  // between the camera and the floor
    at[1].m[2][3] = 3.0f;  // above the camera: only shadow rays meet it
    ASSERT_EQ(s.add_instances(proto, at, 2, {filter}, "filters"), 2u);
    s.lights.push_back(sun_down(3.0f));
    s.camera = ortho_camera_looking_down(2.0f, 1.0f);
    s.finalize();
    ASSERT_TRUE(s.features.transparent);
    const std::vector<float> single = render_combined(s, direct_settings(2));
    const Vec3f m = mean_rgb(single);
    // Through the seen filter once, and the light through both filters.
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(m[k], c[k] * c[k] * c[k] * 3.0f / kPi, 1e-5f) << "channel " << k;
    for (Traversal t : {Traversal::Packet, Traversal::Stream, Traversal::Wavefront})
        EXPECT_EQ(render_combined(s, direct_settings(2, t)), single) << "traversal " << int(t);
}

// A clear transparent quad above an area light changes nothing: a floor's
// BSDF ray meets the light, then the quad, and goes on past it without
// meeting the light a second time (hit_lights' tmin).
TEST(Transparency, RayContinuedPastASurfaceDoesNotMeetTheLightsBeforeItAgain) {
    auto scene = [](bool with_quad) {
        Scene s;
        const uint32_t clear = s.add_material(closure_material(ClosureKind::Transparent, Vec3f(1.0f), "clear"));
        const uint32_t floor = s.add_material(diffuse_material(Vec3f(0.8f), "floor"));
        add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 8, 8, floor, "floor");
        if (with_quad) add_quad(s, {0, 0, 3}, {1, 0, 0}, {0, 1, 0}, 8, 8, clear, "clear");
        Light l;
        l.type = LightType::Area;
        l.position = {0.0f, 0.0f, 1.0f};
        l.direction = {0.0f, 0.0f, -1.0f};
        l.size_u = l.size_v = 1.0f;
        l.power = 20.0f;
        s.lights.push_back(l);
        s.camera = ortho_camera_looking_down(0.5f, 1.0f);
        s.finalize();
        return s;
    };
    RenderSettings rs = direct_settings(16);
    const Vec3f without = mean_rgb(render_combined(scene(false), rs));
    const Vec3f with = mean_rgb(render_combined(scene(true), rs));
    ASSERT_GT(without.x, 0.1f);
    EXPECT_NEAR(with.x, without.x, 1e-5f * without.x);
}
