// Procedural meshes and a brute-force oracle shared by the BVH tests.
// Header-only (tests/native/*.cpp are globbed; this is not a test unit).
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <random>
#include <utility>
#include <vector>

#include "accel/triangle.h"
#include "core/ray.h"
#include "core/vec.h"

namespace coherent::testing_meshes {

// Triangle soup of `n` random triangles of size up to `size` in [-extent, extent]^3.
inline std::vector<Vec3f> random_soup(size_t n, uint32_t seed, float extent = 10.0f, float size = 1.0f) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> pos(-extent, extent), off(-size, size);
    std::vector<Vec3f> v;
    v.reserve(3 * n);
    for (size_t i = 0; i < n; ++i) {
        const Vec3f c(pos(rng), pos(rng), pos(rng));
        for (int k = 0; k < 3; ++k) v.push_back(c + Vec3f(off(rng), off(rng), off(rng)));
    }
    return v;
}

// Indexed mesh: shared vertices are bit-identical in every triangle using them.
struct IndexedMesh {
    std::vector<Vec3f> positions;
    std::vector<std::array<uint32_t, 3>> triangles;

    std::vector<Vec3f> soup() const {
        std::vector<Vec3f> v;
        v.reserve(3 * triangles.size());
        for (const auto& t : triangles)
            for (uint32_t i : t) v.push_back(positions[i]);
        return v;
    }
    // Every undirected edge once, as a vertex-index pair.
    std::vector<std::pair<uint32_t, uint32_t>> edges() const {
        std::map<std::pair<uint32_t, uint32_t>, int> seen;
        for (const auto& t : triangles)
            for (int k = 0; k < 3; ++k) {
                uint32_t a = t[k], b = t[(k + 1) % 3];
                if (a > b) std::swap(a, b);
                seen[{a, b}]++;
            }
        std::vector<std::pair<uint32_t, uint32_t>> out;
        for (const auto& [e, count] : seen) out.push_back(e);
        return out;
    }
};

