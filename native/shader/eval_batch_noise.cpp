// The Noise Texture (3D) on SIMD rows: node_noise.h's Perlin noise and
// fractal sum, operation for operation (the same lookup3 hash on integer
// lanes, the same explicit fused multiply-adds, the other operations each
// one rounding), so every lane equals the scalar texture bit for bit. It
// covers the usual case only: a batch whose Detail and Roughness are the same
// in every lane (the octave loop is then the same for all) and Distortion 0;
// anything else runs the scalar code lane by lane.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "../core/simd.h"
#include "eval_batch_kernels.h"
#include "node_hash.h"
#include "node_procedural.h"

namespace coherent::eval_detail {

namespace {

using V = simd::vfloat8;

struct VI {  // 8 uint32 lanes
    __m256i v;
};
VI operator+(VI a, VI b) { return {_mm256_add_epi32(a.v, b.v)}; }
VI operator-(VI a, VI b) { return {_mm256_sub_epi32(a.v, b.v)}; }
VI operator^(VI a, VI b) { return {_mm256_xor_si256(a.v, b.v)}; }
VI splat(uint32_t x) { return {_mm256_set1_epi32(int(x))}; }
VI rot(VI x, int k) { return {_mm256_or_si256(_mm256_slli_epi32(x.v, k), _mm256_srli_epi32(x.v, 32 - k))}; }

// shader::hash_uint3 (lookup3 final over three words).
VI hash3(VI kx, VI ky, VI kz) {
    VI a = splat(shader::lookup3::start(3)), b = a, c = a;
    c = c + kz;
    b = b + ky;
    a = a + kx;
    c = c ^ b; c = c - rot(b, 14);
    a = a ^ c; a = a - rot(c, 11);
    b = b ^ a; b = b - rot(a, 25);
    c = c ^ b; c = c - rot(b, 16);
    a = a ^ c; a = a - rot(c, 4);
    b = b ^ a; b = b - rot(a, 14);
    c = c ^ b; c = c - rot(b, 24);
    return c;
}

V fma_(V a, V b, V c) { return V(_mm256_fmadd_ps(a.v, b.v, c.v)); }
V mix_fused(V a, V b, V t) { return fma_(t, b - a, a); }
V fade(V t) { return (t * t) * (t * fma_(t, fma_(t, V(6.0f), V(-15.0f)), V(10.0f))); }
// v, its sign flipped where `bit` of h is set.
V negate_if(V v, VI h, int bit) {
    const __m256i set = _mm256_and_si256(h.v, _mm256_set1_epi32(bit));
    const __m256i flip = _mm256_slli_epi32(_mm256_cmpeq_epi32(set, _mm256_set1_epi32(bit)), 31);
    return V(_mm256_xor_ps(v.v, _mm256_castsi256_ps(flip)));
}
__m256 lanes_where(VI h, int value) { return _mm256_castsi256_ps(_mm256_cmpeq_epi32(h.v, _mm256_set1_epi32(value))); }
__m256 lanes_below(VI h, int value) { return _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(value), h.v)); }

// perlin::grad3.
V grad3(VI hash, V x, V y, V z) {
    const VI h{_mm256_and_si256(hash.v, _mm256_set1_epi32(15))};
    const V u(_mm256_blendv_ps(y.v, x.v, lanes_below(h, 8)));
    const V vt(_mm256_blendv_ps(z.v, x.v, _mm256_or_ps(lanes_where(h, 12), lanes_where(h, 14))));
    const V v(_mm256_blendv_ps(vt.v, y.v, lanes_below(h, 4)));
    return negate_if(u, h, 1) + negate_if(v, h, 2);
}

// perlin::noise3.
V noise3(V x, V y, V z) {
    const V fx0 = simd::vfloat8(_mm256_floor_ps(x.v)), fy0(_mm256_floor_ps(y.v)), fz0(_mm256_floor_ps(z.v));
    const VI X{_mm256_cvttps_epi32(fx0.v)}, Y{_mm256_cvttps_epi32(fy0.v)}, Z{_mm256_cvttps_epi32(fz0.v)};
    const V fx = x - fx0, fy = y - fy0, fz = z - fz0;
    V g[8];
    for (int c = 0; c < 8; ++c) {
        const int dx = c & 1, dy = (c >> 1) & 1, dz = (c >> 2) & 1;
        g[c] = grad3(hash3(X + splat(uint32_t(dx)), Y + splat(uint32_t(dy)), Z + splat(uint32_t(dz))),
                     fx - V(float(dx)), fy - V(float(dy)), fz - V(float(dz)));
    }
    const V tx = fade(fx), ty = fade(fy), tz = fade(fz);
    const V y0 = mix_fused(mix_fused(g[0], g[1], tx), mix_fused(g[2], g[3], tx), ty);
    const V y1 = mix_fused(mix_fused(g[4], g[5], tx), mix_fused(g[6], g[7], tx), ty);
    return mix_fused(y0, y1, tz);
}

