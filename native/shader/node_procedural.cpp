// Procedural texture instructions: register lists, validation, and the
// Cycles 3.4 node entry points (svm_node_tex_*) over node_hash.h,
// node_noise.h, node_musgrave.h, node_voronoi.h and node_pattern.h.
#include "node_procedural.h"

#include <algorithm>
#include <cmath>

#include "node_musgrave.h"
#include "node_pattern.h"
#include "node_voronoi.h"

namespace coherent {

using namespace shader;

bool is_procedural(ShaderOp op) { return op >= ShaderOp::TexWhiteNoise && op <= ShaderOp::TexBrick; }

ProceduralLayout procedural_layout(ShaderOp op) {
    switch (op) {
        // vector, w; value, colour
        case ShaderOp::TexWhiteNoise: return {2, 2, {3, 1}, {1, 3}};
        // vector, w, scale, detail, roughness, distortion; fac, colour
        case ShaderOp::TexNoise: return {6, 2, {3, 1, 1, 1, 1, 1}, {1, 3}};
        // vector, w, scale, smoothness, exponent, randomness; distance, colour, position, w, radius
        case ShaderOp::TexVoronoi: return {6, 5, {3, 1, 1, 1, 1, 1}, {1, 3, 3, 1, 1}};
        // vector, w, scale, detail, dimension, lacunarity, offset, gain; fac
        case ShaderOp::TexMusgrave: return {8, 1, {3, 1, 1, 1, 1, 1, 1, 1}, {1}};
        // vector, scale, distortion, detail, detail scale, detail roughness, phase; colour, fac
        case ShaderOp::TexWave: return {7, 2, {3, 1, 1, 1, 1, 1, 1}, {3, 1}};
        // vector; colour, fac
        case ShaderOp::TexGradient: return {1, 2, {3}, {3, 1}};
        // vector, scale, distortion; colour, fac
        case ShaderOp::TexMagic: return {3, 2, {3, 1, 1}, {3, 1}};
        // vector, colour 1, colour 2, mortar, scale, mortar size, mortar smooth, bias, brick width,
        // row height, offset amount, squash amount; colour, fac
        case ShaderOp::TexBrick: return {12, 2, {3, 3, 3, 3, 1, 1, 1, 1, 1, 1, 1, 1}, {3, 1}};
        default: return {};
    }
}

namespace {

bool mode_valid(const ShaderInstr& in) {
    const int dims = in.mode & 0xF;
    switch (in.op) {
        case ShaderOp::TexWhiteNoise:
        case ShaderOp::TexNoise: return in.mode >= 1 && in.mode <= 4;
        case ShaderOp::TexVoronoi:
            return dims >= 1 && dims <= 4 && ((in.mode >> 4) & 0xF) < int(VoronoiFeature::Count) &&
                   (in.mode >> 8) < int(VoronoiMetric::Count);
        case ShaderOp::TexMusgrave: return dims >= 1 && dims <= 4 && (in.mode >> 4) < int(MusgraveType::Count);
        case ShaderOp::TexWave: return in.mode < (1 << 8) && (in.mode & 3) <= 1 && ((in.mode >> 6) & 3) <= 2;
        case ShaderOp::TexGradient: return in.mode < int(GradientType::Count);
        case ShaderOp::TexMagic: return in.mode <= 10;
        case ShaderOp::TexBrick: return true;
        default: return false;
    }
}

}  // namespace

std::string validate_procedural(const ShaderInstr& in, const std::vector<float>& data, size_t register_count) {
    if (!mode_valid(in)) return "unknown procedural texture mode";
    const ProceduralLayout layout = procedural_layout(in.op);
    const size_t count = size_t(layout.inputs + layout.outputs);
    if (size_t(in.data) + count > data.size()) return "register list outside the data";
    for (size_t k = 0; k < count; ++k) {
        const float f = data[in.data + k];
        const bool is_input = k < size_t(layout.inputs);
        const int width = is_input ? layout.input_width[k] : layout.output_width[k - layout.inputs];
        if (!is_input && f == float(kNoRegister)) continue;
        if (!(f >= 0.0f) || f != std::floor(f) || size_t(f) + size_t(width) > register_count)
            return "register list entry " + std::to_string(k) + " outside the registers";
    }
    return {};
}

namespace {

// The instruction's registers, through its list.
// Register i lives at r[i * stride] (1 for one shading point, the lane
// count for a batch's register file, shader/eval_batch.h).
struct Slots {
    const float* list;
    float* r;
    int inputs;
    size_t stride;
    float f(int k) const { return r[size_t(list[k]) * stride]; }
    Vec3f v(int k) const {
        const float* p = r + size_t(list[k]) * stride;
        return {p[0], p[stride], p[2 * stride]};
    }
    bool wants(int output) const { return list[inputs + output] != float(kNoRegister); }
    void set(int output, float x) const {
        if (wants(output)) r[size_t(list[inputs + output]) * stride] = x;
    }
    void set(int output, const Vec3f& x) const {
        if (!wants(output)) return;
        float* p = r + size_t(list[inputs + output]) * stride;
        p[0] = x.x, p[stride] = x.y, p[2 * stride] = x.z;
    }
};

template <int N>
Pt<N> point_of(const Vec3f& v, float w) {
    if constexpr (N == 1) return {{w}};
    else if constexpr (N == 2) return {{v.x, v.y}};
    else if constexpr (N == 3) return {{v.x, v.y, v.z}};
    else return {{v.x, v.y, v.z, w}};
}

void white_noise(int dims, const Slots& s) {
    const Vec3f v = s.v(0);
    const float w = s.f(1);
    switch (dims) {
        case 1: s.set(0, hash_to_float(point_of<1>(v, w))), s.set(1, hash_to_color(point_of<1>(v, w))); break;
        case 2: s.set(0, hash_to_float(point_of<2>(v, w))), s.set(1, hash_to_color(point_of<2>(v, w))); break;
        case 3: s.set(0, hash_to_float(point_of<3>(v, w))), s.set(1, hash_to_color(point_of<3>(v, w))); break;
        default: s.set(0, hash_to_float(point_of<4>(v, w))), s.set(1, hash_to_color(point_of<4>(v, w))); break;
    }
}

// Cycles' random_floatN_offset: a seed's offset in [100, 200]^N.
template <int N>
Pt<N> random_offset(float seed) {
    Pt<N> o;
    if constexpr (N == 1) o[0] = 100.0f + hash_to_float(seed) * 100.0f;
    else
        for (int i = 0; i < N; ++i) o[i] = 100.0f + hash_to_float(seed, float(i)) * 100.0f;
    return o;
}

template <int N>
void noise_texture(Pt<N> p, float detail, float roughness, float distortion, const Slots& s) {
    if (distortion != 0.0f) {
        Pt<N> d;
        for (int i = 0; i < N; ++i) d[i] = snoise(p + random_offset<N>(float(i)));
        // Cycles adds float and float2 distortions in scalar code (fused by its compiler), float3 and
        // float4 ones in SSE registers (not fused).
        for (int i = 0; i < N; ++i) p[i] = N <= 2 ? std::fma(d[i], distortion, p[i]) : p[i] + d[i] * distortion;
    }
    const float value = fractal_noise(p, detail, roughness);
    s.set(0, value);
    if (s.wants(1)) {
        // Seeds after the distortion's: N and N + 1.
        s.set(1, Vec3f{value, fractal_noise(p + random_offset<N>(float(N)), detail, roughness),
                       fractal_noise(p + random_offset<N>(float(N + 1)), detail, roughness)});
    }
}

void noise(int dims, const Slots& s) {
    const float scale = s.f(2);
    const Vec3f v = s.v(0) * scale;
    const float w = s.f(1) * scale;
    const float detail = s.f(3), roughness = s.f(4), distortion = s.f(5);
    switch (dims) {
        case 1: noise_texture(point_of<1>(v, w), detail, roughness, distortion, s); break;
        case 2: noise_texture(point_of<2>(v, w), detail, roughness, distortion, s); break;
        case 3: noise_texture(point_of<3>(v, w), detail, roughness, distortion, s); break;
        default: noise_texture(point_of<4>(v, w), detail, roughness, distortion, s); break;
    }
}

template <int N>
void voronoi_texture(VoronoiFeature feature, const VoronoiParams& params, const Pt<N>& p, float scale,
                     const Slots& s) {
    VoronoiResult<N> out;
    float radius = 0.0f;
    switch (feature) {
        case VoronoiFeature::F1: out = voronoi_f1(p, params); break;
        case VoronoiFeature::F2: out = voronoi_f2(p, params); break;
        case VoronoiFeature::SmoothF1: out = voronoi_smooth_f1(p, params); break;
        case VoronoiFeature::DistanceToEdge: out.distance = voronoi_distance_to_edge(p, params.randomness); break;
        case VoronoiFeature::NSphereRadius: radius = voronoi_n_sphere_radius(p, params.randomness); break;
        case VoronoiFeature::Count: break;
    }
    // Positions back in the input's space (Cycles' safe_divide by the scale).
    Pt<N> position = scale != 0.0f ? out.position / scale : splat<N>(0.0f);
    Vec3f xyz(0.0f);
    float w = 0.0f;
    if constexpr (N == 1) w = position[0];
    else {
        xyz.x = position[0], xyz.y = position[1];
        if constexpr (N >= 3) xyz.z = position[2];
        if constexpr (N == 4) w = position[3];
    }
    s.set(0, out.distance);
    s.set(1, out.color);
    s.set(2, xyz);
    s.set(3, w);
    s.set(4, radius);
}

void voronoi(uint16_t mode, const Slots& s) {
    const float scale = s.f(2);
    const Vec3f v = s.v(0) * scale;
    const float w = s.f(1) * scale;
    VoronoiParams params;
    params.metric = VoronoiMetric(mode >> 8);
    params.smoothness = std::clamp(s.f(3) / 2.0f, 0.0f, 0.5f);
    params.exponent = s.f(4);
    params.randomness = std::clamp(s.f(5), 0.0f, 1.0f);
    const VoronoiFeature feature = VoronoiFeature((mode >> 4) & 0xF);
    switch (mode & 0xF) {
        case 1: voronoi_texture(feature, params, point_of<1>(v, w), scale, s); break;
        case 2: voronoi_texture(feature, params, point_of<2>(v, w), scale, s); break;
        case 3: voronoi_texture(feature, params, point_of<3>(v, w), scale, s); break;
        default: voronoi_texture(feature, params, point_of<4>(v, w), scale, s); break;
    }
}

void musgrave(uint16_t mode, const Slots& s) {
    const float scale = s.f(2);
    const Vec3f v = s.v(0) * scale;
    const float w = s.f(1) * scale;
    MusgraveParams m;
    m.octaves = std::clamp(s.f(3), 0.0f, 15.0f);
    m.dimension = std::fmax(s.f(4), 1e-5f);
    m.lacunarity = std::fmax(s.f(5), 1e-5f);
    m.offset = s.f(6);
    m.gain = s.f(7);
    const MusgraveType type = MusgraveType(mode >> 4);
    float fac;
    switch (mode & 0xF) {
        case 1: fac = shader::musgrave(type, point_of<1>(v, w), m); break;
        case 2: fac = shader::musgrave(type, point_of<2>(v, w), m); break;
        case 3: fac = shader::musgrave(type, point_of<3>(v, w), m); break;
        default: fac = shader::musgrave(type, point_of<4>(v, w), m); break;
    }
    s.set(0, fac);
}

void wave(uint16_t mode, const Slots& s) {
    WaveParams w;
    w.type = WaveType(mode & 3);
    w.bands = WaveBandsDirection((mode >> 2) & 3);
    w.rings = WaveRingsDirection((mode >> 4) & 3);
    w.profile = WaveProfile((mode >> 6) & 3);
    w.distortion = s.f(2), w.detail = s.f(3), w.detail_scale = s.f(4), w.detail_roughness = s.f(5);
    w.phase = s.f(6);
    const float f = svm_wave(w, s.v(0) * s.f(1));
    s.set(0, Vec3f(f));
    s.set(1, f);
}

void brick(uint16_t mode, const Slots& s) {
    BrickParams b;
    b.offset_frequency = mode & 0xFF;
    b.squash_frequency = mode >> 8;
    b.mortar_size = s.f(5), b.mortar_smooth = s.f(6), b.bias = s.f(7);
    b.brick_width = s.f(8), b.row_height = s.f(9), b.offset_amount = s.f(10), b.squash_amount = s.f(11);
    float tint, f;
    svm_brick(b, s.v(0) * s.f(4), tint, f);
    Vec3f color1 = s.v(1);
    if (f != 1.0f) color1 = (1.0f - tint) * color1 + tint * s.v(2);
    s.set(0, color1 * (1.0f - f) + s.v(3) * f);
    s.set(1, f);
}

}  // namespace

void run_procedural(const ShaderInstr& in, const float* data, float* registers, size_t stride) {
    const Slots s{data + in.data, registers, procedural_layout(in.op).inputs, stride};
    switch (in.op) {
        case ShaderOp::TexWhiteNoise: white_noise(in.mode, s); break;
        case ShaderOp::TexNoise: noise(in.mode, s); break;
        case ShaderOp::TexVoronoi: voronoi(in.mode, s); break;
        case ShaderOp::TexMusgrave: musgrave(in.mode, s); break;
        case ShaderOp::TexWave: wave(in.mode, s); break;
        case ShaderOp::TexGradient: {
            const float f = svm_gradient(GradientType(in.mode), s.v(0));
            s.set(0, Vec3f(f));
            s.set(1, f);
            break;
        }
        case ShaderOp::TexMagic: {
            const Vec3f c = svm_magic(s.v(0), s.f(1), in.mode, s.f(2));
            s.set(0, c);
            s.set(1, (c.x + c.y + c.z) * (1.0f / 3.0f));
            break;
        }
        case ShaderOp::TexBrick: brick(in.mode, s); break;
        default: break;
    }
}

}  // namespace coherent
