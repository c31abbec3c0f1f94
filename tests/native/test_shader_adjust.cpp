// Colour adjustment, input and bump instructions (native/shader/node_adjust.h,
// eval.cpp): validation of their operands, and properties with independent
// oracles (round trips, the analytic normal of a linear height field, the
// reflection ensure_valid_reflection promises). Agreement with Cycles itself is
// tested pixel by pixel in tests/blender/test_shader_nodes.py.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "scene/scene.h"
#include "shader/eval.h"
#include "shader/node_adjust.h"
#include "shader/program.h"
#include "shader_test_helpers.h"

namespace coherent {
namespace {

using test::instr;

TEST(ShaderAdjust, ValidateRejectsCurveTablesOutsideTheDataAndBadModes) {
    ShaderProgram p;
    p.constants.assign(8, 0.0f);
    p.data.assign(shader::kCurveHeader + 4 * kCurveTableSize, 0.0f);
    p.code = {instr(ShaderOp::Curves, 1, {4}, {0, 1})};
    EXPECT_EQ(p.validate(0, 0), "");
    p.code = {instr(ShaderOp::Curves, 1, {4}, {0, 1}, /*offset*/ 1)};
    EXPECT_NE(p.validate(0, 0).find("curve table"), std::string::npos);
    p.code = {instr(ShaderOp::Geometry, uint16_t(GeometryKind::Position) | 3 << kBumpAxisShift, {0}, {})};
    EXPECT_NE(p.validate(0, 0).find("unknown"), std::string::npos);
    // Backfacing writes one register: the last one is a valid target.
    p.code = {instr(ShaderOp::Geometry, uint16_t(GeometryKind::Backfacing), {7}, {})};
    EXPECT_EQ(p.validate(0, 0), "");
    p.code = {instr(ShaderOp::MapRange, uint16_t(shader::MapRangeType::Count), {0}, {0, 0, 0, 1})};
    EXPECT_NE(p.validate(0, 0).find("unknown"), std::string::npos);
}

TEST(ShaderAdjust, HsvAndHslConversionsRoundTrip) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    for (int i = 0; i < 1000; ++i) {
        const Vec3f c{unit(rng), unit(rng), unit(rng)};
        for (auto [to, from] : {std::pair{shader::ColorConversion::RgbToHsv, shader::ColorConversion::HsvToRgb},
                                std::pair{shader::ColorConversion::RgbToHsl, shader::ColorConversion::HslToRgb}}) {
            const Vec3f back = shader::convert_color(from, shader::convert_color(to, c));
            EXPECT_NEAR(back.x, c.x, 1e-5f);
            EXPECT_NEAR(back.y, c.y, 1e-5f);
            EXPECT_NEAR(back.z, c.z, 1e-5f);
        }
    }
}

TEST(ShaderAdjust, CurveLookupExtrapolatesTheEndSegmentsOnlyWhenAsked) {
    // A table of y = 2x sampled at 256 points, looked up past both ends.
    std::vector<float> table(kCurveTableSize);
    for (int i = 0; i < kCurveTableSize; ++i) table[i] = 2.0f * float(i) / float(kCurveTableSize - 1);
    EXPECT_NEAR(shader::curve_lookup(table.data(), kCurveTableSize, 1, 0.3f, false), 0.6f, 1e-6f);
    EXPECT_NEAR(shader::curve_lookup(table.data(), kCurveTableSize, 1, 1.5f, true), 3.0f, 1e-5f);
    EXPECT_NEAR(shader::curve_lookup(table.data(), kCurveTableSize, 1, -0.25f, true), -0.5f, 1e-5f);
    EXPECT_EQ(shader::curve_lookup(table.data(), kCurveTableSize, 1, 1.5f, false), 2.0f);
}

TEST(ShaderAdjust, ValidReflectionStaysAboveTheSurface) {
    std::mt19937 rng(5);
    std::normal_distribution<float> gauss;
    const Vec3f ng{0.0f, 0.0f, 1.0f};
    int adjusted = 0;
    for (int i = 0; i < 2000; ++i) {
        Vec3f wi = normalize(Vec3f{gauss(rng), gauss(rng), std::fabs(gauss(rng)) + 0.05f});
        Vec3f n = normalize(Vec3f{gauss(rng), gauss(rng), std::fabs(gauss(rng)) + 0.05f});
        const Vec3f r0 = 2.0f * dot(n, wi) * n - wi;
        const float threshold = std::min(0.9f * dot(ng, wi), 0.01f);
        const Vec3f out = shader::ensure_valid_reflection(ng, wi, n);
        if (dot(ng, r0) >= threshold) {
            EXPECT_EQ(out.x, n.x);  // already valid: untouched
            continue;
        }
        ++adjusted;
        EXPECT_NEAR(length(out), 1.0f, 1e-4f);
        // Above the surface (Cycles aims at the threshold, but where both
        // roots of its quadratic qualify it keeps the shallower reflection,
        // which can fall short of the threshold while staying above 0).
        const Vec3f r = 2.0f * dot(out, wi) * out - wi;
        EXPECT_GT(dot(ng, r), 0.0f) << "n " << n.x << " " << n.y << " " << n.z;
    }
    EXPECT_GT(adjusted, 100);  // the sweep exercised the correction
}

// One triangle in the z = 0 plane, seen from above.
struct FlatScene {
    Scene scene;
    FlatScene() {
        const std::vector<float> positions = {0, 0, 0, 2, 0, 0, 0, 2, 0};
        const std::vector<uint32_t> indices = {0, 1, 2};
        MeshInput mesh;
        mesh.positions = positions.data();
        mesh.vertex_count = 3;
        mesh.indices = indices.data();
        mesh.triangle_count = 1;
        scene.add_mesh(mesh);
    }
};

TEST(ShaderAdjust, BumpOfALinearHeightIsItsAnalyticNormal) {
    // h = a . P sampled at the point and at its two bump offsets; the bumped
    // normal of a plane is normalize(n - distance * a_tangential), whatever the footprint.
    FlatScene s;
    auto p = std::make_shared<ShaderProgram>();
    const Vec3f a{0.7f, -0.4f, 5.0f};  // the normal component must not matter
    p->constants = {a.x, a.y, a.z, 1.0f, 0.5f, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
    // registers: 0-2 a, 3 strength, 4 distance, 5-7 normal, 8-16 positions, 17-19 heights, 20-22 out, 23 scratch
    p->code.push_back(instr(ShaderOp::Geometry, uint16_t(GeometryKind::Normal), {5}, {}));
    for (uint16_t axis = 0; axis < 3; ++axis) {
        const uint16_t pos = uint16_t(8 + 3 * axis);
        p->code.push_back(instr(ShaderOp::Geometry, uint16_t(GeometryKind::Position) | axis << kBumpAxisShift, {pos}, {}));
        p->code.push_back(instr(ShaderOp::VectorMath, uint16_t(shader::VectorMathOp::DotProduct), {20, uint16_t(17 + axis)},
                                {pos, 0, 0, 23}));
    }
    p->code.push_back(instr(ShaderOp::Bump, 0, {20}, {3, 4, 5, 17}));
    p->outputs.push_back({ShaderField::Normal, 0, 20});
    p->uses_bump = true;
    ASSERT_EQ(p->validate(0, 0), "");
    Material m;
    m.program = p;
    for (float footprint : {0.01f, 0.1f}) {
        ShadingGeometry g;
        g.u = 0.2f;
        g.v = 0.3f;
        g.p = Vec3f{0.4f, 0.6f, 0.0f};
        g.n = g.ng = g.wo = Vec3f{0.0f, 0.0f, 1.0f};
        g.footprint = footprint;
        Material out;
        Vec3f n;
        evaluate_material(s.scene, m, g, out, n);
        const Vec3f expected = normalize(Vec3f{-0.5f * a.x, -0.5f * a.y, 1.0f});
        EXPECT_NEAR(n.x, expected.x, 1e-4f);
        EXPECT_NEAR(n.y, expected.y, 1e-4f);
        EXPECT_NEAR(n.z, expected.z, 1e-4f);
    }
}

TEST(ShaderAdjust, LightPathReadsZeroWithoutAPathAndTheFlagsWithOne) {
    Scene scene;
    auto p = std::make_shared<ShaderProgram>();
    p->constants.assign(3, 0.0f);
    p->code.push_back(instr(ShaderOp::LightPath, uint16_t(LightPathKind::IsSingular), {0}, {}));
    p->code.push_back(instr(ShaderOp::LightPath, uint16_t(LightPathKind::RayLength), {1}, {}));
    p->code.push_back(instr(ShaderOp::LightPath, uint16_t(LightPathKind::GlossyDepth), {2}, {}));
    p->outputs.push_back({ShaderField::Emission, 0, 0});
    ASSERT_EQ(p->validate(0, 0), "");
    Material m;
    m.program = p;
    ShadingGeometry g;
    g.n = g.ng = g.wo = Vec3f{0.0f, 0.0f, 1.0f};
    Material out;
    Vec3f n;
    evaluate_material(scene, m, g, out, n);
    EXPECT_EQ(out.emission.x + out.emission.y + out.emission.z, 0.0f);
    LightPathInfo path;
    path.flags = LightPathInfo::kGlossy | LightPathInfo::kSingular | LightPathInfo::kReflect;
    path.ray_length = 2.5f;
    path.glossy_depth = 1;
    g.path = &path;
    evaluate_material(scene, m, g, out, n);
    EXPECT_EQ(out.emission.x, 1.0f);
    EXPECT_EQ(out.emission.y, 2.5f);
    EXPECT_EQ(out.emission.z, 1.0f);
}

}  // namespace
}  // namespace coherent
