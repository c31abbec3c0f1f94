// The top level of a two-level BVH (scene/instance.h): one BVH per
// prototype, built once over its object-space triangles, under a binary
// BVH over the instances' world boxes. A leaf carries the ray into the
// instance's object space (origin and direction through world_to_object;
// the direction is not renormalised, so t means the same in both spaces)
// and traverses the prototype's BVH with the kernel the caller uses:
// single rays with Bvh::intersect, packets with Bvh's packet kernels on a
// scratch packet of the transformed lanes (the lanes keep their positions,
// as Embree does per instance), streams with intersect_stream on the rays
// that reached each instance, grouped per instance.
//
// Why beside the world-space Bvh rather than over it: scenes without
// instances never touch this class, so their kernels, hits and work
// counters stay exactly what they were; a ray's hit is the closer of the
// two structures' (as with MotionBvh).
//
// Motion blur: a moving instance (scene/instance.h) is carried into object
// space by the inverse of instance_transform_at(time), computed per ray by
// the same function in every kernel; its top-level box holds it all
// shutter long. Each call takes the rays' shutter times (0 when omitted).
//
// Tie rule (every kernel): at equal t a world-space triangle wins over an
// instance, then the lower instance index, then the lower triangle index
// (the prototype kernels' own rule). Each prototype kernel returns the same
// hits for the same object-space ray, and every kernel here forms that ray
// with the same operations, so single rays, packets and streams agree bit
// for bit on instanced hits too.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "../core/ray.h"
#include "../core/vec.h"
#include "../scene/instance.h"
#include "bvh.h"
#include "ray_packet.h"
#include "ray_stream.h"

namespace coherent {

struct Scene;

// Whether hit `a` (an instance hit) beats the current closest hit `b`.
inline bool instance_hit_closer(const Hit& a, const Hit& b) {
    if (a.t != b.t) return a.t < b.t;
    if (!b.valid() || b.instance == kInvalidPrim) return !b.valid();
    return a.instance != b.instance ? a.instance < b.instance : a.prim < b.prim;
}

// The ray in an instance's object space (same t, same interval).
Ray ray_to_object(const Transform& world_to_object, const Ray& ray);

class InstanceBvh {
public:
    InstanceBvh() = default;
    // Builds a BVH per prototype that an instance uses (with `options`, so
    // widths and spatial splits match the world-space Bvh's) and the top
    // level over scene.instances.
    void build(const Scene& scene, const BvhBuildOptions& options = {});
    // The same, but a prototype whose object-space triangles equal those of
    // one of `previous_scene`'s (the scene `previous` was built over) shares
    // that prototype's BVH instead of building its own: a re-render with
    // persistent data rebuilds only changed meshes. The top level is always
    // rebuilt (it costs a box per instance), with `previous`'s options.
    void build_reusing(const Scene& scene, const InstanceBvh& previous, const Scene& previous_scene);
    // Prototype BVHs the last build took from a previous InstanceBvh, and
    // those it built.
    size_t reused_prototypes() const { return reused_prototypes_; }
    size_t built_prototypes() const { return built_prototypes_; }
    bool empty() const { return top_.empty(); }

    // Closest instance hit of `ray` improving on `hit` (e.g. the world-space
    // Bvh's hit, which bounds the search); returns true when `hit` was
    // replaced. Counters get the work (not the ray: its first kernel counted it).
    bool intersect(const Ray& ray, Hit& hit, TraversalCounters* counters = nullptr, float time = 0.0f) const;
    bool occluded(const Ray& ray, TraversalCounters* counters = nullptr, float time = 0.0f) const;
    // Packets: improves the active lanes' records in `hits` / sets the bits
    // of active lanes an instance occludes. `times`: per lane, or null.
    void intersect(const RayPacket& packet, HitPacket& hits, PacketCounters* counters = nullptr,
                   const float* times = nullptr) const;
    void occluded(const RayPacket& packet, OcclusionMask& occluded, PacketCounters* counters = nullptr,
                  const float* times = nullptr) const;
    // Streams: improves hits[i] / sets occluded[i] = 1 for rays[0, n).
    // Runs on the calling thread (the renderer traces one tile per task).
    // `times`: per ray, or null.
    void intersect_stream(const Ray* rays, size_t n, Hit* hits, StreamStats* stats = nullptr,
                          const float* times = nullptr) const;
    void occluded_stream(const Ray* rays, size_t n, uint8_t* occluded, StreamStats* stats = nullptr,
                         const float* times = nullptr) const;
    // Whether some instance moves (callers then pass the rays' times).
    bool has_motion() const { return !motions_.empty(); }

    size_t prototype_count() const { return prototypes_.size(); }
    // Bytes of every BVH held: prototypes, top level and the instances' transforms.
    size_t bytes() const;

private:
    struct Placement {
        Transform world_to_object;  // at shutter open
        uint32_t prototype;
        uint32_t motion;  // index into motions_, or kStillInstance
    };
    struct Motion {
        Transform open, close;  // object to world
    };
    // Instance `inst` carried into object space at shutter time `time`.
    Ray to_object(uint32_t inst, const Ray& ray, float time) const;
    template <class Visit>
    void visit_instances(const Ray& ray, float tmax, Visit&& visit, uint64_t* box_tests, uint64_t* node_visits) const;
    template <bool kAnyHit>
    void trace_packet(const RayPacket& packet, HitPacket* hits, OcclusionMask* occluded, PacketCounters* counters,
                      const float* times) const;
    template <bool kAnyHit>
    void trace_stream(const Ray* rays, size_t n, Hit* hits, uint8_t* occluded, StreamStats* stats,
                      const float* times) const;

    // A BVH for every prototype an instance uses: taken from `previous`
    // (built over `previous_scene`) where the triangles are equal, else built.
    void build_prototypes(const Scene& scene, const BvhBuildOptions& options, const InstanceBvh* previous,
                          const Scene* previous_scene);
    // Placements and the top level over scene.instances, once every
    // prototype an instance uses has its BVH.
    void build_top_level(const Scene& scene);

    // Shared: a persistent-data re-render hands unchanged prototypes' BVHs
    // on (build_reusing). Immutable once built.
    std::vector<std::shared_ptr<const Bvh>> prototypes_;  // null for prototypes no instance uses
    std::vector<Placement> placements_;              // per scene instance
    std::vector<Motion> motions_;                    // moving instances' transforms
    std::vector<BvhNode> top_;
    std::vector<uint32_t> order_;  // top-level leaf slot -> instance
    BvhBuildOptions options_;      // of the prototypes' BVHs
    size_t reused_prototypes_ = 0, built_prototypes_ = 0;
};

}  // namespace coherent
