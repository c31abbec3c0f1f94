// The shading-point BSDF: a material (weighted sum of principled closures)
// expanded into at most 12 lobes in one local frame.
//
// Conventions (all directions point away from the surface):
//  - eval() returns f(wo, wi) * |cos(n, wi)| and the solid-angle pdf with which
//    sample() would produce wi (mixture over the non-delta lobes).
//  - sample() returns weight = f * |cos| / pdf, or for a delta lobe the lobe's
//    contribution divided by its selection probability.
//  - Sampled directions must lie on wo's side of BOTH the shading and the
//    geometric normal (reflection), or on the other side of both
//    (transmission); others are never sampled. eval() judges by the shading
//    normal alone, as Cycles 3.4 does: light that grazes a smooth-shaded
//    surface from below its flat triangle still shades it, and the shadow ray
//    (from the smooth surface, render/shadow_terminator.h) decides whether it
//    arrives. Judging by both normals there left dark triangles along the
//    terminator of curved, sunlit meshes that Cycles shades smoothly.
//  - Cycles 3.4 Principled conventions: diffuse and specular are added (not
//    layered); cspec0 = 0.08 specular (1 - metallic) + base_color metallic,
//    shaped towards white by the normalised dielectric Fresnel of the ior
//    whose F0 is 0.08 specular; separable Smith G; glass reflection white,
//    refraction tinted. Measured directional albedo vs Cycles (world-lit
//    plane, view 0/60/80 deg): metal 0.997-1.001, dielectric rough 0.5
//    0.979-0.995, rough glass (60/80 deg) 0.99. Diffuse: Lambert (Diffuse
//    BSDF node) or Cycles' principled diffuse (Principled BSDF, glTF), see
//    principled_diffuse().
//  - Mix/Add: eval = sum_i w_i f_i; lobe i is picked with probability
//    proportional to an albedo estimate, pdf = sum_i p_i pdf_i. Weights may sum
//    above 1 (Add), the sample weight then exceeds the single-lobe weight.
#pragma once

#include <cstdint>

#include "../scene/material.h"
#include "microfacet.h"
#include "stats.h"

namespace coherent {

// Transparent: straight through (delta), a pass-through rather than a bounce
// (BsdfSample::transparent). Translucent: Lambert on the far side.
enum class LobeKind : uint8_t { Diffuse, Reflection, Glass, Transparent, Translucent };

struct Lobe {
    LobeKind kind = LobeKind::Diffuse;
    bool sharp = false;     // delta lobe (mirror / smooth glass)
    Vec3f weight{0.0f};     // closure weight x lobe weight (x base colour for diffuse)
    Vec3f f0{0.0f};         // Reflection: reflectance at normal incidence (Cycles cspec0)
    float fresnel_ior = 1.0f, fresnel_f0 = 0.0f;  // Reflection: Fresnel curve shaping f0 -> 1
    Vec3f tint{1.0f};       // Glass: colour of refracted light
    float alpha = 0.0f;     // GGX alpha = roughness^2
    float eta = 1.0f;       // Glass: eta_transmitted / eta_incident for wo's side
    float retro = -1.0f;    // Diffuse: principled roughness (retro-reflection), < 0 for Lambert
    float pick = 0.0f;      // selection probability
};

struct BsdfSample {
    Vec3f wi;
    Vec3f weight;
    float pdf = 0.0f;       // 0 for delta samples
    bool delta = false;
    bool transparent = false;  // the Transparent lobe: the ray goes on unchanged (render/transparency.h)
    RayType type = RayType::Diffuse;
    LobeKind lobe = LobeKind::Diffuse;  // the lobe sampled (light passes)
};

inline Vec3f sample_cosine_hemisphere(float u1, float u2) {
    // Concentric disk mapping (Shirley-Chiu) lifted to the hemisphere.
    const float a = 2.0f * u1 - 1.0f, b = 2.0f * u2 - 1.0f;
    float r, phi;
    if (a == 0.0f && b == 0.0f) {
        r = 0.0f;
        phi = 0.0f;
    } else if (a * a > b * b) {
        r = a;
        phi = (kPi / 4.0f) * (b / a);
    } else {
        r = b;
        phi = (kPi / 2.0f) - (kPi / 4.0f) * (a / b);
    }
    const float x = r * std::cos(phi), y = r * std::sin(phi);
    return {x, y, std::sqrt(std::max(0.0f, 1.0f - x * x - y * y))};
}

class Bsdf {
public:
    static constexpr int kMaxLobes = 12;

