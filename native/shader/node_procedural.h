// Procedural texture instructions (White Noise, Noise, Voronoi, Musgrave,
// Wave, Gradient, Magic, Brick): how they address their many registers, and
// how they run.
//
// These nodes have more inputs and outputs than ShaderInstr's fixed slots, so
// an instruction's `data` is the offset, in ShaderProgram::data, of its
// register list: the input registers in the order of procedural_layout(op),
// then the output registers, each stored as a float holding an exact integer.
// An output that nothing reads is kNoRegister; inputs are always present.
//
// Modes (Blender's / Cycles' enum values):
//   TexWhiteNoise, TexNoise: dimensions 1..4
//   TexVoronoi:  dimensions | feature << 4 | metric << 8 (VoronoiFeature, VoronoiMetric)
//   TexMusgrave: dimensions | type << 4 (MusgraveType)
//   TexWave:     type | bands direction << 2 | rings direction << 4 | profile << 6
//   TexGradient: GradientType
//   TexMagic:    depth 0..10
//   TexBrick:    offset frequency | squash frequency << 8
#pragma once

#include <string>
#include <vector>

#include "program.h"

namespace coherent {

struct ProceduralLayout {
    int inputs = 0, outputs = 0;
    int input_width[12] = {};
    int output_width[5] = {};
};

bool is_procedural(ShaderOp op);
// The register list of a procedural op (is_procedural(op) must hold).
ProceduralLayout procedural_layout(ShaderOp op);

// Empty when `in` (a procedural instruction) has a valid mode and a register
// list inside `data` whose registers (with their widths) lie in a file of
// `register_count`; else what is wrong.
std::string validate_procedural(const ShaderInstr& in, const std::vector<float>& data, size_t register_count);

// Runs a validated procedural instruction on the register file, whose
// register i is registers[i * stride].
void run_procedural(const ShaderInstr& in, const float* data, float* registers, size_t stride = 1);

constexpr uint16_t voronoi_mode(int dimensions, int feature, int metric) {
    return uint16_t(dimensions | feature << 4 | metric << 8);
}

}  // namespace coherent
