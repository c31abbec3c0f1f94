// Every emitter of a scene behind one interface for next-event estimation
// and for multiple importance sampling of BSDF-sampled rays that hit them:
// analytic lights (point, spot, sun, area), emissive triangles and the
// world (a constant colour or an environment map, world_sampling.h).
//
// Selection: one emitter "unit" (each analytic light, the set of emissive
// triangles, the world: an environment map always, a constant colour only
// when nothing else emits, see the constructor) is picked per shadow ray,
// with probability
//     p_i = (1 - kUniformShare) importance_i / sum(importance) + kUniformShare / units
// (LightSelection::Power), or 1 / units (LightSelection::Uniform, the
// selection before importance). The uniform share keeps every emitter that
// can contribute at p > 0, so the estimator stays unbiased however wrong the
// importance estimate is for a given shading point. sample() and every pdf
// function (hit_lights, escaped, triangle_pdf) read the same p_i, so MIS
// weights stay exact. Importance is an estimate of the power the unit
// delivers into the scene, in watts (light_importance() and the constructor
// in the .cpp state and justify the units per kind of emitter).
//
// Within a unit: an emissive triangle is picked by power (area x emission
// luminance), then sampled by solid angle from shading points near its plane
// (spherical_triangle.h) and by area elsewhere; rectangular area lights by
// solid angle (spherical rectangles) wherever that is numerically sound.
//
// Light units follow Cycles 3.4 exactly. Measured in Blender 3.4.1 (Cycles
// CPU, 512 spp, white Lambert plane, light 2 m above, orthographic camera,
// Standard view transform, /tmp calibration script described in the report):
//   point P=100 W, r=0:       pixel 0.62589 at d^2=4.03125, cos=0.99612;
//                             I = P/(4 pi) predicts 0.62589  -> I = P/(4 pi) W/sr
//   point P=100 W, r=0.5:     0.58935 = 0.62589 * d^2/(d^2+r^2): a disc of radius
//                             r facing the shading point, radiance I/(pi r^2)
//   spot  P=100 W (axis down):0.62345 = point * cos(angle to axis): the spot
//                             mask multiplies the cosine (Cycles 3.x spot_attenuation)
//   sun   S=3, 30 deg:        0.82700 = S cos30 / pi -> S is irradiance
//   sun   S=3, angle 10 deg:  0.82541 = 0.82700 (1+cos 5deg)/2: radiance S / cone solid angle
//   area  square/rect P=100:  implied radiance 24.996 = P/(4 A)  (not P/(pi A))
//   area  disk/ellipse:       implied radiance 31.83 = P/(4 A), A = pi/4 size_u size_v
//   emission strength 10:     seen directly 10.0; implied radiance 9.997
//   world colour 0.5:         0.5 on an unoccluded white plane
//   Lights are not visible to camera rays (a camera looking at an area light,
//   point or spot light with radius sees black), but are hit by bounce rays.
#pragma once

#include <cstdint>
#include <vector>

#include "../scene/scene.h"
#include "spherical_triangle.h"
#include "world_sampling.h"

namespace coherent {

// A light sample as seen from a shading point.
struct LightSample {
    Vec3f wi;            // unit direction from the shading point to the emitter
    float dist = kInf;   // distance to the emitting point (inf for sun/world)
    Vec3f li;            // radiance arriving (delta lights: intensity / d^2, irradiance for sun)
    float pdf = 0.0f;    // solid-angle pdf including the selection probability; unused for delta
    bool delta = false;  // point/spot of radius 0, sun of angle 0: no MIS
    // Emissive triangle: end point on the emitter and its geometric normal, so
    // the shadow ray can stop short of the emitter without self-hits.
    bool on_surface = false;
    Vec3f p_light, n_light;  // n_light faces the shading point
    Vec3f p_light_error;     // floating-point error bound of p_light (ray_offset.h)
};

// Precomputed per-light data.
struct LightRecord {
    LightType type;
    Vec3f position, direction, axis_u, axis_v;
    Vec3f radiance;      // point/spot: intensity (radius 0) or disc radiance; sun: irradiance or cone radiance; area: radiance
    float radius = 0.0f;
    float cos_half_spot = -1.0f, spot_smooth = 0.0f;
    float cos_half_sun = 1.0f, sun_solid_angle = 0.0f;
    AreaShape shape = AreaShape::Square;
    float half_u = 0.5f, half_v = 0.5f, area = 1.0f;
    float pick = 0.0f;   // selection probability of this light
};

enum class LightSelection { Power, Uniform };

// The share of the selection probability spread uniformly over all units.
constexpr double kUniformShare = 0.1;

class LightSet {
public:
    LightSet() = default;
    explicit LightSet(const Scene& scene, LightSelection selection = LightSelection::Power);

