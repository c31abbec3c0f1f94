// Depth-first driver of the path state machine (path_state.h): one camera
// sample's path, each ray traced singly the moment it exists. The reference
// every batched driver (packets, streams, wavefront) must match bit for bit.
//
// The kernel is a template over the few SceneFeatures bits that change which
// rays exist, so a scene without glass has no refraction code, one without
// depth of field never samples the lens, and one without emitters traces no
// shadow rays. The renderer instantiates the variants and picks one.
//
// Bounce limits follow Cycles: after a BSDF sample of type X the total and the
// per-type counters are incremented; if one exceeds its Blender limit, the
// ray is still traced to collect (MIS-weighted) emission, then the path ends.
// So max_bounces = 0 gives direct lighting only, as in Blender.
#pragma once

#include "path_state.h"

namespace coherent {

// Where a ray's traversal work is booked: the render totals and the bounce's
// statistics, and (for heatmaps) the path's node visits.
inline void book_single_ray(RenderStats& st, int bounce, RayType type, const TraversalCounters& c,
                            uint32_t* path_node_visits) {
    ++st.rays[size_t(type)];
    st.traversal += c;
    BounceStats& b = st.bounces[size_t(std::min(bounce, kStatBounces - 1))];
    ++b.rays;
    b.node_visits += c.node_visits;
    b.box_tests += c.box_tests;
    b.triangle_tests += c.triangle_tests;
    if (path_node_visits) *path_node_visits += uint32_t(c.node_visits);
}

// Books the moving triangles' traversal work (its rays were booked already).
inline void book_motion(RenderStats& st, int bounce, const TraversalCounters& c) {
    st.traversal.node_visits += c.node_visits;
    st.traversal.box_tests += c.box_tests;
    st.traversal.triangle_tests += c.triangle_tests;
    BounceStats& b = st.bounces[size_t(std::min(bounce, kStatBounces - 1))];
    b.node_visits += c.node_visits;
    b.box_tests += c.box_tests;
    b.triangle_tests += c.triangle_tests;
}

template <class Sampler, bool kGlass, bool kDepthOfField, bool kLights>
PathOutput trace_path(const PathContext& ctx, const PathSampler<Sampler>& ps, int px, int py, RenderStats& st,
                      uint32_t* node_visits = nullptr) {
    const Bvh& bvh = *ctx.bvh;
    PathState s;
    start_path<Sampler, kDepthOfField>(ctx, ps, px, py, s);
    while (s.alive) {
        const int bounce = s.bounce;
        TraversalCounters c;
        Hit hit;
        const bool found = merge_motion_hit(ctx, s, bvh.intersect(s.ray, hit, &c), hit, &c);
        book_single_ray(st, bounce, s.type, c, node_visits);
        shade_hit<Sampler, kGlass, kLights>(ctx, ps, s, found, hit);
        if (s.has_shadow) {
            TraversalCounters cs;
            const bool occluded = bvh.occluded(s.shadow, &cs) || motion_occluded(ctx, s, s.shadow, &cs);
            book_single_ray(st, bounce, RayType::Shadow, cs, node_visits);
            resolve_shadow(s, occluded);
        }
        if (s.ao_rays > 0) {
            int unoccluded = 0;
            for (int i = 0; i < s.ao_rays; ++i) {
                TraversalCounters ca;
                const Ray r = ao_ray(ctx, ps, s, i);
                unoccluded += bvh.occluded(r, &ca) || motion_occluded(ctx, s, r, &ca) ? 0 : 1;
                book_single_ray(st, bounce, RayType::Shadow, ca, node_visits);
            }
            resolve_ao(s, unoccluded);
        }
    }
    return s.out;
}

}  // namespace coherent
