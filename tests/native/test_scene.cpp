// Scene validation (what add_mesh drops and why) and SceneFeatures.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "scene/scene.h"
#include "test_render_helpers.h"

using namespace coherent;
using namespace coherent::test;

namespace {

MeshInput mesh_of(const std::vector<float>& pos, const std::vector<uint32_t>& idx, const char* name) {
    MeshInput m;
    m.name = name;
    m.positions = pos.data();
    m.vertex_count = pos.size() / 3;
    m.indices = idx.data();
    m.triangle_count = idx.size() / 3;
    return m;
}

TEST(SceneValidation, DropsNonFiniteOutOfRangeAndDegenerate) {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float inf = std::numeric_limits<float>::infinity();
    Scene s;
    // 0..2: a good triangle; 3: NaN vertex; 4: Inf vertex; 5,6: collinear with 0.
    std::vector<float> pos = {0, 0, 0, 1, 0, 0, 0, 1, 0, nan, 0, 0, 0, inf, 0, 2, 0, 0, 3, 0, 0};
    std::vector<uint32_t> idx = {
        0, 1, 2,   // good
        0, 1, 3,   // NaN
        4, 1, 2,   // Inf
        0, 1, 99,  // out of range
        0, 1, 5,   // collinear: zero area
        1, 1, 2,   // repeated vertex: zero area
        2, 1, 0,   // good (other winding)
    };
    const size_t added = s.add_mesh(mesh_of(pos, idx, "Foo"));
    EXPECT_EQ(added, 2u);
    EXPECT_EQ(s.triangle_count(), 2u);
    EXPECT_EQ(s.dropped.nonfinite_vertices, 2u);
    EXPECT_EQ(s.dropped.out_of_range_indices, 1u);
    EXPECT_EQ(s.dropped.degenerate_triangles, 2u);
    EXPECT_EQ(s.dropped.total_triangles(), 5u);
    EXPECT_TRUE(s.dropped.skipped_meshes.empty());

    // A mesh where nothing survives is skipped as a whole, with a reason.
    std::vector<float> pos2 = {0, 0, 0, 1, 0, 0, 2, 0, 0};
    std::vector<uint32_t> idx2 = {0, 1, 2};
    EXPECT_EQ(s.add_mesh(mesh_of(pos2, idx2, "Bar")), 0u);
    ASSERT_EQ(s.dropped.skipped_meshes.size(), 1u);
    EXPECT_NE(s.dropped.skipped_meshes[0].find("Bar"), std::string::npos);

    const std::string summary = s.dropped.summary();
    EXPECT_NE(summary.find("dropped 6 triangles"), std::string::npos) << summary;
    EXPECT_NE(summary.find("2 non-finite vertex"), std::string::npos) << summary;
    EXPECT_NE(summary.find("1 out-of-range index"), std::string::npos) << summary;
    EXPECT_NE(summary.find("3 degenerate"), std::string::npos) << summary;
    EXPECT_NE(summary.find("in meshes: Foo, Bar"), std::string::npos) << summary;
    for (const Vec3f& v : s.vertices) EXPECT_TRUE(is_finite(v));
}

TEST(SceneValidation, CleanSceneHasEmptySummary) {
    Scene s;
    add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1, 1, 0);
    EXPECT_TRUE(s.dropped.empty());
    EXPECT_EQ(s.dropped.summary(), "");
}

TEST(SceneValidation, TransformsToWorldSpaceAndNormalsWithInverseTranspose) {
    Scene s;
    // Non-uniform scale: x * 2, then translate by (10, 0, 0). A normal
    // (1, 1, 0)/sqrt2 of a surface transforms with the inverse transpose to
    // (0.5, 1, 0) normalised, not to (2, 1, 0).
    std::vector<float> pos = {0, 0, 0, 1, -1, 0, 0, 0, 1};
    std::vector<uint32_t> idx = {0, 1, 2};
    const float r = 1.0f / std::sqrt(2.0f);
    std::vector<float> nrm = {r, r, 0, r, r, 0, r, r, 0};
    MeshInput m = mesh_of(pos, idx, "Scaled");
    m.normals = nrm.data();
    m.object_to_world.m[0][0] = 2.0f;
    m.object_to_world.m[0][3] = 10.0f;
    ASSERT_EQ(s.add_mesh(m), 1u);
    EXPECT_FLOAT_EQ(s.vertices[1].x, 12.0f);
    EXPECT_FLOAT_EQ(s.vertices[1].y, -1.0f);
    const Vec3f expect = normalize(Vec3f(0.5f, 1.0f, 0.0f));
    EXPECT_NEAR(s.normals[0].x, expect.x, 1e-6f);
    EXPECT_NEAR(s.normals[0].y, expect.y, 1e-6f);
    EXPECT_NEAR(s.normals[0].z, 0.0f, 1e-6f);
    EXPECT_EQ(s.has_normals[0], 1);
    // The shading normal stays perpendicular to the world-space surface.
    s.finalize();
    EXPECT_NEAR(std::fabs(dot(s.geometric_normals[0], s.normals[0])), 1.0f, 1e-5f);
}

TEST(SceneValidation, MirrorTransformKeepsNormalsAndWindingConsistent) {
    Scene s;
    std::vector<float> pos = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    std::vector<uint32_t> idx = {0, 1, 2};
    std::vector<float> nrm = {0, 0, 1, 0, 0, 1, 0, 0, 1};
    MeshInput m = mesh_of(pos, idx, "Mirrored");
    m.normals = nrm.data();
    m.object_to_world.m[0][0] = -1.0f;  // mirror in x
    ASSERT_EQ(s.add_mesh(m), 1u);
    s.finalize();
    // Shading and geometric normals agree after the winding swap.
    EXPECT_GT(dot(s.geometric_normals[0], s.normals[0]), 0.99f);
}

