// How a path feeds Cycles' light and data passes (film/passes.h defines
// them). path_state.h calls these at the few places where light reaches
// the camera, each call behind `if (s.pass.mask)`: with no pass enabled a
// path does no pass work at all and traces no extra ray, and its radiance is
// computed exactly as without passes (the passes only copy contributions).
#pragma once

#include <algorithm>
#include <cmath>
#include <string>

#include "../accel/bvh.h"
#include "../film/cryptomatte.h"
#include "../film/passes.h"
#include "../scene/scene.h"
#include "bsdf.h"
#include "ray_offset.h"

namespace coherent {

// Per path: the passes it fills, and which lobe its light belongs to
// (Cycles' pass_diffuse_weight / pass_glossy_weight; transmission is the rest).
struct PassState {
    PassMask mask = 0;
    Vec3f diffuse_weight{0.0f}, glossy_weight{0.0f};  // from the first bounce's direction
    // The queued shadow ray's split, and whether it left the first hit.
    Vec3f shadow_diffuse{0.0f}, shadow_glossy{0.0f};
    bool shadow_direct = false;
};

namespace passes {

// Cycles' bsdf_eval_pass_*_weight: per channel share of the evaluation, 0 where it is 0.
inline void split_weights(const Vec3f& sum, const Vec3f& diffuse, const Vec3f& glossy, Vec3f& wd, Vec3f& wg) {
    const auto share = [](float part, float whole) { return whole != 0.0f ? part / whole : 0.0f; };
    wd = Vec3f(share(diffuse.x, sum.x), share(diffuse.y, sum.y), share(diffuse.z, sum.z));
    wg = Vec3f(share(glossy.x, sum.x), share(glossy.y, sum.y), share(glossy.z, sum.z));
}

// Light `c` that scattered at the first hit with lobe split (wd, wg).
inline void add_scattered(PassSample& out, const Vec3f& c, const Vec3f& wd, const Vec3f& wg, bool direct) {
    const Vec3f wt = Vec3f(1.0f) - wd - wg;
    out.add(direct ? RenderPass::DiffuseDirect : RenderPass::DiffuseIndirect, c * wd);
    out.add(direct ? RenderPass::GlossyDirect : RenderPass::GlossyIndirect, c * wg);
    out.add(direct ? RenderPass::TransmissionDirect : RenderPass::TransmissionIndirect, c * wt);
}

// Emission, a lamp or the world met by the path's ray after `bounce` bounces
// (contribution c, as added to Combined): Emit or Env when the camera sees
// it (bounce 0), else the first hit's lobes, direct after one bounce.
inline void add_hit_light(const PassState& st, PassSample& out, const Vec3f& c, int bounce, bool world) {
    if (bounce == 0) out.add(world ? RenderPass::Environment : RenderPass::Emission, c);
    else add_scattered(out, c, st.diffuse_weight, st.glossy_weight, bounce == 1);
}

// Next-event estimation from the vertex after `bounce` bounces, towards wi.
inline void queue_shadow(PassState& st, const Bsdf& bsdf, const Vec3f& wi, int bounce) {
    st.shadow_direct = bounce == 0;
    if (bounce > 0) {
        st.shadow_diffuse = st.diffuse_weight;
        st.shadow_glossy = st.glossy_weight;
        return;
    }
    Vec3f sum, diffuse, glossy;
    bsdf.eval_split(wi, sum, diffuse, glossy);
    split_weights(sum, diffuse, glossy, st.shadow_diffuse, st.shadow_glossy);
}

inline void add_shadow(const PassState& st, PassSample& out, const Vec3f& c) {
    add_scattered(out, c, st.shadow_diffuse, st.shadow_glossy, st.shadow_direct);
}

// The first bounce's sample decides the lobe of everything the path brings
// later: a delta sample its lobe alone (Cycles evaluates only the sampled
// singular closure), otherwise every lobe's share in its direction.
inline void first_bounce(PassState& st, const Bsdf& bsdf, const BsdfSample& bs) {
    if (bs.delta) {
        st.diffuse_weight = Vec3f(bs.lobe == LobeKind::Diffuse ? 1.0f : 0.0f);
        const bool glossy =
            bs.lobe == LobeKind::Reflection || (bs.lobe == LobeKind::Glass && bs.type != RayType::Refraction);
        st.glossy_weight = Vec3f(glossy ? 1.0f : 0.0f);
        return;
    }
    Vec3f sum, diffuse, glossy;
    bsdf.eval_split(bs.wi, sum, diffuse, glossy);
    split_weights(sum, diffuse, glossy, st.diffuse_weight, st.glossy_weight);
}

// The camera's first hit: what the data passes and Col passes read there.
struct FirstHit {
    const Scene* scene;
    const Hit* hit;
    uint32_t material;
    Vec3f p, p_error, n, ng_f;
    float cos_wo;  // dot(n, wo)
    int width, height;  // the full frame, in pixels (Vector)
};

inline uint32_t hit_object(const Scene& scene, const Hit& hit) {
    return hit.instance != kInvalidPrim ? scene.instances[hit.instance].object : scene.object_of[hit.prim];
}

inline float object_pass_index(const Scene& scene, const Hit& hit) {
    const uint32_t object = hit_object(scene, hit);
    const auto& v = scene.data_passes.object_pass_index;
    return object < v.size() ? v[object] : 0.0f;
}

// The names' Cryptomatte ids (hashed per sample: a few ns a name, and only
// when Cryptomatte is on).
inline void record_cryptomatte_ids(const Scene& scene, const Hit& hit, uint32_t material, PassSample& out) {
    const uint32_t object = hit_object(scene, hit);
    const DataPassInputs& d = scene.data_passes;
    const auto name_of = [&](const std::vector<std::string>& names) -> const std::string& {
        return object < names.size() && !names[object].empty() ? names[object] : scene.object_names[object];
    };
    out.crypto_id[0] = cryptomatte_id(name_of(d.crypto_object_names));
    out.crypto_id[1] = cryptomatte_id(scene.materials[material].name);
    out.crypto_id[2] = cryptomatte_id(name_of(d.crypto_asset_names));
}

// Cycles' mist: camera distance (view-axis for orthographic cameras) mapped
// through start, depth and falloff; the film stores 1 - mist per sample.
inline float mist_complement(const Scene& scene, const Vec3f& p) {
    const Camera& cam = scene.camera;
    const DataPassInputs& d = scene.data_passes;
    const float dist =
        cam.projection == Projection::Orthographic ? dot(p - cam.position, cam.forward) : length(p - cam.position);
    float mist = d.mist_depth > 0.0f ? std::clamp((dist - d.mist_start) / d.mist_depth, 0.0f, 1.0f)
                                     : (dist >= d.mist_start ? 1.0f : 0.0f);
    if (d.mist_falloff == 2.0f) mist *= mist;
    else if (d.mist_falloff == 0.5f) mist = std::sqrt(mist);
    else if (d.mist_falloff != 1.0f) mist = std::pow(mist, d.mist_falloff);
    return 1.0f - mist;
}

// Cycles' primitive_uv: the active render UV map ("" in uv_names, which the
// add-on requests when the pass is on) at the hit, (u, v, 1); 0 without it.
// On an instance the prototype's UVs (object space, same corners).
inline Vec3f first_hit_uv(const Scene& scene, const Hit& hit) {
    const auto& names = scene.shading.uv_names;
    const size_t layer = size_t(std::find(names.begin(), names.end(), std::string()) - names.begin());
    const std::vector<std::vector<Vec2f>>& uvs =
        hit.instance != kInvalidPrim ? scene.prototypes[scene.instances[hit.instance].prototype].uvs
                                     : scene.shading.uvs;
    if (layer >= uvs.size() || uvs[layer].size() < 3 * size_t(hit.prim) + 3) return Vec3f(0.0f);
    const Vec2f* c = &uvs[layer][3 * size_t(hit.prim)];
    const float w = 1.0f - hit.u - hit.v;
    return {c[0].x * w + c[1].x * hit.u + c[2].x * hit.v, c[0].y * w + c[1].y * hit.u + c[2].y * hit.v, 1.0f};
}

// Cycles' raster position of world point p seen from camera frame f through
// `cam`'s lens: pixels of the full frame, x right, y up from the bottom edge.
// The inverse of generate_camera_ray's image-plane mapping.
inline Vec2f raster_position(const Camera& cam, const CameraFrame& f, const Vec3f& p, int width, int height) {
    const Vec3f v = p - f.position;
    float px = dot(v, f.right), py = dot(v, f.up);
    if (cam.projection == Projection::Perspective) {
        const float z = dot(v, f.forward);
        px /= z, py /= z;
    }
    const float larger = 2.0f * std::max(cam.half_width, cam.half_height);
    const float sx = (px - cam.shift_x * larger) / cam.half_width;
    const float sy = (py - cam.shift_y * larger) / cam.half_height;
    return {0.5f * (sx + 1.0f) * float(width), 0.5f * (sy + 1.0f) * float(height)};
}

// The frame motion of what `hit` hit, or null where it stands still.
inline const FrameMotion* hit_frame_motion(const Scene& scene, const Hit& hit) {
    const DataPassInputs& d = scene.data_passes;
    if (hit.instance != kInvalidPrim)
        return hit.instance < d.instance_frame_motion.size() ? &d.instance_frame_motion[hit.instance] : nullptr;
    const uint32_t object = scene.object_of[hit.prim];
    return object < d.object_frame_motion.size() ? &d.object_frame_motion[object] : nullptr;
}

// Cycles' primitive_motion_vector for a point p on what `hit` hit, in a
// width x height frame: (previous - now, now - next) raster positions.
inline void record_vector(const Scene& scene, const Hit& hit, const Vec3f& p, int width, int height,
                          PassSample& out) {
    const Camera& cam = scene.camera;
    const DataPassInputs& d = scene.data_passes;
    const CameraFrame now{cam.position, cam.right, cam.up, cam.forward};
    const FrameMotion* m = hit_frame_motion(scene, hit);
    const Vec2f c = raster_position(cam, now, p, width, height);
    const Vec2f a = raster_position(cam, d.camera_moves ? d.camera_previous : now, m ? m->to_previous.point(p) : p,
                                    width, height);
    const Vec2f b =
        raster_position(cam, d.camera_moves ? d.camera_next : now, m ? m->to_next.point(p) : p, width, height);
    out.set(RenderPass::Vector, a.x - c.x, a.y - c.y, c.x - b.x, c.y - b.y);
}

// Col, Mist, UV, Position, Index and AO at the camera's first hit. The AO ray
// (directions from u1, u2, ao_distance long) is traced by `occluded(ray)`.
template <class Occluded>
inline void record_first_hit(PassMask mask, PassSample& out, const FirstHit& h, const Bsdf& bsdf, float u1, float u2,
                             float ao_distance, Occluded&& occluded) {
    const Scene& scene = *h.scene;
    Vec3f col[3] = {Vec3f(0.0f), Vec3f(0.0f), Vec3f(0.0f)};  // diffuse, glossy, transmission
    for (int i = 0; i < bsdf.lobe_count(); ++i) {
        const Lobe& l = bsdf.lobe(i);
        if (l.kind == LobeKind::Diffuse) col[0] += l.weight;
        else if (l.kind == LobeKind::Reflection) col[1] += l.weight;
        else {
            // Cycles' GGX glass: a reflection closure of weight F and a
            // refraction closure of weight tint (1 - F), F at the view angle.
            const float f = fresnel_dielectric(h.cos_wo, l.eta);
            col[1] += l.weight * f;
            col[2] += l.weight * l.tint * std::max(1e-4f, 1.0f - f);
        }
    }
    out.add(RenderPass::DiffuseColor, col[0]);
    out.add(RenderPass::GlossyColor, col[1]);
    out.add(RenderPass::TransmissionColor, col[2]);
    if (mask & pass_bit(RenderPass::Mist)) out.set(RenderPass::Mist, mist_complement(scene, h.p));
    if (mask & pass_bit(RenderPass::UV)) out.set(RenderPass::UV, first_hit_uv(scene, *h.hit));
    out.set(RenderPass::Position, h.p);
    out.set(RenderPass::IndexOB, object_pass_index(scene, *h.hit));
    const auto& ma = scene.data_passes.material_pass_index;
    out.set(RenderPass::IndexMA, h.material < ma.size() ? ma[h.material] : 0.0f);
    if (mask & kCryptomatteIds) record_cryptomatte_ids(scene, *h.hit, h.material, out);
    if (mask & pass_bit(RenderPass::Vector)) record_vector(scene, *h.hit, h.p, h.width, h.height, out);
    if (!(mask & pass_bit(RenderPass::AO))) return;
    // Cycles: cosine about the shading normal, kept only on the geometric side.
    const Vec3f local = sample_cosine_hemisphere(u1, u2);
    Vec3f t, b;
    make_basis(h.n, t, b);
    Ray r;
    r.d = t * local.x + b * local.y + h.n * local.z;
    if (!(dot(r.d, h.ng_f) > 0.0f)) return;
    r.o = offset_ray_origin(h.p, h.p_error, h.ng_f, r.d);
    r.tmin = std::numeric_limits<float>::min();
    r.tmax = ao_distance;
    if (!occluded(r)) out.add(RenderPass::AO, Vec3f(1.0f));
}

}  // namespace passes
}  // namespace coherent
