// Geometry > Random Per Island, as Cycles 3.4 computes it
// (blender/mesh.cpp attr_create_random_per_island): the mesh's vertices are
// joined edge by edge, in edge order, in a disjoint set with union by rank
// (util/disjoint_set.h), and each triangle reads the hash of the set
// representative of its first vertex. The representative depends on the
// order and on the rank rule, not only on the island, so both are kept
// exactly; it runs sequentially, which is why this lives in native code
// rather than in the exporter's numpy.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "../shader/node_hash.h"

namespace coherent {

class VertexIslands {
public:
    explicit VertexIslands(size_t vertex_count) : parent_(vertex_count), rank_(vertex_count, 0) {
        for (size_t i = 0; i < vertex_count; ++i) parent_[i] = i;
    }

    // The representative of x's island (path compression changes no representative).
    size_t find(size_t x) {
        size_t root = x;
        while (parent_[root] != root) root = parent_[root];
        while (parent_[x] != root) {
            const size_t up = parent_[x];
            parent_[x] = root;
            x = up;
        }
        return root;
    }

    // Cycles' DisjointSet::join: the lower-ranked root goes under the other;
    // on equal ranks, y's root goes under x's.
    void join(size_t x, size_t y) {
        size_t rx = find(x), ry = find(y);
        if (rx == ry) return;
        if (rank_[rx] < rank_[ry]) std::swap(rx, ry);
        parent_[ry] = rx;
        if (rank_[rx] == rank_[ry]) ++rank_[rx];
    }

private:
    std::vector<size_t> parent_;
    std::vector<uint32_t> rank_;
};

// Per triangle: hash_uint_to_float of the representative of its first vertex.
// edges: pairs of vertex indices in the mesh's edge order (all < vertex_count).
inline std::vector<float> random_per_island(size_t vertex_count, const std::vector<std::pair<size_t, size_t>>& edges,
                                            const std::vector<size_t>& first_vertex) {
    VertexIslands islands(vertex_count);
    for (const auto& [a, b] : edges) islands.join(a, b);
    std::vector<float> out(first_vertex.size());
    for (size_t t = 0; t < first_vertex.size(); ++t)
        out[t] = shader::uint_to_unit(shader::hash_uint(uint32_t(islands.find(first_vertex[t]))));
    return out;
}

}  // namespace coherent
