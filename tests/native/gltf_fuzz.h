// Random byte edits of a .glb (JSON and binary chunk alike): the loader must
// return, with either a valid scene or a one-line error, never crash. Shared
// by the generated-box test (test_gltf.cpp) and the public-scene one
// (shared/test_public_scenes.cpp).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <random>
#include <string>

#include "io/gltf.h"
#include "test_gltf_util.h"

namespace coherent::test {

inline void expect_fuzzed_glb_never_crashes(const std::string& glb, uint32_t seed) {
    ASSERT_GT(glb.size(), 1000u);  // a real file, not an unreadable one
    TempDir dir;
    std::mt19937 rng(seed);
    // COHERENT_FUZZ_ITERATIONS runs longer campaigns (e.g. under ASan).
    const char* env = std::getenv("COHERENT_FUZZ_ITERATIONS");
    const int iterations = env ? std::max(1, std::atoi(env)) : 300;
    int loaded = 0, failed = 0;
    for (int iter = 0; iter < iterations; ++iter) {
        std::string mutated = glb;
        const int edits = 1 + int(rng() % 8);
        for (int e = 0; e < edits; ++e) {
            const size_t at = rng() % mutated.size();
            switch (rng() % 3) {
                case 0: mutated[at] = char(rng()); break;                          // random byte
                case 1: mutated[at] = "0123456789-e.,:[]{}\""[rng() % 20]; break;  // JSON-ish byte
                default: mutated.resize(at); break;                                // truncate
            }
            if (mutated.empty()) break;
        }
        const std::string path = dir.file("fuzz.glb", mutated);
        Scene scene;
        const GltfLoadResult r = load_gltf(path, scene);
        if (r.ok) {
            ++loaded;
            for (const Vec3f& v : scene.vertices) ASSERT_TRUE(is_finite(v));
            for (uint32_t m : scene.material_of) ASSERT_LT(m, scene.materials.size());
        } else {
            ++failed;
            ASSERT_TRUE(!r.error.empty() && r.error.find('\n') == std::string::npos) << r.error;
        }
    }
    EXPECT_GT(failed, 0);
    EXPECT_EQ(loaded + failed, iterations);
}

}  // namespace coherent::test
