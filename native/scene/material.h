// Materials: a weighted sum of up to four principled closures plus emission.
//
// One closure type covers every BSDF the front ends produce (Principled,
// Diffuse, Glossy, Glass, Emission, Mix and Add nodes are all expressed as
// closure parameters and weights; Transparent, Translucent and Holdout as
// closures of their ClosureKind), so the integrator has a single, small
// shading path and SceneFeatures can tell from the parameters which lobes exist.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <memory>
#include <string>

#include "../core/vec.h"

namespace coherent {

struct ShaderProgram;  // shader/program.h

// What a closure is. Principled covers every BSDF with lobes on wo's side or
// refracting (Principled, Diffuse, Glossy, Glass); the others are Cycles'
// closures that use only `base_color` (transparent/translucent colour):
//  Transparent: light passes straight through, weighted by the colour; it is
//    a pass-through, not a bounce (render/transparency.h), and lets shadow
//    rays through too (Cycles' transparent shadows).
//  Translucent: Lambertian transmission (the cosine lobe on the far side).
//  Holdout: no light; at the camera's surface its weight cuts the pixel's alpha.
enum class ClosureKind : uint8_t { Principled, Transparent, Translucent, Holdout };

// Blender's Principled BSDF restricted to constant inputs.
// Lobes: Lambert diffuse, GGX dielectric specular (F0 from `specular`),
// GGX metal (F0 = base_color), GGX glass (smooth when roughness ~ 0).
struct Closure {
    Vec3f base_color{0.8f, 0.8f, 0.8f};
    float metallic = 0.0f;      // [0,1] blend diffuse/dielectric -> metal
    float roughness = 0.5f;     // [0,1] perceptual; alpha = roughness^2
    float specular = 0.5f;      // [0,1] dielectric F0 = 0.08 * specular (Blender convention)
    float transmission = 0.0f;  // [0,1] blend opaque -> glass (for the non-metal part)
    float ior = 1.45f;          // index of refraction for transmission
    // Diffuse lobe model. Blender's Principled BSDF (and so every glTF material
    // after Blender's importer) uses Cycles' Burley-style "principled diffuse",
    // whose retro-reflection grows with `roughness`; the Diffuse BSDF node is
    // Lambert. Without this the default rough-1 glTF Cornell box renders ~10 %
    // darker than Cycles.
    bool principled_diffuse = false;
    ClosureKind kind = ClosureKind::Principled;
};

// Roughness at or below which a GGX lobe is a perfect mirror / smooth glass
// (delta). Cycles treats alpha_x * alpha_y <= 1e-7 as sharp, i.e. roughness^4
// <= 1e-7, roughness <= 0.01778.
constexpr float kSharpRoughness = 0.01778f;

// Lobe weights of a closure as Blender 3.4's Principled BSDF (Cycles) forms
// them: diffuse and the specular layer are added, not layered.
struct ClosureLobes {
    float diffuse = 0.0f;       // weight of Lambert(base_color)
    float specular = 0.0f;      // weight of the GGX reflection layer (dielectric + metal)
    float transmission = 0.0f;  // weight of the GGX glass lobe
};
inline ClosureLobes closure_lobes(const Closure& c) {
    if (c.kind != ClosureKind::Principled) return {};
    const float metallic = std::clamp(c.metallic, 0.0f, 1.0f);
    const float transmission = std::clamp(c.transmission, 0.0f, 1.0f) * (1.0f - metallic);
    ClosureLobes l;
    l.diffuse = (1.0f - metallic) * (1.0f - std::clamp(c.transmission, 0.0f, 1.0f));
    l.transmission = transmission;
    l.specular = (c.specular > 1e-5f || metallic > 1e-5f) ? 1.0f - transmission : 0.0f;
    return l;
}

struct Material {
    std::string name;
    std::array<Closure, 4> closures{};
    // Non-negative weights. Mix nodes give weights summing to 1; Add nodes may
    // exceed 1 (Blender adds closures). Zero-weight closures are ignored.
    std::array<float, 4> weights{1.0f, 0.0f, 0.0f, 0.0f};
    int closure_count = 1;
    Vec3f emission{0.0f, 0.0f, 0.0f};  // emitted radiance (colour x strength), W/(sr m^2) as in Cycles
    // Alpha (Principled Alpha, glTF alphaMode) is a Transparent closure mixed in.
    // Node graphs with non-constant inputs: a program whose outputs override
    // the constants above per shading point (shader/eval.h). Null for
    // constant materials, which then cost exactly what they did before.
    std::shared_ptr<const ShaderProgram> program;

    bool is_emissive() const { return emission.x > 0.0f || emission.y > 0.0f || emission.z > 0.0f; }
    // Whether some closure of this kind is present (its weight may be program-driven).
    bool has_closure(ClosureKind k) const {
        for (int c = 0; c < closure_count && c < 4; ++c)
            if (closures[size_t(c)].kind == k) return true;
        return false;
    }
};

}  // namespace coherent
