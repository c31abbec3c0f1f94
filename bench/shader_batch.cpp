// shader-batch: one material's shader program evaluated at many shading
// points one point at a time (evaluate_material, the scalar interpreter)
// against SoA batches (evaluate_material_batch), side by side in one run.
//
//   shader-batch [--points N] [--runs R]
//
// Three programs (built here as the add-on's compiler would emit them):
//   noise:   Position -> Mapping -> Noise (3D, detail 2) -> ColorRamp, Mixed
//            with the noise colour by a clamped Math factor; the procedural
//            texture itself has no SIMD kernel and runs lane by lane.
//   texture: Position -> Mapping -> Image Texture (512x512 float RGBA,
//            linear) -> RGB to BW -> ColorRamp -> Mix, Math.
//   math:    Mapping -> Vector Math (Scale, Add, Dot) -> Math chain ->
//            Mix Float -> ColorRamp -> Mix Color: every instruction on SIMD rows.
// Points: N random positions in [0, 4)^3 with random unit normals, in the
// order drawn (batch sizes: whole runs of `batch` points, as a packet of 64
// or a wavefront stretch of 4096 hands them over). One thread; best of R
// runs of the thread's CPU time. Every batch result is checked bit for bit
// against the scalar one (mismatches printed, 0 expected).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "core/thread_time.h"
#include "scene/scene.h"
#include "shader/eval.h"
#include "shader/eval_batch.h"
#include "shader/node_color.h"
#include "shader/node_math.h"
#include "shader/program.h"
#include "shader/textures.h"