// unoise(Pt<3>): 0.5 snoise + 0.5, snoise = 0.982 finite_or_zero(noise3).
V unoise(V x, V y, V z) {
    const V n = noise3(x, y, z);
    const V s = V(0.9820f) * select(isfinite(n), n, V(0.0f));
    return V(0.5f) * s + V(0.5f);
}

// fractal_noise<3> with the octave count and roughness of every lane.
V fractal(V x, V y, V z, float octaves, float roughness) {
    float fscale = 1.0f, amp = 1.0f, maxamp = 0.0f;
    V sum(0.0f);
    octaves = std::clamp(octaves, 0.0f, 15.0f);
    const int n = int(octaves);
    for (int i = 0; i <= n; ++i) {
        sum = fma_(unoise(x * V(fscale), y * V(fscale), z * V(fscale)), V(amp), sum);
        maxamp += amp;
        amp *= std::clamp(roughness, 0.0f, 1.0f);
        fscale *= 2.0f;
    }
    const float rmd = octaves - std::floor(octaves);
    if (rmd == 0.0f) return sum / V(maxamp);
    const V sum2 = sum + unoise(x * V(fscale), y * V(fscale), z * V(fscale)) * V(amp);
    return V(1.0f - rmd) * (sum / V(maxamp)) + V(rmd) * (sum2 / V(maxamp + amp));
}

// Whether row `reg` holds the same bits in every live lane.
bool uniform(const BatchRegisters& b, uint16_t reg, size_t live) {
    const float* row = b.row(reg);
    for (size_t l = 1; l < live; ++l)
        if (std::memcmp(&row[l], &row[0], sizeof(float)) != 0) return false;
    return true;
}

}  // namespace

bool noise3_rows(const ShaderProgram& prog, const ShaderInstr& in, const BatchRegisters& b, size_t live) {
    const float* list = prog.data.data() + in.data;  // inputs: vector, w, scale, detail, roughness, distortion
    auto reg = [&](int k) { return uint16_t(list[k]); };
    if (in.mode != 3 || !uniform(b, reg(3), live) || !uniform(b, reg(4), live) || !uniform(b, reg(5), live) ||
        b.row(reg(5))[0] != 0.0f)
        return false;
    const float detail = b.row(reg(3))[0], roughness = b.row(reg(4))[0];
    const bool want_fac = list[6] != float(kNoRegister), want_color = list[7] != float(kNoRegister);
    float offset[2][3];  // random_offset<3>(3) and (4): the colour's seeds
    for (int s = 0; s < 2; ++s)
        for (int i = 0; i < 3; ++i) offset[s][i] = 100.0f + shader::hash_to_float(float(3 + s), float(i)) * 100.0f;
    const float *vx = b.row(reg(0)), *vy = b.row(uint16_t(reg(0) + 1)), *vz = b.row(uint16_t(reg(0) + 2));
    const float* scale = b.row(reg(2));
    for (size_t l = 0; l < b.blocks * 8; l += 8) {
        const V s = V::loadu(scale + l);
        const V x = V::loadu(vx + l) * s, y = V::loadu(vy + l) * s, z = V::loadu(vz + l) * s;
        const V value = fractal(x, y, z, detail, roughness);
        V color[2];
        if (want_color)
            for (int k = 0; k < 2; ++k)
                color[k] = fractal(x + V(offset[k][0]), y + V(offset[k][1]), z + V(offset[k][2]), detail, roughness);
        if (want_fac) simd::storeu(b.row(uint16_t(list[6])) + l, value);
        if (want_color) {
            const uint16_t c = uint16_t(list[7]);
            simd::storeu(b.row(c) + l, value);
            simd::storeu(b.row(uint16_t(c + 1)) + l, color[0]);
            simd::storeu(b.row(uint16_t(c + 2)) + l, color[1]);
        }
    }
    return true;
}

}  // namespace coherent::eval_detail
