// InstanceBvh (instance_bvh.h): build, and the top-level walks of single
// rays, packets and streams. The top level is a plain binary tree with a
// robust scalar slab test: instances are few next to triangles, and the
// work that matters happens in the prototypes' kernels.
#include "instance_bvh.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <unordered_map>

#include "../core/float_bounds.h"
#include "../scene/scene.h"

namespace coherent {

Ray ray_to_object(const Transform& world_to_object, const Ray& ray) {
    Ray r;
    r.o = world_to_object.point(ray.o);
    r.d = world_to_object.vector(ray.d);
    r.tmin = ray.tmin;
    r.tmax = ray.tmax;
    return r;
}

namespace {

bool valid_ray(const Ray& ray) {
    return is_finite(ray.o) && is_finite(ray.d) && !(ray.d.x == 0.0f && ray.d.y == 0.0f && ray.d.z == 0.0f) &&
           !std::isnan(ray.tmin) && !std::isnan(ray.tmax) && ray.tmin <= ray.tmax;
}

// Robust slab test (Ize 2013) as MotionBvh's: exact products, NaN slabs
// ignored, the far distance scaled up, and the kernels' relative slack.
bool enters(const BBox& b, const Vec3f& o, const Vec3f& inv, float tmin, float tmax) {
    float t0 = tmin, t1 = tmax;
    for (int a = 0; a < 3; ++a) {
        float tn = (b.lo[a] - o[a]) * inv[a];
        float tf = (b.hi[a] - o[a]) * inv[a];
        if (tn > tf) std::swap(tn, tf);
        if (tn > t0) t0 = tn;
        if (tf * kFarScale < t1) t1 = tf * kFarScale;
    }
    return t0 <= t1 + std::fabs(t1) * kCullSlack;
}

void add_work(TraversalCounters* to, const TraversalCounters& w) {
    if (!to) return;
    to->node_visits += w.node_visits;
    to->box_tests += w.box_tests;
    to->triangle_tests += w.triangle_tests;
}

void add_work(PacketCounters* to, const PacketCounters& w) {
    if (!to) return;
    to->node_visits += w.node_visits;
    to->box_tests += w.box_tests;
    to->triangle_tests += w.triangle_tests;
    to->box_lanes += w.box_lanes;
    to->box_lanes_active += w.box_lanes_active;
    to->triangle_lanes += w.triangle_lanes;
    to->triangle_lanes_active += w.triangle_lanes_active;
}

void add_work(StreamStats* to, const StreamStats& w) {
    if (!to) return;
    const uint64_t rays = to->rays, slices = to->slices;
    *to += w;
    to->rays = rays;  // the rays were counted by the world-space stream
    to->slices = slices;
}

std::shared_ptr<const Bvh> build_prototype(const Prototype& prototype, const BvhBuildOptions& options) {
    auto bvh = std::make_shared<Bvh>();
    bvh->build(prototype.vertices, options);
    return bvh;
}

bool same_vertices(const Prototype& a, const Prototype& b) {
    return a.vertices.size() == b.vertices.size() &&
           std::memcmp(a.vertices.data(), b.vertices.data(), a.vertices.size() * sizeof(Vec3f)) == 0;
}

}  // namespace

void InstanceBvh::build(const Scene& scene, const BvhBuildOptions& options) {
    build_prototypes(scene, options, nullptr, nullptr);
    build_top_level(scene);
}

void InstanceBvh::build_reusing(const Scene& scene, const InstanceBvh& previous, const Scene& previous_scene) {
    build_prototypes(scene, previous.options_, &previous, &previous_scene);
    build_top_level(scene);
}

void InstanceBvh::build_prototypes(const Scene& scene, const BvhBuildOptions& options, const InstanceBvh* previous,
                                   const Scene* previous_scene) {
    options_ = options;
    reused_prototypes_ = built_prototypes_ = 0;
    prototypes_.assign(scene.prototypes.size(), nullptr);
    // A BVH depends on its triangles' vertices alone (same options), so equal
    // vertex arrays may share one. Candidates by triangle count, then compared
    // exactly: a mesh the depsgraph did not change exports the same floats.
    std::unordered_multimap<size_t, uint32_t> by_count;
    if (previous)
        for (uint32_t q = 0; q < previous_scene->prototypes.size() && q < previous->prototypes_.size(); ++q)
            if (previous->prototypes_[q]) by_count.emplace(previous_scene->prototypes[q].triangle_count(), q);
    for (const Instance& inst : scene.instances) {
        std::shared_ptr<const Bvh>& bvh = prototypes_[inst.prototype];
        if (bvh) continue;
        const Prototype& proto = scene.prototypes[inst.prototype];
        const auto [first, last] = by_count.equal_range(proto.triangle_count());
        for (auto it = first; it != last && !bvh; ++it)
            if (same_vertices(proto, previous_scene->prototypes[it->second])) bvh = previous->prototypes_[it->second];
        if (bvh) {
            ++reused_prototypes_;
        } else {
            bvh = build_prototype(proto, options_);
            ++built_prototypes_;
        }
    }
}

void InstanceBvh::build_top_level(const Scene& scene) {
    placements_.clear();
    placements_.reserve(scene.instances.size());
    motions_.clear();
    std::vector<BBox> boxes;
    boxes.reserve(scene.instances.size());
    for (const Instance& inst : scene.instances) {
        uint32_t motion = kStillInstance;
        if (inst.motion != kStillInstance) {
            motion = uint32_t(motions_.size());
            motions_.push_back({inst.object_to_world, scene.instance_close[inst.motion]});
        }
        placements_.push_back({inst.world_to_object, inst.prototype, motion});
        boxes.push_back(inst.world_bounds);
    }
    // Leaves of one or two instances: an instance is a whole BVH behind a
    // transform, far dearer to enter than a box test.
    BvhBuildOptions top;
    top.max_leaf_size = 2;
    top.leaf_simd_width = 1;
    top.traversal_cost = 1.0f;
    top.intersection_cost = 4.0f;
    build_box_tree(boxes, top, top_, order_);
}

Ray InstanceBvh::to_object(uint32_t inst, const Ray& ray, float time) const {
    const Placement& p = placements_[inst];
    if (p.motion == kStillInstance) return ray_to_object(p.world_to_object, ray);
    const Motion& m = motions_[p.motion];
    Transform world_to_object;
    // Singular mid-shutter (a flip): the ray becomes invalid and hits nothing there.
    if (!invert_affine(instance_transform_at(m.open, m.close, time), world_to_object)) world_to_object.m[0][0] = NAN;
    return ray_to_object(world_to_object, ray);
}

size_t InstanceBvh::bytes() const {
    size_t b = top_.size() * sizeof(BvhNode) + order_.size() * sizeof(uint32_t) + placements_.size() * sizeof(Placement);
    for (const auto& p : prototypes_)
        if (p) b += p->build_stats().bytes;
    return b;
}

// Calls visit(instance, tmax) for every instance whose box `ray` enters
// within (ray.tmin, tmax]; visit returns the new tmax (a closer hit shortens
// the walk), or a negative value to stop.
template <class Visit>
void InstanceBvh::visit_instances(const Ray& ray, float tmax, Visit&& visit, uint64_t* box_tests,
                                  uint64_t* node_visits) const {
    if (top_.empty() || !valid_ray(ray)) return;
    const Vec3f inv{1.0f / ray.d.x, 1.0f / ray.d.y, 1.0f / ray.d.z};
    uint32_t stack[128];
    int sp = 0;
    uint32_t node = 0;
    while (true) {
        const BvhNode& n = top_[node];
        ++*node_visits;
        ++*box_tests;
        if (enters(n.box, ray.o, inv, ray.tmin, tmax)) {
            if (!n.is_leaf()) {
                stack[sp++] = n.index + 1;
                node = n.index;
                continue;
            }
            for (uint32_t i = n.index; i < n.index + n.count; ++i) {
                tmax = visit(order_[i], tmax);
                if (tmax < 0.0f) return;
            }
        }
        if (sp == 0) return;
        node = stack[--sp];
    }
}

bool InstanceBvh::intersect(const Ray& ray, Hit& hit, TraversalCounters* counters, float time) const {
    TraversalCounters work;
    bool replaced = false;
    visit_instances(
        ray, std::min(ray.tmax, hit.t),
        [&](uint32_t inst, float tmax) {
            Ray r = to_object(inst, ray, time);
            r.tmax = tmax;
            Hit h;
            if (prototypes_[placements_[inst].prototype]->intersect(r, h, &work)) {
                h.instance = inst;
                if (instance_hit_closer(h, hit)) {
                    hit = h;
                    replaced = true;
                    return h.t;
                }
            }
            return tmax;
        },
        &work.box_tests, &work.node_visits);
    add_work(counters, work);
    return replaced;
}

bool InstanceBvh::occluded(const Ray& ray, TraversalCounters* counters, float time) const {
    TraversalCounters work;
    bool blocked = false;
    visit_instances(
        ray, ray.tmax,
        [&](uint32_t inst, float tmax) {
            const Ray r = to_object(inst, ray, time);
            blocked = prototypes_[placements_[inst].prototype]->occluded(r, &work);
            return blocked ? -1.0f : tmax;
        },
        &work.box_tests, &work.node_visits);
    add_work(counters, work);
    return blocked;
}

// --- packets: the top level walked by the whole packet, lane masks per node ---

namespace {

struct PacketScratch {
    RayPacket rays;
    HitPacket hits;
};

PacketScratch& packet_scratch() {
    thread_local std::unique_ptr<PacketScratch> scratch = std::make_unique<PacketScratch>();
    return *scratch;
}

// Per-lane constants of the top-level walk.
struct PacketLanes {
    uint32_t live[kPacketMaskWords] = {};  // active, valid, not yet occluded
    Vec3f o[kMaxPacketRays], inv[kMaxPacketRays];
    float best[kMaxPacketRays];  // tmax, shortened by closer hits
};

template <class F>
void for_each_lane(const uint32_t mask[kPacketMaskWords], F&& f) {
    for (int w = 0; w < kPacketMaskWords; ++w)
        for (uint32_t bits = mask[w]; bits; bits &= bits - 1) f(32 * w + __builtin_ctz(bits));
}

}  // namespace

template <bool kAnyHit>
void InstanceBvh::trace_packet(const RayPacket& pk, HitPacket* hits, OcclusionMask* occluded,
                               PacketCounters* counters, const float* times) const {
    if (top_.empty() || pk.size == 0) return;
    PacketLanes lanes;
    for (int i = 0; i < pk.size; ++i) {
        const Ray r = pk.ray(i);
        if (!pk.is_active(i) || !valid_ray(r) || (kAnyHit && occluded->test(i))) continue;
        lanes.live[i >> 5] |= 1u << (i & 31);
        lanes.o[i] = r.o;
        lanes.inv[i] = Vec3f{1.0f / r.d.x, 1.0f / r.d.y, 1.0f / r.d.z};
        lanes.best[i] = kAnyHit ? r.tmax : std::min(r.tmax, hits->t[i]);
    }
    PacketScratch& sc = packet_scratch();
    PacketCounters work;
    work.ray_node_visits = counters ? counters->ray_node_visits : nullptr;
    // One instance for the lanes in `mask`: carried into object space in a
    // scratch packet (same lane positions) and traced by the prototype's kernel.
    auto trace_instance = [&](uint32_t inst, const uint32_t mask[kPacketMaskWords]) {
        const Placement& pl = placements_[inst];
        sc.rays.size = pk.size;
        std::copy(mask, mask + kPacketMaskWords, sc.rays.active);
        for_each_lane(mask, [&](int l) {
            Ray r = to_object(inst, pk.ray(l), times ? times[l] : 0.0f);
            r.tmax = lanes.best[l];
            sc.rays.set(l, r);
        });
        const Bvh& proto = *prototypes_[pl.prototype];
        if constexpr (kAnyHit) {
            OcclusionMask m;
            proto.occluded(sc.rays, m, &work);
            for (int w = 0; w < kPacketMaskWords; ++w) {
                occluded->bits[w] |= m.bits[w] & mask[w];
                lanes.live[w] &= ~m.bits[w];
            }
        } else {
            for_each_lane(mask, [&](int l) { sc.hits.t[l] = kInf, sc.hits.prim[l] = kInvalidPrim; });
            proto.intersect(sc.rays, sc.hits, &work);
            for_each_lane(mask, [&](int l) {
                if (sc.hits.prim[l] == kInvalidPrim) return;
                Hit h = sc.hits.hit(l);
                h.instance = inst;
                if (!instance_hit_closer(h, hits->hit(l))) return;
                hits->t[l] = h.t, hits->u[l] = h.u, hits->v[l] = h.v;
                hits->prim[l] = h.prim, hits->instance[l] = inst;
                lanes.best[l] = h.t;
            });
        }
    };
    struct Entry {
        uint32_t node;
        uint32_t mask[kPacketMaskWords];
    };
    Entry stack[128];
    int sp = 0;
    stack[sp].node = 0;
    std::copy(lanes.live, lanes.live + kPacketMaskWords, stack[sp++].mask);
    while (sp > 0) {
        Entry e = stack[--sp];
        const BvhNode& n = top_[e.node];
        ++work.node_visits;
        bool any = false;
        for (int w = 0; w < kPacketMaskWords; ++w) {
            uint32_t in = 0;
            for (uint32_t bits = e.mask[w] & lanes.live[w]; bits; bits &= bits - 1) {
                const int l = 32 * w + __builtin_ctz(bits);
                ++work.box_tests;
                if (work.ray_node_visits) ++work.ray_node_visits[l];
                const bool hit = enters(n.box, lanes.o[l], lanes.inv[l], pk.tmin[l], lanes.best[l]);
                in |= hit ? 1u << (l & 31) : 0u;
            }
            e.mask[w] = in;
            any = any || in != 0;
        }
        if (!any) continue;
        if (n.is_leaf()) {
            for (uint32_t i = n.index; i < n.index + n.count; ++i) trace_instance(order_[i], e.mask);
            continue;
        }
        stack[sp] = e;
        stack[sp++].node = n.index + 1;
        stack[sp] = e;
        stack[sp++].node = n.index;
    }
    add_work(counters, work);  // ray_node_visits was counted in place
}

void InstanceBvh::intersect(const RayPacket& packet, HitPacket& hits, PacketCounters* counters,
                            const float* times) const {
    trace_packet<false>(packet, &hits, nullptr, counters, times);
}

void InstanceBvh::occluded(const RayPacket& packet, OcclusionMask& occluded, PacketCounters* counters,
                           const float* times) const {
    trace_packet<true>(packet, nullptr, &occluded, counters, times);
}

// --- streams: each ray's instances gathered first, then one stream per instance ---

namespace {

struct StreamScratch {
    std::vector<uint64_t> visits;  // (instance << 32) | ray
    std::vector<Ray> rays;
    std::vector<Hit> hits;
    std::vector<uint8_t> occluded;
    std::vector<uint32_t> source;  // scratch ray -> stream ray
};

StreamScratch& stream_scratch() {
    thread_local StreamScratch scratch;
    return scratch;
}

StreamOptions one_slice() {
    StreamOptions o;
    o.slice_size = 0;
    o.parallel = false;
    return o;
}

}  // namespace

template <bool kAnyHit>
void InstanceBvh::trace_stream(const Ray* rays, size_t n, Hit* hits, uint8_t* occluded, StreamStats* stats,
                               const float* times) const {
    if (top_.empty() || n == 0) return;
    StreamScratch& sc = stream_scratch();
    sc.visits.clear();
    StreamStats work;
    for (size_t i = 0; i < n; ++i) {
        if (kAnyHit && occluded[i]) continue;
        const float tmax = kAnyHit ? rays[i].tmax : std::min(rays[i].tmax, hits[i].t);
        visit_instances(
            rays[i], tmax,
            [&](uint32_t inst, float t) {
                sc.visits.push_back(uint64_t(inst) << 32 | i);
                return t;
            },
            &work.box_tests, &work.node_visits);
    }
    // Instance-major, rays in stream order within each instance.
    std::sort(sc.visits.begin(), sc.visits.end());
    for (size_t b = 0, e; b < sc.visits.size(); b = e) {
        const uint32_t inst = uint32_t(sc.visits[b] >> 32);
        sc.rays.clear();
        sc.source.clear();
        for (e = b; e < sc.visits.size() && uint32_t(sc.visits[e] >> 32) == inst; ++e) {
            const uint32_t i = uint32_t(sc.visits[e]);
            if (kAnyHit && occluded[i]) continue;
            Ray r = to_object(inst, rays[i], times ? times[i] : 0.0f);
            if constexpr (!kAnyHit) r.tmax = std::min(rays[i].tmax, hits[i].t);
            sc.rays.push_back(r);
            sc.source.push_back(i);
        }
        const Bvh& proto = *prototypes_[placements_[inst].prototype];
        StreamStats ss;
        if constexpr (kAnyHit) {
            sc.occluded.assign(sc.rays.size(), 0);
            coherent::occluded_stream(proto, sc.rays.data(), sc.rays.size(), sc.occluded.data(), &ss, one_slice());
            for (size_t j = 0; j < sc.rays.size(); ++j)
                if (sc.occluded[j]) occluded[sc.source[j]] = 1;
        } else {
            sc.hits.assign(sc.rays.size(), Hit{});
            coherent::intersect_stream(proto, sc.rays.data(), sc.rays.size(), sc.hits.data(), &ss, one_slice());
            for (size_t j = 0; j < sc.rays.size(); ++j) {
                Hit h = sc.hits[j];
                if (!h.valid()) continue;
                h.instance = inst;
                if (instance_hit_closer(h, hits[sc.source[j]])) hits[sc.source[j]] = h;
            }
        }
        add_work(&work, ss);
    }
    add_work(stats, work);
}

void InstanceBvh::intersect_stream(const Ray* rays, size_t n, Hit* hits, StreamStats* stats,
                                   const float* times) const {
    trace_stream<false>(rays, n, hits, nullptr, stats, times);
}

void InstanceBvh::occluded_stream(const Ray* rays, size_t n, uint8_t* occluded, StreamStats* stats,
                                  const float* times) const {
    trace_stream<true>(rays, n, nullptr, occluded, stats, times);
}

}  // namespace coherent