namespace {

using namespace coherent;

ShaderInstr op(ShaderOp o, uint16_t mode, std::initializer_list<uint16_t> outs, std::initializer_list<uint16_t> ins,
               uint32_t data = 0) {
    ShaderInstr in;
    in.op = o;
    in.mode = mode;
    int k = 0;
    for (uint16_t r : outs) in.out[k++] = r;
    k = 0;
    for (uint16_t r : ins) in.in[k++] = r;
    in.data = data;
    return in;
}

// Program builder: registers with constants, tables in data.
struct Builder {
    ShaderProgram p;
    uint16_t reg(std::initializer_list<float> values) {
        const uint16_t r = uint16_t(p.constants.size());
        p.constants.insert(p.constants.end(), values);
        return r;
    }
    uint16_t vec() { return reg({0.0f, 0.0f, 0.0f}); }
    uint16_t scalar() { return reg({0.0f}); }
    // A three-stop ramp (dark red, orange, pale yellow).
    uint32_t ramp() {
        const uint32_t at = uint32_t(p.data.size());
        for (int i = 0; i < kRampTableSize; ++i) {
            const float t = float(i) / float(kRampTableSize - 1);
            p.data.insert(p.data.end(), {0.3f + 0.7f * t, 0.05f + 0.8f * t * t, 0.02f + 0.6f * t * t * t, 1.0f});
        }
        return at;
    }
    void emit(ShaderInstr in) { p.code.push_back(in); }
};

// Position -> Mapping (Point: scale 4, a constant rotation) into `out`.
uint16_t mapped_position(Builder& b) {
    const uint16_t pos = b.vec(), out = b.vec();
    const uint16_t loc = b.reg({0.1f, 0.2f, 0.3f}), rot = b.reg({0.3f, 0.5f, 0.7f}), scale = b.reg({4, 4, 4});
    b.emit(op(ShaderOp::Geometry, uint16_t(GeometryKind::Position), {pos}, {}));
    b.emit(op(ShaderOp::Mapping, uint16_t(MappingType::Point), {out}, {pos, loc, rot, scale}));
    return out;
}

void finish(Builder& b, uint16_t color, uint16_t roughness) {
    b.p.outputs = {{ShaderField::BaseColor, 0, color}, {ShaderField::Roughness, 0, roughness}};
}

ShaderProgram noise_program() {
    Builder b;
    const uint16_t v = mapped_position(b);
    const uint16_t w = b.reg({0}), scale = b.reg({2}), detail = b.reg({2}), rough = b.reg({0.5f}), dist = b.reg({0});
    const uint16_t fac = b.scalar(), col = b.vec();
    const uint32_t list = uint32_t(b.p.data.size());
    for (uint16_t r : {v, w, scale, detail, rough, dist, fac, col}) b.p.data.push_back(float(r));
    b.emit(op(ShaderOp::TexNoise, 3, {}, {}, list));
    const uint16_t ramp_col = b.vec(), ramp_alpha = b.scalar();
    b.emit(op(ShaderOp::ColorRamp, 1, {ramp_col, ramp_alpha}, {fac}, b.ramp()));
    const uint16_t k = b.reg({1.5f}), t = b.scalar(), mixed = b.vec(), zero = b.reg({0});
    b.emit(op(ShaderOp::Math, uint16_t(shader::MathOp::Multiply) | kClampBit, {t}, {fac, k, zero}));
    b.emit(op(ShaderOp::MixColor, uint16_t(shader::MixBlend::Mix), {mixed}, {t, ramp_col, col}));
    finish(b, mixed, t);
    return b.p;
}

ShaderProgram texture_program() {
    Builder b;
    const uint16_t v = mapped_position(b);
    const uint16_t col = b.vec(), alpha = b.scalar();
    b.emit(op(ShaderOp::ImageTexture, 0, {col, alpha}, {v}, 0));
    const uint16_t grey = b.scalar(), ramp_col = b.vec(), ramp_alpha = b.scalar();
    b.emit(op(ShaderOp::RgbToBw, 0, {grey}, {col}));
    b.emit(op(ShaderOp::ColorRamp, 1, {ramp_col, ramp_alpha}, {grey}, b.ramp()));
    const uint16_t half = b.reg({0.5f}), mixed = b.vec(), rough = b.scalar(), k = b.reg({0.8f}), zero = b.reg({0});
    b.emit(op(ShaderOp::MixColor, uint16_t(shader::MixBlend::Mix), {mixed}, {half, ramp_col, col}));
    b.emit(op(ShaderOp::Math, uint16_t(shader::MathOp::Multiply), {rough}, {grey, k, zero}));
    finish(b, mixed, rough);
    return b.p;
}

ShaderProgram math_program() {
    Builder b;
    const uint16_t v = mapped_position(b);
    const uint16_t scaled = b.vec(), sum = b.vec(), dotv = b.scalar(), unused = b.scalar();
    const uint16_t s = b.reg({0.25f}), off = b.reg({0.5f, 0.25f, 0.125f}), axis = b.reg({0.3f, 0.6f, 0.1f});
    using VM = shader::VectorMathOp;
    using M = shader::MathOp;
    b.emit(op(ShaderOp::VectorMath, uint16_t(VM::Scale), {scaled, unused}, {v, v, v, s}));
    b.emit(op(ShaderOp::VectorMath, uint16_t(VM::Add), {sum, unused}, {scaled, off, off, s}));
    b.emit(op(ShaderOp::VectorMath, uint16_t(VM::DotProduct), {kNoRegister, dotv}, {sum, axis, axis, s}));
    const uint16_t a = b.scalar(), c = b.scalar(), d = b.scalar(), e = b.scalar();
    const uint16_t three = b.reg({3.0f}), one = b.reg({1.0f}), zero = b.reg({0.0f});
    b.emit(op(ShaderOp::Math, uint16_t(M::Multiply), {a}, {dotv, three, zero}));
    b.emit(op(ShaderOp::Math, uint16_t(M::Fraction), {c}, {a, zero, zero}));
    b.emit(op(ShaderOp::Math, uint16_t(M::MultiplyAdd), {d}, {c, c, one}));
    b.emit(op(ShaderOp::Math, uint16_t(M::Divide) | kClampBit, {e}, {c, d, zero}));
    const uint16_t f = b.scalar(), ramp_col = b.vec(), ramp_alpha = b.scalar(), mixed = b.vec();
    b.emit(op(ShaderOp::MixFloat, kClampFactorBit, {f}, {e, c, a}));
    b.emit(op(ShaderOp::ColorRamp, 1, {ramp_col, ramp_alpha}, {f}, b.ramp()));
    b.emit(op(ShaderOp::MixColor, uint16_t(shader::MixBlend::Mix), {mixed}, {e, ramp_col, off}));
    finish(b, mixed, e);
    return b.p;
}

std::vector<ShadingGeometry> random_points(size_t n) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(0.0f, 4.0f), s(-1.0f, 1.0f);
    std::vector<ShadingGeometry> g(n);
    for (ShadingGeometry& p : g) {
        p.p = {u(rng), u(rng), u(rng)};
        p.n = normalize(Vec3f{s(rng), s(rng), s(rng)});
        p.ng = p.n;
        p.wo = p.n;
    }
    return g;
}

