// glTF loading: the generated Cornell box against the values its generator
// writes (the public scenes against SOURCES.md are checked in shared/),
// generated files against hand-computed transforms, Blender's importer
// conventions against values Blender 3.4.1 itself reported after importing
// the same light/camera definitions, and malformed files (every one must give
// an error line or a reported drop, never a crash).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <random>

#include "io/gltf.h"
#include "io/gltf_blender.h"
#include "gltf_fuzz.h"
#include "test_fixtures.h"
#include "test_gltf_util.h"

using namespace coherent;
using coherent::test::GltfBuilder;
using coherent::test::TempDir;

namespace {

float deg(float d) { return d * kPi / 180.0f; }

void expect_vec_near(const Vec3f& a, const Vec3f& b, float tol) {
    EXPECT_NEAR(a.x, b.x, tol);
    EXPECT_NEAR(a.y, b.y, tol);
    EXPECT_NEAR(a.z, b.z, tol);
}

bool one_line(const std::string& s) { return !s.empty() && s.find('\n') == std::string::npos; }

// A unit right triangle in the z = 0 plane, its normal +z.
const std::vector<float> kTriangle = {0, 0, 0, 1, 0, 0, 0, 1, 0};

// A scene with one mesh instance of kTriangle under a two-level hierarchy.
GltfBuilder hierarchy_scene(bool child_as_matrix) {
    GltfBuilder b;
    const int pos = b.add_vec3(kTriangle);
    const int nrm = b.add_vec3({0, 0, 1, 0, 0, 1, 0, 0, 1});
    b.doc["meshes"] = {{{"name", "Tri"}, {"primitives", {{{"attributes", {{"POSITION", pos}, {"NORMAL", nrm}}}}}}}};
    nlohmann::json child = {{"mesh", 0}};
    const float s = std::sqrt(0.5f);
    if (child_as_matrix) {
        // Rz(90deg) then translate (0,1,0), column-major.
        child["matrix"] = {0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 1, 0, 0, 1, 0, 1};
    } else {
        child["rotation"] = {0, 0, s, s};
        child["translation"] = {0, 1, 0};
    }
    b.doc["nodes"] = {{{"children", {1}}, {"translation", {10, 0, 0}}, {"scale", {2, 2, 2}}}, child};
    b.doc["scenes"] = {{{"nodes", {0}}}};
    b.doc["scene"] = 0;
    return b;
}

}  // namespace

// --- the generated Cornell box (tests/fixtures/make_gltf.py) ---------------

