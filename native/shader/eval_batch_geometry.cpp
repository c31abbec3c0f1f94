// The nodes that read the mesh at each shading point, in SIMD rows: the UV
// coordinate (Texture Coordinate's and UV Map's UV) and the tangent-space
// Normal Map, the two every textured material runs. Each lane's result is the
// scalar interpreter's (eval.cpp uv_coordinate, normal_map) bit for bit: the
// same float operations in the same order (the build never contracts them),
// a / len as a * (1 / len) as Vec3f's division does, negation as a sign flip.
//
// Points on instances (attributes in object space, transformed per point)
// and lanes whose normal ensure_valid_reflection has to tilt take the scalar
// code; the rows cover the rest.
#include <algorithm>
#include <cstdint>

#include "../core/simd.h"
#include "../scene/scene.h"
#include "eval_batch_kernels.h"
#include "eval_batch_rows.h"
#include "eval_registers.h"
#include "program.h"

namespace coherent::eval_detail {

namespace {

using B = simd::vbool8;

V3 operator+(const V3& a, const V3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
V3 operator-(const V3& a, const V3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
V3 operator*(const V3& a, V s) { return {a.x * s, a.y * s, a.z * s}; }
V3 cross(const V3& a, const V3& b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
V negate(V a) { return V(_mm256_xor_ps(a.v, _mm256_set1_ps(-0.0f))); }
V3 negate(const V3& a) { return {negate(a.x), negate(a.y), negate(a.z)}; }
V3 select(B m, const V3& t, const V3& f) {
    return {simd::select(m, t.x, f.x), simd::select(m, t.y, f.y), simd::select(m, t.z, f.z)};
}

// node_math.h's safe_normalize.
V3 safe_normalize(const V3& a) {
    const V len = V(_mm256_sqrt_ps(dot_(a, a).v));
    return select(len != V(0.0f), a * (V(1.0f) / len), a);
}

// The lanes of a block as SoA rows (padding lanes repeat lane 0's point, so
// every row holds finite values).
struct Lanes {
    alignas(32) float u[8], v[8];
    alignas(32) float n[3][8], ng[3][8], wo[3][8];
    alignas(32) int32_t front[8];  // -1 where the ray hit the front, else 0
    alignas(32) float c[3][3][8];  // corner, component, lane
    alignas(32) float sign[8];
    V3 row3(const float (&r)[3][8]) const { return {V::load(r[0]), V::load(r[1]), V::load(r[2])}; }
};

bool on_flat_mesh(const ShadingGeometry* g, size_t live) {
    for (size_t l = 0; l < live; ++l)
        if (g[l].prototype) return false;
    return true;
}

bool uv_rows(const Scene& scene, const ShaderInstr& in, const ShadingGeometry* g, size_t live,
             const BatchRegisters& b) {
    const auto& layers = scene.shading.uvs;
    if (in.data >= layers.size()) return false;
    const std::vector<Vec2f>& uvs = layers[in.data];
    for (size_t l = 0; l < live; ++l)
        if (uvs.size() < 3 * size_t(g[l].tri) + 3) return false;
    if (in.out[0] == kNoRegister) return true;
    const Rows rows{b};
    for (size_t l0 = 0; l0 < b.blocks * 8; l0 += 8) {
        alignas(32) float u[8], v[8], c[3][2][8];
        for (size_t k = 0; k < 8; ++k) {
            const ShadingGeometry& p = g[l0 + k < live ? l0 + k : 0];
            u[k] = p.u, v[k] = p.v;
            const Vec2f* corner = &uvs[3 * size_t(p.tri)];
            for (int i = 0; i < 3; ++i) c[i][0][k] = corner[i].x, c[i][1][k] = corner[i].y;
        }
        const V gu = V::load(u), gv = V::load(v);
        const V w = V(1.0f) - gu - gv;
        const auto lerp = [&](int axis) {
            return V::load(c[0][axis]) * w + V::load(c[1][axis]) * gu + V::load(c[2][axis]) * gv;
        };
        rows.set(in.out[0], l0, V3{lerp(0), lerp(1), V(0.0f)});
    }
    return true;
}

bool tangent_normal_map_rows(const Scene& scene, const ShaderProgram& prog, const ShaderInstr& in,
                             const ShadingGeometry* g, size_t live, const BatchRegisters& b) {
    const SceneShading& sh = scene.shading;
    for (size_t l = 0; l < live; ++l)
        if (sh.tangents.size() < 3 * size_t(g[l].tri) + 3) return false;
    if (in.out[0] == kNoRegister) return true;
    const Rows rows{b};
    for (size_t l0 = 0; l0 < b.blocks * 8; l0 += 8) {
        Lanes s;
        for (size_t k = 0; k < 8; ++k) {
            const ShadingGeometry& p = g[l0 + k < live ? l0 + k : 0];
            s.u[k] = p.u, s.v[k] = p.v;
            for (int a = 0; a < 3; ++a) s.n[a][k] = p.n[a], s.ng[a][k] = p.ng[a], s.wo[a][k] = p.wo[a];
            s.front[k] = p.front ? -1 : 0;
            const Vec3f* corner = &sh.tangents[3 * size_t(p.tri)];
            for (int i = 0; i < 3; ++i)
                for (int a = 0; a < 3; ++a) s.c[i][a][k] = corner[i][a];
            s.sign[k] = sh.tangent_signs[3 * size_t(p.tri)];
        }
        const B front(_mm256_castsi256_ps(_mm256_load_si256(reinterpret_cast<const __m256i*>(s.front))));
        const V3 n = s.row3(s.n), ng = s.row3(s.ng), wo = s.row3(s.wo);
        const V strength = rows.f(in.in[0], l0);
        V3 color = rows.v(in.in[1], l0);
        color = {color.x * V(2.0f) - V(1.0f), color.y * V(2.0f) - V(1.0f), color.z * V(2.0f) - V(1.0f)};

        const V3 unflipped = select(front, n, negate(n));
        const V gu = V::load(s.u), gv = V::load(s.v);
        const V w = V(1.0f) - gu - gv;
        const V3 tangent = s.row3(s.c[0]) * w + s.row3(s.c[1]) * gu + s.row3(s.c[2]) * gv;
        const V3 bitangent = cross(unflipped, tangent) * V::load(s.sign);
        V3 mapped = safe_normalize(tangent * color.x + bitangent * color.y + unflipped * color.z);
        mapped = select(front, mapped, negate(mapped));
        const B weaker = strength != V(1.0f);
        if (simd::any(weaker)) {
            const V scale = simd::select(strength < V(0.0f), V(0.0f), strength);  // std::max(strength, 0)
            mapped = select(weaker, safe_normalize(n + (mapped - n) * scale), mapped);
        }
        const B black = (mapped.x == V(0.0f)) & (mapped.y == V(0.0f)) & (mapped.z == V(0.0f));
        const B finite = simd::isfinite(mapped.x) & simd::isfinite(mapped.y) & simd::isfinite(mapped.z);
        const B keep_n = black | ~finite;
        // ensure_valid_reflection's test; lanes that fail it are tilted by the
        // scalar code below.
        const V3 r = mapped * (V(2.0f) * dot_(mapped, wo)) - wo;
        const V scaled = V(0.9f) * dot_(ng, wo);
        const V threshold = simd::select(V(0.01f) < scaled, V(0.01f), scaled);
        const B valid = dot_(ng, r) >= threshold;
        const V3 out = select(keep_n, n, mapped);
        const size_t live_here = std::min<size_t>(8, live - l0);
        const int scalar = simd::movemask(~(valid | keep_n)) & ((1 << live_here) - 1);
        if (!scalar) {
            rows.set(in.out[0], l0, out);
            continue;
        }
        alignas(32) float x[3][8];
        simd::store(x[0], out.x), simd::store(x[1], out.y), simd::store(x[2], out.z);
        for (size_t k = 0; k < 8; ++k) {
            float* row = b.row(in.out[0]) + l0 + k;
            if (scalar >> k & 1) {
                run_instruction(scene, prog, g[l0 + k], in, Registers{b.regs + l0 + k, b.lanes});
            } else {
                row[0] = x[0][k], row[b.lanes] = x[1][k], row[2 * b.lanes] = x[2][k];
            }
        }
    }
    return true;
}

}  // namespace

bool geometry_rows(const Scene& scene, const ShaderProgram& prog, const ShaderInstr& in, const ShadingGeometry* g,
                   size_t live, const BatchRegisters& b) {
    if (in.op == ShaderOp::TexCoord && TexCoordKind(in.mode) == TexCoordKind::Uv)
        return on_flat_mesh(g, live) && uv_rows(scene, in, g, live, b);
    if (in.op == ShaderOp::NormalMap && NormalMapSpace(in.mode) == NormalMapSpace::Tangent)
        return on_flat_mesh(g, live) && tangent_normal_map_rows(scene, prog, in, g, live, b);
    return false;
}

}  // namespace coherent::eval_detail
