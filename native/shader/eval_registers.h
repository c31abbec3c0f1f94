// What the scalar interpreter (eval.cpp) and the batch one (eval_batch.cpp)
// share: the register file as instructions address it, and the entry points
// that run one instruction or apply one output at one shading point.
// Internal to shader/.
#pragma once

#include <cstddef>

#include "../core/vec.h"
#include "eval.h"
#include "program.h"
#include "textures.h"

namespace coherent::eval_detail {

// Register i of one shading point is r[i * stride]: stride 1 for a point's
// own register file, the lane count for a batch's (register-major, so a
// register of every lane is one contiguous row).
struct Registers {
    float* r;
    size_t stride = 1;
    float f(uint16_t i) const { return r[i * stride]; }
    Vec3f v(uint16_t i) const {
        const float* p = r + i * stride;
        return {p[0], p[stride], p[2 * stride]};
    }
    void set(uint16_t i, float x) const {
        if (i != kNoRegister) r[i * stride] = x;
    }
    void set(uint16_t i, const Vec3f& x) const {
        if (i == kNoRegister) return;
        float* p = r + i * stride;
        p[0] = x.x;
        p[stride] = x.y;
        p[2 * stride] = x.z;
    }
};

// Runs one instruction of `prog` at g.
void run_instruction(const Scene& scene, const ShaderProgram& prog, const ShadingGeometry& g, const ShaderInstr& in,
                     const Registers& r);

// Starts loading what `in` will read from memory at this point, without
// waiting (an Image Texture's texels): a batch calls it for every lane before
// running the instruction, so the lanes' cache misses overlap. Does nothing
// for other instructions.
void prefetch_instruction(const Scene& scene, const ShaderInstr& in, const Registers& r);

// An Image Texture instruction's interpolation and extension.
TextureLookup image_lookup_of(const ShaderInstr& in);

// Writes output o of a finished register file into `out` (a copy of the
// material's constants) and the shading normal `n`.
void apply_output(const ShaderOutput& o, const Registers& r, const ShadingGeometry& g, Material& out, Vec3f& n);

// `out` and `n` as evaluate_material starts them: mat's constants, g.n.
void start_output(const Material& mat, const ShadingGeometry& g, Material& out, Vec3f& n);

// Runs prog over g[0..live) (live <= kShaderBatchLanes) in one batch pass:
// register i of point l ends at registers[i * kShaderBatchLanes + l]; the
// file holds prog.constants.size() rows.
void run_batch(const Scene& scene, const ShaderProgram& prog, const ShadingGeometry* g, size_t live,
               float* registers);

}  // namespace coherent::eval_detail