// Every value below is written by make_gltf.py; the point light's power
// follows Blender's importer (W = cd * 4 pi / 683, as measured in
// PunctualLightsAndOrthoCameraMatchBlender).
TEST(Gltf, GeneratedCornellBoxLoadsEveryFeature) {
    Scene scene;
    ASSERT_TRUE(test::load_fixture("cornell_box.glb", scene));
    EXPECT_EQ(scene.triangle_count(), 564u);  // 6 quads, 2 boxes, a 12x24 UV sphere (528)
    EXPECT_TRUE(scene.dropped.empty()) << scene.dropped.summary();
    EXPECT_TRUE(is_black(scene.world_color));  // the file has lights: no default world

    const BBox b = scene.bounds();
    expect_vec_near(b.lo, {-1, 0, -1}, 1e-5f);
    expect_vec_near(b.hi, {1, 2, 1}, 1e-5f);

    // Camera at (0, 1, 3.9) looking down -Z, vertical FOV 0.69 rad.
    const Camera& c = scene.camera;
    EXPECT_EQ(c.projection, Projection::Perspective);
    expect_vec_near(c.position, {0, 1, 3.9f}, 1e-6f);
    expect_vec_near(c.forward, {0, 0, -1}, 1e-6f);
    expect_vec_near(c.up, {0, 1, 0}, 1e-6f);
    EXPECT_NEAR(c.half_height, std::tan(0.69f / 2), 1e-6f);
    EXPECT_NEAR(c.half_width, std::tan(0.69f / 2), 1e-6f);
    EXPECT_NEAR(c.clip_start, 0.01f, 1e-7f);

    ASSERT_EQ(scene.lights.size(), 1u);
    const Light& point = scene.lights[0];
    EXPECT_EQ(point.type, LightType::Point);
    EXPECT_NEAR(point.power, 2.0f * 1.8398785591125488f / 100.0f, 1e-7f);
    expect_vec_near(point.color, {1.0f, 0.95f, 0.9f}, 1e-6f);
    expect_vec_near(point.position, {-0.5f, 1.6f, 0.6f}, 1e-6f);

    // Triangles per material, and each material's parameters.
    std::map<std::string, size_t> triangles;
    for (size_t t = 0; t < scene.triangle_count(); ++t) {
        const Material& m = scene.materials[scene.material_of[t]];
        ++triangles[m.name];
        EXPECT_EQ(scene.has_normals[t], m.name == "glass" ? 1 : 0) << m.name;  // only the sphere has NORMAL
        const Closure& cl = m.closures[0];
        if (m.name == "light") {
            EXPECT_TRUE(m.is_emissive());
            expect_vec_near(m.emission, {12.0f, 10.2f, 7.2f}, 1e-5f);  // emissiveFactor x emissiveStrength
        } else {
            EXPECT_FALSE(m.is_emissive()) << m.name;
        }
        if (m.name == "red") expect_vec_near(cl.base_color, {0.65f, 0.05f, 0.05f}, 1e-6f);
        if (m.name == "metal") {
            EXPECT_EQ(cl.metallic, 1.0f);
            EXPECT_EQ(cl.roughness, 0.25f);
        }
        if (m.name == "glass") {
            EXPECT_EQ(cl.transmission, 1.0f);
            EXPECT_NEAR(cl.ior, 1.45f, 1e-6f);
            EXPECT_EQ(cl.roughness, 0.0f);
        }
    }
    const std::map<std::string, size_t> expected = {{"white", 18}, {"red", 2}, {"green", 2},
                                                    {"light", 2}, {"metal", 12}, {"glass", 528}};
    EXPECT_EQ(triangles, expected);
}

TEST(Gltf, CameraFollowsRenderAspectLikeBlender) {
    // Blender imports yfov with sensor fit VERTICAL: the vertical FOV stays,
    // the horizontal one follows the render aspect.
    for (float aspect : {2.0f, 0.5f}) {
        Scene scene;
        ASSERT_TRUE(test::load_fixture("cornell_box.glb", scene, aspect));
        EXPECT_NEAR(scene.camera.half_height, std::tan(0.69f / 2), 1e-6f);
        EXPECT_NEAR(scene.camera.half_width, aspect * std::tan(0.69f / 2), 1e-6f);
    }
}

// --- generated files: transforms, attributes, indices --------------------

TEST(Gltf, NodeHierarchyGivesWorldSpaceVertices) {
    for (bool as_matrix : {false, true}) {
        TempDir dir;
        const std::string path = hierarchy_scene(as_matrix).write(dir.path, "h.gltf", /*external=*/as_matrix);
        Scene scene;
        const GltfLoadResult r = load_gltf(path, scene, 1.0f);
        ASSERT_TRUE(r.ok) << r.error;
        ASSERT_EQ(scene.triangle_count(), 1u);
        // Child: Rz(90) p + (0,1,0); parent: 2 q + (10,0,0).
        expect_vec_near(scene.vertices[0], {10, 2, 0}, 1e-5f);
        expect_vec_near(scene.vertices[1], {10, 4, 0}, 1e-5f);
        expect_vec_near(scene.vertices[2], {8, 2, 0}, 1e-5f);
        ASSERT_EQ(scene.has_normals[0], 1);
        for (int k = 0; k < 3; ++k) expect_vec_near(scene.normals[k], {0, 0, 1}, 1e-6f);
        EXPECT_FALSE(r.had_camera);
        EXPECT_FALSE(r.had_lights);
        // No light at all: a uniform white world, as documented.
        expect_vec_near(scene.world_color, {1, 1, 1}, 0.0f);
    }
}