    // n: shading normal facing wo; ng: geometric normal facing wo; front:
    // whether wo is on the front (winding) side, which decides the glass eta.
    // with_glass = false drops transmission lobes (the kernel was specialised
    // for a scene without glass, where no such lobe can exist anyway).
    // unperturbed: where a shader program replaced the interpolated normal
    // (normal map), the interpolated one, for Cycles' bump shadowing term.
    Bsdf(const Material& mat, const Vec3f& n, const Vec3f& ng, const Vec3f& wo, bool front, bool with_glass,
         const Vec3f* unperturbed = nullptr) : n_(n), ng_(ng) {
        make_basis(n_, t_, b_);
        wo_ = to_local(wo);
        if (unperturbed) {
            bump_ = true;
            n_base_ = to_local(*unperturbed);
        }
        if (!(wo_.z > 0.0f)) return;  // degenerate frame: black
        float total = 0.0f;
        for (int c = 0; c < mat.closure_count && c < 4; ++c) {
            const float w = mat.weights[c];
            if (!(w > 0.0f)) continue;
            const Closure& cl = mat.closures[c];
            if (cl.kind != ClosureKind::Principled) {
                add_non_principled(cl, w);
                continue;
            }
            const ClosureLobes lw = closure_lobes(cl);
            const float rough = std::clamp(cl.roughness, 0.0f, 1.0f);
            const bool sharp = rough <= kSharpRoughness;
            const float alpha = std::max(rough * rough, 1e-4f);
            if (lw.diffuse > 0.0f && !is_black(cl.base_color)) {
                Lobe& l = lobes_[count_++];
                l.kind = LobeKind::Diffuse;
                l.weight = cl.base_color * (w * lw.diffuse);
                l.retro = cl.principled_diffuse ? rough : -1.0f;
                l.pick = luminance(l.weight);
            }
            if (lw.specular > 0.0f) {
                const float metallic = std::clamp(cl.metallic, 0.0f, 1.0f);
                Lobe& l = lobes_[count_++];
                l.kind = LobeKind::Reflection;
                l.sharp = sharp;
                l.alpha = alpha;
                l.weight = Vec3f(w * lw.specular);
                // Cycles: cspec0 = 0.08 * specular * (1 - metallic) + base_color * metallic.
                const float spec = std::clamp(cl.specular, 0.0f, 1.0f);
                l.f0 = Vec3f(0.08f * spec * (1.0f - metallic)) + cl.base_color * metallic;
                // Cycles: ior = 2 / (1 - sqrt(0.08 specular)) - 1, the dielectric whose F0 is 0.08 specular.
                l.fresnel_ior = 2.0f / (1.0f - std::sqrt(0.08f * spec)) - 1.0f;
                l.fresnel_f0 = fresnel_dielectric(1.0f, l.fresnel_ior);
                l.pick = luminance(l.weight * fresnel_of(l, wo_.z));
            }
            if (with_glass && lw.transmission > 0.0f) {
                Lobe& l = lobes_[count_++];
                l.kind = LobeKind::Glass;
                l.sharp = sharp;
                l.alpha = alpha;
                l.weight = Vec3f(w * lw.transmission);
                l.tint = cl.base_color;
                const float ior = std::max(cl.ior, 1.0001f);
                l.eta = front ? ior : 1.0f / ior;
                l.pick = luminance(l.weight) * std::max(0.25f, luminance(cl.base_color));
                transmissive_ = true;
            }
        }
        for (int i = 0; i < count_; ++i) total += lobes_[i].pick;
        if (!(total > 0.0f)) {
            count_ = 0;
            return;
        }
        for (int i = 0; i < count_; ++i) {
            lobes_[i].pick /= total;
            if (!lobes_[i].sharp) has_non_delta_ = true;
        }
    }

