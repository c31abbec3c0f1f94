// Bvh::refit: new boxes for a tree whose triangles moved but kept their
// indices (interactive transforms: a rebuild costs ~0.2 s on Sponza, a refit
// a few milliseconds). The refit tree is as valid as a built one (every box
// bounds everything below it), so traversal returns the same exact closest
// hits; only its SAH quality reflects the old positions.
//
// Three passes, all over arrays the build already laid out:
//  1. binary nodes bottom-up: a leaf's box is the union of its triangles'
//     full boxes (with spatial splits a reference's box was clipped to its
//     part of the triangle; the full box is larger, hence still
//     conservative), an interior node's the union of its two children;
//  2. wide nodes (8-wide, and 4-wide for width 4; width 2 traverses the
//     binary nodes themselves): every child slot copies its binary node's
//     box (wide_binary_ / wide4_binary_ remember which, so the collapse is
//     not redone);
//  3. triangle packs: every lane reloads its triangle's vertices (unused
//     lanes repeat lane 0's, as the build wrote them).
#include <stdexcept>
#include <string>
#include <type_traits>

#include "../scene/scene.h"
#include "bvh.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <chrono>

namespace coherent {

namespace {

constexpr size_t kRefitGrain = 4096;

BBox triangle_box(const Vec3f* verts, uint32_t tri) {
    BBox box;
    const Vec3f& a = verts[3 * size_t(tri)];
    const Vec3f& b = verts[3 * size_t(tri) + 1];
    const Vec3f& c = verts[3 * size_t(tri) + 2];
    // A non-finite vertex would poison every box above it (as in the build).
    if (!is_finite(a) || !is_finite(b) || !is_finite(c)) return box;
    box.expand(a);
    box.expand(b);
    box.expand(c);
    return box;
}

}  // namespace

void Bvh::refit(const Scene& scene) { refit_from(scene.vertices.data(), scene.triangle_count()); }

void Bvh::refit(const std::vector<Vec3f>& triangle_vertices) {
    refit_from(triangle_vertices.data(), triangle_vertices.size() / 3);
}

void Bvh::refit_from(const Vec3f* verts, size_t triangle_count) {
    const auto start = std::chrono::steady_clock::now();
    if (nodes_.empty()) return;
    for (uint32_t tri : prim_order_)
        if (tri >= triangle_count)
            throw std::invalid_argument("Bvh::refit: the BVH references triangle " + std::to_string(tri) +
                                        " but only " + std::to_string(triangle_count) + " were given");

    // 1. Binary nodes. Both builders append each pair of children after its
    // parent, so a reverse sweep sees children first; checked, since a
    // parent refit before its children would be silently wrong.
    for (size_t i = 0; i < nodes_.size(); ++i)
        if (!nodes_[i].is_leaf() && nodes_[i].index <= i)
            throw std::logic_error("Bvh::refit: children must follow their parent in nodes_");
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nodes_.size(), kRefitGrain),
                      [&](const tbb::blocked_range<size_t>& r) {
                          for (size_t i = r.begin(); i < r.end(); ++i) {
                              BvhNode& n = nodes_[i];
                              if (!n.is_leaf()) continue;
                              BBox box;
                              for (uint32_t s = n.index; s < n.index + n.count; ++s)
                                  box.expand(triangle_box(verts, prim_order_[s]));
                              n.box = box;
                          }
                      });
    for (size_t i = nodes_.size(); i-- > 0;) {
        BvhNode& n = nodes_[i];
        if (n.is_leaf()) continue;
        BBox box = nodes_[n.index].box;
        box.expand(nodes_[n.index + 1].box);
        n.box = box;
    }

    // 2. Wide nodes (the 8-wide tree, and the 4-wide one for width 4): same
    // slots, new boxes. An unused slot keeps its empty box.
    auto refit_wide = [&](auto& wide, const std::vector<uint32_t>& slot_binary) {
        using Node = std::decay_t<decltype(wide[0])>;
        constexpr int W = static_cast<int>(sizeof(Node::ref) / sizeof(uint32_t));
        tbb::parallel_for(tbb::blocked_range<size_t>(0, wide.size(), kRefitGrain / W),
                          [&](const tbb::blocked_range<size_t>& r) {
                              for (size_t w = r.begin(); w < r.end(); ++w)
                                  for (int c = 0; c < W; ++c) {
                                      const uint32_t b = slot_binary[w * W + c];
                                      if (b == kEmptyChild) continue;
                                      const BBox& box = nodes_[b].box;
                                      for (int a = 0; a < 3; ++a) {
                                          wide[w].lo[a][c] = box.lo[a];
                                          wide[w].hi[a][c] = box.hi[a];
                                      }
                                  }
                          });
    };
    refit_wide(wide_, wide_binary_);
    refit_wide(wide4_, wide4_binary_);

    // 3. Triangle packs. Lane 0 is always a real triangle; masked lanes copy it.
    tbb::parallel_for(tbb::blocked_range<size_t>(0, packs_.size(), kRefitGrain),
                      [&](const tbb::blocked_range<size_t>& r) {
                          for (size_t p = r.begin(); p < r.end(); ++p) {
                              TrianglePack4& pack = packs_[p];
                              for (int lane = 0; lane < 4; ++lane) {
                                  const uint32_t tri = pack.prim[lane] != kInvalidPrim ? pack.prim[lane] : pack.prim[0];
                                  for (int vtx = 0; vtx < 3; ++vtx)
                                      for (int a = 0; a < 3; ++a)
                                          pack.v[vtx][a][lane] = verts[3 * size_t(tri) + vtx][a];
                              }
                          }
                      });
    stats_.refit_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace coherent
