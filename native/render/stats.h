// Render statistics: what was traced, by ray type, and what was discarded.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "../accel/bvh.h"

namespace coherent {

enum class RayType : uint8_t { Camera, Shadow, Diffuse, Glossy, Reflection, Refraction, Count };
const char* ray_type_name(RayType t);  // "camera", "shadow", "diffuse", ...

struct RenderStats {
    std::array<uint64_t, size_t(RayType::Count)> rays{};
    TraversalCounters traversal;
    uint64_t nonfinite_samples = 0;  // samples whose value was NaN/Inf, discarded
    uint64_t samples = 0;            // pixel samples finished
    int spp = 0;                     // sample passes actually completed (samples per pixel taken)
    // Adaptive sampling: pixels that stopped receiving samples (0 when off),
    // out of `pixels` in the film (the render border).
    uint64_t converged_pixels = 0;
    uint64_t pixels = 0;
    double converged_fraction() const { return pixels ? double(converged_pixels) / double(pixels) : 0.0; }
    // Film::relative_rmse_estimate() after the last completed pass; negative
    // while unknown (fewer than 2 passes).
    double error_estimate = -1.0;
    double seconds = 0.0;

    uint64_t total_rays() const {
        uint64_t n = 0;
        for (uint64_t r : rays) n += r;
        return n;
    }
    RenderStats& operator+=(const RenderStats& o);
};

}  // namespace coherent