    bool empty() const { return count_ == 0; }
    bool has_non_delta() const { return has_non_delta_; }
    bool transmissive() const { return transmissive_; }
    const Vec3f& normal() const { return n_; }

    Vec3f eval(const Vec3f& wi_world, float& pdf) const {
        pdf = 0.0f;
        Vec3f f(0.0f);
        const Vec3f wi = to_local(wi_world);
        const bool reflect_ok = wi.z > 0.0f;
        if (!reflect_ok && !(wi.z < 0.0f)) return f;
        for (int i = 0; i < count_; ++i) {
            const Lobe& l = lobes_[i];
            if (l.sharp) continue;
            float lobe_pdf = 0.0f;
            const Vec3f v = eval_lobe(l, wi, reflect_ok, lobe_pdf);
            f += v;
            pdf += l.pick * lobe_pdf;
        }
        return f;
    }

    // Light passes (render/pass_accumulation.h): eval()'s f split into
    // diffuse lobes and reflection (reflection lobes, and glass towards wo's
    // side); the rest is transmission.
    void eval_split(const Vec3f& wi_world, Vec3f& sum, Vec3f& diffuse, Vec3f& glossy) const {
        sum = diffuse = glossy = Vec3f(0.0f);
        const Vec3f wi = to_local(wi_world);
        const bool reflect_ok = wi.z > 0.0f;
        if (!reflect_ok && !(wi.z < 0.0f)) return;
        for (int i = 0; i < count_; ++i) {
            if (lobes_[i].sharp) continue;
            float lobe_pdf = 0.0f;
            const Vec3f v = eval_lobe(lobes_[i], wi, reflect_ok, lobe_pdf);
            sum += v;
            if (lobes_[i].kind == LobeKind::Diffuse) diffuse += v;
            else if (lobes_[i].kind == LobeKind::Reflection || reflect_ok) glossy += v;
        }
    }
    int lobe_count() const { return count_; }
    const Lobe& lobe(int i) const { return lobes_[i]; }

    // u_lobe picks the lobe (and, rescaled, reflection vs refraction in glass).
    bool sample(float u_lobe, float u1, float u2, BsdfSample& s) const {
        if (count_ == 0) return false;
        int i = 0;
        float cdf = 0.0f;
        for (; i < count_ - 1; ++i) {
            if (u_lobe < cdf + lobes_[i].pick) break;
            cdf += lobes_[i].pick;
        }
        const Lobe& l = lobes_[i];
        const float u_sub = std::clamp((u_lobe - cdf) / l.pick, 0.0f, 0.99999994f);
        s.lobe = l.kind;

        Vec3f wi;
        switch (l.kind) {
            case LobeKind::Diffuse:
                wi = sample_cosine_hemisphere(u1, u2);
                s.type = RayType::Diffuse;
                break;
            case LobeKind::Translucent:
                wi = -sample_cosine_hemisphere(u1, u2);
                s.type = RayType::Diffuse;  // Cycles counts it as a diffuse bounce
                break;
            case LobeKind::Transparent:
                s.wi = -from_local(wo_);
                s.delta = true;
                s.pdf = 0.0f;
                s.weight = l.weight / l.pick;
                s.transparent = true;
                return true;
            case LobeKind::Reflection:
                if (l.sharp) {
                    wi = Vec3f(-wo_.x, -wo_.y, wo_.z);
                    s.type = RayType::Reflection;
                    return finish_delta(wi, l.weight * fresnel_of(l, wo_.z) / l.pick, s);
                }
                wi = reflect(wo_, ggx_sample_vndf(wo_, l.alpha, u1, u2));
                s.type = RayType::Glossy;
                break;
            case LobeKind::Glass: {
                const Vec3f m = l.sharp ? Vec3f(0.0f, 0.0f, 1.0f) : ggx_sample_vndf(wo_, l.alpha, u1, u2);
                const float fr = fresnel_dielectric(dot(wo_, m), l.eta);
                if (u_sub < fr || !refract(wo_, m, l.eta, wi)) {
                    wi = reflect(wo_, m);
                    s.type = l.sharp ? RayType::Reflection : RayType::Glossy;
                    if (l.sharp) return finish_delta(wi, l.weight / l.pick, s);
                } else {
                    s.type = RayType::Refraction;
                    if (l.sharp) return finish_delta(wi, l.weight * l.tint / l.pick, s);
                }
                break;
            }
        }
        s.wi = from_local(wi);
        s.delta = false;
        // A sampled direction must leave on the geometric side its local
        // frame says (Cycles' samplers test Ng likewise), or the path would
        // pass through the surface; eval() alone does not check it.
        const float ng_dot = dot(s.wi, ng_);
        if (wi.z > 0.0f ? !(ng_dot > 0.0f) : !(ng_dot < 0.0f)) return false;
        const Vec3f f = eval(s.wi, s.pdf);
        if (!(s.pdf > 0.0f)) return false;
        s.weight = f / s.pdf;
        return true;
    }

