// The batch interpreter (eval_batch.h): passes of kShaderBatchLanes points,
// each running the program instruction by instruction over the SoA register
// file; an instruction no SIMD kernel covers runs the scalar interpreter's
// code on each live lane, which addresses the same file with a stride.
#include "eval_batch.h"

#include <cstring>
#include <vector>

#include "../core/simd.h"
#include "eval_batch_kernels.h"
#include "eval_registers.h"
#include "program.h"

namespace coherent {

namespace {

using eval_detail::BatchRegisters;
using eval_detail::Registers;

// The register file of the calling thread, grown to the largest program seen.
float* batch_register_file(size_t floats) {
    thread_local std::vector<float> file;
    if (file.size() < floats) file.resize(floats);
    return file.data();
}

// Every lane of each register row starts at the register's constant.
void load_constants(const ShaderProgram& prog, const BatchRegisters& b) {
    for (size_t reg = 0; reg < prog.constants.size(); ++reg) {
        const simd::vfloat8 c(prog.constants[reg]);
        float* row = b.regs + reg * b.lanes;
        for (size_t l = 0; l < b.lanes; l += 8) simd::storeu(row + l, c);
    }
}

// One pass: points g[0..live) in lanes 0..live.
void evaluate_pass(const Scene& scene, const Material& mat, const ShadingGeometry* g, size_t live, Material* out,
                   Vec3f* n) {
    const ShaderProgram& prog = *mat.program;
    float* regs = batch_register_file(prog.constants.size() * kShaderBatchLanes);
    eval_detail::run_batch(scene, prog, g, live, regs);
    for (size_t l = 0; l < live; ++l) {
        const Registers r{regs + l, kShaderBatchLanes};
        eval_detail::start_output(mat, g[l], out[l], n[l]);
        for (const ShaderOutput& o : prog.outputs) eval_detail::apply_output(o, r, g[l], out[l], n[l]);
    }
}

}  // namespace

void eval_detail::run_batch(const Scene& scene, const ShaderProgram& prog, const ShadingGeometry* g, size_t live,
                            float* registers) {
    constexpr size_t lanes = kShaderBatchLanes;
    const BatchRegisters b{registers, lanes, (live + 7) / 8};
    load_constants(prog, b);
    for (const ShaderInstr& in : prog.code) {
        if (run_vector_instruction(prog, in, b, live) || image_texture_rows(scene, in, b) ||
            geometry_rows(scene, prog, in, g, live, b))
            continue;
        if (in.op == ShaderOp::ImageTexture)
            for (size_t l = 0; l < live; ++l) prefetch_instruction(scene, in, Registers{registers + l, lanes});
        for (size_t l = 0; l < live; ++l) run_instruction(scene, prog, g[l], in, Registers{registers + l, lanes});
    }
}

void evaluate_material_batch(const Scene& scene, const Material& mat, const ShadingGeometry* g, size_t count,
                             Material* out, Vec3f* n) {
    for (size_t first = 0; first < count; first += kShaderBatchLanes) {
        const size_t live = std::min(kShaderBatchLanes, count - first);
        evaluate_pass(scene, mat, g + first, live, out + first, n + first);
    }
}

}  // namespace coherent
