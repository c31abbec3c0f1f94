// Shader programs (native/shader): validation, the interpreter against
// hand-computed values, and the OIIO-backed texture store.
#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "scene/scene.h"
#include "shader/eval.h"
#include "shader/node_color.h"
#include "shader/node_math.h"
#include "shader/program.h"
#include "shader_test_helpers.h"
#include "shader/textures.h"

namespace coherent {
namespace {

using test::instr;

TEST(ShaderProgram, ValidateRejectsRegistersOutsideTheFile) {
    ShaderProgram p;
    p.constants.assign(4, 0.0f);
    p.code.push_back(instr(ShaderOp::Math, 0, {3}, {0, 1, 2}));
    EXPECT_EQ(p.validate(0, 0), "");
    p.code.push_back(instr(ShaderOp::VectorMath, 0, {2}, {0, 1, 1, 0}));  // vec3 output at 2 needs 2..4
    EXPECT_NE(p.validate(0, 0).find("output 0"), std::string::npos);
}

TEST(ShaderProgram, ValidateRejectsMissingImagesUvLayersAndUnknownModes) {
    ShaderProgram p;
    p.constants.assign(8, 0.0f);
    p.code.push_back(instr(ShaderOp::ImageTexture, 0, {0, 3}, {4}, /*image*/ 2));
    EXPECT_NE(p.validate(2, 0).find("image 2"), std::string::npos);
    EXPECT_EQ(p.validate(3, 0), "");
    p.code = {instr(ShaderOp::TexCoord, uint16_t(TexCoordKind::Uv), {0}, {}, /*layer*/ 1)};
    EXPECT_NE(p.validate(0, 1).find("UV layer 1"), std::string::npos);
    p.code = {instr(ShaderOp::Math, uint16_t(shader::MathOp::Count), {0}, {1, 2, 3})};
    EXPECT_NE(p.validate(0, 0).find("unknown"), std::string::npos);
}

TEST(ShaderNodes, MathFollowsCyclesSafeConventions) {
    using shader::MathOp;
    EXPECT_EQ(shader::svm_math(MathOp::Divide, 1.0f, 0.0f, 0.0f), 0.0f);
    EXPECT_EQ(shader::svm_math(MathOp::Power, -2.0f, 0.5f, 0.0f), 0.0f);
    EXPECT_EQ(shader::svm_math(MathOp::Power, -2.0f, 3.0f, 0.0f), -8.0f);
    EXPECT_EQ(shader::svm_math(MathOp::Logarithm, -1.0f, 2.0f, 0.0f), 0.0f);
    EXPECT_FLOAT_EQ(shader::svm_math(MathOp::Wrap, 5.5f, 2.0f, 0.0f), 1.5f);
    EXPECT_FLOAT_EQ(shader::svm_math(MathOp::Pingpong, 3.0f, 2.0f, 0.0f), 1.0f);
    EXPECT_EQ(shader::svm_math(MathOp::Compare, 1.0f, 1.05f, 0.1f), 1.0f);
}

TEST(ShaderNodes, HsvRoundTripsAndCheckerAlternates) {
    const Vec3f c{0.2f, 0.7f, 0.4f};
    const Vec3f back = shader::hsv_to_rgb(shader::rgb_to_hsv(c));
    EXPECT_NEAR(back.x, c.x, 1e-6f);
    EXPECT_NEAR(back.y, c.y, 1e-6f);
    EXPECT_NEAR(back.z, c.z, 1e-6f);
    EXPECT_NE(shader::svm_checker({0.5f, 0.5f, 0.5f}), shader::svm_checker({1.5f, 0.5f, 0.5f}));
}

// Image textures convert sRGB as Cycles' CPU kernels do (fastpow24: a bit
// trick and three Newton steps instead of powf). Cycles states its error as
// better than glibc's powf; the oracle here is std::pow in double precision.
TEST(ShaderNodes, FastPow24AndImageSrgbAgreeWithPow) {
    double worst = 0.0;
    for (double x = 1e-8; x < 1e8; x *= 1.0007) {
        const double exact = std::pow(double(float(x)), 2.4);
        worst = std::max(worst, std::fabs(double(shader::fastpow24(float(x))) - exact) / exact);
    }
    EXPECT_LT(worst, 2e-6);
    for (int i = 0; i <= 100000; ++i) {
        const float c = float(i) / 100000.0f;
        const double exact = c < 0.04045f ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
        ASSERT_NEAR(shader::srgb_to_linear_image(c), exact, 2e-6 * exact + 1e-9) << c;
    }
    // Outside [0, 1]: black below, and finite far above fastpow24's domain
    // (float images), where the power of four would overflow.
    EXPECT_EQ(shader::srgb_to_linear_image(-0.5f), 0.0f);
    for (float c : {2.0f, 1e3f, 1e9f, 1e12f, 3e38f}) {
        const float linear = shader::srgb_to_linear_image(c);
        EXPECT_TRUE(std::isfinite(linear) || c > 1e15f) << c << " -> " << linear;
        // Past the domain it is powf(x, 2.4f), whose exponent is float(2.4).
        if (std::isfinite(linear)) {
            EXPECT_NEAR(linear / std::pow((c + 0.055) / 1.055, double(2.4f)), 1.0, 2e-6) << c;
        }
    }
}

// The four-lane conversion an Image Texture uses gives the scalar function's
// bits in every lane, whatever the other lanes hold: the whole [0, 1] range
// in byte steps and between them, the linear segment's end, signed zeros,
// negatives, float images' large values past fastpow24's domain, infinities
// and NaN.
TEST(ShaderNodes, FourLaneImageSrgbEqualsTheScalarBitForBit) {
    std::vector<float> values = {0.0f, -0.0f, -1.0f, 0.04045f, std::nextafter(0.04045f, 0.0f), 1.0f, 1e-30f,
                                 1.5f, 1e8f, 1e9f, 2e9f, 1e20f, 3e38f, INFINITY, -INFINITY, NAN};
    for (int i = 0; i <= 4 * 255; ++i) values.push_back(float(i) / (4.0f * 255.0f));
    const auto same = [](float a, float b) { return std::bit_cast<uint32_t>(a) == std::bit_cast<uint32_t>(b); };
    for (size_t i = 0; i < values.size(); ++i)
        for (size_t rotate = 0; rotate < 4; ++rotate) {  // each value in every lane, next to other kinds
            float c[4];
            for (size_t k = 0; k < 4; ++k) c[k] = values[(i + (k + rotate) * 7) % values.size()];
            float expected[4];
            for (size_t k = 0; k < 4; ++k) expected[k] = shader::srgb_to_linear_image(c[k]);
            const float in[4] = {c[0], c[1], c[2], c[3]};
            shader::srgb_to_linear_image4(c);
            for (size_t k = 0; k < 4; ++k)
                ASSERT_TRUE(same(c[k], expected[k]) || (std::isnan(c[k]) && std::isnan(expected[k])))
                    << in[k] << ": " << c[k] << " against " << expected[k];
        }
}

// A one-triangle scene whose material's emission is a program of its UVs.
struct UvScene {
    Scene scene;
    std::vector<float> positions{0, 0, 0, 1, 0, 0, 0, 1, 0};
    std::vector<uint32_t> indices{0, 1, 2};
    std::vector<float> uvs{0.0f, 0.0f, 4.0f, 0.0f, 0.0f, 2.0f};
    UvScene() {
        scene.shading.uv_names = {""};
        MeshInput mesh;
        mesh.positions = positions.data();
        mesh.vertex_count = 3;
        mesh.indices = indices.data();
        mesh.triangle_count = 1;
        mesh.shading.uvs = {uvs.data()};
        scene.add_mesh(mesh);
    }
};

TEST(ShaderEval, EmissionFromInterpolatedUvs) {
    UvScene s;
    ASSERT_EQ(s.scene.shading.uvs.at(0).size(), 3u);
    auto program = std::make_shared<ShaderProgram>();
    program->constants.assign(3, 0.0f);
    program->code.push_back(instr(ShaderOp::TexCoord, uint16_t(TexCoordKind::Uv), {0}, {}, 0));
    program->outputs.push_back({ShaderField::Emission, 0, 0});
    ASSERT_EQ(program->validate(0, 1), "");
    Material m;
    m.program = program;
    ShadingGeometry g;
    g.u = 0.25f;  // barycentric of corner 1
    g.v = 0.5f;   // of corner 2
    g.n = g.ng = g.wo = Vec3f{0.0f, 0.0f, 1.0f};
    Material out;
    Vec3f n;
    evaluate_material(s.scene, m, g, out, n);
    EXPECT_FLOAT_EQ(out.emission.x, 1.0f);  // 0.25 * 4
    EXPECT_FLOAT_EQ(out.emission.y, 1.0f);  // 0.5 * 2
    EXPECT_FLOAT_EQ(out.emission.z, 0.0f);
}

TEST(TextureStore, PixelBuffersAreLookedUpBottomUpWithRepeatAndClip) {
    TextureStore store(64);
    // 2x2 RGB, first row at the top: top row red, green; bottom row blue, white.
    const float pixels[12] = {1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1};
    const uint32_t id = store.add_pixels("test", 2, 2, 3, pixels);
    EXPECT_TRUE(store.warnings().empty());
    float c[4];
    TextureLookup closest;
    closest.interp = TextureLookup::Interp::Closest;
    store.lookup(id, 0.25f, 0.25f, closest, c);  // bottom-left texel: blue
    EXPECT_EQ(c[0], 0.0f);
    EXPECT_EQ(c[2], 1.0f);
    EXPECT_EQ(c[3], 1.0f);
    store.lookup(id, 1.25f, 0.75f, closest, c);  // repeats to the top-left texel: red
    EXPECT_EQ(c[0], 1.0f);
    EXPECT_EQ(c[1], 0.0f);
    closest.extension = TextureLookup::Extension::Clip;
    store.lookup(id, 1.25f, 0.75f, closest, c);
    EXPECT_EQ(c[0] + c[1] + c[2] + c[3], 0.0f);
}

TEST(TextureStore, MissingAndEmptyImagesAreMagentaWithAWarning) {
    TextureStore store(64);
    const uint32_t missing = store.add_file("/nonexistent/nope.png", "Material 'm', node 'n'");
    const uint32_t empty = store.add_pixels("Material 'm', node 'e'", 0, 0, 4, nullptr);
    ASSERT_EQ(store.warnings().size(), 2u);
    EXPECT_NE(store.warnings()[0].find("node 'n'"), std::string::npos);
    float c[4];
    for (uint32_t id : {missing, empty}) {
        store.lookup(id, 0.5f, 0.5f, TextureLookup{}, c);
        EXPECT_EQ(c[0], 1.0f);
        EXPECT_EQ(c[1], 0.0f);
        EXPECT_EQ(c[2], 1.0f);
    }
}

// A 4 x 4 PNG of one colour at `path`, written in place (same inode), and its
// modification time set to `seconds` (a later save of the file).
void write_flat_png(const std::string& path, uint8_t r, uint8_t g, uint8_t b, time_t seconds) {
    std::vector<uint8_t> px(4 * 4 * 3);
    for (size_t i = 0; i < px.size(); i += 3) px[i] = r, px[i + 1] = g, px[i + 2] = b;
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out);
    ASSERT_TRUE(out->open(path, OIIO::ImageSpec(4, 4, 3, OIIO::TypeDesc::UINT8)));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, px.data()));
    out->close();
    const timespec times[2] = {{seconds, 0}, {seconds, 0}};
    ASSERT_EQ(utimensat(AT_FDCWD, path.c_str(), times, 0), 0);
}

