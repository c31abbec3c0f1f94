// Blender's Sky Texture node as Cycles 3.4 renders it (kernel/svm/sky.h,
// scene/shader_nodes.cpp SkyTextureNode): three models of the clear sky.
//
//  - Preetham ("A Practical Analytic Model for Daylight", 1999): Perez
//    functions in xyY, parameters from the turbidity and sun direction.
//  - Hosek / Wilkie ("An Analytic Model for Full Spectral Sky-Dome
//    Radiance", 2012): 9-parameter configurations per XYZ channel, cooked
//    from the model's coefficient tables (sky_hosek.cpp).
//  - Nishita (Blender's "Nishita improved"): single scattering through a
//    layered atmosphere, precomputed into a 512x128 XYZ image over azimuth
//    and the square root of elevation (sky_nishita.cpp), plus a sun disc with
//    limb darkening whose colour is interpolated between the transmitted sun
//    at the disc's lower and upper edge.
//
// Precomputation happens once per node (scene build); evaluation per
// direction reads only `SkyTexture`, so the world (scene/world.h) and a
// material's shader program (ShaderOp::SkyTexture, data = pack()) share it.
//
// Directions are in the texture's frame: z up, and the model's azimuth as
// Cycles measures it (atan2(x, y)). Output is linear Rec.709 RGB (Cycles'
// xyz_to_rgb for Blender's default OCIO configuration), clamped at 0.
#pragma once

#include <cstddef>
#include <vector>

#include "../core/vec.h"

namespace coherent {

enum class SkyType : uint8_t { Preetham = 0, HosekWilkie = 1, Nishita = 2 };

// The node's settings as Blender stores them (angles in radians, altitude in
// metres); defaults are Blender 3.4's.
struct SkyInputs {
    SkyType type = SkyType::Nishita;
    Vec3f sun_direction{0.0f, 0.0f, 1.0f};  // Preetham, Hosek/Wilkie (normalised here)
    float turbidity = 2.2f;                 // Preetham, Hosek/Wilkie
    float ground_albedo = 0.3f;             // Hosek/Wilkie
    bool sun_disc = true;                   // Nishita from here on
    float sun_size = 0.009512f;             // angular diameter
    float sun_intensity = 1.0f;
    float sun_elevation = 0.2617994f;       // 15 degrees
    float sun_rotation = 0.0f;
    float altitude = 0.0f;
    float air_density = 1.0f, dust_density = 1.0f, ozone_density = 1.0f;
};

// Everything evaluation needs. All floats, so that pack()/unpack() can move
// it through a shader program's float data.
struct SkyParams {
    float type = 0.0f;  // SkyType
    // Preetham / Hosek: sun position, radiance scale and configurations.
    float sun_theta = 0.0f, sun_phi = 0.0f;
    float radiance[3] = {0.0f, 0.0f, 0.0f};
    float config[3][9] = {};
    // Nishita: the sun's XYZ at the bottom and top edge of the disc, the sun
    // as Cycles' kernel reads it (rotation already mapped to its convention),
    // angular_diameter < 0 when there is no disc; the image's size.
    float pixel_bottom[3] = {0.0f, 0.0f, 0.0f}, pixel_top[3] = {0.0f, 0.0f, 0.0f};
    float sun_elevation = 0.0f, sun_rotation = 0.0f, angular_diameter = -1.0f, sun_intensity = 1.0f;
    float image_width = 0.0f, image_height = 0.0f;
};
constexpr size_t kSkyParamFloats = sizeof(SkyParams) / sizeof(float);

struct SkyTexture {
    SkyParams params;
    // Nishita: image_height rows (row 0 at the horizon) of image_width XYZ
    // texels; empty for the other models.
    std::vector<float> image;

    SkyType type() const { return SkyType(int(params.type)); }
    // Radiance (linear RGB) towards `dir` (need not be unit length, as in
    // Cycles, where a material's Generated coordinate goes in unnormalised).
    // Without the sun disc, the Nishita sky shows the sky behind it.
    Vec3f eval(const Vec3f& dir, bool sun_disc = true) const;
};

SkyTexture precompute_sky(const SkyInputs& inputs);

// The flat float form (params, then the image) a shader program carries in
// its data table, and its evaluation in place.
std::vector<float> pack(const SkyTexture& sky);
size_t packed_sky_floats(const float* packed);  // total length, read from the header
// Whether `available` floats at `packed` hold a whole packed sky with a
// sound header (what a shader program or Python hands in is checked so).
bool packed_sky_valid(const float* packed, size_t available);
Vec3f eval_packed_sky(const float* packed, const Vec3f& dir);

}  // namespace coherent
