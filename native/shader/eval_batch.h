// Running a material's shader program over many shading points together
// (SoA), so that shading a packet or a queue's run of hits stays as coherent
// as tracing them was: the program runs instruction-major over a register
// file with one row per register and one lane per point, each instruction
// dispatched once per batch; the common arithmetic nodes run on SIMD rows
// (shader/eval_batch_kernels.h), the rest lane by lane with the scalar
// interpreter's own code. Results are bit-identical to evaluate_material().
#pragma once

#include <cstddef>

#include "eval.h"

namespace coherent {

// Points per pass over the program: the register file's row length (a
// multiple of the SIMD width). Longer batches run in passes of this many.
constexpr size_t kShaderBatchLanes = 32;

// For i < count: out[i] and n[i] exactly as evaluate_material(scene, mat,
// g[i], out[i], n[i]) sets them (mat.program must be set).
void evaluate_material_batch(const Scene& scene, const Material& mat, const ShadingGeometry* g, size_t count,
                             Material* out, Vec3f* n);

}  // namespace coherent
