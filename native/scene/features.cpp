// SceneFeatures: which effects the finalized scene actually uses. Only
// materials referenced by some triangle count, so an unused glass material in
// a .blend file does not switch refraction on.
#include "features.h"

#include "scene.h"
#include "../shader/program.h"

namespace coherent {

std::vector<std::string> SceneFeatures::names() const {
    std::vector<std::string> n;
    auto add = [&](bool on, const char* name) {
        if (on) n.emplace_back(name);
    };
    add(emissive_meshes, "emissive_meshes");
    add(point_lights, "point_lights");
    add(spot_lights, "spot_lights");
    add(sun_lights, "sun_lights");
    add(area_lights, "area_lights");
    add(diffuse, "diffuse");
    add(glossy, "glossy");
    add(specular, "specular");
    add(glass, "glass");
    add(depth_of_field, "depth_of_field");
    add(world_light, "world_light");
    add(motion_blur, "motion_blur");
    add(transparent, "transparent");
    add(holdout, "holdout");
    return n;
}

SceneFeatures SceneFeatures::all() {
    SceneFeatures f;
    f.emissive_meshes = f.point_lights = f.spot_lights = f.sun_lights = f.area_lights = true;
    f.diffuse = f.glossy = f.specular = f.glass = true;
    f.depth_of_field = f.world_light = f.motion_blur = true;
    f.hittable_emitters = true;
    f.transparent = f.holdout = true;
    return f;
}

SceneFeatures compute_features(const Scene& scene) {
    SceneFeatures f;

    std::vector<uint8_t> used(scene.materials.size(), 0);
    for (uint32_t m : scene.material_of)
        if (m < used.size()) used[m] = 1;
    used[0] = used[0] || !scene.instances.empty();  // slots past an instance's own use the default
    for (uint32_t m : scene.instance_materials)
        if (m < used.size()) used[m] = 1;

    for (size_t i = 0; i < scene.materials.size(); ++i) {
        if (!used[i]) continue;
        const Material& mat = scene.materials[i];
        if (mat.is_emissive()) f.emissive_meshes = true;
        if (mat.has_closure(ClosureKind::Transparent)) f.transparent = true;
        if (mat.has_closure(ClosureKind::Holdout)) f.holdout = true;
        if (mat.has_closure(ClosureKind::Translucent)) f.diffuse = true;
        // A shader program may turn any lobe on at some points.
        if (mat.program) {
            f.diffuse = f.glossy = f.specular = true;
            for (const ShaderOutput& o : mat.program->outputs)
                if (o.field == ShaderField::Transmission) f.glass = true;
        }
        for (int c = 0; c < mat.closure_count && c < 4; ++c) {
            if (!(mat.weights[c] > 0.0f)) continue;
            const Closure& cl = mat.closures[c];
            const ClosureLobes lobes = closure_lobes(cl);
            const bool sharp = cl.roughness <= kSharpRoughness;
            if (lobes.diffuse > 0.0f && !is_black(cl.base_color)) f.diffuse = true;
            if (lobes.specular > 0.0f) (sharp ? f.specular : f.glossy) = true;
            if (lobes.transmission > 0.0f) f.glass = true;
        }
    }

    for (const Light& l : scene.lights) {
        if (!(l.power > 0.0f) || is_black(l.color)) continue;  // emits nothing
        switch (l.type) {
            case LightType::Point: f.point_lights = true; break;
            case LightType::Spot: f.spot_lights = true; break;
            case LightType::Sun: f.sun_lights = true; break;
            case LightType::Area: f.area_lights = true; break;
        }
        const bool delta = (l.type == LightType::Point || l.type == LightType::Spot) ? !(l.radius > 0.0f)
                           : l.type == LightType::Sun                            ? !(l.sun_angle > 0.0f)
                                                                                 : false;
        if (!delta) f.hittable_emitters = true;
    }

    f.depth_of_field = scene.camera.aperture_radius > 0.0f;
    f.world_light = !is_black(scene.world_color);
    f.motion_blur = !scene.moving_triangles.empty() || scene.has_moving_instances();
    f.hittable_emitters = f.hittable_emitters || f.emissive_meshes || f.world_light;
    return f;
}

}  // namespace coherent