TEST(Gltf, InstancedMeshesAreTransformedPerNodeAndReportedOnce) {
    GltfBuilder b;
    const int pos = b.add_vec3(kTriangle);
    b.doc["meshes"] = {{{"name", "Good"}, {"primitives", {{{"attributes", {{"POSITION", pos}}}}}}},
                       {{"name", "Broken"}, {"primitives", {{{"attributes", {{"POSITION", 42}}}}}}}};
    b.doc["nodes"] = {{{"mesh", 0}, {"translation", {0, 0, -1}}}, {{"mesh", 0}, {"translation", {0, 0, 1}}},
                      {{"mesh", 1}}, {{"mesh", 1}}};
    b.doc["scenes"] = {{{"nodes", {0, 1, 2, 3}}}};
    TempDir dir;
    Scene scene;
    const GltfLoadResult r = load_gltf(b.write(dir.path, "inst.gltf"), scene);
    ASSERT_TRUE(r.ok) << r.error;
    // Placed by two nodes: stored once (object space), instanced per node.
    EXPECT_EQ(scene.triangle_count(), 0u);
    ASSERT_EQ(scene.prototypes.size(), 1u);
    EXPECT_EQ(scene.prototypes[0].triangle_count(), 1u);
    ASSERT_EQ(scene.instances.size(), 2u);
    EXPECT_EQ(scene.instances[0].object_to_world.point(scene.prototypes[0].vertices[0]).z, -1.0f);
    EXPECT_EQ(scene.instances[1].object_to_world.point(scene.prototypes[0].vertices[0]).z, 1.0f);
    ASSERT_EQ(scene.dropped.skipped_meshes.size(), 1u);
    EXPECT_NE(scene.dropped.skipped_meshes[0].find("Broken"), std::string::npos);
}

TEST(Gltf, OutOfRangeIndicesAreDroppedAndCounted) {
    GltfBuilder b;
    const int pos = b.add_vec3(kTriangle);
    // Second triangle uses vertex 7 of 3; third is fine again.
    const int idx = b.add_indices_u16({0, 1, 2, 0, 7, 2, 2, 1, 0});
    b.doc["meshes"] = {{{"primitives", {{{"attributes", {{"POSITION", pos}}}, {"indices", idx}}}}}};
    b.doc["nodes"] = {{{"mesh", 0}}};
    b.doc["scenes"] = {{{"nodes", {0}}}};
    TempDir dir;
    Scene scene;
    const GltfLoadResult r = load_gltf(b.write(dir.path, "oob.gltf"), scene);
    ASSERT_TRUE(r.ok) << r.error;
    EXPECT_EQ(scene.triangle_count(), 2u);
    EXPECT_EQ(scene.dropped.out_of_range_indices, 1u);
}

