// The glTF scenes the build generates for the tests (tests/fixtures/make_gltf.py,
// run by tests/CMakeLists.txt into COHERENT_TEST_FIXTURES), so the suite needs
// nothing beside the clone. A fixture that is missing or fails to load is a
// test failure, never a skip: the build always makes it.
#pragma once

#include <gtest/gtest.h>

#include <string>

#include "io/gltf.h"
#include "scene/scene.h"

namespace coherent::test {

inline std::string fixture_path(const std::string& name) { return std::string(COHERENT_TEST_FIXTURES) + "/" + name; }

// Loads a generated scene (not finalized); use as ASSERT_TRUE(load_fixture(...)).
inline ::testing::AssertionResult load_fixture(const std::string& name, Scene& scene, float aspect = 1.0f) {
    const std::string path = fixture_path(name);
    const GltfLoadResult r = load_gltf(path, scene, aspect);
    if (!r.ok) return ::testing::AssertionFailure() << path << ": " << r.error;
    return ::testing::AssertionSuccess();
}

}  // namespace coherent::test