TEST(SceneValidation, NonFiniteNormalFallsBackToGeometricNormal) {
    Scene s;
    std::vector<float> pos = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    std::vector<uint32_t> idx = {0, 1, 2};
    const float nan = std::numeric_limits<float>::quiet_NaN();
    std::vector<float> nrm = {nan, 0, 1, 0, 0, 0, 0, 0, 1};  // NaN, zero, fine
    MeshInput m = mesh_of(pos, idx, "BadNormals");
    m.normals = nrm.data();
    ASSERT_EQ(s.add_mesh(m), 1u);
    for (int k = 0; k < 3; ++k) {
        EXPECT_TRUE(is_finite(s.normals[k]));
        EXPECT_NEAR(s.normals[k].z, 1.0f, 1e-6f);
    }
}

TEST(SceneValidation, BadMaterialIdsUseDefaultAndAreCounted) {
    Scene s;
    const uint32_t red = s.add_material(diffuse_material({1, 0, 0}));
    std::vector<float> pos = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
    std::vector<uint32_t> idx = {0, 1, 2, 1, 3, 2};
    std::vector<uint32_t> ids = {0, 5};  // slot 5 does not exist
    MeshInput m = mesh_of(pos, idx, "Slots");
    m.material_ids = ids.data();
    m.material_slots = {red};
    ASSERT_EQ(s.add_mesh(m), 2u);
    EXPECT_EQ(s.material_of[0], red);
    EXPECT_EQ(s.material_of[1], 0u);
    EXPECT_EQ(s.dropped.bad_material_ids, 1u);
    EXPECT_NE(s.dropped.summary().find("invalid material"), std::string::npos);
}

TEST(SceneValidation, SingularTransformDropsEverythingAsDegenerate) {
    Scene s;
    std::vector<float> pos = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    std::vector<uint32_t> idx = {0, 1, 2};
    MeshInput m = mesh_of(pos, idx, "Flat");
    m.object_to_world.m[1][1] = 0.0f;  // squashes y: the triangle has no area
    EXPECT_EQ(s.add_mesh(m), 0u);
    EXPECT_EQ(s.dropped.degenerate_triangles, 1u);
    EXPECT_EQ(s.dropped.skipped_meshes.size(), 1u);
}

TEST(SceneFeatures, GlassOnlyWhenATransmissionClosureIsUsed) {
    Scene s;
    Material glass;
    glass.closures[0].transmission = 1.0f;
    glass.closures[0].roughness = 0.0f;
    const uint32_t g = s.add_material(glass);  // added but not used yet
    add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1, 1, 0);
    s.finalize();
    EXPECT_FALSE(s.features.glass);
    EXPECT_TRUE(s.features.diffuse);
    EXPECT_FALSE(s.features.any_light());

    add_quad(s, {0, 0, 1}, {1, 0, 0}, {0, 1, 0}, 1, 1, g);
    s.finalize();
    EXPECT_TRUE(s.features.glass);
    EXPECT_FALSE(s.features.glossy);  // smooth, fully transmissive: only the glass lobe
}

TEST(SceneFeatures, LobesLightsWorldAndDepthOfField) {
    Scene s;
    Material metal;
    metal.closures[0].metallic = 1.0f;
    metal.closures[0].roughness = 0.4f;
    const uint32_t m = s.add_material(metal);
    Material mirror;
    mirror.closures[0].metallic = 1.0f;
    mirror.closures[0].roughness = 0.0f;
    const uint32_t mi = s.add_material(mirror);
    add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1, 1, m);
    s.finalize();
    EXPECT_TRUE(s.features.glossy);
    EXPECT_FALSE(s.features.specular);
    EXPECT_FALSE(s.features.diffuse);  // fully metallic: no diffuse lobe
    EXPECT_FALSE(s.features.depth_of_field);

    add_quad(s, {0, 0, 1}, {1, 0, 0}, {0, 1, 0}, 1, 1, mi);
    Light sun;
    sun.type = LightType::Sun;
    s.lights.push_back(sun);
    Light dark;  // zero power: not a light
    dark.type = LightType::Area;
    dark.power = 0.0f;
    s.lights.push_back(dark);
    s.world_color = {0.1f, 0.0f, 0.0f};
    s.camera.aperture_radius = 0.01f;
    s.finalize();
    EXPECT_TRUE(s.features.specular);
    EXPECT_TRUE(s.features.sun_lights);
    EXPECT_FALSE(s.features.area_lights);
    EXPECT_FALSE(s.features.point_lights);
    EXPECT_TRUE(s.features.world_light);
    EXPECT_TRUE(s.features.depth_of_field);
    const auto names = s.features.names();
    EXPECT_NE(std::find(names.begin(), names.end(), "depth_of_field"), names.end());
    EXPECT_EQ(SceneFeatures::all().names().size(), 14u);  // transparent and holdout included
    EXPECT_FALSE(s.features.motion_blur);  // nothing moves
}

TEST(SceneFeatures, EmissiveMeshesAndEmissiveTriangleList) {
    Scene s;
    const uint32_t e = s.add_material(emission_material({1, 1, 1}));
    add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1, 1, 0);
    add_quad(s, {0, 0, 1}, {1, 0, 0}, {0, 1, 0}, 1, 1, e);
    s.finalize();
    EXPECT_TRUE(s.features.emissive_meshes);
    ASSERT_EQ(s.emissive_triangles.size(), 2u);
    EXPECT_EQ(s.emissive_triangles[0], 2u);
    EXPECT_EQ(s.emissive_triangles[1], 3u);
}

}  // namespace