// Image files stay in OpenImageIO's cache from one store (one render) to the
// next, so a later store must see a file that changed since, or went.
TEST(TextureStore, ALaterStoreSeesAnImageFileThatChangedOrWent) {
    const std::string path =
        (std::filesystem::temp_directory_path() / ("coherent_held_" + std::to_string(getpid()) + ".png")).string();
    const auto red_of = [&](const char* label) {
        TextureStore store(64);
        const uint32_t id = store.add_file(path, label);
        float c[4];
        store.lookup(id, 0.5f, 0.5f, TextureLookup{}, c);
        return std::vector<float>{c[0], c[1], c[2], float(store.warnings().size())};
    };
    write_flat_png(path, 255, 0, 0, 1700000000);
    EXPECT_EQ(red_of("first"), (std::vector<float>{1.0f, 0.0f, 0.0f, 0.0f}));
    EXPECT_EQ(red_of("unchanged"), (std::vector<float>{1.0f, 0.0f, 0.0f, 0.0f}));
    write_flat_png(path, 0, 255, 0, 1700000001);  // same size, same inode, saved a second later
    EXPECT_EQ(red_of("changed"), (std::vector<float>{0.0f, 1.0f, 0.0f, 0.0f}));
    std::remove(path.c_str());
    const std::vector<float> gone = red_of("gone");  // magenta with a warning, not the cached green
    EXPECT_EQ(gone, (std::vector<float>{1.0f, 0.0f, 1.0f, 1.0f}));
}

}  // namespace
}  // namespace coherent
