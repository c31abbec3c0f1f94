// Depth-first driver of the path state machine (path_state.h): one camera
// sample's path, each ray traced singly the moment it exists. The reference
// every driver that traces many paths together (packets, streams,
// wavefront) must match bit for bit.
//
// The kernel is a template over the few SceneFeatures bits that change which
// rays exist, so a scene without glass has no refraction code, one without
// depth of field never samples the lens, and one without emitters traces no
// shadow rays. Drivers instantiate the variants and pick one at run time
// (kernel_variants.h).
//
// Bounce limits follow Cycles: after a BSDF sample of type X the total and the
// per-type counters are incremented; if one exceeds its Blender limit, the
// ray is still traced to collect (MIS-weighted) emission, then the path ends.
// So max_bounces = 0 gives direct lighting only, as in Blender.
#pragma once


#include "path_state.h"

namespace coherent {

// Traces a path's occlusion rays one at a time and resolves them.
COHERENT_ALWAYS_INLINE void trace_occlusion_rays(const PathContext& ctx, const PathSampler& ps,
                                                 PathState& s, int bounce, RenderStats& st, uint32_t* node_visits) {
    const int rays = occlusion_ray_count(s);
    if (rays == 0) return;
    int unoccluded = 0;
    for (int k = 0; k < rays; ++k) {
        TraversalCounters c;
        const Ray r = occlusion_ray(ctx, ps, s, k);
        unoccluded += ctx.bvh->occluded(r, &c) || motion_occluded(ctx, s, r, &c) || instance_occluded(ctx, s, r, &c) ? 0 : 1;
        book_single_ray(st, bounce, RayType::Shadow, c, node_visits);
    }
    resolve_occlusion(s, unoccluded);
}

template <bool kGlass, bool kDepthOfField, bool kLights>
PathOutput trace_path(const PathContext& ctx, const PathSampler& ps, int px, int py, RenderStats& st,
                      uint32_t* node_visits = nullptr) {
    const Bvh& bvh = *ctx.bvh;
    PathState s;
    start_fresh_path<kDepthOfField>(ctx, ps, px, py, s);
    while (s.alive) {
        const int bounce = s.bounce;
        TraversalCounters c;
        Hit hit;
        const bool found = merge_motion_hit(
            ctx, s, merge_instance_hit(ctx, s, s.ray, bvh.intersect(s.ray, hit, &c), hit, &c), hit, &c);
        book_single_ray(st, bounce, s.type, c, node_visits);
        shade_hit<kGlass, kLights>(ctx, ps, s, found, hit);
        trace_occlusion_rays(ctx, ps, s, bounce, st, node_visits);
    }
    return s.out;
}

}  // namespace coherent
