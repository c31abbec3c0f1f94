// Cycles' pass names and the PassSample layout.
#include "passes.h"

#include <algorithm>
#include <cctype>
#include <stdexcept>

namespace coherent {

const RenderPassInfo& render_pass_info(RenderPass p) {
    // Offsets: 12 RGB passes (the 11 light passes and AO), then Mist, UV,
    // Position, IndexOB, IndexMA, Vector.
    static const RenderPassInfo infos[] = {
        {"DiffDir", "diffdir", 3, "RGB", 0},   {"DiffInd", "diffind", 3, "RGB", 3},
        {"DiffCol", "diffcol", 3, "RGB", 6},   {"GlossDir", "glossdir", 3, "RGB", 9},
        {"GlossInd", "glossind", 3, "RGB", 12}, {"GlossCol", "glosscol", 3, "RGB", 15},
        {"TransDir", "transdir", 3, "RGB", 18}, {"TransInd", "transind", 3, "RGB", 21},
        {"TransCol", "transcol", 3, "RGB", 24}, {"Emit", "emit", 3, "RGB", 27},
        {"Env", "env", 3, "RGB", 30},          {"AO", "ao", 3, "RGB", 33},
        {"Mist", "mist", 1, "Z", 36},          {"UV", "uv", 3, "UVA", 37},
        {"Position", "position", 3, "XYZ", 40}, {"IndexOB", "indexob", 1, "X", 43},
        {"IndexMA", "indexma", 1, "X", 44},     {"Vector", "vector", 4, "XYZW", 45},
    };
    static_assert(sizeof(infos) / sizeof(infos[0]) == size_t(kRenderPassCount));
    return infos[size_t(p)];
}

PassMask pass_mask_from_names(const std::vector<std::string>& names) {
    PassMask mask = 0;
    for (const std::string& name : names) {
        std::string lower = name;
        std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return char(std::tolower(c)); });
        bool found = false;
        for (int i = 0; i < kRenderPassCount && !found; ++i)
            if (lower == render_pass_info(RenderPass(i)).cli_name) {
                mask |= pass_bit(RenderPass(i));
                found = true;
            }
        if (!found) {
            std::string known;
            for (int i = 0; i < kRenderPassCount; ++i) known += std::string(i ? ", " : "") + render_pass_info(RenderPass(i)).name;
            throw std::invalid_argument("unknown pass '" + name + "' (expected one of " + known + ")");
        }
    }
    return mask;
}

}  // namespace coherent
