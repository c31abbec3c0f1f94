// Traversal layout of the BVH (private to the accel layer; read by the
// kernels of traverse_single.cpp and ray_stream.cpp).
//
// The build produces the portable binary tree of bvh.h (BvhNode, 32 bytes).
// Single-ray traversal reads a wide copy of it: the binary tree collapsed to
// 8-wide nodes (as Embree's BVH8 does on AVX2), so one node visit tests eight
// boxes with a handful of 8-wide instructions and the tree is a third as
// deep; leaves are packs of four triangles in SoA order, tested together
// (still watertight, bit for bit the same arithmetic as
// intersect_triangle_watertight).
#pragma once

#include <cstdint>

namespace coherent {

constexpr int kWideWidth = 8;
constexpr uint32_t kEmptyChild = 0xffffffffu;

// An 8-wide node: the boxes of up to eight children in SoA order
// (lo[axis][child], hi[axis][child]).
// Child c is a leaf iff count[c] != 0: its triangles are the first count[c]
// lanes of packs ref[c], ref[c] + 1, ... (4 triangles per pack). An interior
// child has count 0 and ref = its WideNode8 index. Unused slots have
// ref = kEmptyChild, count 0 and an empty box (lo = +inf, hi = -inf), which
// no ray enters.
struct alignas(64) WideNode8 {
    float lo[3][kWideWidth];
    float hi[3][kWideWidth];
    uint32_t ref[kWideWidth];
    uint32_t count[kWideWidth];
};
static_assert(sizeof(WideNode8) == 256, "WideNode8 must fill exactly four cache lines");

// A 4-wide node (BvhBuildOptions::width = 4): the same layout and rules as
// WideNode8 with four slots, tested with one SSE instruction per plane.
// Half the size (two cache lines) and about twice as many nodes per ray as
// the 8-wide tree: the width sweep of bench/wide_bench.cpp measures which
// wins.
constexpr int kWide4Width = 4;
struct alignas(64) WideNode4 {
    float lo[3][kWide4Width];
    float hi[3][kWide4Width];
    uint32_t ref[kWide4Width];
    uint32_t count[kWide4Width];
};
static_assert(sizeof(WideNode4) == 128, "WideNode4 must fill exactly two cache lines");

// Four triangles in SoA order: v[vertex][axis][lane]. Unused lanes repeat
// lane 0's vertices with prim = kInvalidPrim and are masked out by count.
struct alignas(16) TrianglePack4 {
    float v[3][3][4];
    uint32_t prim[4];  // scene triangle index per lane
};
static_assert(sizeof(TrianglePack4) == 160);

}  // namespace coherent
