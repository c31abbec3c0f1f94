// The batch shader interpreter (shader/eval_batch.h) against the scalar one
// (shader/eval.h), its oracle: every ShaderOp in every mode the validator
// accepts, on points whose inputs are random and include NaN, infinities,
// signed zeros, denormals and huge values, must leave every register of
// every lane with the very bits the scalar interpreter leaves there, except
// that a NaN may carry another sign or payload: x86 propagates the NaN of
// an instruction's first operand, and the compiler may commute + and * in
// either interpreter, so which NaN survives is not fixed by the source.
#include <gtest/gtest.h>

#include <array>
#include <cstring>
#include <memory>
#include <random>
#include <tuple>
#include <vector>

#include "scene/scene.h"
#include "shader/eval.h"
#include "shader/eval_batch.h"
#include "shader/eval_batch_kernels.h"
#include "shader/eval_registers.h"
#include "shader/node_math.h"
#include "shader/node_procedural.h"
#include "shader/program.h"
#include "shader/sky_model.h"
#include "shader/textures.h"
#include "shader_test_helpers.h"
#include "test_render_helpers.h"

namespace coherent {
namespace {

using test::instr;

constexpr uint16_t kRegisters = 64;
constexpr uint16_t kConstants = 15;  // registers 15..26 hold random constants
constexpr uint16_t kOut = 32;        // where the instruction under test writes

// A float drawn to hit the edge cases as often as the ordinary values.
float edgy(std::mt19937& rng) {
    std::uniform_real_distribution<float> u(-4.0f, 4.0f);
    switch (rng() % 16) {
        case 0: return std::numeric_limits<float>::quiet_NaN();
        case 1: return std::numeric_limits<float>::infinity();
        case 2: return -std::numeric_limits<float>::infinity();
        case 3: return 0.0f;
        case 4: return -0.0f;
        case 5: return (rng() % 2 ? 1e30f : -1e30f);
        case 6: return 1e-40f;
        case 7: return float(int(rng() % 7) - 3);
        case 8: return 0.5f;
        default: return u(rng);
    }
}

Vec3f edgy3(std::mt19937& rng) {
    const float x = edgy(rng), y = edgy(rng);
    return {x, y, edgy(rng)};
}

// Points whose Position, Normal, Incoming, True Normal and Parametric outputs
// (the program's prelude) carry the random per-lane inputs.
struct Points {
    std::vector<ShadingGeometry> g;
    std::vector<LightPathInfo> path;
    Points(size_t n, std::mt19937& rng) : g(n), path(n) {
        std::uniform_real_distribution<float> unit(0.0f, 1.0f);
        for (size_t l = 0; l < n; ++l) {
            ShadingGeometry& p = g[l];
            p.p = edgy3(rng), p.n = edgy3(rng), p.wo = edgy3(rng), p.ng = edgy3(rng);
            p.u = rng() % 8 ? unit(rng) : edgy(rng);
            p.v = rng() % 8 ? unit(rng) : edgy(rng);
            p.front = rng() % 2 != 0;
            p.footprint = rng() % 8 ? unit(rng) : edgy(rng);
            path[l].flags = uint8_t(rng() % 128);
            path[l].ray_length = edgy(rng);
            path[l].depth = int(rng() % 5), path[l].diffuse_depth = int(rng() % 3);
            p.path = rng() % 4 ? &path[l] : nullptr;
        }
    }
};

// A program: the geometry prelude into registers 0..14, then `in`.
ShaderProgram program_with(const ShaderInstr& in, std::mt19937& rng) {
    ShaderProgram p;
    p.constants.assign(kRegisters, 0.0f);
    for (uint16_t i = kConstants; i < kConstants + 12; ++i) p.constants[i] = edgy(rng);
    const GeometryKind prelude[] = {GeometryKind::Position, GeometryKind::Normal, GeometryKind::Incoming,
                                    GeometryKind::TrueNormal, GeometryKind::Parametric};
    for (int k = 0; k < 5; ++k) p.code.push_back(instr(ShaderOp::Geometry, uint16_t(prelude[k]), {uint16_t(3 * k)}, {}));
    p.code.push_back(in);
    return p;
}

// The data an op addresses at offset 0: a procedural op's register list
// (inputs from `ins`, outputs from kOut on), a packed sky, else random tables.
std::vector<float> data_for(ShaderOp op, const uint16_t* ins, std::mt19937& rng) {
    std::vector<float> d;
    if (is_procedural(op)) {
        const ProceduralLayout layout = procedural_layout(op);
        for (int k = 0; k < layout.inputs; ++k) d.push_back(float(ins[k % 4] + (k / 4)));
        for (int k = 0; k < layout.outputs; ++k) d.push_back(float(kOut + 3 * k));
        return d;
    }
    if (op == ShaderOp::SkyTexture) return pack(SkyTexture{});
    std::uniform_real_distribution<float> u(-0.5f, 1.5f);
    d.resize(4 * 256 + 16);
    for (float& x : d) x = rng() % 16 ? u(rng) : edgy(rng);
    return d;
}

// Registers after the scalar interpreter ran p at each point, laid out as the
// batch file is ([register][lane]).
std::vector<float> scalar_registers(const Scene& scene, const ShaderProgram& p, const Points& pts) {
    std::vector<float> out(p.constants.size() * kShaderBatchLanes, 0.0f);
    for (size_t l = 0; l < pts.g.size(); ++l) {
        std::vector<float> r = p.constants;
        for (const ShaderInstr& in : p.code)
            eval_detail::run_instruction(scene, p, pts.g[l], in, eval_detail::Registers{r.data()});
        for (size_t i = 0; i < r.size(); ++i) out[i * kShaderBatchLanes + l] = r[i];
    }
    return out;
}

// How many (register, lane) bits differ between the two interpreters.
int mismatches(const Scene& scene, const ShaderProgram& p, const Points& pts, std::string& first) {
    const std::vector<float> want = scalar_registers(scene, p, pts);
    std::vector<float> got(want.size(), 0.0f);
    eval_detail::run_batch(scene, p, pts.g.data(), pts.g.size(), got.data());
    int bad = 0;
    for (size_t i = 0; i < p.constants.size(); ++i)
        for (size_t l = 0; l < pts.g.size(); ++l) {
            const float a = want[i * kShaderBatchLanes + l], b = got[i * kShaderBatchLanes + l];
            if (std::memcmp(&a, &b, sizeof(float)) == 0 || (std::isnan(a) && std::isnan(b))) continue;
            if (bad++ == 0)
                first = "register " + std::to_string(i) + " lane " + std::to_string(l) + ": scalar " +
                        std::to_string(a) + ", batch " + std::to_string(b);
        }
    return bad;
}

// Input slot patterns: per-lane inputs, uniform constants, and mixes.
constexpr uint16_t kInputs[][4] = {{0, 3, 6, 9}, {1, 15, 18, 21}, {15, 4, 7, 24}, {2, 5, 19, 10}};

TEST(ShaderBatch, EveryOpInEveryValidModeMatchesTheScalarInterpreterBitForBit) {
    std::mt19937 rng(11);
    const Scene scene;
    int modes_run = 0;
    for (uint16_t op = 0; op < uint16_t(ShaderOp::Count); ++op) {
        int valid = 0;
        for (uint32_t mode = 0; mode < 0x800; ++mode) {
            for (size_t pattern = 0; pattern < std::size(kInputs); ++pattern) {
                const uint16_t* ins = kInputs[pattern];
                // The last pattern writes over its first input (in place).
                const uint16_t out0 = pattern == 3 ? ins[0] : kOut;
                ShaderInstr in = instr(ShaderOp(op), uint16_t(mode), {out0, uint16_t(kOut + 8)},
                                       {ins[0], ins[1], ins[2], ins[3]});
                ShaderProgram p = program_with(in, rng);
                p.data = data_for(in.op, ins, rng);
                if (!p.validate(1, 1).empty()) break;
                if (pattern == 0) ++valid;
                const Points pts(pattern % 2 ? kShaderBatchLanes : 29, rng);
                std::string first;
                EXPECT_EQ(mismatches(scene, p, pts, first), 0)
                    << "op " << op << " mode " << mode << " inputs " << pattern << ": " << first;
            }
        }
        EXPECT_GT(valid, 0) << "op " << op << " was never run";
        modes_run += valid;
    }
    EXPECT_GT(modes_run, 300);
}

// The Noise Texture's SIMD rows (3D, one Detail and Roughness for the
// batch, no Distortion), where the patterns above mostly take the scalar
// path: per-lane vectors and scales, edge-case Detail and Roughness.
TEST(ShaderBatch, NoiseTextureRowsMatchTheScalarTexture) {
    std::mt19937 rng(17);
    const Scene scene;
    const float details[] = {0.0f, 2.0f, 2.5f, 15.0f, 40.0f, -1.0f, std::numeric_limits<float>::quiet_NaN()};
    const float roughnesses[] = {0.5f, 0.0f, 1.0f, 2.0f, -0.0f};
    for (float detail : details)
        for (float roughness : roughnesses)
            for (float distortion : {0.0f, -0.0f})
                for (uint16_t scale : {uint16_t(1), uint16_t(15)}) {  // per lane (Position y) or a constant
                    ShaderInstr in = instr(ShaderOp::TexNoise, 3, {}, {}, 0);
                    ShaderProgram p = program_with(in, rng);
                    p.constants[16] = detail, p.constants[17] = roughness, p.constants[18] = distortion;
                    p.data = {3, 0, float(scale), 16, 17, 18, float(kOut), float(kOut + 1)};
                    ASSERT_EQ(p.validate(0, 0), "");
                    const Points pts(29, rng);
                    std::string first;
                    EXPECT_EQ(mismatches(scene, p, pts, first), 0)
                        << "detail " << detail << " roughness " << roughness << ": " << first;
                }
}

// The Image Texture's SIMD rows (eval_batch_image.cpp: an in-memory byte
// RGBA image, linear, repeat or extend) against the scalar lookup, its
// oracle: images whose sides are and are not powers of two and a single
// texel; texture coordinates inside, on the edges, past them, huge, infinite
// and NaN; every colour-space and alpha flag. Modes the rows do not cover
// (closest, cubic, clip, associated alpha, other channel counts, float
// images) must take the scalar path and agree as well.
TEST(ShaderBatch, ImageTextureRowsMatchTheScalarLookup) {
    std::mt19937 rng(23);
    Scene scene;
    scene.shading.textures = std::make_shared<TextureStore>();
    struct Made {
        uint32_t id;
        bool rows;  // the SIMD rows may cover it
    };
    std::vector<Made> images;
    for (auto [w, h, channels] : {std::tuple{64, 32, 4}, std::tuple{7, 5, 4}, std::tuple{1, 1, 4},
                                  std::tuple{33, 3, 4}, std::tuple{8, 8, 3}}) {
        std::vector<uint8_t> bytes(size_t(w) * size_t(h) * size_t(channels));
        for (uint8_t& b : bytes) b = uint8_t(rng() % 4 ? rng() % 256 : (rng() % 2 ? 0 : 255));
        images.push_back({scene.shading.textures->add_bytes("img", w, h, channels, bytes.data()), channels == 4});
    }
    std::vector<float> floats(16 * 16 * 4);
    for (float& f : floats) f = float(rng() % 1000) / 999.0f;
    images.push_back({scene.shading.textures->add_pixels("float", 16, 16, 4, floats.data()), false});
    int rows_taken = 0;
    for (const Made& image : images)
        for (uint16_t interp : {0, 1, 2})
            for (uint16_t extension : {0, 1, 2})
                for (int flags : {0, int(kImageSrgb), int(kImageIgnoreAlpha), kImageSrgb | kImageIgnoreAlpha,
                                  kImageSrgb | kImageUnassociate, kImagePremultiply | kImageBytes})
                    for (size_t pattern = 0; pattern < std::size(kInputs); ++pattern) {
                        const uint16_t mode = uint16_t(interp | (extension << kImageExtensionShift) | flags);
                        // Texture coordinate: Parametric (u, v) per lane, or Position (edgy).
                        const uint16_t co = pattern % 2 ? 12 : 0;
                        const uint16_t out0 = pattern == 3 ? co : kOut;  // in place: over its input
                        ShaderInstr in = instr(ShaderOp::ImageTexture, mode, {out0, uint16_t(kOut + 8)}, {co});
                        in.data = image.id;
                        ShaderProgram p = program_with(in, rng);
                        ASSERT_EQ(p.validate(images.size(), 0), "");
                        Points pts(pattern < 2 ? kShaderBatchLanes : 29, rng);
                        for (ShadingGeometry& g : pts.g)  // also far outside and on texel centres
                            if (rng() % 4 == 0) g.u = float(int(rng() % 41) - 20) / 8.0f;
                        std::string first;
                        EXPECT_EQ(mismatches(scene, p, pts, first), 0)
                            << "image " << image.id << " mode " << mode << " inputs " << pattern << ": " << first;
                        if (image.rows && interp == 0 && extension < 2 && !(flags & (kImageUnassociate | kImagePremultiply))) {
                            std::vector<float> regs(p.constants.size() * kShaderBatchLanes, 0.0f);
                            const eval_detail::BatchRegisters b{regs.data(), kShaderBatchLanes, 1};
                            rows_taken += eval_detail::image_texture_rows(scene, in, b);
                        }
                    }
    // The covered modes really ran on rows: 4 RGBA byte images x 2 extensions x 4 flag sets x 4 patterns.
    EXPECT_EQ(rows_taken, 4 * 2 * 4 * 4);
}

// The UV coordinate and the tangent-space Normal Map on SIMD rows
// (eval_batch_geometry.cpp) against the scalar nodes: per-lane triangles,
// barycentrics, normals, incoming directions and colours that are both edgy
// and realistic (unit vectors whose mapped normal ensure_valid_reflection
// sometimes has to tilt, which the rows hand to the scalar code), strength 1,
// another constant, or per lane. A point on an instance makes the whole
// instruction scalar.
TEST(ShaderBatch, UvAndNormalMapRowsMatchTheScalarNodes) {
    std::mt19937 rng(31);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f), signed_unit(-1.0f, 1.0f);
    const auto direction = [&] {
        const Vec3f d{signed_unit(rng), signed_unit(rng), signed_unit(rng)};
        return length(d) > 1e-3f ? normalize(d) : Vec3f{0.0f, 0.0f, 1.0f};
    };
    Scene scene;
    constexpr size_t kTriangles = 50;
    scene.shading.uvs.assign(2, {});
    for (auto& layer : scene.shading.uvs)
        for (size_t i = 0; i < 3 * kTriangles; ++i)
            layer.push_back(rng() % 8 ? Vec2f{signed_unit(rng), unit(rng)} : Vec2f{edgy(rng), edgy(rng)});
    for (size_t i = 0; i < 3 * kTriangles; ++i) {
        scene.shading.tangents.push_back(rng() % 8 ? direction() : edgy3(rng));
        scene.shading.tangent_signs.push_back(i % 3 ? 0.0f : (rng() % 2 ? 1.0f : -1.0f));
    }
    const Prototype prototype;
    int rows_taken = 0, tilted = 0;
    for (int round = 0; round < 64; ++round) {
        const bool realistic = round % 2 == 0;
        Points pts(round % 3 ? kShaderBatchLanes : 29, rng);
        for (ShadingGeometry& g : pts.g) {
            g.tri = uint32_t(rng() % kTriangles);
            if (realistic) {
                g.ng = direction();
                g.n = normalize(g.ng + 0.3f * direction());
                g.wo = direction();
                if (dot(g.wo, g.ng) < 0.0f) g.wo = -g.wo;
                g.u = unit(rng) * 0.5f, g.v = unit(rng) * 0.5f;
            }
        }
        const bool on_instance = round == 5;
        if (on_instance) pts.g[3].prototype = &prototype;
        for (const bool normal_map : {false, true}) {
            ShaderInstr in;
            if (normal_map) {
                // Strength: 1 (a constant register), another constant, or per lane (Parametric's u);
                // colour: per lane (Position), or the constant registers 15..17.
                const uint16_t strength = std::array<uint16_t, 3>{28, 15, 12}[round % 3];
                in = instr(ShaderOp::NormalMap, uint16_t(NormalMapSpace::Tangent), {kOut}, {strength, uint16_t(round % 4 ? 0 : 15)});
            } else {
                in = instr(ShaderOp::TexCoord, uint16_t(TexCoordKind::Uv), {round % 5 ? kOut : uint16_t(0)}, {}, uint32_t(round % 2));
            }
            ShaderProgram p = program_with(in, rng);
            p.constants[28] = 1.0f;
            if (normal_map && realistic)  // colours of a normal map: z mostly up
                for (ShadingGeometry& g : pts.g) g.p = {unit(rng), unit(rng), 0.5f + 0.5f * unit(rng)};
            ASSERT_EQ(p.validate(0, 2), "");
            std::string first;
            EXPECT_EQ(mismatches(scene, p, pts, first), 0)
                << (normal_map ? "normal map" : "uv") << " round " << round << ": " << first;
            std::vector<float> regs(p.constants.size() * kShaderBatchLanes, 0.0f);
            eval_detail::run_batch(scene, p, pts.g.data(), 0, regs.data());  // just the constants
            const eval_detail::BatchRegisters b{regs.data(), kShaderBatchLanes, (pts.g.size() + 7) / 8};
            const bool rows = eval_detail::geometry_rows(scene, p, in, pts.g.data(), pts.g.size(), b);
            EXPECT_EQ(rows, !on_instance) << "round " << round;
            rows_taken += rows;
            if (normal_map && realistic)
                for (const ShadingGeometry& g : pts.g) {
                    std::vector<float> r = p.constants;
                    for (const ShaderInstr& i : p.code) eval_detail::run_instruction(scene, p, g, i, eval_detail::Registers{r.data()});
                    const Vec3f mapped{r[kOut], r[kOut + 1], r[kOut + 2]};
                    const Vec3f refl = 2.0f * dot(mapped, g.wo) * mapped - g.wo;
                    // A tilted normal reflects exactly onto the threshold.
                    tilted += std::fabs(dot(g.ng, refl) - std::min(0.9f * dot(g.ng, g.wo), 0.01f)) < 1e-4f;
                }
        }
    }
    EXPECT_EQ(rows_taken, 2 * 63);
    EXPECT_GT(tilted, 0);  // some lanes went through ensure_valid_reflection's tilt
}

template <class T>
bool same_bits(const T& a, const T& b) {
    return std::memcmp(&a, &b, sizeof(T)) == 0;
}

// Noise, ColorRamp and Mix feeding a closure's colour, roughness and emission:
// whole materials from more points than one pass holds.
TEST(ShaderBatch, MaterialsMatchEvaluateMaterialAcrossPasses) {
    std::mt19937 rng(5);
    auto prog = std::make_shared<ShaderProgram>();
    ShaderProgram& p = *prog;
    p.constants.assign(kRegisters, 0.0f);
    p.constants[20] = 5.0f, p.constants[21] = 2.0f, p.constants[22] = 0.5f, p.constants[23] = 0.0f;
    p.code.push_back(instr(ShaderOp::Geometry, uint16_t(GeometryKind::Position), {0}, {}));
    const uint16_t noise_in[4] = {0, 20, 21, 22};
    p.data = data_for(ShaderOp::TexNoise, noise_in, rng);  // fac at 32, colour at 35
    const uint32_t ramp = uint32_t(p.data.size());
    for (int i = 0; i < 4 * kRampTableSize; ++i) p.data.push_back(float(i % 7) / 6.0f);
    p.code.push_back(instr(ShaderOp::TexNoise, 3, {}, {}, 0));
    p.code.push_back(instr(ShaderOp::ColorRamp, 1, {40, 43}, {32}, ramp));
    p.code.push_back(instr(ShaderOp::MixColor, 0, {44}, {43, 35, 40}));
    p.code.push_back(instr(ShaderOp::Math, uint16_t(shader::MathOp::Multiply) | kClampBit, {47}, {32, 20, 21}));
    p.outputs = {{ShaderField::BaseColor, 0, 44}, {ShaderField::Roughness, 0, 47}, {ShaderField::Emission, 0, 35}};
    ASSERT_EQ(p.validate(0, 0), "");
    Material mat;
    mat.program = prog;
    const Scene scene;
    const Points pts(45, rng);
    std::vector<Material> got(pts.g.size());
    std::vector<Vec3f> got_n(pts.g.size());
    evaluate_material_batch(scene, mat, pts.g.data(), pts.g.size(), got.data(), got_n.data());
    for (size_t l = 0; l < pts.g.size(); ++l) {
        Material want;
        Vec3f want_n;
        evaluate_material(scene, mat, pts.g[l], want, want_n);
        const Closure &a = want.closures[0], &b = got[l].closures[0];
        EXPECT_TRUE(same_bits(a.base_color, b.base_color) && same_bits(a.roughness, b.roughness)) << "lane " << l;
        EXPECT_TRUE(same_bits(want.emission, got[l].emission)) << "lane " << l;
        EXPECT_TRUE(same_bits(want_n, got_n[l])) << "lane " << l;
        EXPECT_EQ(want.weights, got[l].weights);
    }
}

// Whole renders: a scene whose floor, sphere and mirror run programs (Noise
// -> ColorRamp on SIMD rows, Light Path and Math, Mapping -> Vector Math)
// renders the same image, bit for bit, with batch shading on and off, under
// every integrator that batches.
std::shared_ptr<ShaderProgram> floor_program() {
    auto p = std::make_shared<ShaderProgram>();
    p->constants.assign(16, 0.0f);
    p->constants[3] = 2.0f, p->constants[4] = 2.0f, p->constants[5] = 0.5f;  // scale, detail, roughness
    p->data = {0, 6, 3, 4, 5, 6, 7, 8};                                       // noise: fac 7, colour 8..10
    for (int i = 0; i < kRampTableSize; ++i) p->data.insert(p->data.end(), {float(i) / 255.0f, 0.4f, 0.2f, 1.0f});
    p->code = {instr(ShaderOp::Geometry, uint16_t(GeometryKind::Position), {0}, {}),
               instr(ShaderOp::TexNoise, 3, {}, {}, 0), instr(ShaderOp::ColorRamp, 1, {11, 14}, {7}, 8)};
    p->outputs = {{ShaderField::BaseColor, 0, 11}, {ShaderField::Roughness, 0, 7}};
    return p;
}

std::shared_ptr<ShaderProgram> sphere_program() {
    auto p = std::make_shared<ShaderProgram>();
    p->constants.assign(16, 0.0f);
    p->constants[4] = 3.0f, p->constants[6] = 0.9f, p->constants[7] = 0.1f, p->constants[8] = 0.1f;
    using M = shader::MathOp;
    p->code = {instr(ShaderOp::Geometry, uint16_t(GeometryKind::Position), {0}, {}),
               instr(ShaderOp::Math, uint16_t(M::Multiply), {3}, {2, 4, 4}),
               instr(ShaderOp::Math, uint16_t(M::Fraction), {3}, {3, 4, 4}),
               instr(ShaderOp::LightPath, uint16_t(LightPathKind::IsCamera), {5}, {}),
               instr(ShaderOp::Math, uint16_t(M::Maximum), {3}, {3, 5, 5}),
               instr(ShaderOp::MixColor, 0, {9}, {3, 6, 0})};
    p->outputs = {{ShaderField::BaseColor, 0, 9}};
    p->uses_light_path = true;
    return p;
}

std::shared_ptr<ShaderProgram> mirror_program() {
    auto p = std::make_shared<ShaderProgram>();
    p->constants = {0, 0, 0, 0.1f, 0.2f, 0.3f, 0.3f, 0.2f, 0.1f, 2, 2, 2, 0, 0, 0, 0, 0.2f, 0.5f, 0.1f};
    p->code = {instr(ShaderOp::Geometry, uint16_t(GeometryKind::Position), {0}, {}),
               instr(ShaderOp::Mapping, uint16_t(MappingType::Point), {12}, {0, 3, 6, 9}),
               instr(ShaderOp::VectorMath, uint16_t(shader::VectorMathOp::DotProduct), {kNoRegister, 15},
                     {12, 16, 16, 15}),
               instr(ShaderOp::Math, uint16_t(shader::MathOp::Fraction) | kClampBit, {15}, {15, 15, 15})};
    p->outputs = {{ShaderField::Roughness, 0, 15}};
    return p;
}

// Renders `scene` with every traversal that shades in batches, with shader
// batches off (each hit alone) and on: the images must be the same to the
// bit, and lit (not an empty image that would agree trivially).
void expect_batches_render_the_scalar_image(const Scene& scene, uint32_t seed) {
    for (Traversal traversal : {Traversal::Packet, Traversal::Stream, Traversal::Wavefront}) {
        RenderSettings rs;
        rs.width = 40, rs.height = 36, rs.spp = 2, rs.seed = seed, rs.threads = 2, rs.max_bounces = 4;
        rs.traversal = traversal;
        rs.shader_batch = false;
        const std::vector<float> scalar = test::render_combined(scene, rs);
        rs.shader_batch = true;
        const std::vector<float> batch = test::render_combined(scene, rs);
        ASSERT_EQ(scalar.size(), batch.size());
        EXPECT_EQ(std::memcmp(scalar.data(), batch.data(), scalar.size() * sizeof(float)), 0)
            << "traversal " << int(traversal);
        double sum = 0.0;
        for (float x : batch) sum += x;
        EXPECT_GT(sum, 0.0);
    }
}

TEST(ShaderBatch, RendersAreIdenticalWithBatchShadingOnAndOff) {
    Scene scene = test::lobes_scene(false);
    int programs = 0;
    for (Material& m : scene.materials) {  // by their constants: the floor, the red sphere, the rough metal
        const Closure& c = m.closures[0];
        if (c.base_color.x == 0.7f) m.program = floor_program();
        else if (c.base_color.x == 0.8f && c.base_color.y == 0.2f) m.program = sphere_program();
        else if (c.metallic == 1.0f && c.roughness == 0.3f) m.program = mirror_program();
        else continue;
        ASSERT_EQ(m.program->validate(0, 0), "");
        ++programs;
    }
    ASSERT_EQ(programs, 3);
    expect_batches_render_the_scalar_image(scene, 3);
}

// Base Color from the Object texture coordinate: on an instance the point
// in its object space (the instance's transforms), elsewhere the world point.
std::shared_ptr<ShaderProgram> object_coordinate_program() {
    auto p = std::make_shared<ShaderProgram>();
    p->constants.assign(8, 0.0f);
    p->constants[3] = 1.0f;  // the fraction's operand
    using M = shader::MathOp;
    p->code = {instr(ShaderOp::TexCoord, uint16_t(TexCoordKind::Object), {0}, {}),
               instr(ShaderOp::Math, uint16_t(M::Fraction), {4}, {0, 3, 3}),
               instr(ShaderOp::Math, uint16_t(M::Fraction), {5}, {1, 3, 3}),
               instr(ShaderOp::Math, uint16_t(M::Fraction), {6}, {2, 3, 3})};
    p->outputs = {{ShaderField::BaseColor, 0, 4}};
    return p;
}

// Batches reuse their ShadingGeometry arrays, and a hit that is not on an
// instance leaves the transforms an instance hit wrote before it
// (fill_shading_geometry): nothing may read them there. Here one program
// runs on instanced quads (rotated, scaled, offset: far from the identity)
// and on plain geometry, whose hits share batches; a read of the stale
// transforms would change the plain hits' colour from the per-hit path's.
TEST(ShaderBatch, InstancesAndPlainHitsShareBatchesWithoutSharingTransforms) {
    Scene scene = test::lobes_scene(false);
    uint32_t programs = 0;
    for (Material& m : scene.materials) {  // by their constants: the floor and the red sphere
        const Vec3f& c = m.closures[0].base_color;
        if (c.x == 0.7f || (c.x == 0.8f && c.y == 0.2f)) m.program = object_coordinate_program(), ++programs;
    }
    ASSERT_EQ(programs, 2u);
    const uint32_t floor_material = scene.material_of[0];
    ASSERT_TRUE(scene.materials[floor_material].program);
    const float pos[] = {-0.5f, -0.5f, 0.0f, 0.5f, -0.5f, 0.0f, 0.5f, 0.5f, 0.0f, -0.5f, 0.5f, 0.0f};
    const uint32_t idx[] = {0, 1, 2, 0, 2, 3};
    MeshInput quad;
    quad.name = "tile";
    quad.positions = pos, quad.vertex_count = 4, quad.indices = idx, quad.triangle_count = 2;
    const uint32_t proto = scene.add_prototype(quad);
    ASSERT_NE(proto, Scene::kNoPrototype);
    std::vector<Transform> placements;
    for (int k = 0; k < 4; ++k) {
        Transform t;
        const float a = 0.4f + 0.5f * float(k), scale = 0.9f + 0.3f * float(k);
        t.m[0][0] = scale * std::cos(a), t.m[0][1] = -scale * std::sin(a);
        t.m[1][0] = scale * std::sin(a), t.m[1][1] = scale * std::cos(a);
        t.m[2][2] = scale;
        t.m[0][3] = -2.5f + 1.6f * float(k), t.m[1][3] = -1.2f + 0.3f * float(k), t.m[2][3] = 0.01f + 0.02f * float(k);
        placements.push_back(t);
    }
    ASSERT_EQ(scene.add_instances(proto, placements.data(), placements.size(), {floor_material}, "tiles"), 4u);
    scene.finalize();
    expect_batches_render_the_scalar_image(scene, 5);
}

}  // namespace
}  // namespace coherent
