// Cycles' render passes (Blender 3.4 names and meanings) beyond Combined,
// Depth and Normal: which a render accumulates (a PassMask), and the values
// one camera sample contributes to them (PassSample).
//
// Light passes, as Cycles 3.4 defines them (kernel/film/light_passes.h):
//   Emit: emission of the surface the camera sees. Env: the world seen by
//   the camera (also under a transparent film, as in Cycles).
//   <Lobe>Dir: light that reaches the camera after exactly one scattering
//   at the first hit: next-event estimation there, and emission, the world
//   or a lamp met by the first bounce ray. <Lobe>Ind: everything later.
//   Which lobe light belongs to is decided at the first hit, per channel,
//   by the share of the BSDF evaluation (Cycles' bsdf_eval diffuse/glossy
//   split) in the direction the light came from (next-event estimation) or
//   the first bounce went (everything after it); transmission takes what
//   diffuse and glossy leave.
//   <Lobe>Col: the closures' weights at the first hit (Cycles'
//   shader_bsdf_diffuse/glossy/transmission): diffuse = base colour x
//   diffuse weight, glossy = the specular layer's weight. Glass is split as
//   Cycles' (default, GGX) glass is: a reflection closure, glossy, of weight
//   F and a refraction closure, transmission, of weight tint x (1 - F),
//   with F the dielectric Fresnel at the view angle; so light reflected by
//   glass is Glossy, light refracted is Transmission.
//   Cycles writes Dir and Ind divided by Col (Film resolves them so), so
//   that Combined = sum over lobes of (Dir + Ind) x Col + Emit + Env.
// Data passes (kernel/film/data_passes.h), at the camera's first hit:
//   AO: one ray per sample, cosine-distributed about the shading normal
//   (only where it leaves the geometric surface's side), the World's AO
//   distance long; 1 where unoccluded. Mist: 1 - (1 - mist) averaged over
//   samples, mist = clamp((distance - start) / depth)^falloff, 1 for
//   samples that see the world. UV: the active render UV map at the hit,
//   (u, v, 1), or 0 without one (Cycles' primitive_uv), averaged over all
//   samples (0 for those that see the world). Position, IndexOB and
//   IndexMA: from the first sample only (Cycles writes them at sample 0), 0
//   where nothing was hit.
//   Vector (Cycles' primitive_motion_vector): in raster pixels (x right, y up
//   from the bottom row, Cycles' raster space), (previous - now, now - next)
//   of where the hit point is seen: the point carried by its object's motion
//   to the previous and the next frame, projected by the camera of that frame
//   (with this frame's lens). Averaged over the samples that hit geometry.
// Cycles 3.4 has no Shadow pass (removed with Cycles X), so neither do we.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "../core/vec.h"

namespace coherent {

// The passes of this file, in PassType order (film.h) starting at
// PassType::FirstRenderPass; bit i of a PassMask enables pass i.
enum class RenderPass : uint8_t {
    DiffuseDirect,
    DiffuseIndirect,
    DiffuseColor,
    GlossyDirect,
    GlossyIndirect,
    GlossyColor,
    TransmissionDirect,
    TransmissionIndirect,
    TransmissionColor,
    Emission,
    Environment,
    AO,
    Mist,
    UV,
    Position,
    IndexOB,
    IndexMA,
    Vector,
    Count
};
constexpr int kRenderPassCount = int(RenderPass::Count);

using PassMask = uint32_t;
constexpr PassMask pass_bit(RenderPass p) { return PassMask(1) << uint32_t(p); }
constexpr PassMask kLightPassMask = pass_bit(RenderPass::Environment) * 2 - 1;  // DiffuseDirect..Environment
// Not a pass: paths record their first hit's Cryptomatte ids (cryptomatte.h).
constexpr PassMask kCryptomatteIds = PassMask(1) << 31;

struct RenderPassInfo {
    const char* name;     // Blender (Cycles) render-result pass name
    const char* cli_name; // lower-case, for --passes
    int channels;
    const char* chan_id;  // Blender channel ids
    // Float offset of the pass's values in PassSample::v.
    int offset;
};
const RenderPassInfo& render_pass_info(RenderPass p);

// "diffdir,glossind" or Blender names ("DiffDir"): the mask; throws
// std::invalid_argument naming an unknown pass.
PassMask pass_mask_from_names(const std::vector<std::string>& names);

// One camera sample's contributions to every pass (zero where not enabled).
struct PassSample {
    static constexpr int kFloats = 3 * 12 + 1 + 3 + 3 + 2 + 4;
    float v[kFloats] = {};
    float crypto_id[3] = {};  // object, material, asset of the first hit; 0 = none (cryptomatte.h)
    void add(RenderPass p, const Vec3f& c) {
        float* d = v + render_pass_info(p).offset;
        d[0] += c.x, d[1] += c.y, d[2] += c.z;
    }
    void set(RenderPass p, float x) { v[render_pass_info(p).offset] = x; }
    void set(RenderPass p, const Vec3f& c) {
        float* d = v + render_pass_info(p).offset;
        d[0] = c.x, d[1] = c.y, d[2] = c.z;
    }
    void set(RenderPass p, float x, float y, float z, float w) {
        float* d = v + render_pass_info(p).offset;
        d[0] = x, d[1] = y, d[2] = z, d[3] = w;
    }
};


}  // namespace coherent
