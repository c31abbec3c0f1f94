// A BBox held in two SSE registers (lanes x, y, z; lane 3 carries no
// meaning), for the builders' binning loops, which expand, bin and centre
// boxes once per reference and axis at every level of the tree.
//
// Invariant: every operation gives, in lanes 0-2, bit for bit what the
// scalar BBox code gives, so a builder may switch between the two without
// changing a tree:
//  - expand: BBox::expand is lo = std::min(lo, p), which returns lo on ties
//    (and so keeps lo's signed zero); simd::min(p, lo) is _mm_min_ps(p, lo),
//    which returns its second operand on ties. Likewise max for hi;
//  - centre: (lo + hi) * 0.5f, two roundings as in BBox::center();
//  - bin index: static_cast<int>((c - lo) * scale) truncates toward zero, as
//    _mm_cvttps_epi32 does; both give INT_MIN for NaN or out-of-range values,
//    which the clamp sends to bin 0.
#pragma once

#include <cstdint>

#include "../core/bbox.h"
#include "../core/simd.h"

namespace coherent {

struct Box4 {
    // Left uninitialised by the default constructor, so that an array of
    // bins costs nothing until a builder initialises the bins it uses.
    simd::vfloat4 lo, hi;

    static Box4 empty() {
        Box4 b;
        b.lo = simd::vfloat4(kInf);
        b.hi = simd::vfloat4(-kInf);
        return b;
    }

    // Two loads that stay inside the 24 bytes of the BBox: (lo.x, lo.y,
    // lo.z, hi.x) and (lo.z, hi.x, hi.y, hi.z), the second shuffled to
    // (hi.x, hi.y, hi.z, lo.z).
    static Box4 load(const BBox& b) {
        static_assert(sizeof(BBox) == 24, "BBox must be lo then hi, six floats");
        const float* f = &b.lo.x;
        Box4 r;  // both registers are assigned below
        r.lo = simd::vfloat4::loadu(f);
        r.hi = simd::vfloat4(_mm_shuffle_ps(_mm_loadu_ps(f + 2), _mm_loadu_ps(f + 2), _MM_SHUFFLE(0, 3, 2, 1)));
        return r;
    }

    void expand(const Box4& b) {
        lo = simd::min(b.lo, lo);
        hi = simd::max(b.hi, hi);
    }
    void expand_point(simd::vfloat4 p) {
        lo = simd::min(p, lo);
        hi = simd::max(p, hi);
    }
    simd::vfloat4 center() const { return (lo + hi) * simd::vfloat4(0.5f); }

    BBox to_bbox() const {
        alignas(16) float l[4], h[4];
        simd::store(l, lo);
        simd::store(h, hi);
        BBox b;
        b.lo = {l[0], l[1], l[2]};
        b.hi = {h[0], h[1], h[2]};
        return b;
    }
};

// Centroid-to-bin mapping on three axes at once: lane a is the bin of the
// centroid along axis a, in [0, bins - 1]. The scalar mapping it replaces is
// std::clamp(static_cast<int>((c[a] - lo[a]) * scale[a]), 0, bins - 1).
struct BinIndex4 {
    simd::vfloat4 lo, scale;
    __m128i last;

    BinIndex4(const Vec3f& lo_, const Vec3f& scale_, int bins)
        : lo(lo_.x, lo_.y, lo_.z, 0.0f), scale(scale_.x, scale_.y, scale_.z, 0.0f), last(_mm_set1_epi32(bins - 1)) {}

    void bins(simd::vfloat4 c, int32_t out[4]) const {
        const __m128i i = _mm_cvttps_epi32(((c - lo) * scale).v);
        _mm_storeu_si128(reinterpret_cast<__m128i*>(out), _mm_min_epi32(_mm_max_epi32(i, _mm_setzero_si128()), last));
    }
};

}  // namespace coherent