    // Maps world <-> local shading frame (z = shading normal).
    Vec3f to_local(const Vec3f& w) const { return {dot(w, t_), dot(w, b_), dot(w, n_)}; }
    Vec3f from_local(const Vec3f& w) const { return t_ * w.x + b_ * w.y + n_ * w.z; }

private:
    // A Transparent, Translucent or Holdout closure of weight w (a holdout
    // scatters nothing: shading reads its weight off the material).
    void add_non_principled(const Closure& cl, float w) {
        if (cl.kind == ClosureKind::Holdout || is_black(cl.base_color)) return;
        Lobe& l = lobes_[count_++];
        l.weight = cl.base_color * w;
        l.pick = luminance(l.weight);
        if (cl.kind == ClosureKind::Transparent) {
            l.kind = LobeKind::Transparent;
            l.sharp = true;
        } else {
            l.kind = LobeKind::Translucent;
            transmissive_ = true;
        }
    }

    static Vec3f fresnel_of(const Lobe& l, float cos_i) {
        return fresnel_interpolated(l.f0, cos_i, l.fresnel_ior, l.fresnel_f0);
    }

    bool finish_delta(const Vec3f& wi_local, const Vec3f& weight, BsdfSample& s) const {
        s.wi = from_local(wi_local);
        s.delta = true;
        s.pdf = 0.0f;
        s.weight = weight;
        // Geometric consistency: the delta direction must leave on the side
        // its local frame says, or the path would leak through the surface.
        const float ng_dot = dot(s.wi, ng_);
        if (wi_local.z > 0.0f ? !(ng_dot > 0.0f) : !(ng_dot < 0.0f)) return false;
        return true;
    }

    // Cycles 3.4 calculate_principled_diffuse_brdf() relative to Lambert: the
    // Disney diffuse (1 + (F90 - 1) FL)(1 + (F90 - 1) FV) with F90 = 0.5 + RR,
    // RR = 2 roughness cos^2(theta_d) = roughness (1 + L.V), FX = (1 - cos)^5.
    // Sampled by the cosine lobe like Lambert.
    float principled_diffuse(float roughness, const Vec3f& wi) const {
        auto schlick = [](float c) {
            const float m = std::clamp(1.0f - c, 0.0f, 1.0f);
            const float m2 = m * m;
            return m2 * m2 * m;
        };
        const float fl = schlick(wi.z), fv = schlick(wo_.z);
        const float rr = roughness * (dot(wi, wo_) + 1.0f);
        return (1.0f - 0.5f * fl) * (1.0f - 0.5f * fv) + rr * (fl + fv + fl * fv * (rr - 1.0f));
    }

