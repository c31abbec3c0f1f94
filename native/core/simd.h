// SIMD wrapper types (DESIGN.md, core layer), in the manner of Embree's
// vfloat<N> / vint<N> / vbool<N>: N lanes of one value each, with the
// arithmetic written as operators so that kernels read like their scalar
// counterparts. N = 4 is SSE (simd/simd4.h), N = 8 is AVX2 (simd/simd8.h),
// the baseline ISA (CMakeLists.txt).
//
// Contract (the kernels' bit-for-bit agreement rests on it):
//  - every operation is one intrinsic (or a fixed sequence of them) with the
//    IEEE single-precision semantics of that instruction; nothing rounds
//    differently from the raw-intrinsic code it replaced;
//  - + - * / are separate roundings and never contract (the build also uses
//    -ffp-contract=off); a fused multiply-subtract is only ever spelled
//    fmsub(a, b, c);
//  - min(a, b) / max(a, b) are the x86 instructions, which return b when
//    either operand is NaN: argument order is part of the meaning (box tests
//    put the slab term first so that a NaN slab leaves the interval as it is);
//  - comparisons are ordered (false for NaN) except !=, which is true for
//    NaN (C++'s rule);
//  - a vbool lane is true where its sign bit is set. Comparisons set all 32
//    bits; signbit(x) reinterprets x's bits, which select(), movemask() and
//    the bitwise operators read correctly since they only look at (or
//    combine bit by bit) the top bit.
//
// Lane masks also travel as plain ints (bit i = lane i, movemask()), which is
// what traversal loops iterate over with ctz.
#pragma once

#include "simd/simd4.h"
#include "simd/simd8.h"

namespace coherent::simd {

// Starts loading the cache line at p into L1 (a hint; never faults). Not
// _mm_prefetch: GCC counts that as free of side effects, so a function that
// only prefetches is pure and its calls are deleted as unused (the texture
// prefetch of shader/image_filter.h compiled to a bare return); an asm
// statement is kept where it is written.
inline void prefetch(const void* p) { asm volatile("prefetcht0 %0" : : "m"(*static_cast<const char*>(p))); }

}  // namespace coherent::simd
