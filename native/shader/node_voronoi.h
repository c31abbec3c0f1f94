// Voronoi (Worley) noise as Blender 3.4's Cycles computes it (intern/cycles/
// kernel/svm/voronoi.h, after Inigo Quilez): one jittered feature point per
// unit cell, placed by the lookup3 hash of the cell; F1, F2 and smooth F1 scan
// the neighbouring cells, distance to edge and n-sphere radius follow
// Quilez' two-pass method. Cells are visited in Cycles' order (x fastest),
// so ties resolve the same way.
#pragma once

#include <algorithm>
#include <cfloat>
#include <cmath>

#include "node_hash.h"

namespace coherent::shader {

enum class VoronoiFeature : uint16_t { F1 = 0, F2 = 1, SmoothF1 = 2, DistanceToEdge = 3, NSphereRadius = 4, Count };
enum class VoronoiMetric : uint16_t { Euclidean = 0, Manhattan = 1, Chebychev = 2, Minkowski = 3, Count };

struct VoronoiParams {
    VoronoiMetric metric = VoronoiMetric::Euclidean;
    float exponent = 1.0f, randomness = 1.0f, smoothness = 0.0f;
};

template <int N>
struct VoronoiResult {
    float distance = 0.0f;
    Vec3f color{0.0f, 0.0f, 0.0f};
    Pt<N> position = splat<N>(0.0f);
};

// Cycles' float4 dot sums in pairs (SSE4.1 dpps); smaller points in order.
template <int N>
float cycles_dot(const Pt<N>& a, const Pt<N>& b) {
    if constexpr (N == 4) return (a[0] * b[0] + a[1] * b[1]) + (a[2] * b[2] + a[3] * b[3]);
    else return dot(a, b);
}
template <int N>
float length_squared(const Pt<N>& d) { return cycles_dot(d, d); }
template <int N>
float euclidean(const Pt<N>& a, const Pt<N>& b) { return std::sqrt(length_squared(a - b)); }

template <int N>
float voronoi_distance(const Pt<N>& a, const Pt<N>& b, const VoronoiParams& p) {
    if constexpr (N == 1) return std::fabs(b[0] - a[0]);  // 1D ignores the metric
    switch (p.metric) {
        case VoronoiMetric::Euclidean: return euclidean(a, b);
        case VoronoiMetric::Manhattan: {
            float s = std::fabs(a[0] - b[0]);
            for (int i = 1; i < N; ++i) s += std::fabs(a[i] - b[i]);
            return s;
        }
        case VoronoiMetric::Chebychev: {
            float s = std::fabs(a[0] - b[0]);
            for (int i = 1; i < N; ++i) s = std::max(s, std::fabs(a[i] - b[i]));
            return s;
        }
        case VoronoiMetric::Minkowski: {
            float s = std::pow(std::fabs(a[0] - b[0]), p.exponent);
            for (int i = 1; i < N; ++i) s += std::pow(std::fabs(a[i] - b[i]), p.exponent);
            return std::pow(s, 1.0f / p.exponent);
        }
        case VoronoiMetric::Count: break;
    }
    return 0.0f;
}

// The offset of neighbour `index` of a (2 r + 1)^N block, component 0 fastest.
template <int N>
Pt<N> neighbour(int index, int r) {
    Pt<N> o;
    for (int i = 0; i < N; ++i) {
        o[i] = float(index % (2 * r + 1) - r);
        index /= 2 * r + 1;
    }
    return o;
}
template <int N>
constexpr int neighbour_count(int r) {
    int n = 1;
    for (int i = 0; i < N; ++i) n *= 2 * r + 1;
    return n;
}

template <int N>
Pt<N> feature_point(const Pt<N>& cell, const Pt<N>& offset, float randomness) {
    return offset + hash_to_point(cell + offset) * randomness;
}

template <int N>
VoronoiResult<N> voronoi_f1(const Pt<N>& coord, const VoronoiParams& p) {
    const Pt<N> cell = floor(coord), local = coord - cell;
    float min_distance = FLT_MAX;
    Pt<N> target_offset = splat<N>(0.0f), target = splat<N>(0.0f);
    for (int k = 0; k < neighbour_count<N>(1); ++k) {
        const Pt<N> offset = neighbour<N>(k, 1);
        const Pt<N> point = feature_point(cell, offset, p.randomness);
        const float d = voronoi_distance(point, local, p);
        if (d < min_distance) {
            target_offset = offset;
            min_distance = d;
            target = point;
        }
    }
    return {min_distance, hash_to_color(cell + target_offset), target + cell};
}

template <int N>
VoronoiResult<N> voronoi_f2(const Pt<N>& coord, const VoronoiParams& p) {
    const Pt<N> cell = floor(coord), local = coord - cell;
    float d1 = FLT_MAX, d2 = FLT_MAX;
    Pt<N> offset1 = splat<N>(0.0f), position1 = offset1, offset2 = offset1, position2 = offset1;
    for (int k = 0; k < neighbour_count<N>(1); ++k) {
        const Pt<N> offset = neighbour<N>(k, 1);
        const Pt<N> point = feature_point(cell, offset, p.randomness);
        const float d = voronoi_distance(point, local, p);
        if (d < d1) {
            d2 = d1, d1 = d;
            offset2 = offset1, offset1 = offset;
            position2 = position1, position1 = point;
        } else if (d < d2) {
            d2 = d, offset2 = offset, position2 = point;
        }
    }
    return {d2, hash_to_color(cell + offset2), position2 + cell};
}

inline float smoothstep01(float x) {
    if (x < 0.0f) return 0.0f;
    if (x >= 1.0f) return 1.0f;
    return (3.0f - 2.0f * x) * (x * x);
}

template <int N>
VoronoiResult<N> voronoi_smooth_f1(const Pt<N>& coord, const VoronoiParams& p) {
    const Pt<N> cell = floor(coord), local = coord - cell;
    float smooth_distance = 0.0f, h = -1.0f;
    Vec3f smooth_color{0.0f, 0.0f, 0.0f};
    Pt<N> smooth_position = splat<N>(0.0f);
    for (int k = 0; k < neighbour_count<N>(2); ++k) {
        const Pt<N> offset = neighbour<N>(k, 2);
        const Pt<N> point = feature_point(cell, offset, p.randomness);
        const float d = voronoi_distance(point, local, p);
        h = h == -1.0f ? 1.0f : smoothstep01(0.5f + 0.5f * (smooth_distance - d) / p.smoothness);
        float correction = p.smoothness * h * (1.0f - h);
        smooth_distance = mix(smooth_distance, d, h) - correction;
        correction /= 1.0f + 3.0f * p.smoothness;
        smooth_color = mix(smooth_color, hash_to_color(cell + offset), h) - Vec3f(correction);
        smooth_position = mix(smooth_position, point, h) - splat<N>(correction);
    }
    return {smooth_distance, smooth_color, cell + smooth_position};
}

template <int N>
float voronoi_distance_to_edge(const Pt<N>& coord, float randomness) {
    const Pt<N> cell = floor(coord), local = coord - cell;
    if constexpr (N == 1) {
        const float mid = hash_to_float(cell[0]) * randomness;
        const float left = -1.0f + hash_to_float(cell[0] - 1.0f) * randomness;
        const float right = 1.0f + hash_to_float(cell[0] + 1.0f) * randomness;
        return std::min(std::fabs((mid + left) / 2.0f - local[0]), std::fabs((mid + right) / 2.0f - local[0]));
    } else {
        Pt<N> to_closest = splat<N>(0.0f);
        float min_distance = FLT_MAX;
        for (int k = 0; k < neighbour_count<N>(1); ++k) {
            const Pt<N> to_point = feature_point(cell, neighbour<N>(k, 1), randomness) - local;
            const float d = length_squared(to_point);
            if (d < min_distance) min_distance = d, to_closest = to_point;
        }
        min_distance = FLT_MAX;
        for (int k = 0; k < neighbour_count<N>(1); ++k) {
            const Pt<N> to_point = feature_point(cell, neighbour<N>(k, 1), randomness) - local;
            const Pt<N> perpendicular = to_point - to_closest;
            const float l2 = length_squared(perpendicular);
            if (l2 > 0.0001f) {
                const Pt<N> mid = (to_closest + to_point) / 2.0f;
                const Pt<N> normal = perpendicular / std::sqrt(l2);
                min_distance = std::min(min_distance, cycles_dot(mid, normal));
            }
        }
        return min_distance;
    }
}

template <int N>
float voronoi_n_sphere_radius(const Pt<N>& coord, float randomness) {
    const Pt<N> cell = floor(coord), local = coord - cell;
    Pt<N> closest = splat<N>(0.0f), closest_offset = splat<N>(0.0f);
    float min_distance = FLT_MAX;
    for (int k = 0; k < neighbour_count<N>(1); ++k) {
        const Pt<N> offset = neighbour<N>(k, 1);
        const Pt<N> point = feature_point(cell, offset, randomness);
        const float d = euclidean(point, local);
        if (d < min_distance) min_distance = d, closest = point, closest_offset = offset;
    }
    min_distance = FLT_MAX;
    Pt<N> closest_to_closest = splat<N>(0.0f);
    for (int k = 0; k < neighbour_count<N>(1); ++k) {
        if (k == neighbour_count<N>(1) / 2) continue;  // the centre: the closest point itself
        const Pt<N> offset = neighbour<N>(k, 1) + closest_offset;
        const Pt<N> point = feature_point(cell, offset, randomness);
        const float d = euclidean(closest, point);
        if (d < min_distance) min_distance = d, closest_to_closest = point;
    }
    return euclidean(closest_to_closest, closest) / 2.0f;
}

}  // namespace coherent::shader
