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
    float half_area() const {
        if (empty()) return 0.0f;
        const Vec3f e = extent();
        return e.x * e.y + e.y * e.z + e.z * e.x;
    }
};

}  // namespace coherent
