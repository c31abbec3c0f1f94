// Small scene builders and statistics shared by the render tests.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <utility>
#include <vector>

#include "film/film.h"
#include "render/renderer.h"
#include "scene/scene.h"

namespace coherent::test {

inline Material diffuse_material(const Vec3f& color, const char* name = "diffuse") {
    Material m;
    m.name = name;
    m.closures[0].base_color = color;
    m.closures[0].specular = 0.0f;
    m.closures[0].metallic = 0.0f;
    m.closures[0].roughness = 0.5f;
    return m;
}

// One principled closure with constant inputs (Lambert diffuse unless stated).
inline Material principled(float base, float metallic, float roughness, float specular, float transmission,
                           float ior = 1.5f) {
    Material m;
    Closure& c = m.closures[0];
    c.base_color = Vec3f(base);
    c.metallic = metallic;
    c.roughness = roughness;
    c.specular = specular;
    c.transmission = transmission;
    c.ior = ior;
    return m;
}

inline Material emission_material(const Vec3f& radiance) {
    Material m = diffuse_material(Vec3f(0.0f), "emission");
    m.emission = radiance;
    return m;
}

// Axis-aligned quad in the plane through `center` spanned by unit vectors
// (u, v), extents su x sv, facing cross(u, v).
inline void add_quad(Scene& s, const Vec3f& center, const Vec3f& u, const Vec3f& v, float su, float sv,
                     uint32_t material, const char* name = "quad") {
    const Vec3f a = center - u * (0.5f * su) - v * (0.5f * sv);
    const Vec3f b = center + u * (0.5f * su) - v * (0.5f * sv);
    const Vec3f c = center + u * (0.5f * su) + v * (0.5f * sv);
    const Vec3f d = center - u * (0.5f * su) + v * (0.5f * sv);
    const float pos[] = {a.x, a.y, a.z, b.x, b.y, b.z, c.x, c.y, c.z, d.x, d.y, d.z};
    const uint32_t idx[] = {0, 1, 2, 0, 2, 3};
    MeshInput m;
    m.name = name;
    m.positions = pos;
    m.vertex_count = 4;
    m.indices = idx;
    m.triangle_count = 2;
    m.material_slots = {material};
    s.add_mesh(m);
}

// UV sphere with smooth per-corner normals.
inline void add_sphere(Scene& s, const Vec3f& center, float radius, uint32_t material, int rings = 48,
                       int segments = 96) {
    std::vector<float> pos;
    for (int r = 0; r <= rings; ++r) {
        const float theta = kPi * float(r) / float(rings);
        for (int k = 0; k < segments; ++k) {
            const float phi = 2.0f * kPi * float(k) / float(segments);
            pos.push_back(center.x + radius * std::sin(theta) * std::cos(phi));
            pos.push_back(center.y + radius * std::sin(theta) * std::sin(phi));
            pos.push_back(center.z + radius * std::cos(theta));
        }
    }
    std::vector<uint32_t> idx;
    std::vector<float> nrm;
    auto vid = [&](int r, int k) { return uint32_t(r * segments + (k % segments)); };
    auto push = [&](uint32_t a, uint32_t b, uint32_t c) {
        for (uint32_t i : {a, b, c}) {
            idx.push_back(i);
            const Vec3f p{pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]};
            const Vec3f n = normalize(p - center);
            nrm.insert(nrm.end(), {n.x, n.y, n.z});
        }
    };
    for (int r = 0; r < rings; ++r)
        for (int k = 0; k < segments; ++k) {
            // Outward winding: (p00, p10, p11) has normal along +radius.
            if (r != 0) push(vid(r, k), vid(r + 1, k), vid(r, k + 1));
            if (r != rings - 1) push(vid(r, k + 1), vid(r + 1, k), vid(r + 1, k + 1));
        }
    MeshInput m;
    m.name = "sphere";
    m.positions = pos.data();
    m.vertex_count = pos.size() / 3;
    m.indices = idx.data();
    m.triangle_count = idx.size() / 3;
    m.normals = nrm.data();
    m.material_slots = {material};
    s.add_mesh(m);
}

