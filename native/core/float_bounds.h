// Floating-point error bounds shared by the traversal kernels (accel/) and
// the ray-spawning code (render/ray_offset.h). One definition each, so that
// kernels which must agree bit for bit cannot drift apart.
#pragma once

namespace coherent {

// gamma(n) = n eps / (1 - n eps), eps = 2^-24: the relative error bound of n
// rounded single-precision operations (pbrt-v3, section 3.9).
constexpr float gamma_bound(int n) {
    constexpr float eps = 0x1p-24f;
    return (n * eps) / (1.0f - n * eps);
}

// Ize 2013 ("Robust BVH Ray Traversal"): a slab distance (plane - o) * (1/d)
// is within gamma(3) of the exact one, so a box test that enlarges the far
// distance by (1 + 2 gamma(3)) never culls a box the ray enters.
constexpr float kFarScale = 1.0f + 2.0f * gamma_bound(3);

// Boxes are culled against the closest hit so far plus this relative slack.
// A triangle's computed t carries its own rounding error and may land a few
// ulps below the (exactly conservative) entry distance of its box; without
// slack, a tie between neighbours (a ray through a shared edge) would be
// resolved by whichever leaf the traversal happened to reach first. With it,
// every triangle whose computed t is <= the best t is tested (unless its t
// error exceeds 2^-12 relative, which takes a pathologically ill-conditioned
// hit), so the tie rule (lowest triangle index) decides, independent of the
// tree and of the kernel (single rays, packets and streams alike).
constexpr float kCullSlack = 0x1p-12f;

}  // namespace coherent
