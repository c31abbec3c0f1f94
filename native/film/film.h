// Accumulation buffers for every pass. Row 0 is the TOP row of the image;
// front ends flip if their convention differs (Blender's is bottom-up).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "../core/vec.h"

namespace coherent {

enum class PassType : uint8_t { Combined, Depth, Normal };

struct PassInfo {
    PassType type;
    const char* name;  // Blender pass name
    int channels;
    const char* chan_id;  // Blender channel ids
};

const PassInfo& pass_info(PassType t);

class Film {
public:
    Film() = default;
    Film(int width, int height);

    int width() const { return width_; }
    int height() const { return height_; }

    // Adds one sample's values to pixel (x, y). The caller guarantees finite
    // values (the renderer guards and counts before calling).
    void add_sample(int x, int y, const Vec3f& radiance, float alpha, float depth, const Vec3f& normal);

    // Resolved pass as interleaved floats, width*height*channels, top row first.
    // Depth/Normal are from the first hit averaged over samples; Depth is inf
    // where nothing was hit (as Cycles writes 1e10).
    std::vector<float> resolve(PassType t) const;
    void resolve_into(PassType t, float* out) const;  // out has width*height*channels floats
    uint32_t samples_at(int x, int y) const { return count_[size_t(y) * width_ + x]; }

    void clear();

private:
    int width_ = 0, height_ = 0;
    std::vector<float> rgba_;     // 4 per pixel, sums
    std::vector<float> depth_;    // sum of depths over samples that hit
    std::vector<float> normal_;   // 3 per pixel, sums
    std::vector<uint32_t> count_; // samples per pixel
    std::vector<uint32_t> hits_;  // samples that hit geometry
};

}  // namespace coherent
