// Random Per Island's representatives (scene/mesh_islands.h) follow Cycles'
// DisjointSet exactly: union by rank in edge order, y's root under x's on
// equal ranks. The representative, not only the island, decides the value.
#include <gtest/gtest.h>

#include <utility>
#include <vector>

#include "scene/mesh_islands.h"

using namespace coherent;

namespace {

float hashed(uint32_t root) { return shader::uint_to_unit(shader::hash_uint(root)); }

}  // namespace

TEST(MeshIslands, EqualRanksPutTheSecondRootUnderTheFirst) {
    EXPECT_EQ(random_per_island(2, {{1, 0}}, {0, 1}), (std::vector<float>{hashed(1), hashed(1)}));
    EXPECT_EQ(random_per_island(2, {{0, 1}}, {1}), std::vector<float>{hashed(0)});
}

TEST(MeshIslands, TheHigherRankedRootStays) {
    // {2, 3} first gets rank 1 under 2; joining the single vertex 0 to it
    // (x = 0, rank 0) swaps, so 0 goes under 2, not 2 under 0.
    VertexIslands islands(4);
    islands.join(2, 3);
    islands.join(0, 3);
    EXPECT_EQ(islands.find(0), 2u);
    EXPECT_EQ(islands.find(3), 2u);
    EXPECT_EQ(islands.find(1), 1u);  // untouched: its own island
}

TEST(MeshIslands, TwoIslandsKeepTheirOwnValues) {
    const std::vector<std::pair<size_t, size_t>> edges{{0, 1}, {1, 2}, {3, 4}};
    const std::vector<float> v = random_per_island(5, edges, {2, 4, 0, 3});
    EXPECT_EQ(v[0], hashed(0));
    EXPECT_EQ(v[2], hashed(0));
    EXPECT_EQ(v[1], hashed(3));
    EXPECT_EQ(v[3], hashed(3));
    EXPECT_NE(v[0], v[1]);
}
