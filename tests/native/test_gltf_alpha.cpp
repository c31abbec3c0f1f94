// glTF alphaMode (io/gltf.cpp convert_alpha, gltf_textures.cpp texture_alpha):
// BLEND and MASK become a white Transparent closure mixed with the
// Principled one, as Cycles expands a Principled BSDF's Alpha; a base colour
// texture's alpha drives the mix per shading point.
#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>

#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "io/gltf.h"
#include "render/renderer.h"
#include "shader/textures.h"
#include "test_gltf_util.h"

using namespace coherent;
using namespace coherent::test;

namespace {

// A 2 x 2 quad at z = 0 with UVs (glTF v runs down the image).
GltfBuilder quad_with_material(const nlohmann::json& material) {
    GltfBuilder b;
    const std::vector<float> pos = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0};
    const std::vector<float> uv = {0, 1, 1, 1, 1, 0, 0, 0};
    const int p = b.add_vec3(pos);
    const int t = b.add_accessor(b.add_view(uv.data(), uv.size() * 4), 5126, 4, "VEC2");
    const int i = b.add_indices_u16({0, 1, 2, 0, 2, 3});
    b.doc["materials"] = {material};
    b.doc["meshes"] = {{{"primitives", {{{"attributes", {{"POSITION", p}, {"TEXCOORD_0", t}}}, {"indices", i},
                                          {"material", 0}}}}}};
    b.doc["nodes"] = {{{"mesh", 0}}};
    b.doc["scenes"] = {{{"nodes", {0}}}};
    return b;
}

const Material& load_material(const nlohmann::json& material, Scene& scene, TempDir& dir) {
    const GltfLoadResult r = load_gltf(quad_with_material(material).write(dir.path, "alpha.gltf"), scene);
    EXPECT_TRUE(r.ok) << r.error;
    return scene.materials[scene.material_of.at(0)];
}

nlohmann::json pbr(double alpha) {
    return {{"baseColorFactor", {0.8, 0.6, 0.4, alpha}}, {"metallicFactor", 0.0}};
}

}  // namespace

TEST(GltfAlpha, BlendMixesATransparentClosureByTheFactorsAlpha) {
    TempDir dir;
    Scene scene;
    const Material& m = load_material({{"alphaMode", "BLEND"}, {"pbrMetallicRoughness", pbr(0.25)},
                                       {"emissiveFactor", {1.0, 1.0, 1.0}}}, scene, dir);
    ASSERT_EQ(m.closure_count, 2);
    EXPECT_EQ(m.closures[1].kind, ClosureKind::Transparent);
    EXPECT_EQ(m.weights[0], 0.25f);
    EXPECT_EQ(m.weights[1], 0.75f);
    EXPECT_NEAR(m.emission.x, 0.25f, 1e-6f);  // Cycles mixes the emission with the BSDF
}

TEST(GltfAlpha, MaskCutsAtTheCutoffAndOpaqueIgnoresAlpha) {
    TempDir dir;
    Scene a, b, c;
    const Material& cut = load_material({{"alphaMode", "MASK"}, {"alphaCutoff", 0.5}, {"pbrMetallicRoughness", pbr(0.3)}},
                                        a, dir);
    ASSERT_EQ(cut.closure_count, 2);
    EXPECT_EQ(cut.weights[0], 0.0f);
    EXPECT_EQ(cut.weights[1], 1.0f);
    const Material& kept = load_material({{"alphaMode", "MASK"}, {"alphaCutoff", 0.2}, {"pbrMetallicRoughness", pbr(0.3)}},
                                         b, dir);
    EXPECT_EQ(kept.closure_count, 1);
    const Material& opaque = load_material({{"pbrMetallicRoughness", pbr(0.1)}}, c, dir);
    EXPECT_EQ(opaque.closure_count, 1);
    c.finalize();
    EXPECT_FALSE(c.features.transparent);
}

