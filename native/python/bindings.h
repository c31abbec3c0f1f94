// Shared pieces of the pybind11 module `_coherent` (DESIGN.md "python" layer).
//
// The module is the only place that knows about Python. It converts numpy
// arrays and keyword arguments into the engine's plain structs, validates
// their shapes up front (so a wrong array is a TypeError/ValueError naming the
// argument, never a crash), and releases the GIL around everything that takes
// time (mesh validation, BVH build, rendering).
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <atomic>
#include <memory>
#include <string>

#include "scene/scene.h"

namespace coherent {
class Bvh;
class InstanceBvh;
}

namespace coherent::python {

namespace py = pybind11;

// The Python-side Scene. Holds the engine scene plus the bookkeeping the
// binding needs: whether finalize() ran since the last change, and how many
// Renderers currently reference it.
//
// Invariant: while `active_renderers > 0` the scene is immutable, because a
// Renderer keeps a reference to it and a BVH built over its triangles; every
// mutating method checks this and raises RuntimeError instead.
struct PyScene {
    Scene scene;
    bool finalized = false;
    std::atomic<int> active_renderers{0};
    // The BVH over the current triangles, built by Scene.build_bvh() or the
    // first Renderer and reused by the next ones (interactive viewports
    // restart a Renderer on every camera, material, light or world edit).
    // Invariant: null or built (or refit, Scene.refit_bvh_from) over exactly
    // `scene`'s current triangles; add_mesh resets it.
    std::shared_ptr<const Bvh> bvh;
    // Likewise the instances' two-level BVH (null while the scene has no
    // instances or no Renderer built it yet); add_instances resets it.
    std::shared_ptr<const InstanceBvh> instance_bvh;

    void check_mutable(const char* what) const;
    void ensure_finalized();
};

void bind_scene(py::module_& m);
void bind_render(py::module_& m);
void bind_sky(py::module_& m);  // bind_sky.cpp: sky_texture, Scene.set_world_sky / world_radiance

// --- argument conversion helpers (module.cpp) -------------------------------

// Reads a length-3 float sequence (tuple, list, numpy array). Raises
// ValueError naming `arg` if it has the wrong length or a non-finite entry.
Vec3f to_vec3(const py::handle& obj, const char* arg);
// Python floats and ints, numpy scalars and anything with __float__; not
// bools or strings, which Python would happily convert.
bool is_python_number(const py::handle& obj);
// Python ints and anything with __index__ (numpy integers); not bools,
// which Python counts as ints.
bool is_python_integer(const py::handle& obj);
// A Python number (not a bool or a string) as a double; TypeError naming `arg` otherwise.
double number_arg(const py::handle& obj, const std::string& arg);
// A Python integer (or numpy integer; not a bool); TypeError naming `arg` otherwise.
long long integer_arg(const py::handle& obj, const std::string& arg);
// Scalar that must be finite. Raises ValueError naming `arg`.
float finite_float(double v, const char* arg);

}  // namespace coherent::python