    bool empty() const { return units_ == 0; }
    bool has_world() const { return world_; }

    // Samples one emitter for shading point p with shading normal n (facing
    // the viewer). `transmissive` selects uniform-sphere instead of cosine
    // sampling for a constant world (the BSDF can see the lower hemisphere);
    // an environment map is sampled by its own distribution either way.
    bool sample(const Vec3f& p, const Vec3f& n, bool transmissive, float u_pick, float u1, float u2, LightSample& ls) const;

    // Emission picked up by a bounce ray o + t d (unit d), t < tmax, from
    // analytic lights (area, and point/spot with radius): returns the sum of
    // MIS-weighted radiance given the BSDF pdf of d (bsdf_pdf = 0: delta, no MIS).
    // tmin: a ray continued past transparent surfaces (render/transparency.h)
    // met the lights before tmin on its earlier stretch.
    Vec3f hit_lights(const Vec3f& o, const Vec3f& d, float tmax, float bsdf_pdf, float tmin = 0.0f) const;
    // Radiance from an escaped bounce ray: world and suns with an angle, MIS-weighted.
    // n/transmissive: the frame of the vertex that sampled d (for the world pdf).
    Vec3f escaped(const Vec3f& d, const Vec3f& n, bool transmissive, float bsdf_pdf) const;
    // Solid-angle pdf with which sample() would pick point `p_light` on
    // emissive triangle `tri` (unit normal n_light) from `o`.
    float triangle_pdf(uint32_t tri, const Vec3f& o, const Vec3f& p_light, const Vec3f& n_light) const;

    // World radiance in direction d (camera rays that miss everything).
    Vec3f world_radiance(const Vec3f& d) const;

    // Selection probabilities (tests, statistics): analytic light i in the
    // order of the scene's emitting lights, the emissive triangles as a
    // whole, the world. 0 for a unit that does not exist.
    size_t light_count() const { return lights_.size(); }
    float light_pick(size_t i) const { return lights_[i].pick; }
    float triangles_pick() const { return tri_unit_pick_; }
    float world_pick() const { return world_pick_; }

private:
    float world_pdf(const Vec3f& d, const Vec3f& n, bool transmissive) const;
    bool sample_triangle(const Vec3f& p, float u_pick, float u1, float u2, LightSample& ls) const;
    // Whether emissive triangle `tri` is sampled by solid angle from p (st
    // then holds it) rather than by area. sample_triangle and triangle_pdf
    // both decide here, so MIS sees the pdf the sample was drawn with.
    bool triangle_by_solid_angle(uint32_t tri, const Vec3f& p, SphericalTriangle& st) const;
    bool sample_world(const Vec3f& n, bool transmissive, float u1, float u2, LightSample& ls) const;
    // The emissive triangles' pick distribution (tri_*), by power.
    void pick_triangles_by_power(const Scene& scene);
    // The units' probabilities (LightRecord::pick, tri_unit_pick_, world_pick_,
    // unit_cdf_) from their importance, in unit order.
    void choose_unit_probabilities(const std::vector<double>& importance, LightSelection selection);

    const Scene* scene_ = nullptr;
    std::vector<LightRecord> lights_;
    // Selection over units: lights_, then the triangles, then the world.
    int units_ = 0;
    bool uniform_ = true;            // pick by u * units_ (bit-identical to the selection before importance)
    std::vector<float> unit_cdf_;    // inclusive prefix sums of the units' picks, last == 1
    float tri_unit_pick_ = 0.0f, world_pick_ = 0.0f;
    bool triangles_ = false, world_ = false;
    bool world_unit_ = false;        // the world is a unit of next-event estimation
    Vec3f world_color_{0.0f};        // constant radiance, or the map's strength
    bool has_map_ = false;           // the world is world_color_ x env_ (black if env_ is empty)
    EnvironmentSampler env_;
    double total_triangle_power_ = 0.0;  // sum of area x luminance(emission)
    // Emissive triangles picked by power (area x luminance of emission).
    std::vector<uint32_t> tri_ids_;
    std::vector<float> tri_cdf_;        // inclusive prefix sums, normalised, last == 1
    std::vector<float> tri_pick_;       // per scene triangle: probability within the set (0 if not emissive)
    std::vector<float> tri_area_;       // per emissive list entry
};

// Power heuristic (beta = 2).
inline float power_heuristic(float a, float b) {
    const float a2 = a * a, b2 = b * b;
    if (!(a2 > 0.0f)) return 0.0f;
    if (!std::isfinite(a2)) return 1.0f;
    return a2 / (a2 + b2);
}

}  // namespace coherent