bool same(const Material& a, const Vec3f& na, const Material& b, const Vec3f& nb) {
    const Closure &x = a.closures[0], &y = b.closures[0];
    return std::memcmp(&x.base_color, &y.base_color, sizeof(Vec3f)) == 0 &&
           std::memcmp(&x.roughness, &y.roughness, sizeof(float)) == 0 && std::memcmp(&na, &nb, sizeof(Vec3f)) == 0;
}

template <class F>
double best_seconds(int runs, F f) {
    double best = 1e30;
    for (int r = 0; r < runs; ++r) {
        const double start = thread_cpu_seconds();
        f();
        best = std::min(best, thread_cpu_seconds() - start);
    }
    return best;
}

void bench(const char* name, const Scene& scene, ShaderProgram program, size_t points, int runs) {
    const std::string error = program.validate(scene.shading.textures ? 1 : 0, 0);
    if (!error.empty()) {
        std::fprintf(stderr, "%s: invalid program: %s\n", name, error.c_str());
        std::exit(1);
    }
    Material mat;
    mat.program = std::make_shared<ShaderProgram>(std::move(program));
    const std::vector<ShadingGeometry> g = random_points(points);
    std::vector<Material> want(points), got(points);
    std::vector<Vec3f> want_n(points), got_n(points);
    const double scalar = best_seconds(runs, [&] {
        for (size_t i = 0; i < points; ++i) evaluate_material(scene, mat, g[i], want[i], want_n[i]);
    });
    std::printf("| %-7s | %5zu | %8.1f |", name, mat.program->code.size(), 1e9 * scalar / double(points));
    for (size_t batch : {size_t(8), size_t(64), size_t(4096)}) {
        const double t = best_seconds(runs, [&] {
            for (size_t first = 0; first < points; first += batch)
                evaluate_material_batch(scene, mat, &g[first], std::min(batch, points - first), &got[first],
                                        &got_n[first]);
        });
        size_t bad = 0;
        for (size_t i = 0; i < points; ++i) bad += same(want[i], want_n[i], got[i], got_n[i]) ? 0 : 1;
        std::printf(" %8.1f | %5.2f | %zu |", 1e9 * t / double(points), scalar / t, bad);
    }
    std::printf("\n");
}

}  // namespace

int main(int argc, char** argv) {
    size_t points = 1 << 16;
    int runs = 5;
    for (int i = 1; i + 1 < argc; i += 2) {
        if (!std::strcmp(argv[i], "--points")) points = size_t(std::atol(argv[i + 1]));
        else if (!std::strcmp(argv[i], "--runs")) runs = std::atoi(argv[i + 1]);
        else {
            std::fprintf(stderr, "usage: shader-batch [--points N] [--runs R]\n");
            return 2;
        }
    }
    Scene scene;
    Scene textured;
    textured.shading.textures = std::make_shared<TextureStore>(256);
    std::vector<float> pixels(512 * 512 * 4);
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (float& x : pixels) x = u(rng);
    textured.shading.textures->add_pixels("bench", 512, 512, 4, pixels.data());

    std::printf("%zu points, best of %d runs, one thread; ns per point; ratio = scalar / batch; "
                "mismatch = points whose batch result differs from the scalar one in any bit\n\n",
                points, runs);
    std::printf("| program | instr | scalar | batch 8 | ratio | mismatch | batch 64 | ratio | mismatch "
                "| batch 4096 | ratio | mismatch |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    bench("noise", scene, noise_program(), points, runs);
    bench("texture", textured, texture_program(), points, runs);
    bench("math", scene, math_program(), points, runs);
    return 0;
}
