// One camera sample's path as an explicit state machine, so that any driver
// can trace its rays however it likes: one path at a time depth-first
// (path_tracer.h), many paths bounce by bounce with their rays gathered into
// SIMD packets or streams (packet_paths.h), or whole waves with reordering
// (wavefront.h). The state machine owns every shading decision; drivers only
// trace rays. Because each step is a pure function of the state, the hit and
// the path's own random numbers, every driver computes bit-identical
// radiance for the same rays and samples: traversal is a speed choice, never
// a different image.
//
// A path alternates two kinds of rays:
//   extension ray (state.ray): traced with Bvh::intersect; the driver calls
//     shade_hit() with the result. shade_hit() adds emission and may queue
//     one shadow ray (next-event estimation) and set up the next extension
//     ray, or end the path (state.alive = false).
//   shadow ray (state.shadow, when state.has_shadow): traced with
//     Bvh::occluded; the driver calls resolve_occlusion() with the result
//     BEFORE tracing the path's next extension ray. (The radiance sum then
//     adds contributions in the same order as a depth-first loop.)
// Ambient occlusion (Integrator::AmbientOcclusion) instead queues
// ao_samples occlusion rays at the first hit (ao_ray()) and ends. Drivers
// see both kinds through one interface: occlusion_ray_count(),
// occlusion_ray(), resolve_occlusion().
//
// Integrators differ only in which BSDF samples continue the path
// (may_continue below); light sampling, MIS and bounce limits are shared.
#pragma once

#include <cmath>
#include <limits>
#include <optional>

#include "../accel/bvh.h"
#include "../accel/instance_bvh.h"
#include "../accel/motion_bvh.h"
#include "../core/inline.h"
#include "../denoise/denoising_features.h"
#include "../sample/image_sampler.h"
#include "../scene/scene.h"
#include "../shader/eval.h"
#include "../shader/program.h"
#include "bsdf.h"
#include "camera_rays.h"
#include "instance_shading.h"
#include "light_sampling.h"
#include "pass_accumulation.h"
#include "ray_offset.h"
#include "render_modes.h"
#include "shading_normal.h"
#include "shadow_terminator.h"
#include "settings.h"
#include "stats.h"
#include "transparency.h"

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
    // Denoising features (denoise/denoising_features.h); 0 unless requested.
    Vec3f albedo{0.0f};
    Vec3f denoising_normal{0.0f};
    float denoising_depth = 0.0f;
    PassSample passes;  // Cycles' passes (film/passes.h); 0 unless enabled
    // The part of `radiance` that reached the camera after at most one
    // scattering: emission and the world seen directly, next-event
    // estimation at the first hit, and what the first bounce's ray met
    // (Cycles' Dir + Emit + Env). The denoiser filters it apart from the rest
    // where it is a tenth of the light or more (denoiser.h); a few additions
    // a path.
    Vec3f direct{0.0f};
};

struct PathContext {
    const Scene* scene;
    const Bvh* bvh;
    const LightSet* lights;
    const RenderSettings* settings;
    float ao_distance = 0.0f;  // resolved AO ray length (Integrator::AmbientOcclusion)
    // Object motion blur: the moving triangles (null when nothing moves;
    // they are then absent from `bvh`, see Renderer).
    const MotionBvh* motion = nullptr;
    // Shared geometry: the instances' two-level BVH (null without instances).
    const InstanceBvh* instances = nullptr;
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

struct PathState {
    Ray ray;                         // the next extension ray (valid while alive)
    RayType type = RayType::Camera;  // its type
    bool alive = true;               // an extension ray is waiting to be traced
    bool has_shadow = false;         // a shadow ray is waiting to be traced
    Ray shadow;
    Vec3f shadow_contribution{0.0f};  // added if the shadow ray is unoccluded
    bool shadow_direct = false;        // queued at the first hit: its light is direct (PathOutput)

    Vec3f throughput{1.0f};
    int bounce = 0, diffuse_bounce = 0, glossy_bounce = 0, transmission_bounce = 0;
    int transparent_bounce = 0;  // pass-throughs (transparency.h); not bounces, but they draw numbers
    float prev_pdf = 0.0f;  // BSDF pdf of the current ray's direction; 0 = camera or delta
    Vec3f prev_n{0.0f, 0.0f, 1.0f};
    bool prev_transmissive = false;
    bool last_ray = false;  // a bounce limit was reached: collect emission, then stop
    // Ambient occlusion: occlusion rays queued at the first hit (ao_ray(i)),
    // and the frame they are drawn in.
    int ao_rays = 0;
    Vec3f ao_origin{0.0f}, ao_normal{0.0f};
    // Motion blur: the shutter time, in [0, 1), at which this path sees the
    // scene (every ray of a path, as in distribution ray tracing).
    float time = 0.0f;
    DenoisingFeatureState features;
    PassState pass;

