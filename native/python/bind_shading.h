// Python bindings of shading data: shader programs, images, and the UVs,
// tangents and texture spaces add_mesh passes on (bind_shading.cpp).
#pragma once

#include <vector>

#include "bindings.h"
#include "shader/program.h"

namespace coherent::python {

// Arrays add_mesh borrows for the mesh's shading inputs; kept alive until it returns.
struct MeshShadingArrays {
    std::vector<py::array> keep;
};
// Fills mesh.shading from add_mesh's uvs / tangents / generated / colors arguments.
void read_mesh_shading(const PyScene& self, MeshInput& mesh, const py::handle& uvs, const py::handle& tangents,
                       const py::handle& generated, const py::handle& colors, MeshShadingArrays& arrays);
// A validated shader program from add_material's `program` dict (None -> null).
std::shared_ptr<const ShaderProgram> program_from_object(const PyScene& self, const py::handle& obj);
// Scene.set_shading_inputs, Scene.add_image, Scene.texture_stats.
void bind_shading(py::module_& m);

}  // namespace coherent::python