// Icosphere of radius `radius` about `center`, `levels` times subdivided.
// The vertices are computed about the origin then translated in float, so
// that shared vertices stay bit-identical far from the origin.
inline IndexedMesh icosphere(int levels, float radius, const Vec3f& center) {
    const float p = (1.0f + std::sqrt(5.0f)) * 0.5f;
    std::vector<Vec3f> pos = {{-1, p, 0}, {1, p, 0}, {-1, -p, 0}, {1, -p, 0}, {0, -1, p}, {0, 1, p},
                              {0, -1, -p}, {0, 1, -p}, {p, 0, -1}, {p, 0, 1}, {-p, 0, -1}, {-p, 0, 1}};
    std::vector<std::array<uint32_t, 3>> tris = {
        {0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
        {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8}, {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
    for (auto& v : pos) v = normalize(v);
    for (int l = 0; l < levels; ++l) {
        std::map<std::pair<uint32_t, uint32_t>, uint32_t> mid;
        auto midpoint = [&](uint32_t a, uint32_t b) {
            auto key = std::make_pair(std::min(a, b), std::max(a, b));
            auto it = mid.find(key);
            if (it != mid.end()) return it->second;
            pos.push_back(normalize(pos[a] + pos[b]));
            const uint32_t i = static_cast<uint32_t>(pos.size() - 1);
            mid[key] = i;
            return i;
        };
        std::vector<std::array<uint32_t, 3>> next;
        for (const auto& t : tris) {
            const uint32_t a = midpoint(t[0], t[1]), b = midpoint(t[1], t[2]), c = midpoint(t[2], t[0]);
            next.push_back({t[0], a, c});
            next.push_back({t[1], b, a});
            next.push_back({t[2], c, b});
            next.push_back({a, b, c});
        }
        tris = std::move(next);
    }
    IndexedMesh m;
    for (const auto& v : pos) m.positions.push_back(v * radius + center);
    m.triangles = tris;
    return m;
}

// Axis-aligned cube [lo, lo + n*step]^3, each face an n x n grid of quads
// split into two triangles. With integer lo and step, every coordinate is exact.
inline IndexedMesh tessellated_cube(int n, float step, const Vec3f& lo) {
    IndexedMesh m;
    std::map<std::array<int, 3>, uint32_t> index;
    auto vertex = [&](int i, int j, int k) {
        const std::array<int, 3> key{i, j, k};
        auto it = index.find(key);
        if (it != index.end()) return it->second;
        m.positions.push_back(lo + Vec3f(i * step, j * step, k * step));
        const uint32_t id = static_cast<uint32_t>(m.positions.size() - 1);
        index[key] = id;
        return id;
    };
    for (int axis = 0; axis < 3; ++axis)
        for (int side = 0; side <= 1; ++side)
            for (int a = 0; a < n; ++a)
                for (int b = 0; b < n; ++b) {
                    auto corner = [&](int da, int db) {
                        int c[3];
                        c[axis] = side * n;
                        c[(axis + 1) % 3] = a + da;
                        c[(axis + 2) % 3] = b + db;
                        return vertex(c[0], c[1], c[2]);
                    };
                    const uint32_t v00 = corner(0, 0), v10 = corner(1, 0), v01 = corner(0, 1), v11 = corner(1, 1);
                    // Alternate the diagonal so that both orientations are exercised.
                    if ((a + b) % 2 == 0) {
                        m.triangles.push_back({v00, v10, v11});
                        m.triangles.push_back({v00, v11, v01});
                    } else {
                        m.triangles.push_back({v00, v10, v01});
                        m.triangles.push_back({v10, v11, v01});
                    }
                }
    return m;
}

// Closest hit by testing every triangle, with the BVH's tie rule (smallest t,
// then smallest triangle index) so that results must match exactly.
inline Hit brute_force_closest(const std::vector<Vec3f>& soup, const Ray& ray) {
    Hit best;
    const WatertightRay wr(ray.o, ray.d);
    for (size_t i = 0; i < soup.size() / 3; ++i) {
        if (!is_finite(soup[3 * i]) || !is_finite(soup[3 * i + 1]) || !is_finite(soup[3 * i + 2])) continue;
        TriangleHit th;
        if (!intersect_triangle_watertight(wr, soup[3 * i], soup[3 * i + 1], soup[3 * i + 2], ray.tmin, ray.tmax, th))
            continue;
        if (th.t < best.t || !best.valid()) {
            best.t = th.t;
            best.u = th.u;
            best.v = th.v;
            best.prim = static_cast<uint32_t>(i);
        }
    }
    return best;
}

// All hits along a ray (t values), for counting surface crossings.
inline std::vector<float> brute_force_all(const std::vector<Vec3f>& soup, const Ray& ray) {
    std::vector<float> ts;
    const WatertightRay wr(ray.o, ray.d);
    for (size_t i = 0; i < soup.size() / 3; ++i) {
        TriangleHit th;
        if (intersect_triangle_watertight(wr, soup[3 * i], soup[3 * i + 1], soup[3 * i + 2], ray.tmin, ray.tmax, th))
            ts.push_back(th.t);
    }
    return ts;
}

inline Vec3f random_unit(std::mt19937& rng) {
    std::normal_distribution<float> g(0.0f, 1.0f);
    while (true) {
        const Vec3f v(g(rng), g(rng), g(rng));
        const float l = length(v);
        if (l > 1e-3f) return v / l;
    }
}

// Rays from random points in a box toward random directions, some with the
// origin far outside so that many miss; some with a positive tmin or a
// finite tmax.
inline std::vector<Ray> random_rays(size_t n, uint32_t seed, float extent) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> pos(-1.5f * extent, 1.5f * extent);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    std::vector<Ray> rays(n);
    for (auto& r : rays) {
        r.o = Vec3f(pos(rng), pos(rng), pos(rng));
        // Un-normalised directions exercise t in units of |d|.
        r.d = random_unit(rng) * (0.25f + 2.0f * unit(rng));
        r.tmin = unit(rng) < 0.2f ? 0.5f * unit(rng) : 0.0f;
        r.tmax = unit(rng) < 0.3f ? 1.0f + 30.0f * unit(rng) : kInf;
    }
    return rays;
}

// Rays from a sphere around box `b` toward random points inside it: most
// hit what the box holds, from every side.
inline std::vector<Ray> rays_into_box(const BBox& b, size_t n, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    const Vec3f c = b.center();
    const float r = length(b.extent());
    std::vector<Ray> rays(n);
    for (Ray& ray : rays) {
        ray.o = c + random_unit(rng) * r;
        const float x = unit(rng), y = unit(rng), z = unit(rng);
        ray.d = b.lo + b.extent() * Vec3f(x, y, z) - ray.o;
    }
    return rays;
}

}  // namespace coherent::testing_meshes