    // Cycles' bump_shadowing_term: diffuse light on a normal-mapped point
    // fades out where the light is below the unperturbed surface, without
    // the hard terminator the perturbed normal alone would give.
    float bump_shadowing(const Vec3f& wi) const {
        const float denom = wi.z * n_base_.z;
        const float g = denom != 0.0f ? dot(n_base_, wi) / denom : 0.0f;
        if (g >= 1.0f) return 1.0f;
        if (g < 0.0f) return 0.0f;
        const float g2 = g * g;
        return -g2 * g + g2 + g;
    }

    Vec3f eval_lobe(const Lobe& l, const Vec3f& wi, bool reflect_side, float& pdf) const {
        pdf = 0.0f;
        switch (l.kind) {
            case LobeKind::Diffuse: {
                if (!reflect_side) return Vec3f(0.0f);
                pdf = wi.z * kInvPi;
                const Vec3f f = l.weight * (wi.z * kInvPi * (l.retro < 0.0f ? 1.0f : principled_diffuse(l.retro, wi)));
                return bump_ ? f * bump_shadowing(wi) : f;
            }
            case LobeKind::Translucent: {
                if (reflect_side) return Vec3f(0.0f);
                pdf = -wi.z * kInvPi;
                return l.weight * pdf;
            }
            case LobeKind::Transparent: return Vec3f(0.0f);  // delta: never evaluated
            case LobeKind::Reflection: {
                if (!reflect_side) return Vec3f(0.0f);
                const Vec3f m = normalize(wo_ + wi);
                const float wom = dot(wo_, m);
                if (!(wom > 0.0f)) return Vec3f(0.0f);
                const float d = ggx_d(m, l.alpha);
                pdf = ggx_vndf_pdf(wo_, m, l.alpha) / (4.0f * wom);
                return l.weight * fresnel_of(l, wom) * (d * ggx_g2(wo_, wi, l.alpha) / (4.0f * wo_.z));
            }
            case LobeKind::Glass: {
                if (reflect_side) {
                    const Vec3f m = normalize(wo_ + wi);
                    const float wom = dot(wo_, m);
                    if (!(wom > 0.0f)) return Vec3f(0.0f);
                    const float fr = fresnel_dielectric(wom, l.eta);
                    const float d = ggx_d(m, l.alpha);
                    pdf = fr * ggx_vndf_pdf(wo_, m, l.alpha) / (4.0f * wom);
                    return l.weight * (fr * d * ggx_g2(wo_, wi, l.alpha) / (4.0f * wo_.z));
                }
                // Generalised half vector of refraction, oriented to wo's side.
                Vec3f m = wo_ + wi * l.eta;
                const float len = length(m);
                if (!(len > 0.0f)) return Vec3f(0.0f);
                m = m / len;
                if (m.z < 0.0f) m = -m;
                const float wom = dot(wo_, m), wim = dot(wi, m);
                if (!(wom > 0.0f) || !(wim < 0.0f)) return Vec3f(0.0f);
                const float denom = wom + l.eta * wim;
                const float fr = fresnel_dielectric(wom, l.eta);
                if (fr >= 1.0f) return Vec3f(0.0f);
                const float d = ggx_d(m, l.alpha);
                const float jacobian = l.eta * l.eta * std::fabs(wim) / (denom * denom);
                pdf = (1.0f - fr) * ggx_vndf_pdf(wo_, m, l.alpha) * jacobian;
                // f * |cos_i| = tint (1-F) D G2 |wo.m| |wi.m| eta^2 / (|cos_o| denom^2): the
                // sample weight is then tint * G2/G1 with no eta^2 factor, as in Cycles.
                return l.weight * l.tint * ((1.0f - fr) * d * ggx_g2(wo_, wi, l.alpha) * wom * jacobian / wo_.z);
            }
        }
        return Vec3f(0.0f);
    }

    Vec3f n_, t_, b_, ng_;
    Vec3f wo_;
    Vec3f n_base_{0.0f, 0.0f, 1.0f};  // the unperturbed normal in the local frame, when bump_
    bool bump_ = false;
    Lobe lobes_[kMaxLobes];
    int count_ = 0;
    bool has_non_delta_ = false;
    bool transmissive_ = false;
};

}  // namespace coherent
