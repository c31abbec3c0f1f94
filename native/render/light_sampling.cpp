// Light selection, sampling and MIS pdfs. Units: see light_sampling.h.
#include "light_sampling.h"

#include <algorithm>
#include <cmath>

#include "bsdf.h"
#include "ray_offset.h"
#include "spherical_triangle.h"

namespace coherent {

namespace {

// Direction in the cone of half-angle theta around unit axis w, uniform in
// solid angle. one_minus_cos = 1 - cos(theta) is passed directly so tiny
// cones (small lights far away) keep their precision.
Vec3f sample_cone(const Vec3f& w, float one_minus_cos, float u1, float u2) {
    const float omc = u1 * one_minus_cos;           // 1 - cos(sampled angle)
    const float cos_t = 1.0f - omc;
    const float sin_t = std::sqrt(std::max(0.0f, omc * (2.0f - omc)));
    const float phi = 2.0f * kPi * u2;
    Vec3f t, b;
    make_basis(w, t, b);
    return normalize(t * (sin_t * std::cos(phi)) + b * (sin_t * std::sin(phi)) + w * cos_t);
}

// 1 - cos(angle between unit vectors a and b), accurate for small angles.
float one_minus_cos_between(const Vec3f& a, const Vec3f& b) { return 0.5f * length_squared(a - b); }

Vec2f concentric_disk(float u1, float u2) {
    const float a = 2.0f * u1 - 1.0f, b = 2.0f * u2 - 1.0f;
    if (a == 0.0f && b == 0.0f) return {0.0f, 0.0f};
    float r, phi;
    if (a * a > b * b) {
        r = a;
        phi = (kPi / 4.0f) * (b / a);
    } else {
        r = b;
        phi = (kPi / 2.0f) - (kPi / 4.0f) * (a / b);
    }
    return {r * std::cos(phi), r * std::sin(phi)};
}

// Blender 3.x spot mask: the cosine to the axis, zero outside the cone, with a
// smoothstep over the blend region (Cycles spot_attenuation).
float spot_attenuation(const LightRecord& l, const Vec3f& dir_from_light) {
    if (l.type != LightType::Spot) return 1.0f;
    float att = dot(dir_from_light, l.direction);
    if (att <= l.cos_half_spot) return 0.0f;
    const float t = att - l.cos_half_spot;
    if (t < l.spot_smooth && l.spot_smooth != 0.0f) {
        const float x = std::clamp(t / l.spot_smooth, 0.0f, 1.0f);
        att *= x * x * (3.0f - 2.0f * x);
    }
    return att;
}

// Half-angle cone a disc of radius r facing a point at distance d subtends:
// sin^2 = r^2 / (d^2 + r^2). Returns 1 - cos.
float disc_one_minus_cos(float r, float d) {
    const float s2 = (r * r) / (d * d + r * r);
    const float c = std::sqrt(std::max(0.0f, 1.0f - s2));
    return s2 / (1.0f + c);
}

Vec3f safe_normalize(const Vec3f& v, const Vec3f& fallback) {
    const float l = length(v);
    return l > 0.0f && std::isfinite(l) ? v / l : fallback;
}

// Solid-angle sampling of rectangular lights (Urena, Fajardo, King 2013, "An
// Area-Preserving Parametrization for Spherical Rectangles"), as Cycles does:
// far less noise than area sampling close to the light. Computed in double:
// the solid angle is a difference of angles near 2 pi and cancels badly in
// float for small, distant lights, where we fall back to area sampling.
// Measured: 1 m square light 0.5 m above a white plane, 16 spp, per-pixel
// sigma 0.539 with area sampling, 0.192 with this (7.9x less variance).
constexpr double kMinRectSolidAngle = 1e-7;

struct SphericalRect {
    double x0, y0, z0, x1, y1;  // rectangle in the local frame (x along u, y along v, z towards it)
    double b0, b1, k, solid_angle;
    Vec3f ex, ey, ez;           // local frame, world space
};

bool make_spherical_rect(const Vec3f& p, const LightRecord& l, SphericalRect& r) {
    const Vec3f corner = l.position - l.axis_u * l.half_u - l.axis_v * l.half_v;
    r.ex = l.axis_u;
    r.ey = l.axis_v;
    r.ez = cross(r.ex, r.ey);
    const Vec3f dir = corner - p;
    r.z0 = dot(dir, r.ez);
    if (r.z0 > 0.0) {
        r.ez = -r.ez;
        r.z0 = -r.z0;
    }
    if (r.z0 == 0.0) return false;  // in the light's plane
    r.x0 = dot(dir, r.ex);
    r.y0 = dot(dir, r.ey);
    r.x1 = r.x0 + 2.0 * l.half_u;
    r.y1 = r.y0 + 2.0 * l.half_v;
    // Normals of the four planes through p and the rectangle's edges.
    const double dx[4] = {r.x0 - r.x1, r.y1 - r.y0, r.x1 - r.x0, r.y0 - r.y1};
    const double m[4] = {r.y0, r.x1, r.y1, r.x0};
    double nz[4];
    for (int i = 0; i < 4; ++i) {
        const double a = m[i] * dx[i];
        nz[i] = a / std::sqrt(r.z0 * r.z0 * dx[i] * dx[i] + a * a);
    }
    auto safe_acos = [](double x) { return std::acos(std::clamp(x, -1.0, 1.0)); };
    const double g0 = safe_acos(-nz[0] * nz[1]);
    const double g1 = safe_acos(-nz[1] * nz[2]);
    const double g2 = safe_acos(-nz[2] * nz[3]);
    const double g3 = safe_acos(-nz[3] * nz[0]);
    r.b0 = nz[0];
    r.b1 = nz[2];
    r.k = 2.0 * 3.14159265358979323846 - g2 - g3;
    r.solid_angle = g0 + g1 - r.k;
    return r.solid_angle > kMinRectSolidAngle;
}

Vec3f sample_spherical_rect(const Vec3f& p, const SphericalRect& r, float u1, float u2) {
    const double au = double(u1) * r.solid_angle + r.k;
    const double fu = (std::cos(au) * r.b0 - r.b1) / std::sin(au);
    double cu = (fu > 0.0 ? 1.0 : -1.0) / std::sqrt(fu * fu + r.b0 * r.b0);
    cu = std::clamp(cu, -1.0, 1.0);
    double xu = -(cu * r.z0) / std::max(std::sqrt(1.0 - cu * cu), 1e-12);
    xu = std::clamp(xu, r.x0, r.x1);
    const double d2 = xu * xu + r.z0 * r.z0;
    const double h0 = r.y0 / std::sqrt(d2 + r.y0 * r.y0);
    const double h1 = r.y1 / std::sqrt(d2 + r.y1 * r.y1);
    const double hv = h0 + double(u2) * (h1 - h0), hv2 = hv * hv;
    const double yv = hv2 < 1.0 - 1e-12 ? hv * std::sqrt(d2) / std::sqrt(1.0 - hv2) : r.y1;
    return p + r.ex * float(xu) + r.ey * float(std::clamp(yv, r.y0, r.y1)) + r.ez * float(r.z0);
}

bool is_rect(const LightRecord& l) { return l.shape == AreaShape::Square || l.shape == AreaShape::Rectangle; }

}  // namespace

namespace {

// The record of analytic light `in`; false for one that emits nothing.
bool light_record(const Light& in, LightRecord& l) {
    if (!(in.power > 0.0f) || is_black(in.color) || !is_finite(in.color) || !std::isfinite(in.power)) return false;
    l.type = in.type;
    l.position = in.position;
    l.direction = safe_normalize(in.direction, Vec3f(0.0f, 0.0f, -1.0f));
    const Vec3f flux = in.color * in.power;
    switch (in.type) {
        case LightType::Point:
        case LightType::Spot: {
            const Vec3f intensity = flux * (1.0f / (4.0f * kPi));  // W/sr, measured
            l.radius = std::max(in.radius, 0.0f);
            l.radiance = l.radius > 0.0f ? intensity / (kPi * l.radius * l.radius) : intensity;
            if (in.type == LightType::Spot) {
                l.cos_half_spot = std::cos(0.5f * std::clamp(in.spot_size, 0.0f, kPi));
                l.spot_smooth = (1.0f - l.cos_half_spot) * std::clamp(in.spot_blend, 0.0f, 1.0f);
            }
            return true;
        }
        case LightType::Sun: {
            const float half = 0.5f * std::clamp(in.sun_angle, 0.0f, kPi);
            if (half > 0.0f) {
                const float s = std::sin(0.5f * half);
                const float omc = 2.0f * s * s;  // 1 - cos(half)
                l.cos_half_sun = 1.0f - omc;
                l.sun_solid_angle = 2.0f * kPi * omc;
                l.radiance = flux / l.sun_solid_angle;  // measured: radiance = S / cone solid angle
            } else {
                l.radiance = flux;  // irradiance on a surface facing the sun
            }
            return true;
        }
        case LightType::Area: {
            l.shape = in.shape;
            l.axis_u = safe_normalize(in.axis_u, Vec3f(1.0f, 0.0f, 0.0f));
            l.axis_v = safe_normalize(in.axis_v, Vec3f(0.0f, 1.0f, 0.0f));
            const bool square = in.shape == AreaShape::Square || in.shape == AreaShape::Disk;
            const float su = std::max(in.size_u, 0.0f), sv = square ? su : std::max(in.size_v, 0.0f);
            l.half_u = 0.5f * su;
            l.half_v = 0.5f * sv;
            const bool round = in.shape == AreaShape::Disk || in.shape == AreaShape::Ellipse;
            l.area = su * sv * (round ? 0.25f * kPi : 1.0f);
            if (!(l.area > 0.0f)) return false;
            l.radiance = flux / (4.0f * l.area);  // measured: Cycles 3.4 area radiance = P / (4 A)
            return true;
        }
    }
    return true;
}

}  // namespace

namespace {

// What a unit delivers into the scene, in watts, so that lights of every kind
// compare on one scale:
// - point/spot: the emitted flux P (Cycles: intensity P / (4 pi) over the
//   sphere); a spot's mask is ignored, as the camera usually sees what it lights;
// - area: flux pi L A = pi P / 4 (one-sided Lambertian emitter of radiance P / (4 A));
// - emissive triangles: 2 pi L A summed (two-sided);
// - sun: irradiance E times the scene's cross-section pi r^2 (r: half the
//   bounding-box diagonal): the flux of a parallel beam through the scene;
// - world: the irradiance an upward patch gets from the mean radiance,
//   pi L_mean, times the same cross-section pi r^2.
// Sun and world thus compare as the light they put on an unoccluded patch
// facing them, and with local lights as the flux they bring into the scene's
// bounding sphere. A wrong estimate costs noise, never bias (kUniformShare).
float scene_cross_section(const Scene& scene) {
    const BBox b = scene.bounds();
    const float r = b.empty() ? 0.0f : 0.5f * length(b.extent());
    return r > 0.0f && std::isfinite(r) ? kPi * r * r : kPi;
}

double light_importance(const Light& in, const LightRecord& l, float cross_section) {
    const double flux = double(in.power) * double(luminance(in.color));
    switch (l.type) {
        case LightType::Point:
        case LightType::Spot: return flux;
        case LightType::Area: return 0.25 * double(kPi) * flux;
        case LightType::Sun: return flux * double(cross_section);
    }
    return flux;
}

}  // namespace

LightSet::LightSet(const Scene& scene, LightSelection selection) : scene_(&scene) {
    // Only suns and the world need the cross-section; bounds() walks every vertex.
    float cross_section = -1.0f;
    auto section = [&] { return cross_section < 0.0f ? (cross_section = scene_cross_section(scene)) : cross_section; };
    std::vector<double> importance;  // per unit, in the order of unit_cdf_
    for (const Light& in : scene.lights) {
        LightRecord l;
        if (!light_record(in, l)) continue;
        lights_.push_back(l);
        importance.push_back(light_importance(in, l, l.type == LightType::Sun ? section() : 0.0f));
    }
    pick_triangles_by_power(scene);
    world_color_ = scene.world_color;
    has_map_ = !scene.world_map.empty();
    if (has_map_) env_ = EnvironmentSampler(scene.world_map);
    world_ = !is_black(world_color_) && is_finite(world_color_) && (!has_map_ || !env_.empty());
    // A constant world beside other emitters is left to BSDF rays, as in
    // Cycles 3.4 (its background MIS is off for a uniform background): its
    // cosine-distributed shadow rays find nothing a diffuse BSDF's rays do
    // not, and every one of them is a shadow ray the lights lose. Sun-lit
    // Sponza with a 0.05 world: 2.2x less variance of direct light
    // (docs/results/efficiency_gap.md). Alone, it keeps next-event estimation.
    world_unit_ = world_ && (has_map_ || (lights_.empty() && !triangles_));
    units_ = int(lights_.size()) + (triangles_ ? 1 : 0) + (world_unit_ ? 1 : 0);
    if (triangles_) importance.push_back(2.0 * double(kPi) * total_triangle_power_);
    if (world_unit_) {
        const double mean_radiance = double(luminance(world_color_)) * (has_map_ ? env_.mean_luminance() : 1.0);
        importance.push_back(double(kPi) * mean_radiance * double(section()));
    }
    choose_unit_probabilities(importance, selection);
}

void LightSet::choose_unit_probabilities(const std::vector<double>& importance, LightSelection selection) {
    if (units_ == 0) return;
    double total = 0.0;
    for (double w : importance) total += std::isfinite(w) && w > 0.0 ? w : 0.0;
    // One unit: p = 1 either way, picked with the uniform arithmetic (bit-identical to before).
    uniform_ = selection == LightSelection::Uniform || units_ == 1 || !(total > 0.0) || !std::isfinite(total);
    std::vector<float> pick(static_cast<size_t>(units_));
    for (size_t i = 0; i < pick.size(); ++i) {
        const double w = std::isfinite(importance[i]) && importance[i] > 0.0 ? importance[i] : 0.0;
        pick[i] = uniform_ ? 1.0f / float(units_)
                           : float((1.0 - kUniformShare) * w / total + kUniformShare / double(units_));
    }
    for (size_t i = 0; i < lights_.size(); ++i) lights_[i].pick = pick[i];
    if (triangles_) tri_unit_pick_ = pick[lights_.size()];
    if (world_unit_) world_pick_ = pick.back();
    unit_cdf_.resize(pick.size());
    double acc = 0.0;
    for (size_t i = 0; i < pick.size(); ++i) unit_cdf_[i] = float(acc += double(pick[i]));
    unit_cdf_.back() = 1.0f;
}

void LightSet::pick_triangles_by_power(const Scene& scene) {
    tri_pick_.assign(scene.triangle_count(), 0.0f);
    double total = 0.0;
    std::vector<double> power;
    for (uint32_t t : scene.emissive_triangles) {
        const Vec3f* v = &scene.vertices[3 * size_t(t)];
        const float area = 0.5f * length(cross(v[1] - v[0], v[2] - v[0]));
        const float p = area * luminance(scene.materials[scene.material_of[t]].emission);
        if (!(p > 0.0f) || !std::isfinite(p)) continue;
        tri_ids_.push_back(t);
        tri_area_.push_back(area);
        power.push_back(p);
        total += p;
    }
    if (!(total > 0.0)) return;
    triangles_ = true;
    total_triangle_power_ = total;
    double acc = 0.0;
    tri_cdf_.resize(power.size());
    for (size_t i = 0; i < power.size(); ++i) {
        acc += power[i];
        tri_cdf_[i] = float(acc / total);
        tri_pick_[tri_ids_[i]] = float(power[i] / total);
    }
    tri_cdf_.back() = 1.0f;
}

float LightSet::world_pdf(const Vec3f& d, const Vec3f& n, bool transmissive) const {
    if (has_map_) return env_.pdf(d);
    if (transmissive) return 1.0f / (4.0f * kPi);
    return std::max(0.0f, dot(d, n)) * kInvPi;
}

namespace {

// Point and spot lights: a sphere of l.radius, by the cone it subtends, or a point.
bool sample_point_light(const LightRecord& l, const Vec3f& p, float u1, float u2, float unit_pdf, LightSample& ls) {
    const Vec3f to = l.position - p;
    const float d2 = length_squared(to);
    const float d = std::sqrt(d2);
    if (!(d > 0.0f) || !std::isfinite(d2)) return false;
    const Vec3f w = to / d;
    if (l.radius > 0.0f) {
        const float omc = disc_one_minus_cos(l.radius, d);
        ls.wi = sample_cone(w, omc, u1, u2);
        const float cos_t = dot(ls.wi, w);
        ls.dist = d / std::max(cos_t, 1e-6f);
        ls.li = l.radiance * spot_attenuation(l, -ls.wi);
        ls.pdf = unit_pdf / (2.0f * kPi * omc);
    } else {
        ls.wi = w;
        ls.dist = d;
        ls.li = l.radiance * (spot_attenuation(l, -w) / d2);
        ls.delta = true;
        ls.pdf = unit_pdf;
    }
    return true;
}

// Sun: the cone of its angle, or one direction.
void sample_sun(const LightRecord& l, float u1, float u2, float unit_pdf, LightSample& ls) {
    if (l.sun_solid_angle > 0.0f) {
        ls.wi = sample_cone(-l.direction, 1.0f - l.cos_half_sun, u1, u2);
        ls.pdf = unit_pdf / l.sun_solid_angle;
    } else {
        ls.wi = -l.direction;
        ls.delta = true;
        ls.pdf = unit_pdf;
    }
    ls.li = l.radiance;
    ls.dist = kInf;
}

// Area lights, one-sided: rectangles by solid angle where the spherical
// rectangle can be formed, else (and disks, ellipses) by area.
bool sample_area_light(const LightRecord& l, const Vec3f& p, float u1, float u2, float unit_pdf, LightSample& ls) {
    if (!(dot(p - l.position, l.direction) > 0.0f)) return false;  // behind the emitting side
    SphericalRect sr;
    const bool by_solid_angle = is_rect(l) && make_spherical_rect(p, l, sr);
    Vec3f q;
    if (by_solid_angle) {
        q = sample_spherical_rect(p, sr, u1, u2);
    } else {
        Vec2f xy;
        if (l.shape == AreaShape::Disk || l.shape == AreaShape::Ellipse) {
            xy = concentric_disk(u1, u2);
        } else {
            xy = {2.0f * u1 - 1.0f, 2.0f * u2 - 1.0f};
        }
        q = l.position + l.axis_u * (xy.x * l.half_u) + l.axis_v * (xy.y * l.half_v);
    }
    const Vec3f to = q - p;
    const float d2 = length_squared(to);
    const float d = std::sqrt(d2);
    if (!(d > 0.0f)) return false;
    ls.wi = to / d;
    const float cos_l = -dot(ls.wi, l.direction);
    if (!(cos_l > 0.0f)) return false;  // one-sided: the back emits nothing
    ls.dist = d;
    ls.li = l.radiance;
    ls.pdf = by_solid_angle ? unit_pdf / float(sr.solid_angle) : unit_pdf * d2 / (l.area * cos_l);
    return true;
}

bool sample_analytic_light(const LightRecord& l, const Vec3f& p, float u1, float u2, float unit_pdf,
                           LightSample& ls) {
    switch (l.type) {
        case LightType::Point:
        case LightType::Spot:
            if (!sample_point_light(l, p, u1, u2, unit_pdf, ls)) return false;
            break;
        case LightType::Sun: sample_sun(l, u1, u2, unit_pdf, ls); break;
        case LightType::Area:
            if (!sample_area_light(l, p, u1, u2, unit_pdf, ls)) return false;
            break;
    }
    return ls.pdf > 0.0f && std::isfinite(ls.pdf);
}

}  // namespace

bool LightSet::sample(const Vec3f& p, const Vec3f& n, bool transmissive, float u_pick, float u1, float u2,
                      LightSample& ls) const {
    if (units_ == 0) return false;
    int unit;
    float u_rest;
    if (uniform_) {
        const float scaled = u_pick * float(units_);
        unit = std::min(int(scaled), units_ - 1);
        u_rest = std::clamp(scaled - float(unit), 0.0f, 0.99999994f);
    } else {
        unit = std::min(int(std::upper_bound(unit_cdf_.begin(), unit_cdf_.end(), u_pick) - unit_cdf_.begin()),
                        units_ - 1);
        const float lo = unit > 0 ? unit_cdf_[size_t(unit) - 1] : 0.0f;
        const float width = unit_cdf_[size_t(unit)] - lo;
        u_rest = std::clamp(width > 0.0f ? (u_pick - lo) / width : 0.5f, 0.0f, 0.99999994f);
    }
    ls = LightSample{};
    if (unit < int(lights_.size())) return sample_analytic_light(lights_[unit], p, u1, u2, lights_[unit].pick, ls);
    if (triangles_ && unit == int(lights_.size())) return sample_triangle(p, u_rest, u1, u2, ls);
    return sample_world(n, transmissive, u1, u2, ls);
}

// World: cosine around the shading normal, or the whole sphere for BSDFs that transmit.
bool LightSet::sample_world(const Vec3f& n, bool transmissive, float u1, float u2, LightSample& ls) const {
    if (has_map_) {
        float pdf;
        if (!env_.sample(u1, u2, ls.wi, pdf)) return false;
        ls.pdf = world_pick_ * pdf;
        ls.li = world_color_ * env_.eval(ls.wi);
        ls.dist = kInf;
        return ls.pdf > 0.0f;
    }
    if (transmissive) {
        const float z = 1.0f - 2.0f * u1;
        const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
        const float phi = 2.0f * kPi * u2;
        ls.wi = Vec3f(r * std::cos(phi), r * std::sin(phi), z);
    } else {
        const Vec3f local = sample_cosine_hemisphere(u1, u2);
        Vec3f t, b;
        make_basis(n, t, b);
        ls.wi = t * local.x + b * local.y + n * local.z;
    }
    ls.pdf = world_pick_ * world_pdf(ls.wi, n, transmissive);
    ls.li = world_color_;
    ls.dist = kInf;
    return ls.pdf > 0.0f;
}

// Solid angle where the triangle's plane is nearer than its longest edge:
// there area sampling's d^2 / cos varies most over the triangle. Farther
// away both pdfs converge and area sampling costs less. Cycles 3.4 makes the
// same kind of choice. Measured (bench/efficiency_gap.py, public Cornell box,
// 256 spp, 4 bounces): RMSE/Cycles 1.15 by area only; 0.97 with this, with
// the threshold at 2x the edge and with solid angle everywhere, at 7 %, 11 %
// and 20 % more time than area only; efficiency 1.04 -> 1.37, 1.32, 1.23.
bool LightSet::triangle_by_solid_angle(uint32_t tri, const Vec3f& p, SphericalTriangle& st) const {
    const Vec3f* v = &scene_->vertices[3 * size_t(tri)];
    const float to_plane = dot(scene_->geometric_normals[tri], v[0] - p);
    const float longest2 =
        std::max({length_squared(v[1] - v[0]), length_squared(v[2] - v[0]), length_squared(v[2] - v[1])});
    if (!(to_plane * to_plane < longest2)) return false;
    return make_spherical_triangle(p, v[0], v[1], v[2], st) && st.solid_angle >= SphericalTriangle::kMinSolidAngle;
}

bool LightSet::sample_triangle(const Vec3f& p, float u_pick, float u1, float u2, LightSample& ls) const {
    const size_t i = std::min(size_t(std::upper_bound(tri_cdf_.begin(), tri_cdf_.end(), u_pick) - tri_cdf_.begin()),
                              tri_cdf_.size() - 1);
    const uint32_t tri = tri_ids_[i];
    const Vec3f* v = &scene_->vertices[3 * size_t(tri)];
    SphericalTriangle st;
    const bool by_solid_angle = triangle_by_solid_angle(tri, p, st);
    float b1, b2;  // barycentrics of v[1], v[2]
    if (by_solid_angle) {
        // The sampled direction's point on the triangle (Moller-Trumbore), held
        // inside it against rounding so that no sample is lost at the edges.
        const Vec3f d = sample_spherical_triangle(st, u1, u2);
        const Vec3f e1 = v[1] - v[0], e2 = v[2] - v[0];
        const Vec3f pv = cross(d, e2);
        const float det = dot(e1, pv);
        if (!(det != 0.0f)) return false;
        const Vec3f tv = p - v[0];
        b1 = std::max(0.0f, dot(tv, pv) / det);
        b2 = std::max(0.0f, dot(d, cross(tv, e1)) / det);
        if (b1 + b2 > 1.0f) {
            const float s = 1.0f / (b1 + b2);
            b1 *= s;
            b2 *= s;
        }
    } else {
        const float su = std::sqrt(u1);
        b1 = u2 * su;
        b2 = 1.0f - (1.0f - su) - b1;
    }
    const Vec3f q = triangle_point(v[0], v[1], v[2], b1, b2, ls.p_light_error);
    const Vec3f to = q - p;
    const float d2 = length_squared(to);
    const float d = std::sqrt(d2);
    if (!(d > 0.0f)) return false;
    ls.wi = to / d;
    const Vec3f ng = scene_->geometric_normals[tri];
    const float cos_l = std::fabs(dot(ng, ls.wi));  // emission is two-sided, as in Cycles
    if (!(cos_l > 0.0f)) return false;
    ls.dist = d;
    ls.li = scene_->materials[scene_->material_of[tri]].emission;
    const float pick = tri_unit_pick_ * tri_pick_[tri];
    ls.pdf = by_solid_angle ? pick / st.solid_angle : pick / tri_area_[i] * d2 / cos_l;
    ls.on_surface = true;
    ls.p_light = q;
    ls.n_light = dot(ng, ls.wi) < 0.0f ? ng : -ng;  // facing the shading point
    return ls.pdf > 0.0f && std::isfinite(ls.pdf);
}

float LightSet::triangle_pdf(uint32_t tri, const Vec3f& o, const Vec3f& p_light, const Vec3f& n_light) const {
    if (!triangles_ || tri >= tri_pick_.size() || tri_pick_[tri] <= 0.0f) return 0.0f;
    const float pick = tri_unit_pick_ * tri_pick_[tri];
    SphericalTriangle st;
    if (triangle_by_solid_angle(tri, o, st)) return pick / st.solid_angle;
    const Vec3f* v = &scene_->vertices[3 * size_t(tri)];
    const float area = 0.5f * length(cross(v[1] - v[0], v[2] - v[0]));
    const Vec3f to = p_light - o;
    const float d2 = length_squared(to);
    const float cos_l = std::fabs(dot(n_light, to)) / std::sqrt(d2);
    if (!(cos_l > 0.0f) || !(area > 0.0f)) return 0.0f;
    return pick / area * d2 / cos_l;
}

Vec3f LightSet::hit_lights(const Vec3f& o, const Vec3f& d, float tmax, float bsdf_pdf, float tmin) const {
    Vec3f sum(0.0f);
    for (const LightRecord& l : lights_) {
        if (l.type == LightType::Area) {
            const float denom = dot(d, l.direction);
            if (!(denom < 0.0f)) continue;  // only the front side emits
            const float t = dot(l.position - o, l.direction) / denom;
            if (!(t > tmin) || !(t < tmax)) continue;
            const Vec3f q = o + d * t - l.position;
            const float x = dot(q, l.axis_u) / l.half_u, y = dot(q, l.axis_v) / l.half_v;
            const bool round = l.shape == AreaShape::Disk || l.shape == AreaShape::Ellipse;
            if (round ? (x * x + y * y > 1.0f) : (std::fabs(x) > 1.0f || std::fabs(y) > 1.0f)) continue;
            float w = 1.0f;
            if (bsdf_pdf > 0.0f) {
                SphericalRect sr;
                const float light_pdf = is_rect(l) && make_spherical_rect(o, l, sr)
                                            ? l.pick / float(sr.solid_angle)
                                            : l.pick * t * t / (l.area * -denom);
                w = power_heuristic(bsdf_pdf, light_pdf);
            }
            sum += l.radiance * w;
        } else if ((l.type == LightType::Point || l.type == LightType::Spot) && l.radius > 0.0f) {
            const Vec3f to = l.position - o;
            const float dist = length(to);
            if (!(dist > 0.0f)) continue;
            const Vec3f w_c = to / dist;
            const float cos_c = dot(d, w_c);
            if (!(cos_c > 0.0f)) continue;
            const float omc = disc_one_minus_cos(l.radius, dist);
            if (one_minus_cos_between(d, w_c) > omc) continue;
            const float t_disc = dist / cos_c;  // the disc faces o at distance `dist`
            if (!(t_disc < tmax) || !(t_disc > tmin)) continue;
            const float light_pdf = l.pick / (2.0f * kPi * omc);
            const float w = bsdf_pdf > 0.0f ? power_heuristic(bsdf_pdf, light_pdf) : 1.0f;
            sum += l.radiance * (spot_attenuation(l, -d) * w);
        }
    }
    return sum;
}

Vec3f LightSet::world_radiance(const Vec3f& d) const {
    if (!has_map_) return world_color_;
    return env_.empty() ? Vec3f(0.0f) : world_color_ * env_.eval(d);
}

Vec3f LightSet::escaped(const Vec3f& d, const Vec3f& n, bool transmissive, float bsdf_pdf) const {
    Vec3f sum(0.0f);
    if (world_) {
        const float light_pdf = world_pick_ * world_pdf(d, n, transmissive);
        const float w = bsdf_pdf > 0.0f ? power_heuristic(bsdf_pdf, light_pdf) : 1.0f;
        sum += world_radiance(d) * w;
    }
    for (const LightRecord& l : lights_) {
        if (l.type != LightType::Sun || !(l.sun_solid_angle > 0.0f)) continue;
        if (one_minus_cos_between(d, -l.direction) > 1.0f - l.cos_half_sun) continue;
        const float light_pdf = l.pick / l.sun_solid_angle;
        const float w = bsdf_pdf > 0.0f ? power_heuristic(bsdf_pdf, light_pdf) : 1.0f;
        sum += l.radiance * w;
    }
    return sum;
}

}  // namespace coherent
