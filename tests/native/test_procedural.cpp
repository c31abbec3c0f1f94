// Procedural textures (shader/node_procedural.h and the headers under it):
// the register-list validation, and properties of the patterns that hold
// whatever the hash (the pixel-exact comparison with Cycles is
// tests/blender/test_shader_nodes.py).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "shader/eval.h"
#include "shader/node_musgrave.h"
#include "shader/node_pattern.h"
#include "shader/node_procedural.h"
#include "shader/node_voronoi.h"
#include "shader/program.h"

namespace coherent {
namespace {

using namespace shader;

// A program running one procedural op: registers 0..2 the vector, 3.. the
// float inputs (all `value`), outputs after them; the list at data 0.
struct OneOp {
    ShaderProgram p;
    ProceduralLayout layout;
    std::vector<uint16_t> out_reg;

    OneOp(ShaderOp op, uint16_t mode, const Vec3f& vector, float value) : layout(procedural_layout(op)) {
        p.constants = {vector.x, vector.y, vector.z};
        p.data.push_back(0.0f);
        for (int k = 1; k < layout.inputs; ++k) {
            p.data.push_back(float(p.constants.size()));
            for (int c = 0; c < layout.input_width[k]; ++c) p.constants.push_back(value);
        }
        for (int k = 0; k < layout.outputs; ++k) {
            out_reg.push_back(uint16_t(p.constants.size()));
            p.data.push_back(float(p.constants.size()));
            p.constants.resize(p.constants.size() + size_t(layout.output_width[k]), 0.0f);
        }
        ShaderInstr in;
        in.op = op;
        in.mode = mode;
        in.data = 0;
        p.code.push_back(in);
    }
    std::vector<float> run() const {
        std::vector<float> r = p.constants;
        run_constant_program(p, r.data());
        return r;
    }
};

TEST(Procedural, ValidateChecksModesAndRegisterLists) {
    OneOp ok(ShaderOp::TexVoronoi, voronoi_mode(3, 2, 3), Vec3f(0.3f), 1.0f);
    EXPECT_EQ(ok.p.validate(0, 0), "");

    OneOp bad_mode = ok;
    bad_mode.p.code[0].mode = voronoi_mode(5, 0, 0);  // 5 dimensions
    EXPECT_NE(bad_mode.p.validate(0, 0).find("mode"), std::string::npos);

    OneOp outside = ok;
    outside.p.data[2] = float(outside.p.constants.size());  // an input past the register file
    EXPECT_NE(outside.p.validate(0, 0).find("entry 2"), std::string::npos);

    OneOp fractional = ok;
    fractional.p.data[1] = 1.5f;
    EXPECT_NE(fractional.p.validate(0, 0), "");

    OneOp short_list = ok;
    short_list.p.data.resize(4);
    EXPECT_NE(short_list.p.validate(0, 0).find("outside the data"), std::string::npos);

    OneOp unused_output = ok;
    unused_output.p.data.back() = float(kNoRegister);  // an output nothing reads is allowed
    EXPECT_EQ(unused_output.p.validate(0, 0), "");
    unused_output.p.data[0] = float(kNoRegister);  // an input is not
    EXPECT_NE(unused_output.p.validate(0, 0), "");
}

TEST(Procedural, VoronoiFeaturesAreOrderedAndPositive) {
    VoronoiParams params;
    params.randomness = 1.0f;
    for (int i = 0; i < 200; ++i) {
        const Pt<3> p{{0.37f * float(i), 1.3f - 0.11f * float(i), 0.05f * float(i * i % 17)}};
        for (VoronoiMetric m : {VoronoiMetric::Euclidean, VoronoiMetric::Manhattan, VoronoiMetric::Chebychev}) {
            params.metric = m;
            const float f1 = voronoi_f1(p, params).distance, f2 = voronoi_f2(p, params).distance;
            EXPECT_LE(f1, f2);
            EXPECT_GE(f1, 0.0f);
        }
        params.metric = VoronoiMetric::Euclidean;
        // A vanishing smoothness is F1 (up to the blend's rounding).
        params.smoothness = 1e-6f;
        EXPECT_NEAR(voronoi_smooth_f1(p, params).distance, voronoi_f1(p, params).distance, 1e-5f);
        EXPECT_GE(voronoi_distance_to_edge(p, 1.0f), -1e-6f);
        EXPECT_GT(voronoi_n_sphere_radius(p, 1.0f), 0.0f);
    }
}

TEST(Procedural, ZeroRandomnessPutsFeaturePointsOnTheLattice) {
    VoronoiParams params;
    params.randomness = 0.0f;
    const Pt<2> p{{2.25f, -0.75f}};
    const VoronoiResult<2> r = voronoi_f1(p, params);
    EXPECT_FLOAT_EQ(r.position[0], 2.0f);
    EXPECT_FLOAT_EQ(r.position[1], -1.0f);
    EXPECT_FLOAT_EQ(r.distance, std::sqrt(0.25f * 0.25f + 0.25f * 0.25f));
    EXPECT_FLOAT_EQ(voronoi_n_sphere_radius(p, 0.0f), 0.5f);
}

TEST(Procedural, NoiseIsZeroOnTheLatticeAndFractalsStayInRange) {
    // Gradient noise vanishes at integer points.
    EXPECT_EQ(snoise(Pt<3>{{2.0f, -1.0f, 5.0f}}), 0.0f);
    EXPECT_EQ(snoise(Pt<4>{{0.0f, 3.0f, -2.0f, 1.0f}}), 0.0f);
    for (int i = 0; i < 500; ++i) {
        const Pt<3> p{{0.173f * float(i), -0.291f * float(i), 0.057f * float(i)}};
        const float f = fractal_noise(p, 3.5f, 0.6f);
        EXPECT_GE(f, 0.0f);
        EXPECT_LE(f, 1.0f);
    }
    // Musgrave fBm with no octaves is 0, with one octave the signed noise itself.
    const Pt<2> q{{0.3f, 0.8f}};
    EXPECT_EQ(musgrave(MusgraveType::Fbm, q, {1.0f, 2.0f, 0.0f, 0.0f, 1.0f}), 0.0f);
    EXPECT_EQ(musgrave(MusgraveType::Fbm, q, {1.0f, 2.0f, 1.0f, 0.0f, 1.0f}), snoise(q));
}

TEST(Procedural, PatternsAtKnownPoints) {
    EXPECT_FLOAT_EQ(svm_gradient(GradientType::Linear, {0.3f, 9.0f, 9.0f}), 0.3f);
    EXPECT_FLOAT_EQ(svm_gradient(GradientType::Diagonal, {0.2f, 0.4f, 9.0f}), 0.3f);
    EXPECT_FLOAT_EQ(svm_gradient(GradientType::Spherical, {0.0f, 0.0f, 0.0f}), 0.999999f);
    EXPECT_FLOAT_EQ(svm_gradient(GradientType::Radial, {0.0f, 1.0f, 0.0f}), 0.75f);
    EXPECT_EQ(svm_gradient(GradientType::Quadratic, {-2.0f, 0.0f, 0.0f}), 0.0f);
    // Magic with depth 0 and no distortion is 0.5 minus its three waves.
    const Vec3f m = svm_magic({0.1f, 0.2f, 0.3f}, 1.0f, 0, 0.0f);
    EXPECT_FLOAT_EQ(m.x, 0.5f - std::sin(0.6f * 5.0f));
    // A brick's corner is mortar, its middle is not (row 0 is offset by half a brick).
    BrickParams b{0.1f, 0.0f, 0.0f, 1.0f, 0.5f, 0.5f, 1.0f, 2, 1};
    float tint, mortar;
    svm_brick(b, {0.51f, 0.01f, 0.0f}, tint, mortar);
    EXPECT_EQ(mortar, 1.0f);
    svm_brick(b, {0.0f, 0.25f, 0.0f}, tint, mortar);
    EXPECT_EQ(mortar, 0.0f);
    EXPECT_GE(tint, 0.0f);
    EXPECT_LE(tint, 1.0f);
}

TEST(Procedural, InstructionsWriteOnlyTheOutputsAsked) {
    OneOp noise(ShaderOp::TexNoise, 3, {0.4f, 1.7f, -0.2f}, 2.0f);
    noise.p.data[noise.layout.inputs + 1] = float(kNoRegister);  // colour unused
    const std::vector<float> r = noise.run();
    const float fac = r[noise.out_reg[0]];
    EXPECT_GT(fac, 0.0f);
    EXPECT_LT(fac, 1.0f);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(r[noise.out_reg[1] + size_t(c)], 0.0f);

    OneOp white(ShaderOp::TexWhiteNoise, 3, {0.4f, 1.7f, -0.2f}, 0.0f);
    const std::vector<float> w = white.run();
    EXPECT_EQ(w[white.out_reg[0]], w[white.out_reg[1]]);  // Value is the colour's red
}

}  // namespace
}  // namespace coherent
