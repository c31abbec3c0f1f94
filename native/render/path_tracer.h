// Unidirectional path tracer with next-event estimation and multiple
// importance sampling (power heuristic), one camera sample at a time.
//
// The kernel is a template over the few SceneFeatures bits that change which
// rays exist, so a scene without glass has no refraction code, one without
// depth of field never samples the lens, and one without emitters traces no
// shadow rays. The renderer instantiates the 8 variants and picks one.
//
// Bounce limits follow Cycles: after a BSDF sample of type X the total and the
// per-type counters are incremented; if one exceeds its Blender limit, the
// ray is still traced to collect (MIS-weighted) emission, then the path ends.
// So max_bounces = 0 gives direct lighting only, as in Blender.
#pragma once

#include <cmath>
#include <limits>

#include "../accel/bvh.h"
#include "../sample/sampler.h"
#include "../scene/scene.h"
#include "bsdf.h"
#include "camera_rays.h"
#include "light_sampling.h"
#include "ray_offset.h"
#include "settings.h"
#include "stats.h"

namespace coherent {

// Spawned rays start just past the surface (ray_offset.h); t = 0 can still
// come out of the intersector when the offset is a single denormal (a plane
// through the origin), so hits at t < FLT_MIN are excluded. No legitimate hit
// is that close.
constexpr float kSpawnTmin = std::numeric_limits<float>::min();

struct PathOutput {
    Vec3f radiance{0.0f};
    float alpha = 1.0f;
    float depth = kInf;  // view-axis distance of the first hit, inf if none
    Vec3f normal{0.0f};  // shading normal at the first hit (facing the camera)
};

struct PathContext {
    const Scene* scene;
    const Bvh* bvh;
    const LightSet* lights;
    const RenderSettings* settings;
};

// Cycles' sample clamping: a contribution whose light left path vertex
// `origin` (-1: seen by the camera, 0: first hit) is limited by clamp_direct
// when origin <= 0, else by clamp_indirect. Limits <= 0 disable clamping.
inline Vec3f clamp_contribution(const Vec3f& c, int origin, const RenderSettings& rs) {
    const float limit = origin <= 0 ? rs.clamp_direct : rs.clamp_indirect;
    if (!(limit > 0.0f)) return c;
    const float m = max_component(c);
    return m > limit ? c * (limit / m) : c;
}

template <class Sampler, bool kGlass, bool kDepthOfField, bool kLights>
PathOutput trace_path(const PathContext& ctx, const PathSampler<Sampler>& ps, int px, int py, RenderStats& st) {
    const Scene& scene = *ctx.scene;
    const RenderSettings& rs = *ctx.settings;
    const Bvh& bvh = *ctx.bvh;
    const LightSet& lights = *ctx.lights;
    using D = PathDims;

    PathOutput out;
    const float fx = float(px) + ps.get(D::kPixelX);
    const float fy = float(py) + ps.get(D::kPixelY);
    float lens_u = 0.5f, lens_v = 0.5f;
    if constexpr (kDepthOfField) {
        lens_u = ps.get(D::kLensU);
        lens_v = ps.get(D::kLensV);
    }
    const CameraRay cr = generate_camera_ray<kDepthOfField>(scene.camera, fx, fy, rs.width, rs.height, lens_u, lens_v);
    Ray ray = cr.ray;
    RayType type = RayType::Camera;

    Vec3f throughput(1.0f), radiance(0.0f);
    int bounce = 0, diffuse_bounce = 0, glossy_bounce = 0, transmission_bounce = 0;
    float prev_pdf = 0.0f;      // BSDF pdf of the current ray's direction; 0 = camera or delta
    Vec3f prev_n(0.0f, 0.0f, 1.0f);
    bool prev_transmissive = false;
    bool last_ray = false;      // a bounce limit was reached: collect emission, then stop

    for (;;) {
        ++st.rays[size_t(type)];
        Hit hit;
        const bool found = bvh.intersect(ray, hit, &st.traversal);

        // Analytic lights are invisible to camera rays (measured in Cycles) and
        // transparent: every one in front of the surface adds its emission.
        if constexpr (kLights) {
            if (bounce > 0)
                radiance += clamp_contribution(throughput * lights.hit_lights(ray.o, ray.d, found ? hit.t : ray.tmax, prev_pdf),
                                               bounce - 1, rs);
        }

        if (!found) {
            if (bounce == 0) {
                if (rs.transparent_film) out.alpha = 0.0f;
                else radiance += clamp_contribution(lights.world_color(), -1, rs);
            } else if constexpr (kLights) {
                radiance += clamp_contribution(throughput * lights.escaped(ray.d, prev_n, prev_transmissive, prev_pdf),
                                               bounce - 1, rs);
            }
            break;
        }

        const uint32_t tri = hit.prim;
        const Vec3f* v = &scene.vertices[3 * size_t(tri)];
        Vec3f p_error;
        const Vec3f p = triangle_point(v[0], v[1], v[2], hit.u, hit.v, p_error);
        const Vec3f wo = -ray.d;
        const Vec3f ng = scene.geometric_normals[tri];
        const bool front = dot(wo, ng) > 0.0f;
        const Vec3f ng_f = front ? ng : -ng;
        Vec3f n = ng_f;
        if (scene.has_normals[tri]) {
            const Vec3f* sn = &scene.normals[3 * size_t(tri)];
            const Vec3f interp = sn[0] * (1.0f - hit.u - hit.v) + sn[1] * hit.u + sn[2] * hit.v;
            const float len = length(interp);
            if (len > 0.0f && std::isfinite(len)) {
                const Vec3f ns = (front ? interp : -interp) / len;
                // A shading normal facing away from the viewer cannot shade it.
                if (dot(ns, wo) > 1e-4f) n = ns;
            }
        }
        if (bounce == 0) {
            out.depth = dot(p - scene.camera.position, scene.camera.forward);
            out.normal = n;
        }

        const Material& mat = scene.materials[scene.material_of[tri]];
        if (mat.is_emissive()) {
            float w = 1.0f;
            if constexpr (kLights) {
                if (prev_pdf > 0.0f) w = power_heuristic(prev_pdf, lights.triangle_pdf(tri, ray.o, p, ng));
            }
            radiance += clamp_contribution(throughput * mat.emission * w, bounce - 1, rs);
        }
        if (last_ray) break;

        const Bsdf bsdf(mat, n, ng_f, wo, front, kGlass);
        if (bsdf.empty()) break;

        // Next-event estimation.
        if constexpr (kLights) {
            LightSample ls;
            if (bsdf.has_non_delta() &&
                lights.sample(p, n, bsdf.transmissive(), ps.get(D::bounce(bounce, D::kLightPick)),
                              ps.get(D::bounce(bounce, D::kLightU)), ps.get(D::bounce(bounce, D::kLightV)), ls)) {
                float bsdf_pdf = 0.0f;
                const Vec3f f = bsdf.eval(ls.wi, bsdf_pdf);
                if (!is_black(f) && !is_black(ls.li)) {
                    Ray shadow;
                    shadow.o = offset_ray_origin(p, p_error, ng_f, ls.wi);
                    shadow.d = ls.wi;
                    shadow.tmin = kSpawnTmin;
                    // Analytic lights are not geometry: the shadow ray runs the
                    // full distance, so an occluder however close to the light
                    // (a light just outside a wall) still blocks it.
                    shadow.tmax = ls.dist;
                    if (ls.on_surface) {
                        // Emissive triangles are in the BVH: aim at a point pushed
                        // off the emitter by its error bound, towards us, so the
                        // emitter cannot occlude itself and nothing in front of it
                        // is skipped.
                        const Vec3f target = offset_ray_origin(ls.p_light, ls.p_light_error, ls.n_light, -ls.wi);
                        const Vec3f to = target - shadow.o;
                        const float d = length(to);
                        shadow.d = to / d;
                        shadow.tmax = d * (1.0f - 1e-6f);
                    }
                    ++st.rays[size_t(RayType::Shadow)];
                    if (!bvh.occluded(shadow, &st.traversal)) {
                        const float w = ls.delta ? 1.0f : power_heuristic(ls.pdf, bsdf_pdf);
                        radiance += clamp_contribution(throughput * f * ls.li * (w / ls.pdf), bounce, rs);
                    }
                }
            }
        }

        // Russian roulette on the path throughput (Cycles: sqrt of the max component).
        if (bounce >= rs.rr_min_bounces) {
            const float q = std::min(1.0f, std::sqrt(max_component(throughput)));
            if (!(ps.get(D::bounce(bounce, D::kRoulette)) < q)) break;
            throughput = throughput / q;
        }

        BsdfSample bs;
        if (!bsdf.sample(ps.get(D::bounce(bounce, D::kBsdfLobe)), ps.get(D::bounce(bounce, D::kBsdfU)),
                         ps.get(D::bounce(bounce, D::kBsdfV)), bs))
            break;
        if constexpr (!kGlass) {
            if (bs.type == RayType::Refraction) break;  // unreachable: no glass lobes exist
        }
        throughput *= bs.weight;
        if (is_black(throughput) || !is_finite(throughput)) break;

        ++bounce;
        switch (bs.type) {
            case RayType::Diffuse: ++diffuse_bounce; break;
            case RayType::Refraction: ++transmission_bounce; break;
            default: ++glossy_bounce; break;
        }
        if (bounce > rs.max_bounces || diffuse_bounce > rs.diffuse_bounces || glossy_bounce > rs.glossy_bounces ||
            transmission_bounce > rs.transmission_bounces)
            last_ray = true;

        prev_pdf = bs.delta ? 0.0f : bs.pdf;
        prev_n = n;
        prev_transmissive = bsdf.transmissive();
        ray.o = offset_ray_origin(p, p_error, ng_f, bs.wi);
        ray.d = bs.wi;
        ray.tmin = kSpawnTmin;
        ray.tmax = kInf;
        type = bs.type;
    }

    out.radiance = radiance;
    return out;
}

}  // namespace coherent
