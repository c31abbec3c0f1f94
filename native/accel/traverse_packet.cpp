// Packet traversal (ray_packet.h). PLACEHOLDER: traces each active ray with
// the single-ray kernel, so callers can be written against the packet API
// while the SIMD kernel (masked first-hit traversal, interval-arithmetic
// culling) is developed. Results are by construction those of intersect().
#include "bvh.h"

namespace coherent {

void Bvh::intersect(const RayPacket& packet, HitPacket& hits, PacketCounters* counters) const {
    if (counters) ++counters->packets;
    for (int i = 0; i < packet.size; ++i) {
        if (!packet.is_active(i)) continue;
        TraversalCounters c;
        Hit h;
        if (intersect(packet.ray(i), h, counters ? &c : nullptr)) {
            hits.t[i] = h.t; hits.u[i] = h.u; hits.v[i] = h.v; hits.prim[i] = h.prim;
        }
        if (counters) {
            counters->rays += 1;
            counters->node_visits += c.node_visits;
            counters->box_tests += c.box_tests;
            counters->triangle_tests += c.triangle_tests;
            if (counters->ray_node_visits) counters->ray_node_visits[i] += uint32_t(c.node_visits);
        }
    }
}

void Bvh::occluded(const RayPacket& packet, OcclusionMask& occluded_out, PacketCounters* counters) const {
    if (counters) ++counters->packets;
    for (int i = 0; i < packet.size; ++i) {
        if (!packet.is_active(i)) continue;
        TraversalCounters c;
        if (occluded(packet.ray(i), counters ? &c : nullptr)) occluded_out.set(i);
        if (counters) {
            counters->rays += 1;
            counters->node_visits += c.node_visits;
            counters->box_tests += c.box_tests;
            counters->triangle_tests += c.triangle_tests;
            if (counters->ray_node_visits) counters->ray_node_visits[i] += uint32_t(c.node_visits);
        }
    }
}

}  // namespace coherent