TEST(Gltf, IndexOutsideItsPrimitiveDoesNotReachAnotherPrimitive) {
    // Two primitives in one mesh: an index valid for the concatenation but not
    // for its own primitive must still be dropped.
    GltfBuilder b;
    const int p0 = b.add_vec3(kTriangle);
    const int p1 = b.add_vec3({5, 0, 0, 6, 0, 0, 5, 1, 0});
    const int i0 = b.add_indices_u8({0, 1, 2, 0, 1, 4});
    const int i1 = b.add_indices_u32({0, 1, 2});
    b.doc["materials"] = {{{"name", "A"}}, {{"name", "B"}, {"pbrMetallicRoughness", {{"baseColorFactor", {0.1, 0.2, 0.3, 1}}}}}};
    b.doc["meshes"] = {{{"primitives",
                         {{{"attributes", {{"POSITION", p0}}}, {"indices", i0}, {"material", 0}},
                          {{"attributes", {{"POSITION", p1}}}, {"indices", i1}, {"material", 1}},
                          {{"attributes", {{"POSITION", p1}}}, {"mode", 1}}}}}};
    b.doc["nodes"] = {{{"mesh", 0}}};
    b.doc["scenes"] = {{{"nodes", {0}}}};
    TempDir dir;
    Scene scene;
    const GltfLoadResult r = load_gltf(b.write(dir.path, "prims.gltf"), scene);
    ASSERT_TRUE(r.ok) << r.error;
    ASSERT_EQ(scene.triangle_count(), 2u);
    EXPECT_EQ(scene.dropped.out_of_range_indices, 1u);
    // Per-primitive materials.
    EXPECT_EQ(scene.materials[scene.material_of[0]].name, "A");
    EXPECT_EQ(scene.materials[scene.material_of[1]].name, "B");
    expect_vec_near(scene.materials[scene.material_of[1]].closures[0].base_color, {0.1f, 0.2f, 0.3f}, 1e-6f);
    // glTF defaults: metallic 1, roughness 1.
    EXPECT_EQ(scene.materials[scene.material_of[0]].closures[0].metallic, 1.0f);
    expect_vec_near(scene.vertices[3], {5, 0, 0}, 0.0f);
    // The LINES primitive is reported with its reason.
    ASSERT_EQ(scene.dropped.skipped_meshes.size(), 1u);
    EXPECT_NE(scene.dropped.skipped_meshes[0].find("TRIANGLES"), std::string::npos) << scene.dropped.skipped_meshes[0];
}

TEST(Gltf, InvalidMaterialIndexUsesDefaultAndIsCounted) {
    GltfBuilder b;
    const int pos = b.add_vec3(kTriangle);
    b.doc["meshes"] = {{{"primitives", {{{"attributes", {{"POSITION", pos}}}, {"material", 5}}}}}};
    b.doc["nodes"] = {{{"mesh", 0}}};
    b.doc["scenes"] = {{{"nodes", {0}}}};
    TempDir dir;
    Scene scene;
    const GltfLoadResult r = load_gltf(b.write(dir.path, "mat.gltf"), scene);
    ASSERT_TRUE(r.ok) << r.error;
    ASSERT_EQ(scene.triangle_count(), 1u);
    EXPECT_EQ(scene.material_of[0], 0u);
    EXPECT_EQ(scene.dropped.bad_material_ids, 1u);
}

TEST(Gltf, InterleavedStridedAndSparseAccessors) {
    GltfBuilder b;
    // Interleaved position+normal, stride 24 bytes.
    std::vector<float> inter = {0, 0, 0, 0, 0, 1, 1, 0, 0, 0, 0, 1, 0, 1, 0, 0, 0, 1};
    const int view = b.add_view(inter.data(), inter.size() * 4);
    b.doc["bufferViews"][size_t(view)]["byteStride"] = 24;
    const int pos = b.add_accessor(view, 5126, 3, "VEC3");
    const int nrm = b.add_accessor(view, 5126, 3, "VEC3");
    b.doc["accessors"][size_t(nrm)]["byteOffset"] = 12;
    // Sparse: vertex 2 of the position accessor is replaced by (0, 3, 0).
    const uint8_t sp_idx[4] = {2, 0, 0, 0};
    const float sp_val[3] = {0, 3, 0};
    const int iv = b.add_view(sp_idx, 1);
    const int vv = b.add_view(sp_val, 12);
    b.doc["accessors"][size_t(pos)]["sparse"] = {
        {"count", 1}, {"indices", {{"bufferView", iv}, {"componentType", 5121}}}, {"values", {{"bufferView", vv}}}};
    b.doc["meshes"] = {{{"primitives", {{{"attributes", {{"POSITION", pos}, {"NORMAL", nrm}}}}}}}};
    b.doc["nodes"] = {{{"mesh", 0}}};
    b.doc["scenes"] = {{{"nodes", {0}}}};
    TempDir dir;
    Scene scene;
    const GltfLoadResult r = load_gltf(b.write(dir.path, "strided.gltf"), scene);
    ASSERT_TRUE(r.ok) << r.error;
    ASSERT_EQ(scene.triangle_count(), 1u);
    expect_vec_near(scene.vertices[1], {1, 0, 0}, 0.0f);
    expect_vec_near(scene.vertices[2], {0, 3, 0}, 0.0f);
    EXPECT_EQ(scene.has_normals[0], 1);
    expect_vec_near(scene.normals[1], {0, 0, 1}, 1e-6f);
}

