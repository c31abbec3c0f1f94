// The SIMD row kernels of the batch interpreter (eval_batch.h): instructions
// whose scalar formula is a fixed sequence of IEEE operations, rewritten on
// 8-lane rows with the very same operations in the same order, so each lane
// rounds exactly as the scalar interpreter does (-ffp-contract=off on both
// sides; the scalar std::fmin/fmax are glibc's, which return the second
// operand for equal arguments as the x86 min/max instructions do and skip a
// NaN operand, which the helpers below add).
//
// A kernel returns false when it does not cover the instruction's mode; the
// caller then runs the scalar code lane by lane.
#pragma once

#include <cstddef>
#include <cstdint>

#include "program.h"

namespace coherent {
struct Scene;
struct ShadingGeometry;
}

namespace coherent::eval_detail {

// A batch's register file: row `reg` holds register reg of every lane.
struct BatchRegisters {
    float* regs;
    size_t lanes;   // row length, a multiple of 8
    size_t blocks;  // 8-lane blocks holding live points (the rest is padding)
    float* row(uint16_t reg) const { return regs + size_t(reg) * lanes; }
};

// Runs `in` on every live block when a kernel covers it; false otherwise.
bool run_vector_instruction(const ShaderProgram& prog, const ShaderInstr& in, const BatchRegisters& b,
                            size_t live_lanes);

// Noise Texture 3D with Detail and Roughness the same in every live lane and
// Distortion 0 (eval_batch_noise.cpp); false otherwise.
bool noise3_rows(const ShaderProgram& prog, const ShaderInstr& in, const BatchRegisters& b, size_t live_lanes);

// Image Texture on an in-memory byte RGBA image, linear, repeat or extend,
// alpha straight or ignored (eval_batch_image.cpp); false otherwise.
bool image_texture_rows(const Scene& scene, const ShaderInstr& in, const BatchRegisters& b);

// UV coordinates and the tangent-space Normal Map of points g[0..live) on
// the flattened mesh (eval_batch_geometry.cpp); false otherwise.
bool geometry_rows(const Scene& scene, const ShaderProgram& prog, const ShaderInstr& in, const ShadingGeometry* g,
                   size_t live, const BatchRegisters& b);

}  // namespace coherent::eval_detail