    PathOutput out;
};

// The block of sampler dimensions (PathDims::bounce) the path's current
// vertex reads: pass-throughs draw numbers too, so each surface met has its own.
COHERENT_ALWAYS_INLINE int vertex_index(const PathState& s) { return s.bounce + s.transparent_bounce; }

// Motion blur, for drivers: merge the moving triangles' closest hit of s.ray
// into the static BVH's (found, hit); returns whether anything is hit.
inline bool merge_motion_hit(const PathContext& ctx, const PathState& s, bool found, Hit& hit,
                             TraversalCounters* counters = nullptr) {
    if (!ctx.motion) return found;
    return ctx.motion->intersect(s.ray, s.time, hit, counters) || found;
}
// Whether a moving triangle blocks occlusion ray `r` of path s.
inline bool motion_occluded(const PathContext& ctx, const PathState& s, const Ray& r,
                            TraversalCounters* counters = nullptr) {
    return ctx.motion && ctx.motion->occluded(r, s.time, counters);
}

// Shared geometry, for drivers tracing one ray at a time: merge the
// instances' closest hit of `r` into (found, hit); whether an instance
// blocks occlusion ray `r`. Packet and stream drivers call the
// InstanceBvh's packet and stream kernels instead.
inline bool merge_instance_hit(const PathContext& ctx, const PathState& s, const Ray& r, bool found, Hit& hit,
                               TraversalCounters* counters = nullptr) {
    if (!ctx.instances) return found;
    return ctx.instances->intersect(r, hit, counters, s.time) || found;
}
inline bool instance_occluded(const PathContext& ctx, const PathState& s, const Ray& r,
                              TraversalCounters* counters = nullptr) {
    return ctx.instances && ctx.instances->occluded(r, counters, s.time);
}

// Integrators as continuation rules (render_modes.h): after a BSDF sample,
// whether the sampled ray may start a new bounce. A ray that may not is still
// traced once to collect its (MIS-weighted) emission, as for bounce limits,
// so the direct lighting estimate keeps both of its MIS halves.
inline bool may_continue(Integrator integrator, const BsdfSample& bs) {
    switch (integrator) {
        case Integrator::PathTrace: return true;
        case Integrator::Distribution: return bs.type != RayType::Diffuse;
        case Integrator::Whitted: return bs.delta;
        case Integrator::RayCast: return false;
        case Integrator::AmbientOcclusion: return false;
    }
    return true;
}

// Whether an integrator samples the lens: Whitted ray tracing and ray
// casting are pinhole methods (one exact ray per pixel sample), the others
// follow the camera's depth of field.
constexpr bool integrator_uses_lens(Integrator i) {
    return i == Integrator::PathTrace || i == Integrator::Distribution || i == Integrator::AmbientOcclusion;
}

// The camera ray of pixel (px, py)'s sample, set on a default-constructed
// state `s` (start_path resets any state first; a driver that has just
// constructed one skips that second pass over its ~500 bytes).
template <bool kDepthOfField>
inline void start_fresh_path(const PathContext& ctx, const PathSampler& ps, int px, int py, PathState& s) {
    using D = PathDims;
    const RenderSettings& rs = *ctx.settings;
    const float fx = float(px) + ps.get(D::kPixelX);
    const float fy = float(py) + ps.get(D::kPixelY);
    float lens_u = 0.5f, lens_v = 0.5f;
    if constexpr (kDepthOfField) {
        lens_u = ps.get(D::kLensU);
        lens_v = ps.get(D::kLensV);
    }
    if (ctx.motion || (ctx.instances && ctx.instances->has_motion())) s.time = ps.get(D::kTime);
    s.features.pending = rs.denoising_features();
    s.pass.mask = rs.passes;
    s.ray = generate_camera_ray<kDepthOfField>(ctx.scene->camera, fx, fy, rs.width, rs.height, lens_u, lens_v).ray;
    s.type = RayType::Camera;
}

// The camera ray of pixel (px, py)'s sample, on any state.
template <bool kDepthOfField>
inline void start_path(const PathContext& ctx, const PathSampler& ps, int px, int py, PathState& s) {
    s = PathState{};
    start_fresh_path<kDepthOfField>(ctx, ps, px, py, s);
}

// The i-th ambient occlusion ray (i < s.ao_rays): cosine-distributed about
// the geometric normal facing the camera, ao_distance long. Dimensions: the
// i-th AO ray reads bounce block i's BSDF dimensions.
inline Ray ao_ray(const PathContext& ctx, const PathSampler& ps, const PathState& s, int i) {
    using D = PathDims;
    const Vec3f local = sample_cosine_hemisphere(ps.get(D::bounce(i, D::kBsdfU)), ps.get(D::bounce(i, D::kBsdfV)));
    Vec3f t, b;
    make_basis(s.ao_normal, t, b);
    Ray r;
    r.d = t * local.x + b * local.y + s.ao_normal * local.z;
    r.o = s.ao_origin;  // already offset for this side of the surface
    r.tmin = kSpawnTmin;
    r.tmax = ctx.ao_distance;
    return r;
}

// The steps of shade_hit() are always inlined (core/inline.h), so the
// per-hit code is one body as it was before they were named.

namespace shading {

// The point where s.ray met triangle `tri`, as shading sees it.
struct SurfacePoint {
    uint32_t tri;      // world-space triangle; kInvalidPrim on an instance (never a sampled light)
    uint32_t material;
    Vec3f p, p_error;  // position and its rounding error bound (ray_offset.h)
    Vec3f ng;          // geometric normal, as stored (light pdfs use it)
    Vec3f ng_f;        // geometric normal on the side the ray came from
    Vec3f n;           // shading normal on that side
    Vec3f ns;          // the interpolated normal on that side, unbent (ng_f without normals)
    float b1, b2;      // barycentric weights of corners 1 and 2 (world-space triangles)
    bool smooth;       // tri has interpolated normals
    Vec3f wo;          // towards where the ray came from
    bool front;        // the ray hit the side ng points to
    float t;           // the hit's ray parameter (a pass-through continues past it)
};

// The side the ray came from, and the shading normal there (`interp`, the
// interpolated one, when the surface has shading normals).
COHERENT_ALWAYS_INLINE void orient(SurfacePoint& sp, const Ray& ray, bool has_normals, const Vec3f& interp) {
    sp.wo = -ray.d;
    sp.front = dot(sp.wo, sp.ng) > 0.0f;
    sp.ng_f = sp.front ? sp.ng : -sp.ng;
    sp.n = sp.ns = sp.ng_f;
    sp.smooth = false;
    if (has_normals) {
        const float len = length(interp);
        if (len > 0.0f && std::isfinite(len)) {
            sp.ns = (sp.front ? interp : -interp) / len;
            sp.smooth = true;
            // Bent towards ng where the viewer's mirror direction would be
            // below the surface, as Cycles 3.4 does (shading_normal.h).
            sp.n = valid_reflection_normal(sp.ng_f, sp.wo, sp.ns);
        }
    }
}

// A hit on an instance: the prototype's triangle carried to the world.
COHERENT_ALWAYS_INLINE SurfacePoint instance_surface_point(const Scene& scene, const Ray& ray, float time,
                                                           const Hit& hit) {
    const InstancedPoint ip = instanced_point(scene, hit, time);
    SurfacePoint sp;
    sp.tri = kInvalidPrim;
    sp.material = ip.material;
    sp.p = ip.p;
    sp.p_error = ip.p_error;
    sp.ng = ip.ng;
    sp.t = hit.t;
    orient(sp, ray, ip.has_normal, ip.ns);
    return sp;
}

// The point where `ray`, at shutter time `time`, met hit.
COHERENT_ALWAYS_INLINE SurfacePoint surface_point(const Scene& scene, const Ray& ray, float time, const Hit& hit) {
    if (hit.instance != kInvalidPrim) return instance_surface_point(scene, ray, time, hit);
    SurfacePoint sp;
    sp.t = hit.t;
    sp.tri = hit.prim;
    sp.material = scene.material_of[hit.prim];
    const uint32_t tri = hit.prim;
    const Vec3f* v = &scene.vertices[3 * size_t(tri)];
    const Vec3f* sn = &scene.normals[3 * size_t(tri)];
    sp.ng = scene.geometric_normals[tri];
    // A moving triangle is shaded where the ray met it: at the path's time,
    // with the very vertices the intersector used (motion_vertex()).
    Vec3f moved[3], moved_n[3];
    if (scene.is_moving(tri)) {
        const Vec3f* vc = &scene.motion_vertices[3 * size_t(tri)];
        const Vec3f* nc = &scene.motion_normals[3 * size_t(tri)];
        for (int k = 0; k < 3; ++k) {
            moved[k] = motion_vertex(v[k], vc[k], time);
            moved_n[k] = motion_vertex(sn[k], nc[k], time);
        }
        v = moved;
        sn = moved_n;
        const Vec3f c = cross(v[1] - v[0], v[2] - v[0]);
        const float len = length(c);
        if (len > 0.0f && std::isfinite(len)) sp.ng = c / len;  // else keep the open pose's normal
    }
    sp.p = triangle_point(v[0], v[1], v[2], hit.u, hit.v, sp.p_error);
    sp.b1 = hit.u;
    sp.b2 = hit.v;
    const bool has_normals = scene.has_normals[tri] != 0;
    const Vec3f interp = has_normals ? sn[0] * (1.0f - hit.u - hit.v) + sn[1] * hit.u + sn[2] * hit.v : Vec3f(0.0f);
    orient(sp, ray, has_normals, interp);
    return sp;
}
COHERENT_ALWAYS_INLINE SurfacePoint surface_point(const Scene& scene, const PathState& s, const Hit& hit) {
    return surface_point(scene, s.ray, s.time, hit);
}

// Cycles' path flags and bounce counters at a hit of s.ray (the Light Path
// node): the ray's type says how it left the previous surface.
inline LightPathInfo light_path_info(const PathState& s, float t) {
    using F = LightPathInfo;
    LightPathInfo info;
    switch (s.type) {
        case RayType::Camera: info.flags = F::kCamera; break;
        case RayType::Diffuse: info.flags = F::kDiffuse | F::kReflect; break;
        case RayType::Glossy: info.flags = F::kGlossy | F::kReflect; break;
        case RayType::Reflection: info.flags = F::kGlossy | F::kSingular | F::kReflect; break;
        case RayType::Refraction:  // sharp glass leaves prev_pdf 0 (a delta)
            info.flags = F::kGlossy | F::kTransmit | (s.prev_pdf == 0.0f ? F::kSingular : 0);
            break;
        default: info.flags = 0; break;
    }
    info.ray_length = t;
    info.depth = s.bounce;
    info.diffuse_depth = s.diffuse_bounce;
    info.glossy_depth = s.glossy_bounce;
    info.transmission_depth = s.transmission_bounce;
    return info;
}

// The same at a surface a shadow ray from the current vertex meets at
// distance t (transparent shadows, transparency.h): Cycles evaluates the
// shader there with PATH_RAY_SHADOW as the only flag, so Is Shadow Ray reads
// 1 and every other ray type 0; the depths are the casting vertex's (Ray
// Depth one more, in light_path()).
inline LightPathInfo shadow_path_info(const PathState& s, float t) {
    LightPathInfo info = light_path_info(s, t);
    info.flags = LightPathInfo::kShadow;
    info.transparent_depth = s.transparent_bounce;
    return info;
}

// Cycles' compact ray differential dP at a hit: the width a pixel covers
// there, as seen from the camera (later bounces keep the camera's spread).
inline float pixel_footprint(const Scene& scene, const RenderSettings& rs, const Vec3f& p) {
    const Camera& cam = scene.camera;
    const float pixel = cam.half_width / float(std::max(rs.width, 1)) + cam.half_height / float(std::max(rs.height, 1));
    return cam.projection == Projection::Orthographic ? pixel : pixel * length(p - cam.position);
}

// What a program reads at sp (shader/eval.h), written into an existing g.
// The Light Path input is left to the caller, who owns the LightPathInfo
// g.path points to (reset here). Batches fill their reused arrays in place
// (batch_shading.h): constructing a fresh ShadingGeometry per hit zeroed
// ~200 bytes and wrote two identity transforms only to copy them over (a
// third of HitShading::evaluate's samples in perf). The transforms are
// written only on an instance, the one case that reads them (eval.h).
COHERENT_ALWAYS_INLINE void fill_shading_geometry(const PathContext& ctx, const PathState& s, const Hit& hit,
                                                  const SurfacePoint& sp, const ShaderProgram& program,
                                                  ShadingGeometry& g) {
    const Scene& scene = *ctx.scene;
    g.tri = sp.tri;
    g.prototype = nullptr;
    g.prim = 0;
    if (hit.instance != kInvalidPrim) {
        const Instance& inst = scene.instances[hit.instance];
        const InstanceFrame frame = instance_frame(scene, inst, s.time);
        g.prototype = &scene.prototypes[inst.prototype];
        g.prim = hit.prim;
        g.object_to_world = frame.to_world;
        g.world_to_object = frame.to_object;
    }
    g.u = hit.u;
    g.v = hit.v;
    g.p = sp.p;
    g.n = sp.n;
    g.ng = sp.ng_f;
    g.wo = sp.wo;
    g.front = sp.front;
    g.path = nullptr;
    g.footprint = program.uses_bump ? pixel_footprint(scene, *ctx.settings, sp.p) : 0.0f;
}

COHERENT_ALWAYS_INLINE ShadingGeometry shading_geometry(const PathContext& ctx, const PathState& s, const Hit& hit,
                                                        const SurfacePoint& sp, const ShaderProgram& program) {
    ShadingGeometry g;
    fill_shading_geometry(ctx, s, hit, sp, program, g);
    return g;
}

// The Light Path input of a program at `hit` of s.ray. Cycles starts camera
// rays on the near clip plane: lengths count from there.
COHERENT_ALWAYS_INLINE LightPathInfo hit_light_path(const PathState& s, const Hit& hit) {
    return light_path_info(s, hit.t - s.ray.tmin);
}

// The material at sp: its constants, or for a node graph with non-constant
// inputs what its shader program computes there (built in `scratch`; a
// normal map also replaces sp.n). Constant materials take the first return.
// shadow: the Light Path node's view for a shadow ray (else that of s.ray).
COHERENT_ALWAYS_INLINE const Material& material_at(const PathContext& ctx, const PathState& s, const Hit& hit,
                                                    SurfacePoint& sp, std::optional<Material>& scratch,
                                                    const LightPathInfo* shadow = nullptr) {
    const Scene& scene = *ctx.scene;
    const Material& base = scene.materials[sp.material];
    if (!base.program) return base;
    ShadingGeometry g = shading_geometry(ctx, s, hit, sp, *base.program);
    LightPathInfo path;
    if (base.program->uses_light_path) {
        path = shadow ? *shadow : hit_light_path(s, hit);
        g.path = &path;
    }
    evaluate_material(scene, base, g, scratch.emplace(), sp.n);
    return *scratch;
}

// A hit shaded ahead of shade_hit() with others (render/batch_shading.h):
// its surface point and, for a program material, what the program computed.
struct PreShaded {
    SurfacePoint sp;                     // as surface_point() gives it
    const Material* material = nullptr;  // what the program computed; null: the scene's constant one
    Vec3f n{0.0f};                       // the shading normal the program leaves
};

// Analytic lights are invisible to camera rays (measured in Cycles) and
// transparent: every one in front of the surface (or of nothing) adds its emission.
COHERENT_ALWAYS_INLINE void add_lights_passed(const PathContext& ctx, PathState& s, bool found, const Hit& hit) {
    if (s.bounce > 0) {
        const Vec3f c = clamp_contribution(
            s.throughput * ctx.lights->hit_lights(s.ray.o, s.ray.d, found ? hit.t : s.ray.tmax, s.prev_pdf,
                                                  s.transparent_bounce > 0 ? s.ray.tmin : 0.0f),
            s.bounce - 1, *ctx.settings);
        s.out.radiance += c;
        if (s.bounce == 1) s.out.direct += c;
        if (s.pass.mask) passes::add_hit_light(s.pass, s.out.passes, c, s.bounce, false);
    }
}

// s.ray left the scene.
template <bool kLights>
COHERENT_ALWAYS_INLINE void shade_miss(const PathContext& ctx, PathState& s) {
    const RenderSettings& rs = *ctx.settings;
    // The world as the features see it: its radiance that way, unless transparent.
    if (s.features.pending && !(s.bounce == 0 && rs.transparent_film))
        record_emission_feature(s.features, ctx.lights->world_radiance(s.ray.d), s.out.albedo);
    if (s.bounce == 0) {
        if (rs.integrator == Integrator::AmbientOcclusion) {
            // Nothing occludes a ray that leaves the scene.
            if (rs.transparent_film) s.out.alpha = 0.0f;
            else s.out.radiance += Vec3f(1.0f);
        } else if (rs.transparent_film) {
            s.out.alpha -= average(s.throughput);  // 1 - 1 = 0 straight from the camera
        } else {
            // Throughput 1 (exactly) unless transparent surfaces were passed.
            const Vec3f c = clamp_contribution(s.throughput * ctx.lights->world_radiance(s.ray.d), -1, rs);
            s.out.radiance += c;
            s.out.direct += c;
        }
        // Env holds the world also under a transparent film, as in Cycles.
        if (s.pass.mask && rs.integrator != Integrator::AmbientOcclusion)
            s.out.passes.add(RenderPass::Environment, clamp_contribution(ctx.lights->world_radiance(s.ray.d), -1, rs));
    } else if constexpr (kLights) {
        const Vec3f c = clamp_contribution(
            s.throughput * ctx.lights->escaped(s.ray.d, s.prev_n, s.prev_transmissive, s.prev_pdf), s.bounce - 1, rs);
        s.out.radiance += c;
        if (s.bounce == 1) s.out.direct += c;
        if (s.pass.mask) passes::add_hit_light(s.pass, s.out.passes, c, s.bounce, true);
    }
}

// Ambient occlusion at the first hit: the AO rays leave the side the camera
// sees; the driver traces them and resolve_occlusion() adds 1 / ao_samples
// per unoccluded ray.
COHERENT_ALWAYS_INLINE void queue_ao_rays(const PathContext& ctx, PathState& s, const SurfacePoint& sp) {
    s.ao_rays = ctx.settings->ao_samples;
    s.ao_normal = sp.ng_f;
    s.ao_origin = offset_ray_origin(sp.p, sp.p_error, sp.ng_f, sp.ng_f);
}

// An emissive surface hit: its emission, MIS-weighted against next-event
// estimation from the previous vertex when that sampled lights.
template <bool kLights>
COHERENT_ALWAYS_INLINE void add_emission(const PathContext& ctx, PathState& s, const Material& mat,
                                         const SurfacePoint& sp) {
    float w = 1.0f;
    if constexpr (kLights) {
        if (s.prev_pdf > 0.0f) w = power_heuristic(s.prev_pdf, ctx.lights->triangle_pdf(sp.tri, s.ray.o, sp.p, sp.ng));
    }
    const Vec3f c = clamp_contribution(s.throughput * mat.emission * w, s.bounce - 1, *ctx.settings);
    s.out.radiance += c;
    if (s.bounce <= 1) s.out.direct += c;
    if (s.pass.mask) passes::add_hit_light(s.pass, s.out.passes, c, s.bounce, false);
}

// Where a shadow ray from sp towards unit direction l starts: just off the
// surface, past its rounding error; or, where l grazes a smooth-shaded
// triangle, on the smooth surface its vertex normals describe, as Cycles
// does (shadow_terminator.h). Light below the geometric surface is then
// meant to be blocked by the triangle itself: the ray starts on the
// triangle's lit side, as Cycles, which skips the triangle only where the
// light is above it. Instanced and moving triangles keep the plain origin.
COHERENT_ALWAYS_INLINE Vec3f shadow_origin(const Scene& scene, const SurfacePoint& sp, const Vec3f& l) {
    if (sp.smooth && sp.tri != kInvalidPrim && !scene.is_moving(sp.tri)) {
        const float cutoff = scene.terminator_offset(sp.tri);
        Vec3f ng_light;
        float ng_dot_l = 0.0f;
        const float amount = cutoff > 0.0f ? terminator_amount(cutoff, sp.ns, sp.ng_f, l, ng_light, ng_dot_l) : 0.0f;
        if (amount > 0.0f) {
            const size_t t = 3 * size_t(sp.tri);
            const Vec3f lift = smooth_surface_lift(&scene.vertices[t], &scene.normals[t], 1.0f - sp.b1 - sp.b2, sp.b1,
                                                   sp.b2, ng_light);
            const Vec3f p = sp.p + lift * amount;
            if (is_finite(p)) return offset_ray_origin(p, sp.p_error, ng_light, ng_dot_l > 0.0f ? l : ng_light);
        }
    }
    return offset_ray_origin(sp.p, sp.p_error, sp.ng_f, l);
}

// The shadow ray from sp towards light sample ls.
COHERENT_ALWAYS_INLINE Ray shadow_ray(const Scene& scene, const SurfacePoint& sp, const LightSample& ls) {
    Ray shadow;
    shadow.o = shadow_origin(scene, sp, ls.wi);
    shadow.d = ls.wi;
    shadow.tmin = kSpawnTmin;
    // Analytic lights are not geometry: the shadow ray runs the full
    // distance, so an occluder however close to the light (a light just
    // outside a wall) still blocks it.
    shadow.tmax = ls.dist;
    if (ls.on_surface) {
        // Emissive triangles are in the BVH: aim at a point pushed off the
        // emitter by its error bound, towards us, so the emitter cannot
        // occlude itself and nothing in front of it is skipped.
        const Vec3f target = offset_ray_origin(ls.p_light, ls.p_light_error, ls.n_light, -ls.wi);
        const Vec3f to = target - shadow.o;
        const float d = length(to);
        shadow.d = to / d;
        shadow.tmax = d * (1.0f - 1e-6f);
    }
    return shadow;
}

// A shadow ray's closest hit beyond r.tmin in every part of the scene.
COHERENT_ALWAYS_INLINE bool closest_hit(const PathContext& ctx, const PathState& s, const Ray& r, Hit& hit) {
    bool found = merge_instance_hit(ctx, s, r, ctx.bvh->intersect(r, hit), hit);
    if (ctx.motion) found = ctx.motion->intersect(r, s.time, hit) || found;
    return found;
}

// The transparent colour of the surface r met at `hit` (black: opaque).
COHERENT_ALWAYS_INLINE Vec3f transparency_at(const PathContext& ctx, const PathState& s, const Ray& r,
                                             const Hit& hit) {
    SurfacePoint sp = surface_point(*ctx.scene, r, s.time, hit);
    if (!ctx.scene->materials[sp.material].has_closure(ClosureKind::Transparent)) return Vec3f(0.0f);
    std::optional<Material> scratch;
    const LightPathInfo shadow = shadow_path_info(s, hit.t);  // shadow rays start at their vertex
    return material_transparency(material_at(ctx, s, hit, sp, scratch, &shadow));
}

// Scenes with transparent surfaces: the queued shadow ray resolved here, in
// the state machine, so that every driver gets the same answer (transparency.h).
// An unoccluded ray adds its contribution; an occluded one is walked hit by
// hit through transparent surfaces. The driver then has nothing to trace.
// Kept out of line: opaque scenes never call it, and shade_hit stays small.
[[gnu::noinline]] inline void trace_transparent_shadow(const PathContext& ctx, PathState& s) {
    s.has_shadow = false;
    const Ray& r = s.shadow;
    Vec3f t(1.0f);
    if (ctx.bvh->occluded(r) || motion_occluded(ctx, s, r) || instance_occluded(ctx, s, r)) {
        Hit hit;
        const int max_hits = std::max(ctx.settings->transparent_max_bounces - s.transparent_bounce, 0);
        t = shadow_transmittance(
            r, max_hits,
            [&](const Ray& ray, float& t_hit) {
                hit = Hit{};
                if (!closest_hit(ctx, s, ray, hit)) return false;
                t_hit = hit.t;
                return true;
            },
            [&](const Ray& ray) { return transparency_at(ctx, s, ray, hit); });
        if (is_black(t)) return;
    }
    s.out.radiance += s.shadow_contribution * t;
    if (s.shadow_direct) s.out.direct += s.shadow_contribution * t;
    if (s.pass.mask) passes::add_shadow(s.pass, s.out.passes, s.shadow_contribution * t);
}

// Next-event estimation: samples a light and queues the shadow ray with the
// contribution it adds if unoccluded.
COHERENT_ALWAYS_INLINE void queue_shadow_ray(const PathContext& ctx, const PathSampler& ps, PathState& s,
                             const Bsdf& bsdf, const SurfacePoint& sp) {
    using D = PathDims;
    LightSample ls;
    const int v = vertex_index(s);
    if (!bsdf.has_non_delta() ||
        !ctx.lights->sample(sp.p, sp.n, bsdf.transmissive(), ps.get(D::bounce(v, D::kLightPick)),
                            ps.get(D::bounce(v, D::kLightU)), ps.get(D::bounce(v, D::kLightV)), ls))
        return;
    float bsdf_pdf = 0.0f;
    const Vec3f f = bsdf.eval(ls.wi, bsdf_pdf);
    if (is_black(f) || is_black(ls.li)) return;
    s.shadow = shadow_ray(*ctx.scene, sp, ls);
    const float w = ls.delta ? 1.0f : power_heuristic(ls.pdf, bsdf_pdf);
    s.shadow_contribution = clamp_contribution(s.throughput * f * ls.li * (w / ls.pdf), s.bounce, *ctx.settings);
    s.has_shadow = true;
    s.shadow_direct = s.bounce == 0;
    if (s.pass.mask) passes::queue_shadow(s.pass, bsdf, ls.wi, s.bounce);
    if (ctx.scene->features.transparent) trace_transparent_shadow(ctx, s);
}

// Russian roulette on the path throughput (Cycles: sqrt of the max
// component); returns whether the path survives, its throughput rescaled.
COHERENT_ALWAYS_INLINE bool survive_roulette(const PathContext& ctx, const PathSampler& ps,
                                             PathState& s) {
    using D = PathDims;
    if (s.bounce < ctx.settings->rr_min_bounces) return true;
    const float q = std::min(1.0f, std::sqrt(max_component(s.throughput)));
    if (!(ps.get(D::bounce(vertex_index(s), D::kRoulette)) < q)) return false;
    s.throughput = s.throughput / q;
    return true;
}

// Counts the bounce of BSDF sample `bs` and decides whether its ray is the
// path's last (a bounce limit or the integrator's continuation rule).
COHERENT_ALWAYS_INLINE void count_bounce(const RenderSettings& rs, PathState& s, const BsdfSample& bs) {
    ++s.bounce;
    switch (bs.type) {
        case RayType::Diffuse: ++s.diffuse_bounce; break;
        case RayType::Refraction: ++s.transmission_bounce; break;
        default: ++s.glossy_bounce; break;
    }
    if (s.bounce > rs.max_bounces || s.diffuse_bounce > rs.diffuse_bounces || s.glossy_bounce > rs.glossy_bounces ||
        s.transmission_bounce > rs.transmission_bounces || !may_continue(rs.integrator, bs))
        s.last_ray = true;
}

// A pass-through (transparency.h): the same ray goes on past the surface at
// parameter t, weighted; no bounce is counted, the ray keeps its type and
// MIS state. Beyond transparent_max_bounces the next ray is the last.
COHERENT_ALWAYS_INLINE void continue_through(const RenderSettings& rs, PathState& s, float t, const Vec3f& weight) {
    s.throughput *= weight;
    if (is_black(s.throughput) || !is_finite(s.throughput)) return;
    ++s.transparent_bounce;
    if (s.transparent_bounce >= rs.transparent_max_bounces) s.last_ray = true;
    s.ray.tmin = t;
    s.alive = true;
}

// A last ray (a bounce limit was reached) that meets a transparent surface
// still passes through it to the emission behind, as Cycles' paths do
// (only the surface's transparent closures scatter then).
COHERENT_ALWAYS_INLINE void last_ray_through(const RenderSettings& rs, PathState& s, const Material& mat, float t) {
    if (s.transparent_bounce >= rs.transparent_max_bounces) return;
    const Vec3f transparency = material_transparency(mat);
    if (!is_black(transparency)) continue_through(rs, s, t, transparency);
}

// Holdout (transparency.h): on the camera's path, takes the holdout weight
// off the pixel's alpha; returns whether the path ends (a full holdout).
COHERENT_ALWAYS_INLINE bool apply_holdout(PathState& s, const Material& mat) {
    const float h = material_holdout(mat);
    if (!(h > 0.0f) || s.bounce != 0) return false;
    s.out.alpha -= h * average(s.throughput);
    return h >= 1.0f;
}

// Samples the BSDF and sets up the next extension ray (s.alive), unless the
// sample fails or carries no throughput.
template <bool kGlass>
COHERENT_ALWAYS_INLINE void sample_next_ray(const PathContext& ctx, const PathSampler& ps, PathState& s,
                            const Bsdf& bsdf, const SurfacePoint& sp) {
    using D = PathDims;
    BsdfSample bs;
    const int v = vertex_index(s);
    if (!bsdf.sample(ps.get(D::bounce(v, D::kBsdfLobe)), ps.get(D::bounce(v, D::kBsdfU)),
                     ps.get(D::bounce(v, D::kBsdfV)), bs))
        return;
    if (bs.transparent) return continue_through(*ctx.settings, s, sp.t, bs.weight);
    if constexpr (!kGlass) {
        if (bs.type == RayType::Refraction) return;  // unreachable: no glass lobes exist
    }
    s.throughput *= bs.weight;
    if (is_black(s.throughput) || !is_finite(s.throughput)) return;
    if (s.pass.mask && s.bounce == 0) passes::first_bounce(s.pass, bsdf, bs);

    count_bounce(*ctx.settings, s, bs);
    // A last ray is traced only for the emission it may hit.
    if (s.last_ray && !ctx.scene->features.hittable_emitters) return;
    s.prev_pdf = bs.delta ? 0.0f : bs.pdf;
    s.prev_n = sp.n;
    s.prev_transmissive = bsdf.transmissive();
    s.ray.o = offset_ray_origin(sp.p, sp.p_error, sp.ng_f, bs.wi);
    s.ray.d = bs.wi;
    s.ray.tmin = kSpawnTmin;
    s.ray.tmax = kInf;
    s.type = bs.type;
    s.alive = true;
}

// Cycles' data and Col passes at the camera's first hit; the AO pass's own
// ray is traced here, one at a time, whatever the driver.
inline void record_first_hit_passes(const PathContext& ctx, const PathSampler& ps, PathState& s, const Hit& hit,
                                    const SurfacePoint& sp, const Bsdf& bsdf) {
    using D = PathDims;
    const float ao_distance = ctx.scene->data_passes.ao_distance > 0.0f ? ctx.scene->data_passes.ao_distance
                                                                         : ctx.ao_distance;
    const passes::FirstHit h{ctx.scene, &hit, sp.material, sp.p, sp.p_error, sp.n, sp.ng_f, dot(sp.n, sp.wo),
                             ctx.settings->width, ctx.settings->height};
    passes::record_first_hit(s.pass.mask, s.out.passes, h, bsdf, ps.get(D::bounce(0, D::kBsdfU)),
                             ps.get(D::bounce(0, D::kBsdfV)), ao_distance, [&](const Ray& r) {
                                 return ctx.bvh->occluded(r) || instance_occluded(ctx, s, r) ||
                                        motion_occluded(ctx, s, r);
                             });
}

}  // namespace shading

// Shades the result of tracing s.ray (found/hit as from Bvh::intersect).
// Precondition: s.alive and !s.has_shadow. Afterwards the path may have a
// shadow ray queued even when it ended (!s.alive): drivers resolve it either way.
template <bool kGlass, bool kLights>
inline void shade_hit(const PathContext& ctx, const PathSampler& ps, PathState& s, bool found,
                      const Hit& hit, const shading::PreShaded* pre = nullptr) {
    using namespace shading;
    const Scene& scene = *ctx.scene;
    s.alive = false;  // until a next ray is set up

    if constexpr (kLights) add_lights_passed(ctx, s, found, hit);
    if (!found) {
        shade_miss<kLights>(ctx, s);
        return;
    }
    SurfacePoint sp = pre ? pre->sp : surface_point(scene, s, hit);
    if (s.bounce == 0 && s.transparent_bounce == 0) {
        s.out.depth = dot(sp.p - scene.camera.position, scene.camera.forward);
        s.out.normal = sp.n;
    }
    if (ctx.settings->integrator == Integrator::AmbientOcclusion) {
        queue_ao_rays(ctx, s, sp);
        return;
    }

    std::optional<Material> scratch;
    const Vec3f interpolated_n = sp.n;
    if (pre && pre->material) sp.n = pre->n;
    const Material& mat = pre && pre->material ? *pre->material : material_at(ctx, s, hit, sp, scratch);
    if (s.features.pending) {
        record_emission_feature(s.features, mat.emission, s.out.albedo);
        record_surface_features(mat, sp.n, dot(sp.n, sp.wo), sp.t - s.ray.tmin, scene.camera, s.features, s.out.albedo,
                                s.out.denoising_normal, s.out.denoising_depth);
    }
    if (scene.features.holdout && apply_holdout(s, mat)) return;
    if (mat.is_emissive()) add_emission<kLights>(ctx, s, mat, sp);
    if (s.last_ray) {
        if (scene.features.transparent) last_ray_through(*ctx.settings, s, mat, sp.t);
        return;
    }

    const bool perturbed = sp.n.x != interpolated_n.x || sp.n.y != interpolated_n.y || sp.n.z != interpolated_n.z;
    const Bsdf bsdf(mat, sp.n, sp.ng_f, sp.wo, sp.front, kGlass, perturbed ? &interpolated_n : nullptr);
    if (s.pass.mask && s.bounce == 0) record_first_hit_passes(ctx, ps, s, hit, sp, bsdf);
    if (bsdf.empty()) return;
    if constexpr (kLights) queue_shadow_ray(ctx, ps, s, bsdf, sp);
    if (!survive_roulette(ctx, ps, s)) return;
    sample_next_ray<kGlass>(ctx, ps, s, bsdf, sp);
}

// A shaded path's occlusion rays: its shadow ray, or its ambient occlusion
// rays (never both: AO ends the path at its first hit). Drivers trace
// occlusion_ray(.., k) for k < occlusion_ray_count(s), in any order, then
// call resolve_occlusion() with how many were unoccluded, before tracing the
// path's next extension ray.
COHERENT_ALWAYS_INLINE int occlusion_ray_count(const PathState& s) { return s.has_shadow ? 1 : s.ao_rays; }

COHERENT_ALWAYS_INLINE Ray occlusion_ray(const PathContext& ctx, const PathSampler& ps,
                                         const PathState& s, int k) {
    return s.has_shadow ? s.shadow : ao_ray(ctx, ps, s, k);
}

// The shadow ray adds its contribution if unoccluded; the AO rays add
// 1 / ao_rays each. Afterwards the path has no occlusion ray queued.
COHERENT_ALWAYS_INLINE void resolve_occlusion(PathState& s, int unoccluded) {
    if (s.has_shadow) {
        if (unoccluded > 0) s.out.radiance += s.shadow_contribution;
        if (unoccluded > 0 && s.shadow_direct) s.out.direct += s.shadow_contribution;
        if (unoccluded > 0 && s.pass.mask) passes::add_shadow(s.pass, s.out.passes, s.shadow_contribution);
        s.has_shadow = false;
        return;
    }
    if (s.ao_rays > 0) s.out.radiance += Vec3f(float(unoccluded) / float(s.ao_rays));
    s.ao_rays = 0;
}

// The results of a path-major occlusion queue (streams, wavefront): the
// rays of each path consecutive, in occlusion_ray() order, one path after
// another; occluded[i] != 0 where ray i is occluded and path_of(i) is its
// path's state. Resolves every path of the queue.
template <class PathOf>
inline void resolve_occlusion_queue(const uint8_t* occluded, size_t rays, PathOf&& path_of) {
    for (size_t i = 0; i < rays;) {
        PathState& s = path_of(i);
        const size_t n = size_t(occlusion_ray_count(s));
        int unoccluded = 0;
        for (size_t k = 0; k < n; ++k) unoccluded += occluded[i + k] ? 0 : 1;
        resolve_occlusion(s, unoccluded);
        i += n;
    }
}

// The AO ray length: the setting, or a tenth of the scene's diagonal.
inline float resolve_ao_distance(const RenderSettings& rs, const Scene& scene) {
    if (rs.ao_distance > 0.0f && std::isfinite(rs.ao_distance)) return rs.ao_distance;
    const float d = 0.1f * length(scene.bounds().extent());
    return d > 0.0f && std::isfinite(d) ? d : 1.0f;
}

}  // namespace coherent