TEST(Gltf, MaterialExtensions) {
    GltfBuilder b;
    const int pos = b.add_vec3(kTriangle);
    b.doc["materials"] = {{{"name", "Glass"},
                           {"pbrMetallicRoughness", {{"metallicFactor", 0.0}, {"roughnessFactor", 0.1}}},
                           {"emissiveFactor", {0.5, 0.25, 1.0}},
                           {"extensions",
                            {{"KHR_materials_transmission", {{"transmissionFactor", 1.0}}},
                             {"KHR_materials_ior", {{"ior", 1.33}}},
                             {"KHR_materials_emissive_strength", {{"emissiveStrength", 4.0}}}}}}};
    b.doc["meshes"] = {{{"primitives", {{{"attributes", {{"POSITION", pos}}}, {"material", 0}}}}}};
    b.doc["nodes"] = {{{"mesh", 0}}};
    b.doc["scenes"] = {{{"nodes", {0}}}};
    TempDir dir;
    Scene scene;
    const GltfLoadResult r = load_gltf(b.write(dir.path, "ext.gltf"), scene);
    ASSERT_TRUE(r.ok) << r.error;
    const Material& m = scene.materials[scene.material_of.at(0)];
    EXPECT_EQ(m.closures[0].transmission, 1.0f);
    EXPECT_NEAR(m.closures[0].ior, 1.33f, 1e-6f);
    EXPECT_NEAR(m.closures[0].roughness, 0.1f, 1e-6f);
    expect_vec_near(m.emission, {2.0f, 1.0f, 4.0f}, 1e-6f);
    EXPECT_TRUE(r.had_lights);  // an emissive material counts as light
    expect_vec_near(scene.world_color, {0, 0, 0}, 0.0f);
}

TEST(Gltf, TexturesAreIgnoredEvenWhenMissingOrUndecodable) {
    GltfBuilder b;
    const int pos = b.add_vec3(kTriangle);
    const std::string junk = "definitely not a PNG";
    const int junk_view = b.add_view(junk.data(), junk.size());
    b.doc["images"] = {{{"uri", "missing_texture.png"}},
                       {{"uri", "data:image/png;base64," + test::base64(junk)}},
                       {{"bufferView", junk_view}, {"mimeType", "image/png"}}};
    b.doc["textures"] = {{{"source", 0}}, {{"source", 1}}, {{"source", 2}}};
    b.doc["materials"] = {{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}, {"baseColorFactor", {0.5, 0.5, 0.5, 1}}}},
                           {"emissiveTexture", {{"index", 1}}},
                           {"normalTexture", {{"index", 2}}}}};
    b.doc["meshes"] = {{{"primitives", {{{"attributes", {{"POSITION", pos}}}, {"material", 0}}}}}};
    b.doc["nodes"] = {{{"mesh", 0}}};
    b.doc["scenes"] = {{{"nodes", {0}}}};
    TempDir dir;
    Scene scene;
    const GltfLoadResult r = load_gltf(b.write(dir.path, "textured.gltf"), scene);
    ASSERT_TRUE(r.ok) << r.error;
    ASSERT_EQ(scene.triangle_count(), 1u);
    expect_vec_near(scene.materials[scene.material_of[0]].closures[0].base_color, {0.5f, 0.5f, 0.5f}, 0.0f);
}

// --- Blender importer conventions -----------------------------------------

