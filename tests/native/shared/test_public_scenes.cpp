// The public scenes beside the checkout (../shared/scenes) against the facts
// their SOURCES.md states; CTest label `shared`, run only where ../shared
// exists (./run_tests.sh leaves it out). Twins of the loader checks on the
// generated Cornell box are in ../test_gltf.cpp and run everywhere.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>
#include <string>

#include "accel/bvh.h"
#include "bvh_test_meshes.h"
#include "gltf_fuzz.h"
#include "io/gltf.h"
#include "test_gltf_util.h"

using namespace coherent;
using namespace coherent::testing_meshes;

namespace {

// A public scene that is absent is a failure here: this executable runs only
// when ../shared exists (see tests/CMakeLists.txt).
std::string shared_scene(const std::string& name) { return std::string(COHERENT_SHARED_SCENES) + "/" + name; }

float deg(float d) { return d * kPi / 180.0f; }

void expect_vec_near(const Vec3f& a, const Vec3f& b, float tol) {
    EXPECT_NEAR(a.x, b.x, tol);
    EXPECT_NEAR(a.y, b.y, tol);
    EXPECT_NEAR(a.z, b.z, tol);
}

}  // namespace

TEST(SharedScenes, CornellBoxMatchesSources) {
    Scene scene;
    const GltfLoadResult r = load_gltf(shared_scene("cornell_box.glb"), scene, 1.0f);
    ASSERT_TRUE(r.ok) << r.error;
    EXPECT_TRUE(r.had_camera);
    EXPECT_TRUE(r.had_lights);
    EXPECT_EQ(scene.triangle_count(), 36u);
    EXPECT_TRUE(scene.dropped.empty()) << scene.dropped.summary();
    EXPECT_TRUE(scene.lights.empty());
    EXPECT_TRUE(is_black(scene.world_color));  // lit by its emitter only

    const BBox b = scene.bounds();
    expect_vec_near(b.lo, {-1, 0, -1}, 1e-5f);
    expect_vec_near(b.hi, {1, 2, 1}, 1e-5f);

    // Camera: (0, 1, 6.8) looking down -Z, up +Y, 19.5 degree FOV both ways.
    const Camera& c = scene.camera;
    EXPECT_EQ(c.projection, Projection::Perspective);
    expect_vec_near(c.position, {0, 1, 6.8f}, 1e-5f);
    expect_vec_near(c.forward, {0, 0, -1}, 1e-6f);
    expect_vec_near(c.up, {0, 1, 0}, 1e-6f);
    expect_vec_near(c.right, {1, 0, 0}, 1e-6f);
    EXPECT_NEAR(c.half_height, std::tan(deg(19.5f) / 2), 1e-6f);
    EXPECT_NEAR(c.half_width, std::tan(deg(19.5f) / 2), 1e-6f);
    EXPECT_NEAR(c.clip_start, 0.01f, 1e-7f);
    EXPECT_NEAR(c.clip_end, 1000.0f, 1e-3f);

    // The emitter: radiance (17, 12, 4) on the triangles of the light quad.
    size_t emissive = 0, red = 0;
    for (uint32_t m : scene.material_of) {
        const Material& mat = scene.materials[m];
        if (mat.is_emissive()) {
            ++emissive;
            expect_vec_near(mat.emission, {17.0f, 12.0f, 4.0f}, 0.01f);
            expect_vec_near(mat.closures[0].base_color, {0, 0, 0}, 0.0f);
        }
        if (mat.name == "LeftWall") {
            ++red;
            expect_vec_near(mat.closures[0].base_color, {0.63f, 0.065f, 0.05f}, 1e-6f);
            EXPECT_EQ(mat.closures[0].metallic, 0.0f);
            EXPECT_EQ(mat.closures[0].roughness, 1.0f);  // glTF default roughnessFactor
            EXPECT_EQ(mat.closures[0].transmission, 0.0f);
            EXPECT_EQ(mat.closures[0].specular, 0.5f);
            EXPECT_EQ(mat.closures[0].ior, 1.5f);
        }
    }
    EXPECT_EQ(emissive, 2u);
    EXPECT_EQ(red, 2u);
    // The file has no NORMAL attributes: flat shading everywhere.
    for (uint8_t h : scene.has_normals) EXPECT_EQ(h, 0);
}

TEST(SharedScenes, CornellBoxCameraFollowsRenderAspectLikeBlender) {
    // Blender imports yfov with sensor fit VERTICAL: the vertical FOV stays,
    // the horizontal one follows the render aspect.
    for (float aspect : {2.0f, 0.5f}) {
        Scene scene;
        ASSERT_TRUE(load_gltf(shared_scene("cornell_box.glb"), scene, aspect).ok);
        EXPECT_NEAR(scene.camera.half_height, std::tan(deg(19.5f) / 2), 1e-6f);
        EXPECT_NEAR(scene.camera.half_width, aspect * std::tan(deg(19.5f) / 2), 1e-6f);
    }
}

