// Axis-aligned bounding boxes.
#pragma once

#include "vec.h"

namespace coherent {

struct BBox {
    // An empty box: any expansion replaces it.
    Vec3f lo{kInf, kInf, kInf};
    Vec3f hi{-kInf, -kInf, -kInf};

    void expand(const Vec3f& p) { lo = min(lo, p); hi = max(hi, p); }
    void expand(const BBox& b) { lo = min(lo, b.lo); hi = max(hi, b.hi); }
    bool empty() const { return lo.x > hi.x || lo.y > hi.y || lo.z > hi.z; }
    Vec3f extent() const { return hi - lo; }
    Vec3f center() const { return (lo + hi) * 0.5f; }
    // The same box with every -0 bound made +0. min and max return one of
    // their operands when they compare equal, so with -0 and +0 about a
    // union's bits depend on the order of expansion; builders that reduce
    // boxes in parallel canonicalise their inputs to stay deterministic.
    BBox with_positive_zeros() const {
        BBox b;
        b.lo = lo + Vec3f(0.0f);
        b.hi = hi + Vec3f(0.0f);
        return b;
    }
    float half_area() const {
        if (empty()) return 0.0f;
        const Vec3f e = extent();
        return e.x * e.y + e.y * e.z + e.z * e.x;
    }
};

}  // namespace coherent