TEST(Gltf, PunctualLightsAndOrthoCameraMatchBlender) {
    // Expected values were printed by Blender 3.4.1 after importing this very
    // set of definitions (bpy.ops.import_scene.gltf, default options).
    GltfBuilder b;
    const int pos = b.add_vec3(kTriangle);
    b.doc["extensionsUsed"] = {"KHR_lights_punctual"};
    b.doc["extensions"] = {{"KHR_lights_punctual",
                            {{"lights",
                              {{{"type", "point"}, {"intensity", 100}, {"color", {1, 0.5, 0.25}}},
                               {{"type", "spot"}, {"intensity", 50}, {"spot", {{"innerConeAngle", 0.2}, {"outerConeAngle", 0.6}}}},
                               {{"type", "directional"}},
                               {{"type", "point"}}}}}}};
    b.doc["meshes"] = {{{"primitives", {{{"attributes", {{"POSITION", pos}}}}}}}};
    b.doc["cameras"] = {{{"type", "orthographic"}, {"orthographic", {{"xmag", 2}, {"ymag", 1.5}, {"znear", 0.1}, {"zfar", 100}}}}};
    const float s = std::sqrt(0.5f);
    b.doc["nodes"] = {{{"mesh", 0}},
                      {{"camera", 0}, {"translation", {0, 0, 5}}},
                      {{"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}, {"translation", {1, 2, 3}}},
                      // Spot rotated -90 deg about X: -Z turns into -Y (pointing down).
                      {{"extensions", {{"KHR_lights_punctual", {{"light", 1}}}}}, {"rotation", {-s, 0, 0, s}}},
                      {{"extensions", {{"KHR_lights_punctual", {{"light", 2}}}}}},
                      {{"extensions", {{"KHR_lights_punctual", {{"light", 3}}}}}}};
    b.doc["scenes"] = {{{"nodes", {0, 1, 2, 3, 4, 5}}}};
    TempDir dir;
    const std::string path = b.write(dir.path, "lights.gltf");

    Scene scene;
    const GltfLoadResult r = load_gltf(path, scene, 1.0f);
    ASSERT_TRUE(r.ok) << r.error;
    EXPECT_TRUE(r.had_lights);
    EXPECT_TRUE(r.had_camera);
    ASSERT_EQ(scene.lights.size(), 4u);
    const Light &point = scene.lights[0], &spot = scene.lights[1], &sun = scene.lights[2], &bare = scene.lights[3];
    EXPECT_EQ(point.type, LightType::Point);
    EXPECT_NEAR(point.power, 1.8398785591125488f, 1e-6f);
    expect_vec_near(point.color, {1.0f, 0.5f, 0.25f}, 0.0f);
    expect_vec_near(point.position, {1, 2, 3}, 0.0f);
    EXPECT_EQ(point.radius, 0.25f);
    EXPECT_EQ(spot.type, LightType::Spot);
    EXPECT_NEAR(spot.power, 0.9199392795562744f, 1e-6f);
    EXPECT_NEAR(spot.spot_size, 1.2000000476837158f, 1e-6f);
    EXPECT_NEAR(spot.spot_blend, 0.6666666865348816f, 1e-6f);
    expect_vec_near(spot.direction, {0, -1, 0}, 1e-6f);
    EXPECT_EQ(sun.type, LightType::Sun);
    EXPECT_EQ(sun.power, 10.0f);  // no intensity: Blender's default energy
    EXPECT_NEAR(sun.sun_angle, 0.009180432185530663f, 1e-7f);
    expect_vec_near(sun.direction, {0, 0, -1}, 0.0f);
    EXPECT_EQ(bare.power, 10.0f);

    // ortho_scale = 2 max(xmag, ymag) = 4, across the larger image dimension.
    EXPECT_EQ(scene.camera.projection, Projection::Orthographic);
    EXPECT_NEAR(scene.camera.half_width, 2.0f, 1e-6f);
    EXPECT_NEAR(scene.camera.half_height, 2.0f, 1e-6f);
    EXPECT_NEAR(scene.camera.clip_start, 0.1f, 1e-7f);
    EXPECT_NEAR(scene.camera.clip_end, 100.0f, 1e-5f);
    for (float aspect : {2.0f, 0.5f}) {
        Scene s2;
        ASSERT_TRUE(load_gltf(path, s2, aspect).ok);
        EXPECT_NEAR(std::max(s2.camera.half_width, s2.camera.half_height), 2.0f, 1e-6f);
        EXPECT_NEAR(s2.camera.half_width / s2.camera.half_height, aspect, 1e-6f);
    }
}

TEST(Gltf, FramingCameraSeesWholeScene) {
    for (float aspect : {1.0f, 1.7f, 0.6f}) {
        BBox box;
        box.expand(Vec3f(-3, 1, 2));
        box.expand(Vec3f(5, 2, 9));
        const Camera c = gltf::framing_camera(box, aspect);
        EXPECT_NEAR(c.half_width / c.half_height, aspect, 1e-5f);
        EXPECT_NEAR(std::min(c.half_width, c.half_height), std::tan(deg(20.0f)), 1e-6f);
        EXPECT_NEAR(dot(c.forward, c.up), 0.0f, 1e-6f);
        EXPECT_NEAR(length(cross(c.right, c.up) - (-c.forward)), 0.0f, 1e-5f);  // right-handed frame
        for (int i = 0; i < 8; ++i) {
            const Vec3f p{i & 1 ? box.hi.x : box.lo.x, i & 2 ? box.hi.y : box.lo.y, i & 4 ? box.hi.z : box.lo.z};
            const Vec3f d = p - c.position;
            const float z = dot(d, c.forward);
            ASSERT_GT(z, c.clip_start);
            ASSERT_LT(z, c.clip_end);
            EXPECT_LE(std::fabs(dot(d, c.right) / z), c.half_width);
            EXPECT_LE(std::fabs(dot(d, c.up) / z), c.half_height);
        }
    }
}

TEST(Gltf, SceneWithoutCameraGetsFramingCamera) {
    TempDir dir;
    Scene scene;
    const GltfLoadResult r = load_gltf(hierarchy_scene(false).write(dir.path, "nocam.gltf"), scene, 1.0f);
    ASSERT_TRUE(r.ok);
    const Camera expected = gltf::framing_camera(scene.bounds(), 1.0f);
    expect_vec_near(scene.camera.position, expected.position, 0.0f);
    expect_vec_near(scene.camera.forward, expected.forward, 0.0f);
}

// --- malformed input --------------------------------------------------------

TEST(Gltf, UnreadableFilesGiveOneLineErrors) {
    TempDir dir;
    std::mt19937 rng(42);
    std::string noise(4096, '\0');
    for (char& c : noise) c = char(rng());
    const std::string glb = test::read_bytes(test::fixture_path("cornell_box.glb"));
    ASSERT_GT(glb.size(), 1000u);
    const std::vector<std::string> paths = {
        (dir.path / "missing.glb").string(),
        dir.file("empty.glb", ""),
        dir.file("noise.glb", noise),
        dir.file("noise.gltf", "glTF" + noise),
        dir.file("text.gltf", "{ this is not json"),
        dir.file("array.gltf", "[1, 2, 3]"),
        dir.file("noversion.gltf", "{\"asset\": {}}"),
        dir.file("truncated.glb", glb.substr(0, glb.size() / 2)),
        dir.file("header_only.glb", glb.substr(0, 20)),
        dir.path.string(),  // a directory
    };
    for (const std::string& path : paths) {
        Scene scene;
        const GltfLoadResult r = load_gltf(path, scene);
        EXPECT_FALSE(r.ok) << path;
        EXPECT_TRUE(one_line(r.error)) << r.error;
        EXPECT_NE(r.error.find(path), std::string::npos) << r.error;  // names the file
    }
}

TEST(Gltf, BrokenReferencesAreErrorsOrReportedDrops) {
    // Each case: a JSON edit of a valid one-triangle file. Structural damage
    // (nodes, meshes, lights) is an error; damaged geometry is a reported drop.
    struct Case {
        const char* name;
        void (*edit)(nlohmann::json&);
        bool loads;
    };
    const Case cases[] = {
        {"accessor index", [](nlohmann::json& d) { d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 99; }, true},
        {"buffer view index", [](nlohmann::json& d) { d["accessors"][0]["bufferView"] = 42; }, true},
        {"accessor count", [](nlohmann::json& d) { d["accessors"][0]["count"] = 1000000; }, true},
        {"huge count", [](nlohmann::json& d) { d["accessors"][0]["count"] = 4000000000u; }, true},
        {"accessor offset", [](nlohmann::json& d) { d["accessors"][0]["byteOffset"] = 1u << 31; }, true},
        {"view overruns buffer", [](nlohmann::json& d) { d["bufferViews"][0]["byteLength"] = 4096; }, true},
        {"view offset", [](nlohmann::json& d) { d["bufferViews"][0]["byteOffset"] = 1u << 30; }, true},
        {"bad stride", [](nlohmann::json& d) { d["bufferViews"][0]["byteStride"] = 4; }, true},
        {"vec2 positions", [](nlohmann::json& d) { d["accessors"][0]["type"] = "VEC2"; }, true},
        {"bad component type", [](nlohmann::json& d) { d["accessors"][0]["componentType"] = 1234; }, false},
        {"bad index accessor", [](nlohmann::json& d) { d["meshes"][0]["primitives"][0]["indices"] = 0; }, true},
        {"missing mesh", [](nlohmann::json& d) { d["nodes"][0]["mesh"] = 3; }, false},
        {"missing child", [](nlohmann::json& d) { d["nodes"][0]["children"] = {7}; }, false},
        {"node cycle", [](nlohmann::json& d) { d["nodes"][0]["children"] = {0}; }, false},
        {"shared children", [](nlohmann::json& d) {
             // 40 levels, each node listing the next one twice: 2^40 instances.
             for (int i = 1; i <= 40; ++i) d["nodes"].push_back({{"children", {i + 1, i + 1}}});
             d["nodes"].push_back({{"mesh", 0}});
             d["scenes"][0]["nodes"] = {1};
         }, false},
        {"missing scene node", [](nlohmann::json& d) { d["scenes"][0]["nodes"] = {5}; }, false},
        {"missing camera", [](nlohmann::json& d) { d["nodes"][0]["camera"] = 2; }, false},
        {"missing light", [](nlohmann::json& d) {
             d["nodes"][0]["extensions"] = {{"KHR_lights_punctual", {{"light", 0}}}};
         }, false},
        {"NaN-free huge values", [](nlohmann::json& d) { d["nodes"][0]["scale"] = {1e38, 1e38, 1e38}; }, true},
    };
    for (const Case& c : cases) {
        GltfBuilder b;
        const int pos = b.add_vec3(kTriangle);
        b.doc["meshes"] = {{{"primitives", {{{"attributes", {{"POSITION", pos}}}}}}}};
        b.doc["nodes"] = {{{"mesh", 0}}};
        b.doc["scenes"] = {{{"nodes", {0}}}};
        c.edit(b.doc);
        TempDir dir;
        Scene scene;
        const GltfLoadResult r = load_gltf(b.write(dir.path, "case.gltf"), scene);
        if (!r.ok) {
            EXPECT_FALSE(c.loads) << c.name << ": " << r.error;
            EXPECT_TRUE(one_line(r.error)) << c.name;
            continue;
        }
        EXPECT_TRUE(c.loads) << c.name << " loaded";
        // Loaded: the damage must be visible in the drop report.
        EXPECT_EQ(scene.triangle_count(), 0u) << c.name;
        EXPECT_FALSE(scene.dropped.empty()) << c.name;
        for (const Vec3f& v : scene.vertices) EXPECT_TRUE(is_finite(v)) << c.name;
    }
}

TEST(Gltf, FuzzedCornellBoxNeverCrashes) {
    test::expect_fuzzed_glb_never_crashes(test::read_bytes(test::fixture_path("cornell_box.glb")), 1234);
}
