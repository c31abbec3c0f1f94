// Ray packets: up to 256 rays (a 16x16 pixel packet) in SoA order, traced
// together through the BVH by the packet kernels (traverse_packet.cpp;
// Boulos et al. 2007, Wald et al. 2007). Lanes are processed in chunks of
// kPacketLanes (8 floats, one AVX2 register), so a packet of n rays has
// ceil(n / 8) chunks; lanes at or beyond `size` are never read as rays.
//
// Semantics per ray are exactly those of Bvh::intersect / Bvh::occluded
// (bvh.h): hits with t in (tmin, tmax], ties to the lowest triangle index,
// invalid rays (NaN, zero or non-finite direction, tmin > tmax) hit nothing.
// Every packet kernel returns bit-identical t, u, v and prim to the single-ray
// kernel for the same ray: a packet is a faster way to trace the same rays,
// never a different answer.
#pragma once

#include <cstdint>

#include "../core/ray.h"

namespace coherent {

constexpr int kPacketLanes = 8;
constexpr int kMaxPacketRays = 256;
constexpr int kPacketMaskWords = kMaxPacketRays / 32;

struct alignas(32) RayPacket {
    int size = 0;  // rays in use, [0, kMaxPacketRays]
    // Which of the first `size` rays take part (bit i%32 of word i/32).
    // Inactive rays come back with their hit record and occlusion bit untouched.
    uint32_t active[kPacketMaskWords] = {};
    alignas(32) float ox[kMaxPacketRays], oy[kMaxPacketRays], oz[kMaxPacketRays];
    alignas(32) float dx[kMaxPacketRays], dy[kMaxPacketRays], dz[kMaxPacketRays];
    alignas(32) float tmin[kMaxPacketRays], tmax[kMaxPacketRays];

    void clear() {
        size = 0;
        for (uint32_t& w : active) w = 0;
    }
    // Appends `r` as an active ray; returns its lane. Precondition: size < kMaxPacketRays.
    int push(const Ray& r) {
        const int i = size++;
        set(i, r);
        active[i >> 5] |= 1u << (i & 31);
        return i;
    }
    void set(int i, const Ray& r) {
        ox[i] = r.o.x; oy[i] = r.o.y; oz[i] = r.o.z;
        dx[i] = r.d.x; dy[i] = r.d.y; dz[i] = r.d.z;
        tmin[i] = r.tmin; tmax[i] = r.tmax;
    }
    Ray ray(int i) const {
        Ray r;
        r.o = {ox[i], oy[i], oz[i]};
        r.d = {dx[i], dy[i], dz[i]};
        r.tmin = tmin[i];
        r.tmax = tmax[i];
        return r;
    }
    bool is_active(int i) const { return (active[i >> 5] >> (i & 31)) & 1u; }
    // Active bits of chunk c (lanes 8c .. 8c + 7), one bit per lane.
    uint32_t chunk_mask(int c) const { return (active[c >> 2] >> (8 * (c & 3))) & 0xffu; }
    int chunks() const { return (size + kPacketLanes - 1) / kPacketLanes; }
};

// Closest hits, one record per lane. The caller initialises the records it
// cares about (t = inf, prim = kInvalidPrim: the default); a kernel writes a
// lane's record only where that ray hits.
struct alignas(32) HitPacket {
    alignas(32) float t[kMaxPacketRays];
    alignas(32) float u[kMaxPacketRays], v[kMaxPacketRays];
    alignas(32) uint32_t prim[kMaxPacketRays];
    // Hit::instance; only the instance kernels (instance_bvh.h) write it.
    alignas(32) uint32_t instance[kMaxPacketRays];

    void reset(int n) {
        for (int i = 0; i < n; ++i) {
            t[i] = kInf;
            u[i] = v[i] = 0.0f;
            prim[i] = kInvalidPrim;
            instance[i] = kInvalidPrim;
        }
    }
    Hit hit(int i) const { return Hit{t[i], u[i], v[i], prim[i], instance[i]}; }
};

// Occlusion results: bit i set = ray i is occluded. Kernels only set bits of
// active rays; the caller clears the mask first.
struct OcclusionMask {
    uint32_t bits[kPacketMaskWords] = {};
    bool test(int i) const { return (bits[i >> 5] >> (i & 31)) & 1u; }
    void set(int i) { bits[i >> 5] |= 1u << (i & 31); }
};

// Work counters of packet traversal, the packets paper's architecture-
// independent metrics plus SIMD utilisation.
//  - rays: active rays that entered a kernel;
//  - node_visits: (packet, node) visits;
//  - box_tests / triangle_tests: ray-box and ray-triangle tests computed for
//    active lanes (a SIMD test of 8 lanes with 5 active counts 5), plus one
//    box test per interval-arithmetic (frustum) test of a whole packet;
//  - *_lanes / *_lanes_active: lanes of every SIMD box / triangle test and
//    how many held an active ray: utilisation = active / lanes.
// Per-ray attribution (heatmaps): if `ray_node_visits` is set (size >= the
// packet's size), each node visit adds 1 to every ray active at that visit.
struct PacketCounters {
    uint64_t packets = 0;
    uint64_t rays = 0;
    uint64_t node_visits = 0;
    uint64_t box_tests = 0;
    uint64_t triangle_tests = 0;
    uint64_t box_lanes = 0, box_lanes_active = 0;
    uint64_t triangle_lanes = 0, triangle_lanes_active = 0;
    uint32_t* ray_node_visits = nullptr;  // not owned; not merged by +=

    double box_utilisation() const { return box_lanes ? double(box_lanes_active) / double(box_lanes) : 0.0; }
    double triangle_utilisation() const {
        return triangle_lanes ? double(triangle_lanes_active) / double(triangle_lanes) : 0.0;
    }
    PacketCounters& operator+=(const PacketCounters& o) {
        packets += o.packets; rays += o.rays; node_visits += o.node_visits;
        box_tests += o.box_tests; triangle_tests += o.triangle_tests;
        box_lanes += o.box_lanes; box_lanes_active += o.box_lanes_active;
        triangle_lanes += o.triangle_lanes; triangle_lanes_active += o.triangle_lanes_active;
        return *this;
    }
};

}  // namespace coherent
