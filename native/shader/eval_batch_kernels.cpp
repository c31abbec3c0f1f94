// SIMD row kernels of the batch interpreter; see eval_batch_kernels.h for
// why each one rounds exactly as its scalar formula (node_math.h,
// node_color.h) does. Every kernel loads a block's inputs before it stores
// its outputs, as the scalar code reads before it writes, so an output may
// share rows with an input.
#include "eval_batch_kernels.h"
#include "eval_batch_rows.h"

#include <cfloat>
#include <cmath>

#include "../core/simd.h"
#include "node_color.h"
#include "node_math.h"

namespace coherent::eval_detail {

namespace {

using shader::MathOp;
using shader::VectorMathOp;
// std::fmax(a, c) for a constant c (never NaN): a NaN `a` gives c, equal
// operands the second, as glibc's fmaxf (maxss) and vmaxps both return it.
// Only constant second operands: GCC treats fmin/fmax as commutative and may
// swap two variables, which then decides which of -0 and +0 comes out, so
// nodes that take the min or max of two inputs (Minimum, Maximum, Clamp)
// stay with the scalar code.
V fmax_(V a, float c) { return max(a, V(c)); }
// saturatef: fmin(fmax(a, 0), 1).
V saturate_(V a) { return min(max(a, V(0.0f)), V(1.0f)); }
V floor_(V a) { return V(_mm256_floor_ps(a.v)); }
V ceil_(V a) { return V(_mm256_ceil_ps(a.v)); }
V sqrt_(V a) { return V(_mm256_sqrt_ps(a.v)); }
V safe_divide_(V a, V b) { return select(b != V(0.0f), a / b, V(0.0f)); }

template <class F>
void for_blocks(const BatchRegisters& b, F f) {
    for (size_t l = 0; l < b.blocks * 8; l += 8) f(l);
}

// Math: x = f(a, b, c) on every block, then the optional clamp.
template <class F>
bool math_rows(const ShaderInstr& in, const BatchRegisters& b, F f) {
    const Rows r{b};
    const bool clamp = (in.mode & kClampBit) != 0;
    for_blocks(b, [&](size_t l) {
        V x = f(r.f(in.in[0], l), r.f(in.in[1], l), r.f(in.in[2], l));
        if (clamp) x = saturate_(x);
        r.set(in.out[0], l, x);
    });
    return true;
}

bool math(const ShaderInstr& in, const BatchRegisters& b) {
    const V zero(0.0f), one(1.0f);
    switch (MathOp(in.mode & 0xFF)) {
        case MathOp::Add: return math_rows(in, b, [](V a, V c, V) { return a + c; });
        case MathOp::Subtract: return math_rows(in, b, [](V a, V c, V) { return a - c; });
        case MathOp::Multiply: return math_rows(in, b, [](V a, V c, V) { return a * c; });
        case MathOp::Divide: return math_rows(in, b, [](V a, V c, V) { return safe_divide_(a, c); });
        case MathOp::MultiplyAdd: return math_rows(in, b, [](V a, V c, V d) { return a * c + d; });
        case MathOp::Sqrt: return math_rows(in, b, [](V a, V, V) { return sqrt_(fmax_(a, 0.0f)); });
        case MathOp::InvSqrt: return math_rows(in, b, [&](V a, V, V) { return one / sqrt_(a); });
        case MathOp::Absolute: return math_rows(in, b, [](V a, V, V) { return abs(a); });
        case MathOp::Radians: return math_rows(in, b, [](V a, V, V) { return a * V(float(M_PI) / 180.0f); });
        case MathOp::Degrees: return math_rows(in, b, [](V a, V, V) { return a * V(180.0f / float(M_PI)); });
        case MathOp::LessThan: return math_rows(in, b, [&](V a, V c, V) { return select(a < c, one, zero); });
        case MathOp::GreaterThan: return math_rows(in, b, [&](V a, V c, V) { return select(a > c, one, zero); });
        case MathOp::Round: return math_rows(in, b, [](V a, V, V) { return floor_(a + V(0.5f)); });
        case MathOp::Floor: return math_rows(in, b, [](V a, V, V) { return floor_(a); });
        case MathOp::Ceil: return math_rows(in, b, [](V a, V, V) { return ceil_(a); });
        case MathOp::Fraction: return math_rows(in, b, [](V a, V, V) { return a - floor_(a); });
        case MathOp::Trunc: return math_rows(in, b, [&](V a, V, V) { return select(a >= zero, floor_(a), ceil_(a)); });
        case MathOp::Snap: return math_rows(in, b, [](V a, V c, V) { return floor_(safe_divide_(a, c)) * c; });
        case MathOp::Sign:
            return math_rows(in, b, [&](V a, V, V) { return select(a == zero, zero, select(a > zero, one, V(-1.0f))); });
        case MathOp::Compare:
            return math_rows(in, b, [&](V a, V c, V d) {
                return select((a == c) | (abs(a - c) <= fmax_(d, FLT_EPSILON)), one, zero);
            });
        default: return false;  // transcendental (libm), Minimum, Maximum: lane by lane
    }
}

// Vector Math: the vector and the float result (the other one 0).
template <class F>
bool vector_math_rows(const ShaderInstr& in, const BatchRegisters& b, F f) {
    const Rows r{b};
    for_blocks(b, [&](size_t l) {
        V3 vec{V(0.0f), V(0.0f), V(0.0f)};
        V value(0.0f);
        f(r.v(in.in[0], l), r.v(in.in[1], l), r.v(in.in[2], l), r.f(in.in[3], l), vec, value);
        r.set(in.out[0], l, vec);
        r.set(in.out[1], l, value);
    });
    return true;
}

bool vector_math(const ShaderInstr& in, const BatchRegisters& b) {
    using R = V3&;
    switch (VectorMathOp(in.mode)) {
        case VectorMathOp::Add:
            return vector_math_rows(in, b, [](V3 a, V3 c, V3, V, R o, V&) { o = {a.x + c.x, a.y + c.y, a.z + c.z}; });
        case VectorMathOp::Subtract:
            return vector_math_rows(in, b, [](V3 a, V3 c, V3, V, R o, V&) { o = {a.x - c.x, a.y - c.y, a.z - c.z}; });
        case VectorMathOp::Multiply:
            return vector_math_rows(in, b, [](V3 a, V3 c, V3, V, R o, V&) { o = {a.x * c.x, a.y * c.y, a.z * c.z}; });
        case VectorMathOp::Divide:
            return vector_math_rows(in, b, [](V3 a, V3 c, V3, V, R o, V&) {
                o = {safe_divide_(a.x, c.x), safe_divide_(a.y, c.y), safe_divide_(a.z, c.z)};
            });
        case VectorMathOp::MultiplyAdd:
            return vector_math_rows(in, b, [](V3 a, V3 c, V3 d, V, R o, V&) {
                o = {a.x * c.x + d.x, a.y * c.y + d.y, a.z * c.z + d.z};
            });
        case VectorMathOp::Scale:
            return vector_math_rows(in, b, [](V3 a, V3, V3, V s, R o, V&) { o = {a.x * s, a.y * s, a.z * s}; });
        case VectorMathOp::DotProduct:
            return vector_math_rows(in, b, [](V3 a, V3 c, V3, V, R, V& value) { value = dot_(a, c); });
        case VectorMathOp::Length:
            return vector_math_rows(in, b, [](V3 a, V3, V3, V, R, V& value) { value = sqrt_(dot_(a, a)); });
        case VectorMathOp::Distance:
            return vector_math_rows(in, b, [](V3 a, V3 c, V3, V, R, V& value) {
                const V3 d{a.x - c.x, a.y - c.y, a.z - c.z};
                value = sqrt_(dot_(d, d));
            });
        case VectorMathOp::Floor:
            return vector_math_rows(in, b, [](V3 a, V3, V3, V, R o, V&) { o = {floor_(a.x), floor_(a.y), floor_(a.z)}; });
        case VectorMathOp::Fraction:
            return vector_math_rows(in, b, [](V3 a, V3, V3, V, R o, V&) {
                o = {a.x - floor_(a.x), a.y - floor_(a.y), a.z - floor_(a.z)};
            });
        default: return false;
    }
}

// Mix Color (blend Mix only: interp(c1, c2, t)), Mix Float, Mix Vector.
bool mix(const ShaderInstr& in, const BatchRegisters& b) {
    const Rows r{b};
    const bool clamp_factor = (in.mode & kClampFactorBit) != 0;
    if (in.op == ShaderOp::MixColor) {
        if (shader::MixBlend(in.mode & 0xFF) != shader::MixBlend::Mix) return false;
        const bool clamp_result = (in.mode & kClampResultBit) != 0;
        for_blocks(b, [&](size_t l) {
            V t = r.f(in.in[0], l);
            if (clamp_factor) t = saturate_(t);
            const V3 c1 = r.v(in.in[1], l), c2 = r.v(in.in[2], l);
            V3 c{c1.x + t * (c2.x - c1.x), c1.y + t * (c2.y - c1.y), c1.z + t * (c2.z - c1.z)};
            if (clamp_result) c = {saturate_(c.x), saturate_(c.y), saturate_(c.z)};
            r.set(in.out[0], l, c);
        });
    } else if (in.op == ShaderOp::MixFloat) {
        for_blocks(b, [&](size_t l) {
            V t = r.f(in.in[0], l);
            if (clamp_factor) t = saturate_(t);
            r.set(in.out[0], l, r.f(in.in[1], l) * (V(1.0f) - t) + r.f(in.in[2], l) * t);
        });
    } else {
        const bool non_uniform = (in.mode & kNonUniformBit) != 0;
        for_blocks(b, [&](size_t l) {
            V3 t = non_uniform ? r.v(in.in[0], l) : V3{r.f(in.in[0], l), r.f(in.in[0], l), r.f(in.in[0], l)};
            if (clamp_factor) t = {saturate_(t.x), saturate_(t.y), saturate_(t.z)};
            const V3 c1 = r.v(in.in[1], l), c2 = r.v(in.in[2], l), one{V(1.0f), V(1.0f), V(1.0f)};
            r.set(in.out[0], l, V3{c1.x * (one.x - t.x) + c2.x * t.x, c1.y * (one.y - t.y) + c2.y * t.y,
                                   c1.z * (one.z - t.z) + c2.z * t.z});
        });
    }
    return true;
}

// Whether rows reg..reg + 2 hold the same bits in every live lane.
bool uniform_vec3(const BatchRegisters& b, uint16_t reg, size_t live_lanes) {
    for (int k = 0; k < 3; ++k) {
        const uint32_t* row = reinterpret_cast<const uint32_t*>(b.row(uint16_t(reg + k)));
        for (size_t l = 1; l < live_lanes; ++l)
            if (row[l] != row[0]) return false;
    }
    return true;
}

// Mapping (Point, Texture, Vector) with one rotation for the whole batch, the
// usual case of a constant rotation input: its sines and cosines once.
bool mapping(const ShaderInstr& in, const BatchRegisters& b, size_t live_lanes) {
    if (in.mode > 2 || !uniform_vec3(b, in.in[2], live_lanes)) return false;
    const float* rot = b.row(in.in[2]);
    const shader::EulerRotation e(Vec3f{rot[0], rot[b.lanes], rot[2 * b.lanes]});
    const V3 x{V(e.x.x), V(e.x.y), V(e.x.z)}, y{V(e.y.x), V(e.y.y), V(e.y.z)}, z{V(e.z.x), V(e.z.y), V(e.z.z)};
    const Rows r{b};
    for_blocks(b, [&](size_t l) {
        const V3 v = r.v(in.in[0], l), loc = r.v(in.in[1], l), scale = r.v(in.in[3], l);
        V3 o;
        if (in.mode == 1) {  // Texture: safe_divide(R^T (v - location), scale)
            const V3 a{v.x - loc.x, v.y - loc.y, v.z - loc.z};
            o = {safe_divide_(a.x * x.x + a.y * y.x + a.z * z.x, scale.x),
                 safe_divide_(a.x * x.y + a.y * y.y + a.z * z.y, scale.y),
                 safe_divide_(a.x * x.z + a.y * y.z + a.z * z.z, scale.z)};
        } else {  // Point: R (v scale) + location; Vector: R (v scale)
            const V3 a{v.x * scale.x, v.y * scale.y, v.z * scale.z};
            o = {dot_(x, a), dot_(y, a), dot_(z, a)};
            if (in.mode == 0) o = {o.x + loc.x, o.y + loc.y, o.z + loc.z};
        }
        r.set(in.out[0], l, o);
    });
    return true;
}

// ColorRamp: the table entries gathered, blended where t > 0 (ramp_lookup).
bool color_ramp(const ShaderProgram& prog, const ShaderInstr& in, const BatchRegisters& b) {
    const float* table = prog.data.data() + in.data;
    const bool interpolate = in.mode != 0;
    const Rows r{b};
    for_blocks(b, [&](size_t l) {
        const V f = saturate_(r.f(in.in[0], l)) * V(float(kRampTableSize - 1));
        const __m256i i = _mm256_cvttps_epi32(f.v);  // f in [0, size - 1]: int(f) needs no clamp
        const V t = f - V(_mm256_cvtepi32_ps(i));
        const __m256i at = _mm256_slli_epi32(i, 2);
        V c[4];
        for (int k = 0; k < 4; ++k) c[k] = V(_mm256_i32gather_ps(table + k, at, 4));
        if (interpolate) {
            const simd::vbool8 blend = t > V(0.0f);  // t > 0 only below the last entry
            for (int k = 0; k < 4; ++k) {
                const V next(_mm256_mask_i32gather_ps(_mm256_setzero_ps(), table + 4 + k, at, blend.m, 4));
                c[k] = select(blend, (V(1.0f) - t) * c[k] + t * next, c[k]);
            }
        }
        r.set(in.out[0], l, V3{c[0], c[1], c[2]});
        r.set(in.out[1], l, c[3]);
    });
    return true;
}

// Invert, RGB to BW, Combine.
bool simple(const ShaderInstr& in, const BatchRegisters& b) {
    const Rows r{b};
    for_blocks(b, [&](size_t l) {
        switch (in.op) {
            case ShaderOp::Invert: {  // interp(c, 1 - c, t)
                const V t = r.f(in.in[0], l);
                const V3 c = r.v(in.in[1], l);
                const V3 inv{V(1.0f) - c.x, V(1.0f) - c.y, V(1.0f) - c.z};
                r.set(in.out[0], l, V3{c.x + t * (inv.x - c.x), c.y + t * (inv.y - c.y), c.z + t * (inv.z - c.z)});
                break;
            }
            case ShaderOp::RgbToBw: {
                const V3 c = r.v(in.in[0], l);
                r.set(in.out[0], l, V(0.212671f) * c.x + V(0.71516f) * c.y + V(0.072169f) * c.z);
                break;
            }
            default: r.set(in.out[0], l, V3{r.f(in.in[0], l), r.f(in.in[1], l), r.f(in.in[2], l)}); break;  // Combine
        }
    });
    return true;
}

}  // namespace

bool run_vector_instruction(const ShaderProgram& prog, const ShaderInstr& in, const BatchRegisters& b,
                            size_t live_lanes) {
    switch (in.op) {
        case ShaderOp::Math: return math(in, b);
        case ShaderOp::VectorMath: return vector_math(in, b);
        case ShaderOp::MixColor:
        case ShaderOp::MixFloat:
        case ShaderOp::MixVector: return mix(in, b);
        case ShaderOp::Mapping: return mapping(in, b, live_lanes);
        case ShaderOp::ColorRamp: return color_ramp(prog, in, b);
        case ShaderOp::Invert:
        case ShaderOp::RgbToBw:
        case ShaderOp::Combine: return simple(in, b);
        case ShaderOp::TexNoise: return noise3_rows(prog, in, b, live_lanes);
        default: return false;
    }
}

}  // namespace coherent::eval_detail
