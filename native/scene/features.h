// What effects a scene calls for, computed once so the renderer generates only
// the ray types and code paths it needs.
#pragma once

#include <string>
#include <vector>

namespace coherent {

struct Scene;

struct SceneFeatures {
    bool emissive_meshes = false;  // some triangle has an emissive material
    bool point_lights = false;     // point lights
    bool spot_lights = false;
    bool sun_lights = false;
    bool area_lights = false;
    bool diffuse = false;          // some closure has a diffuse lobe
    bool glossy = false;           // rough (alpha > threshold) reflection lobe
    bool specular = false;         // near-perfect mirror reflection lobe
    bool glass = false;            // transmission lobe
    bool depth_of_field = false;   // camera aperture > 0
    bool world_light = false;      // non-black world colour
    bool motion_blur = false;      // some triangle moves during the shutter
    // Some emitter can be hit by a ray (emissive mesh, area light, point or
    // spot light with a radius, sun with an angle, world). Without one, a
    // path's last ray (traced only to collect emission) would find nothing.
    bool hittable_emitters = false;
    // Some used material has a Transparent closure (alpha): paths may pass
    // through surfaces and shadow rays look for transparent occluders
    // (render/transparency.h). Holdout: some material cuts the pixel alpha.
    bool transparent = false;
    bool holdout = false;

    bool any_light() const {
        return emissive_meshes || point_lights || spot_lights || sun_lights || area_lights || world_light;
    }
    // A path can reach a light through a mirror or glass lobe after a
    // diffuse bounce: a caustic, the rarest and brightest kind of sample.
    // Where it can, the denoiser clips outliers lower and Distribute Samples
    // decides later (denoiser.h, sample_distribution.h).
    bool can_make_caustics() const { return specular || glass; }
    // Names of the enabled features, for statistics and reports.
    std::vector<std::string> names() const;
    // Every feature on: used to measure what specialisation buys.
    static SceneFeatures all();
};

SceneFeatures compute_features(const Scene& scene);

}  // namespace coherent