// Blender-style camera frame: right x up = -forward, world +z as the up hint.
inline Camera perspective_camera(const Vec3f& position, const Vec3f& target, float half_fov_tan) {
    Camera c;
    c.projection = Projection::Perspective;
    c.position = position;
    c.forward = normalize(target - position);
    const Vec3f hint = std::fabs(c.forward.z) > 0.99f ? Vec3f(0, 1, 0) : Vec3f(0, 0, 1);
    c.right = normalize(cross(c.forward, hint));
    c.up = cross(c.right, c.forward);
    c.half_width = c.half_height = half_fov_tan;
    return c;
}

inline Camera ortho_camera_looking_down(float height, float half_extent) {
    Camera c;
    c.projection = Projection::Orthographic;
    c.position = {0.0f, 0.0f, height};
    c.right = {1.0f, 0.0f, 0.0f};
    c.up = {0.0f, 1.0f, 0.0f};
    c.forward = {0.0f, 0.0f, -1.0f};
    c.half_width = c.half_height = half_extent;
    return c;
}

struct MeanVar {
    double mean = 0.0, var = 0.0;  // var: sample variance of the values
    size_t n = 0;
    double stderr_of_mean() const { return n > 1 ? std::sqrt(var / double(n)) : 0.0; }
};

inline MeanVar mean_var(const std::vector<double>& v) {
    MeanVar r;
    r.n = v.size();
    for (double x : v) r.mean += x;
    r.mean /= double(std::max<size_t>(r.n, 1));
    for (double x : v) r.var += (x - r.mean) * (x - r.mean);
    r.var /= double(std::max<size_t>(r.n, 2) - 1);
    return r;
}

// Paired differences between two renders of the same image over many seeds
// (e.g. with and without a sampling rule that must not bias it): of the
// image mean and of a few pixels. expect_zero_mean() asserts each mean
// difference is 0 within 4 standard errors (a pixel whose samples are the
// same in both gives exactly 0).
struct PairedDifferences {
    int width;
    std::vector<std::pair<int, int>> pixels;  // (x, y)
    std::vector<double> image{};  // a default: brace-initialised without it, GCC warns (-Wmissing-field-initializers)
    std::vector<std::vector<double>> at = std::vector<std::vector<double>>(pixels.size());

    // a, b: RGBA images of `width` columns.
    void add(const std::vector<float>& a, const std::vector<float>& b);
    void expect_zero_mean(const char* what) const;
};

// Mean of the RGB channels of an RGBA image (Film::resolve(Combined)).
inline double image_mean(const std::vector<float>& img) {
    double m = 0.0;
    for (size_t i = 0; i < img.size(); i += 4) m += img[i] + img[i + 1] + img[i + 2];
    return m / (3.0 * double(img.size() / 4));
}

inline void PairedDifferences::add(const std::vector<float>& a, const std::vector<float>& b) {
    image.push_back(image_mean(a) - image_mean(b));
    for (size_t k = 0; k < pixels.size(); ++k) {
        const size_t i = 4 * (size_t(pixels[k].second) * size_t(width) + size_t(pixels[k].first));
        at[k].push_back((a[i] + a[i + 1] + a[i + 2] - b[i] - b[i + 1] - b[i + 2]) / 3.0);
    }
}

inline void PairedDifferences::expect_zero_mean(const char* what) const {
    const MeanVar img = mean_var(image);
    std::printf("%s: image diff %.2e +- %.2e (%.2f sigma)\n", what, img.mean, img.stderr_of_mean(),
                img.mean / img.stderr_of_mean());
    EXPECT_GT(img.stderr_of_mean(), 0.0);
    EXPECT_LT(std::abs(img.mean), 4.0 * img.stderr_of_mean());
    for (size_t k = 0; k < pixels.size(); ++k) {
        const MeanVar p = mean_var(at[k]);
        std::printf("  pixel (%d,%d): diff %.2e +- %.2e\n", pixels[k].first, pixels[k].second, p.mean,
                    p.stderr_of_mean());
        EXPECT_LE(std::abs(p.mean), 4.0 * p.stderr_of_mean() + 1e-7);
    }
}

