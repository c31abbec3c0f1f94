// Shared by the shader program tests: one instruction from its parts.
#pragma once

#include <cstdint>
#include <initializer_list>

#include "shader/program.h"

namespace coherent::test {

inline ShaderInstr instr(ShaderOp op, uint16_t mode, std::initializer_list<uint16_t> outs,
                         std::initializer_list<uint16_t> ins, uint32_t data = 0) {
    ShaderInstr in;
    in.op = op;
    in.mode = mode;
    int k = 0;
    for (uint16_t o : outs) in.out[k++] = o;
    k = 0;
    for (uint16_t i : ins) in.in[k++] = i;
    in.data = data;
    return in;
}

}  // namespace coherent::test
