// The five Musgrave fractals of Blender 3.4 (intern/cycles/kernel/svm/
// musgrave.h, after "Texturing and Modeling: A Procedural Approach"), over
// Cycles' signed Perlin noise. `octaves` is the node's Detail: its integer
// part counts full octaves, its fraction weights one more.
#pragma once

#include <algorithm>
#include <cmath>

#include "node_noise.h"

namespace coherent::shader {

enum class MusgraveType : uint16_t { MultiFractal = 0, Fbm = 1, HybridMultiFractal = 2, RidgedMultiFractal = 3,
                                     HeteroTerrain = 4, Count };

struct MusgraveParams {
    float dimension, lacunarity, octaves, offset, gain;
};

template <int N>
float musgrave_fbm(Pt<N> p, const MusgraveParams& m) {
    float value = 0.0f, pwr = 1.0f;
    const float pw_hl = std::pow(m.lacunarity, -m.dimension);
    for (int i = 0; i < int(m.octaves); ++i) {
        value += snoise(p) * pwr;
        pwr *= pw_hl;
        p = p * m.lacunarity;
    }
    const float rmd = m.octaves - std::floor(m.octaves);
    if (rmd != 0.0f) value += rmd * snoise(p) * pwr;
    return value;
}

template <int N>
float musgrave_multi_fractal(Pt<N> p, const MusgraveParams& m) {
    float value = 1.0f, pwr = 1.0f;
    const float pw_hl = std::pow(m.lacunarity, -m.dimension);
    for (int i = 0; i < int(m.octaves); ++i) {
        value *= (pwr * snoise(p) + 1.0f);
        pwr *= pw_hl;
        p = p * m.lacunarity;
    }
    const float rmd = m.octaves - std::floor(m.octaves);
    if (rmd != 0.0f) value *= (rmd * pwr * snoise(p) + 1.0f);
    return value;
}

template <int N>
float musgrave_hetero_terrain(Pt<N> p, const MusgraveParams& m) {
    const float pw_hl = std::pow(m.lacunarity, -m.dimension);
    float pwr = pw_hl;
    // The first octave unscaled, later ones scaled by the value so far.
    float value = m.offset + snoise(p);
    p = p * m.lacunarity;
    for (int i = 1; i < int(m.octaves); ++i) {
        value += (snoise(p) + m.offset) * pwr * value;
        pwr *= pw_hl;
        p = p * m.lacunarity;
    }
    const float rmd = m.octaves - std::floor(m.octaves);
    if (rmd != 0.0f) value += rmd * ((snoise(p) + m.offset) * pwr * value);
    return value;
}

template <int N>
float musgrave_hybrid_multi_fractal(Pt<N> p, const MusgraveParams& m) {
    const float pw_hl = std::pow(m.lacunarity, -m.dimension);
    float pwr = 1.0f, value = 0.0f, weight = 1.0f;
    for (int i = 0; weight > 0.001f && i < int(m.octaves); ++i) {
        weight = std::min(weight, 1.0f);
        const float signal = (snoise(p) + m.offset) * pwr;
        pwr *= pw_hl;
        value += weight * signal;
        weight *= m.gain * signal;
        p = p * m.lacunarity;
    }
    const float rmd = m.octaves - std::floor(m.octaves);
    if (rmd != 0.0f && weight > 0.001f) {
        weight = std::min(weight, 1.0f);
        value += rmd * weight * ((snoise(p) + m.offset) * pwr);
    }
    return value;
}

template <int N>
float musgrave_ridged_multi_fractal(Pt<N> p, const MusgraveParams& m) {
    const float pw_hl = std::pow(m.lacunarity, -m.dimension);
    float pwr = pw_hl;
    float signal = m.offset - std::fabs(snoise(p));
    signal *= signal;
    float value = signal;
    for (int i = 1; i < int(m.octaves); ++i) {
        p = p * m.lacunarity;
        const float weight = std::clamp(signal * m.gain, 0.0f, 1.0f);
        signal = m.offset - std::fabs(snoise(p));
        signal *= signal;
        signal *= weight;
        value += signal * pwr;
        pwr *= pw_hl;
    }
    return value;
}

template <int N>
float musgrave(MusgraveType type, const Pt<N>& p, const MusgraveParams& m) {
    switch (type) {
        case MusgraveType::MultiFractal: return musgrave_multi_fractal(p, m);
        case MusgraveType::Fbm: return musgrave_fbm(p, m);
        case MusgraveType::HybridMultiFractal: return musgrave_hybrid_multi_fractal(p, m);
        case MusgraveType::RidgedMultiFractal: return musgrave_ridged_multi_fractal(p, m);
        case MusgraveType::HeteroTerrain: return musgrave_hetero_terrain(p, m);
        case MusgraveType::Count: break;
    }
    return 0.0f;
}

}  // namespace coherent::shader
