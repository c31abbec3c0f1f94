// The pybind11 module `_coherent`: the only place that knows about Python.
// Scene bindings live in bind_scene.cpp, renderer bindings in bind_render.cpp.
#include <cmath>
#include <thread>

#include "bind_settings.h"
#include "bind_shading.h"
#include "bindings.h"
#include "render/convergence.h"
#include "render/stats.h"
#include "scene/features.h"

namespace coherent::python {

float finite_float(double v, const char* arg) {
    const float f = float(v);
    if (!std::isfinite(f)) throw py::value_error(std::string(arg) + ": must be finite, got " + std::to_string(v));
    return f;
}

bool is_python_number(const py::handle& obj) {
    return !PyBool_Check(obj.ptr()) && !py::isinstance<py::str>(obj) && PyNumber_Check(obj.ptr()) &&
           py::hasattr(obj, "__float__");
}

bool is_python_integer(const py::handle& obj) { return PyIndex_Check(obj.ptr()) && !PyBool_Check(obj.ptr()); }

double number_arg(const py::handle& obj, const std::string& arg) {
    if (!is_python_number(obj))
        throw py::type_error(arg + ": expected a number, got " +
                             std::string(py::str(py::type::of(obj).attr("__name__"))));
    return py::float_(py::reinterpret_borrow<py::object>(obj)).cast<double>();
}

long long integer_arg(const py::handle& obj, const std::string& arg) {
    if (!is_python_integer(obj))
        throw py::type_error(arg + ": expected an integer, got " +
                             std::string(py::str(py::type::of(obj).attr("__name__"))));
    return py::int_(py::reinterpret_borrow<py::object>(obj)).cast<long long>();
}

Vec3f to_vec3(const py::handle& obj, const char* arg) {
    // Tuples, lists, numpy arrays and Blender's mathutils.Vector/Color all qualify.
    if (obj.is_none() || !py::hasattr(obj, "__len__") || !py::hasattr(obj, "__getitem__"))
        throw py::type_error(std::string(arg) + ": expected a sequence of 3 floats");
    if (py::len(obj) != 3)
        throw py::value_error(std::string(arg) + ": expected 3 components, got " + std::to_string(py::len(obj)));
    Vec3f v;
    for (int i = 0; i < 3; ++i) v[i] = finite_float(number_arg(obj[py::int_(i)], arg), arg);
    return v;
}

}  // namespace coherent::python

PYBIND11_MODULE(_coherent, m) {
    using namespace coherent;
    using namespace coherent::python;
    m.doc() = "COHERENT native engine: Scene (geometry, materials, lights, camera) and Renderer.";
#ifdef COHERENT_VERSION
    m.attr("__version__") = COHERENT_VERSION;
#else
    m.attr("__version__") = "0.1.0";
#endif
    bind_scene(m);
    bind_shading(m);
    bind_sky(m);
    bind_settings(m);
    bind_render(m);

    std::vector<std::string> ray_types;
    for (size_t i = 0; i < size_t(RayType::Count); ++i) ray_types.emplace_back(ray_type_name(RayType(i)));
    m.attr("ray_types") = ray_types;
    m.attr("all_features") = SceneFeatures::all().names();
    m.def("hardware_threads", [] { return std::max(1u, std::thread::hardware_concurrency()); },
          "Number of hardware threads (what threads=0 uses).");
    m.def("predicted_seconds_to_error", &predicted_seconds_to_error, py::arg("seconds"), py::arg("error"), py::arg("target"),
          "Total render seconds at which the error estimate reaches `target` if it keeps falling as 1/sqrt(samples): "
          "seconds * (error / target)**2; negative when no prediction is possible (no estimate or no target).");
}
