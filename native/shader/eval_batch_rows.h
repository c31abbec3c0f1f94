// What the SIMD row kernels of the batch interpreter (eval_batch_kernels.cpp,
// eval_batch_geometry.cpp) share: eight lanes of a vector, and reading and
// writing a block of a register row. Internal to shader/.
#pragma once

#include <cstddef>
#include <cstdint>

#include "../core/simd.h"
#include "eval_batch_kernels.h"

namespace coherent::eval_detail {

using V = simd::vfloat8;

struct V3 {
    V x, y, z;
};

// dot(a, b) of vec.h, lane-wise: the same sum in the same order.
inline V dot_(const V3& a, const V3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

// Block l (lanes l..l+7) of register rows; writes to kNoRegister are dropped,
// as Registers::set drops them.
struct Rows {
    const BatchRegisters& b;
    V f(uint16_t reg, size_t l) const { return V::loadu(b.row(reg) + l); }
    V3 v(uint16_t reg, size_t l) const { return {f(reg, l), f(uint16_t(reg + 1), l), f(uint16_t(reg + 2), l)}; }
    void set(uint16_t reg, size_t l, V x) const {
        if (reg != kNoRegister) storeu(b.row(reg) + l, x);
    }
    void set(uint16_t reg, size_t l, const V3& x) const {
        if (reg == kNoRegister) return;
        storeu(b.row(reg) + l, x.x);
        storeu(b.row(uint16_t(reg + 1)) + l, x.y);
        storeu(b.row(uint16_t(reg + 2)) + l, x.z);
    }
};

}  // namespace coherent::eval_detail