// A texture whose left half has alpha 0.2 and right half 0.9, cut at 0.5:
// seen from above against a white world, the left half shows the world
// unchanged (transparent film: alpha 0) and the right half the surface.
TEST(GltfAlpha, MaskedTextureAlphaCutsTheSurfaceOut) {
    TempDir dir;
    const int n = 8;
    std::vector<float> px(size_t(n * n * 4));
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            float* p = &px[size_t(4 * (y * n + x))];
            p[0] = p[1] = p[2] = 1.0f;
            p[3] = x < n / 2 ? 0.2f : 0.9f;
        }
    const std::string png = (dir.path / "mask.png").string();
    auto out = OIIO::ImageOutput::create(png);
    ASSERT_TRUE(out && out->open(png, OIIO::ImageSpec(n, n, 4, OIIO::TypeDesc::UINT8)));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, px.data()));
    out->close();

    nlohmann::json material = {{"alphaMode", "MASK"}, {"alphaCutoff", 0.5},
                               {"pbrMetallicRoughness", {{"baseColorFactor", {1.0, 1.0, 1.0, 1.0}},
                                                         {"baseColorTexture", {{"index", 0}}}}}};
    GltfBuilder b = quad_with_material(material);
    b.doc["images"] = {{{"uri", "mask.png"}}};
    b.doc["samplers"] = {{{"magFilter", 9728}, {"minFilter", 9728}}};  // nearest
    b.doc["textures"] = {{{"source", 0}, {"sampler", 0}}};
    Scene scene;
    const GltfLoadResult r = load_gltf(b.write(dir.path, "masked.gltf"), scene);
    ASSERT_TRUE(r.ok) << r.error;
    scene.camera = Camera{};
    scene.camera.projection = Projection::Orthographic;
    scene.camera.position = {0.0f, 0.0f, 2.0f};
    scene.camera.right = {1.0f, 0.0f, 0.0f};
    scene.camera.up = {0.0f, 1.0f, 0.0f};
    scene.camera.forward = {0.0f, 0.0f, -1.0f};
    scene.camera.half_width = scene.camera.half_height = 1.0f;
    scene.world_color = Vec3f(1.0f);
    scene.lights.clear();
    scene.finalize();
    ASSERT_TRUE(scene.features.transparent);
    RenderSettings rs;
    rs.width = rs.height = 8;
    rs.spp = 4;
    rs.threads = 1;
    rs.max_bounces = 0;
    rs.transparent_film = true;
    Renderer renderer(scene, rs);
    renderer.render();
    const std::vector<float> rgba = renderer.film().resolve(PassType::Combined);
    for (int y = 0; y < 8; ++y) {
        EXPECT_EQ(rgba[size_t(4 * (y * 8 + 1) + 3)], 0.0f) << "row " << y;  // cut out
        EXPECT_EQ(rgba[size_t(4 * (y * 8 + 6) + 3)], 1.0f) << "row " << y;  // kept
        EXPECT_GT(rgba[size_t(4 * (y * 8 + 6))], 0.1f) << "row " << y;     // lit by the white world
    }
}

// An image embedded in the glTF's buffer and the same PNG beside it, by URI,
// are decoded alike: straight colour (as stored, which the base colour's
// program then premultiplies or keeps by whether alpha is used), where
// OpenImageIO's default read of the embedded bytes had associated it (the
// colour of a half-transparent texel halved, then premultiplied again).
TEST(GltfAlpha, EmbeddedAndReferencedImagesKeepTheirStraightColour) {
    TempDir dir;
    const int n = 4;
    std::vector<uint8_t> px(size_t(n * n * 4));
    for (size_t i = 0; i < px.size(); i += 4) px[i] = 200, px[i + 1] = uint8_t(i * 3), px[i + 2] = 40, px[i + 3] = 128;
    const std::string png = (dir.path / "straight.png").string();
    auto out = OIIO::ImageOutput::create(png);
    OIIO::ImageSpec spec(n, n, 4, OIIO::TypeDesc::UINT8);
    spec.attribute("oiio:UnassociatedAlpha", 1);  // store the values as given
    ASSERT_TRUE(out && out->open(png, spec));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, px.data()));
    out->close();
    std::ifstream file(png, std::ios::binary);
    const std::string encoded((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
    ASSERT_FALSE(encoded.empty());

    const nlohmann::json material = {{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}};
    GltfBuilder embedded = quad_with_material(material), referenced = quad_with_material(material);
    embedded.doc["images"] = {{{"bufferView", embedded.add_view(encoded.data(), encoded.size())},
                               {"mimeType", "image/png"}}};
    referenced.doc["images"] = {{{"uri", "straight.png"}}};
    std::vector<std::vector<float>> texels;
    for (GltfBuilder* b : {&embedded, &referenced}) {
        b->doc["textures"] = {{{"source", 0}}};
        Scene scene;
        const GltfLoadResult r = load_gltf(b->write(dir.path, b == &embedded ? "embedded.gltf" : "referenced.gltf"), scene);
        ASSERT_TRUE(r.ok) << r.error;
        ASSERT_TRUE(scene.shading.textures && scene.shading.textures->size() == 1);
        for (const std::string& w : scene.shading.textures->warnings()) ADD_FAILURE() << w;
        std::vector<float> t;
        TextureLookup closest;
        closest.interp = TextureLookup::Interp::Closest;
        for (int y = 0; y < n; ++y)
            for (int x = 0; x < n; ++x) {
                float c[4];
                scene.shading.textures->lookup(0, (x + 0.5f) / n, (n - 1 - y + 0.5f) / n, closest, c);
                t.insert(t.end(), c, c + 4);
            }
        texels.push_back(t);
    }
    EXPECT_EQ(texels[0], texels[1]);
    for (size_t i = 0; i < px.size(); ++i) EXPECT_FLOAT_EQ(texels[0][i], px[i] / 255.0f) << "value " << i;
}