TEST(SharedScenes, BunnyCameraSunAndNormals) {
    Scene scene;
    const GltfLoadResult r = load_gltf(shared_scene("stanford_bunny.glb"), scene, 1.0f);
    ASSERT_TRUE(r.ok) << r.error;
    EXPECT_EQ(scene.triangle_count(), 69451u);
    EXPECT_TRUE(scene.dropped.empty()) << scene.dropped.summary();

    // SOURCES.md: eye (-0.017, 0.14, 0.37), look-at (-0.017, 0.11, -0.0016), FOV 40 deg.
    const Camera& c = scene.camera;
    expect_vec_near(c.position, {-0.017f, 0.14f, 0.37f}, 1e-5f);
    expect_vec_near(c.forward, normalize(Vec3f(-0.017f, 0.11f, -0.0016f) - c.position), 1e-3f);
    EXPECT_NEAR(dot(c.right, c.up), 0.0f, 1e-6f);
    EXPECT_NEAR(c.right.y, 0.0f, 1e-6f);  // no roll
    EXPECT_NEAR(c.half_height, std::tan(deg(20.0f)), 1e-5f);

    // One sun, strength 3 (2049 lux / 683), travelling along (-0.4, -1, -0.6).
    ASSERT_EQ(scene.lights.size(), 1u);
    const Light& sun = scene.lights[0];
    EXPECT_EQ(sun.type, LightType::Sun);
    EXPECT_NEAR(sun.power, 3.0f, 1e-5f);
    expect_vec_near(sun.color, {1, 1, 1}, 0.0f);
    expect_vec_near(sun.direction, normalize(Vec3f(-0.4f, -1.0f, -0.6f)), 1e-3f);

    // Smooth normals from the file: unit length and close to the face normal.
    size_t with_normals = 0;
    for (size_t t = 0; t < scene.triangle_count(); ++t) {
        if (!scene.has_normals[t]) continue;
        ++with_normals;
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(length(scene.normals[3 * t + k]), 1.0f, 1e-4f);
    }
    EXPECT_EQ(with_normals, scene.triangle_count());
}

TEST(SharedScenes, SponzaCameraAndSun) {
    Scene scene;
    const GltfLoadResult r = load_gltf(shared_scene("crytek_sponza.glb"), scene, 1.0f);
    ASSERT_TRUE(r.ok) << r.error;
    EXPECT_EQ(scene.triangle_count() + scene.dropped.total_triangles(), 262205u);
    EXPECT_LT(scene.dropped.total_triangles(), 1000u);
    const BBox b = scene.bounds();
    expect_vec_near(b.lo, {-192.095f, -12.644f, -118.281f}, 2e-3f);
    expect_vec_near(b.hi, {179.991f, 142.943f, 110.543f}, 2e-3f);
    // eye (-118, 18, -3.6), look-at (100, 32, -3.6), 65 degree FOV.
    expect_vec_near(scene.camera.position, {-118.0f, 18.0f, -3.6f}, 1e-4f);
    expect_vec_near(scene.camera.forward, normalize(Vec3f(218.0f, 14.0f, 0.0f)), 1e-3f);
    EXPECT_NEAR(scene.camera.half_height, std::tan(deg(32.5f)), 1e-5f);
    ASSERT_EQ(scene.lights.size(), 1u);
    EXPECT_NEAR(scene.lights[0].power, 10.0f, 1e-4f);
    expect_vec_near(scene.lights[0].direction, normalize(Vec3f(0.3f, -1.0f, 0.15f)), 1e-3f);
}

TEST(SharedScenes, FuzzedCornellBoxNeverCrashes) {
    const std::string path = shared_scene("cornell_box.glb");
    ASSERT_TRUE(std::filesystem::exists(path)) << path;
    test::expect_fuzzed_glb_never_crashes(test::read_bytes(path), 1234);
}

// A dense scanned mesh (69k triangles, deep trees): every BVH width finds
// exactly the brute-force closest hit. The same check on the generated box
// runs everywhere (BvhScene.GeneratedCornellBoxMatchesBruteForce).
TEST(SharedScenes, StanfordBunnyBvhMatchesBruteForceAtEveryWidth) {
    Scene scene;
    const GltfLoadResult res = load_gltf(shared_scene("stanford_bunny.glb"), scene, 1.0f);
    ASSERT_TRUE(res.ok) << res.error;
    scene.finalize();
    Bvh bvh[3];
    const int widths[3] = {2, 4, 8};
    for (int w = 0; w < 3; ++w) {
        BvhBuildOptions opt;
        opt.width = widths[w];
        bvh[w].build(scene, opt);
    }
    const int n = 400;
    const std::vector<Ray> rays = rays_into_box(scene.bounds(), n, 2024);
    size_t hits = 0;
    for (int i = 0; i < n; ++i) {
        const Ray& ray = rays[size_t(i)];
        const Hit expected = brute_force_closest(scene.vertices, ray);
        hits += expected.valid();
        for (int w = 0; w < 3; ++w) {
            Hit got;
            ASSERT_EQ(bvh[w].intersect(ray, got), expected.valid()) << "width " << widths[w] << " ray " << i;
            EXPECT_EQ(bvh[w].occluded(ray), expected.valid()) << "width " << widths[w] << " ray " << i;
            if (!expected.valid()) continue;
            EXPECT_EQ(got.prim, expected.prim) << "width " << widths[w] << " ray " << i;
            EXPECT_EQ(got.t, expected.t) << "width " << widths[w] << " ray " << i;
        }
    }
    EXPECT_GT(hits, size_t(n / 10));
}