inline std::vector<float> render_combined(const Scene& scene, const RenderSettings& rs, RenderStats* stats = nullptr) {
    Renderer r(scene, rs);
    r.render();
    if (stats) *stats = r.stats();
    return r.film().resolve(PassType::Combined);
}

// A diffuse sphere on a floor under a small area light and a dim world: a
// smooth lit floor next to soft shadows, the sphere's rim and indirect light.
// Used where a second scene besides the Cornell box is wanted.
inline Scene sphere_on_floor_scene() {
    Scene s;
    const uint32_t white = s.add_material(diffuse_material(Vec3f(0.7f)));
    const uint32_t red = s.add_material(diffuse_material(Vec3f(0.8f, 0.2f, 0.1f)));
    const uint32_t light = s.add_material(emission_material(Vec3f(4.0f)));
    add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 6.0f, 6.0f, white, "floor");
    add_sphere(s, {0, 0, 1}, 1.0f, red, 16, 32);
    add_quad(s, {1, 1, 4}, {0, 1, 0}, {1, 0, 0}, 2.5f, 2.5f, light, "light");  // faces -z
    Camera c;
    c.position = {0.0f, -6.0f, 3.0f};
    c.forward = normalize(Vec3f(0.0f, 6.0f, -2.5f));
    c.right = {1.0f, 0.0f, 0.0f};
    c.up = normalize(cross(c.right, c.forward));
    c.half_width = c.half_height = 0.6f;
    s.camera = c;
    s.world_color = Vec3f(0.2f);
    s.finalize();
    return s;
}

// Every lobe the integrators tell apart: a diffuse floor and sphere, a
// mirror, a rough metal, a glass sphere, an area light and a dim world,
// optionally seen through a lens with depth of field. From farther away
// (camera_distance 9) camera rays also miss everything at the image's edges.
inline Scene lobes_scene(bool depth_of_field, float camera_distance = 7.0f) {
    Scene s;
    const uint32_t white = s.add_material(diffuse_material(Vec3f(0.7f)));
    const uint32_t red = s.add_material(diffuse_material(Vec3f(0.8f, 0.2f, 0.1f)));
    const uint32_t mirror = s.add_material(principled(0.9f, 1.0f, 0.0f, 0.5f, 0.0f));
    const uint32_t rough = s.add_material(principled(0.8f, 1.0f, 0.3f, 0.5f, 0.0f));
    const uint32_t glass = s.add_material(principled(1.0f, 0.0f, 0.0f, 0.5f, 1.0f, 1.45f));
    const uint32_t light = s.add_material(emission_material(Vec3f(6.0f)));
    add_quad(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 8.0f, 8.0f, white, "floor");
    add_quad(s, {0, 3, 2}, {1, 0, 0}, {0, 0, 1}, 8.0f, 4.0f, mirror, "mirror wall");
    add_sphere(s, {-1.5f, 0, 1}, 1.0f, red, 12, 24);
    add_sphere(s, {1.5f, 0.5f, 0.8f}, 0.8f, glass, 12, 24);
    add_sphere(s, {0.0f, -1.5f, 0.5f}, 0.5f, rough, 10, 20);
    add_quad(s, {0, 0, 5}, {0, 1, 0}, {1, 0, 0}, 2.5f, 2.5f, light, "light");
    Camera c;
    c.position = {0.0f, -camera_distance, 3.0f};
    c.forward = normalize(Vec3f(0.0f, camera_distance, -2.5f));
    c.right = {1.0f, 0.0f, 0.0f};
    c.up = normalize(cross(c.right, c.forward));
    c.half_width = c.half_height = 0.6f;
    if (depth_of_field) {
        c.aperture_radius = 0.15f;
        c.focus_distance = camera_distance;
    }
    s.camera = c;
    s.world_color = Vec3f(0.1f);
    s.finalize();
    return s;
}

}  // namespace coherent::test
