// Python bindings of shading data. See bind_shading.h; the program layout is
// native/shader/program.h.
#include "bind_shading.h"

#include <cstdio>
#include <sstream>

// Header-only: the hash functions compile into this module (libxxhash-dev ships the header).
#define XXH_INLINE_ALL
#include <xxhash.h>

#include "scene/mesh_islands.h"
#include "shader/eval.h"
#include "shader/textures.h"

namespace coherent::python {

namespace {

using FloatArray = py::array_t<float, py::array::c_style | py::array::forcecast>;
using IntArray = py::array_t<int64_t, py::array::c_style | py::array::forcecast>;

FloatArray float_rows(const py::handle& obj, std::initializer_list<py::ssize_t> shape, const std::string& arg) {
    FloatArray a = FloatArray::ensure(obj);
    if (!a) {
        PyErr_Clear();
        throw py::type_error(arg + ": expected a float array");
    }
    bool ok = a.ndim() == py::ssize_t(shape.size());
    py::ssize_t i = 0;
    for (py::ssize_t d : shape) {
        if (ok && d >= 0 && a.shape(i) != d) ok = false;
        ++i;
    }
    if (!ok) throw py::value_error(arg + ": wrong shape");
    return a;
}

uint16_t register_arg(int64_t v, const std::string& what) {
    if (v < 0 || v > int64_t(kNoRegister)) throw py::value_error(what + ": register index out of range");
    return uint16_t(v);
}

// code: integer (N, 9) rows: op, mode, out0, out1, in0, in1, in2, in3, data (-1 = no register).
std::vector<ShaderInstr> read_code(const py::handle& obj) {
    IntArray a = IntArray::ensure(obj);
    if (!a || a.ndim() != 2 || a.shape(1) != 9) {
        PyErr_Clear();
        throw py::value_error("program['code']: expected an integer array of shape (N, 9)");
    }
    std::vector<ShaderInstr> code(size_t(a.shape(0)));
    for (size_t i = 0; i < code.size(); ++i) {
        const int64_t* row = a.data() + 9 * i;
        const std::string what = "program['code'][" + std::to_string(i) + "]";
        if (row[0] < 0 || row[0] >= int64_t(ShaderOp::Count) || row[1] < 0 || row[1] > 0xFFFF || row[8] < 0 ||
            row[8] > 0xFFFFFFFFll)
            throw py::value_error(what + ": operation, mode or data out of range");
        ShaderInstr& in = code[i];
        in.op = ShaderOp(row[0]);
        in.mode = uint16_t(row[1]);
        for (int k = 0; k < 2; ++k) in.out[k] = row[2 + k] < 0 ? kNoRegister : register_arg(row[2 + k], what);
        for (int k = 0; k < 4; ++k) in.in[k] = row[4 + k] < 0 ? kNoRegister : register_arg(row[4 + k], what);
        in.data = uint32_t(row[8]);
    }
    return code;
}

std::vector<float> read_floats(const py::dict& d, const char* key) {
    if (!d.contains(key)) return {};
    FloatArray a = float_rows(d[key], {-1}, std::string("program['") + key + "']");
    return std::vector<float>(a.data(), a.data() + a.size());
}

std::vector<ShaderOutput> read_outputs(const py::handle& obj) {
    std::vector<ShaderOutput> outputs;
    for (auto item : py::iter(obj)) {
        auto t = item.cast<py::tuple>();
        if (t.size() != 3) throw py::value_error("program['outputs']: expected (field, closure, register) tuples");
        const auto field = integer_arg(t[0], "program['outputs'] field");
        const auto closure = integer_arg(t[1], "program['outputs'] closure");
        if (field < 0 || field >= int64_t(ShaderField::Count) || closure < 0 || closure >= 4)
            throw py::value_error("program['outputs']: field or closure out of range");
        outputs.push_back({ShaderField(field), uint8_t(closure), register_arg(integer_arg(t[2], "register"), "outputs")});
    }
    return outputs;
}

TextureStore& texture_store(PyScene& self) {
    auto& store = self.scene.shading.textures;
    if (!store) store = std::make_shared<TextureStore>();
    return *store;
}

// pixels: uint8 (H, W, C) stays bytes; anything else is read as float.
uint32_t add_pixel_image(TextureStore& store, const std::string& label, const py::handle& pixels,
                         const std::string& key, bool associate) {
    using ByteArray = py::array_t<uint8_t, py::array::c_style>;
    bool bytes = false;
    if (py::isinstance<py::array>(pixels)) {
        const py::dtype type = py::reinterpret_borrow<py::array>(pixels).dtype();
        bytes = type.kind() == 'u' && type.itemsize() == 1;
    }
    py::array a = bytes ? py::array(ByteArray::ensure(pixels)) : py::array(float_rows(pixels, {-1, -1, -1}, "pixels"));
    if (a.ndim() != 3) throw py::value_error("pixels: wrong shape");
    const int channels = int(a.shape(2));
    if (channels < 1 || channels > 4) throw py::value_error("pixels: expected 1 to 4 channels");
    const int width = int(a.shape(1)), height = int(a.shape(0));
    py::gil_scoped_release unlocked;
    if (bytes)
        return store.add_bytes(label, width, height, channels, static_cast<const uint8_t*>(a.data()), key, associate);
    return store.add_pixels(label, width, height, channels, static_cast<const float*>(a.data()), key);
}

uint32_t add_image(PyScene& self, const std::string& label, const py::handle& path, const py::handle& pixels,
                   const std::string& key, bool associate) {
    self.check_mutable("add_image");
    TextureStore& store = texture_store(self);
    if (!pixels.is_none()) return add_pixel_image(store, label, pixels, key, associate);
    if (path.is_none()) throw py::value_error("add_image: give a path or pixels");
    const std::string file = path.cast<std::string>();
    py::gil_scoped_release unlocked;
    return store.add_file(file, label, associate);
}

py::object add_retained_image(PyScene& self, const std::string& label, const std::string& key) {
    self.check_mutable("add_retained_image");
    uint32_t index = 0;
    if (!texture_store(self).add_retained(label, key, index)) return py::none();
    return py::int_(index);
}

py::dict texture_stats(const PyScene& self) {
    py::dict d;
    const auto& store = self.scene.shading.textures;
    d["images"] = store ? store->size() : size_t(0);
    d["memory_bytes"] = store ? store->memory_bytes() : size_t(0);
    d["buffer_bytes"] = store ? store->buffer_bytes() : size_t(0);
    d["reused"] = store ? store->reused() : size_t(0);
    d["warnings"] = store ? store->warnings() : std::vector<std::string>{};
    return d;
}

}  // namespace

void read_mesh_shading(const PyScene& self, MeshInput& mesh, const py::handle& uvs, const py::handle& tangents,
                       const py::handle& generated, const py::handle& colors, MeshShadingArrays& arrays) {
    const py::ssize_t m = py::ssize_t(mesh.triangle_count);
    if (!uvs.is_none()) {
        for (auto item : py::iter(uvs)) {
            if (item.is_none()) {
                mesh.shading.uvs.push_back(nullptr);
                continue;
            }
            FloatArray a = float_rows(item, {m, 3, 2}, "uvs[" + std::to_string(mesh.shading.uvs.size()) + "] (M, 3, 2)");
            mesh.shading.uvs.push_back(a.data());
            arrays.keep.push_back(a);
        }
        if (mesh.shading.uvs.size() > self.scene.shading.uv_names.size())
            throw py::value_error("uvs: more layers than set_shading_inputs declared");
    }
    if (!colors.is_none()) {
        for (auto item : py::iter(colors)) {
            if (item.is_none()) {
                mesh.shading.colors.push_back(nullptr);
                continue;
            }
            FloatArray a =
                float_rows(item, {m, 3, 4}, "colors[" + std::to_string(mesh.shading.colors.size()) + "] (M, 3, 4)");
            mesh.shading.colors.push_back(a.data());
            arrays.keep.push_back(a);
        }
        if (mesh.shading.colors.size() > self.scene.shading.color_names.size())
            throw py::value_error("colors: more attributes than set_shading_inputs declared");
    }
    if (!tangents.is_none()) {
        FloatArray a = float_rows(tangents, {m, 3, 4}, "tangents (M, 3, 4)");
        mesh.shading.tangents = a.data();
        arrays.keep.push_back(a);
    }
    if (!generated.is_none()) {
        auto t = generated.cast<py::tuple>();
        if (t.size() != 2) throw py::value_error("generated: expected (scale, offset)");
        mesh.shading.generated_scale = to_vec3(t[0], "generated scale");
        mesh.shading.generated_offset = to_vec3(t[1], "generated offset");
    }
}

std::shared_ptr<const ShaderProgram> program_from_object(const PyScene& self, const py::handle& obj) {
    if (obj.is_none()) return nullptr;
    if (!py::isinstance<py::dict>(obj)) throw py::type_error("program: expected a dict");
    const py::dict d = obj.cast<py::dict>();
    auto p = std::make_shared<ShaderProgram>();
    p->code = d.contains("code") ? read_code(d["code"]) : std::vector<ShaderInstr>{};
    p->constants = read_floats(d, "constants");
    p->data = read_floats(d, "data");
    if (d.contains("outputs")) p->outputs = read_outputs(d["outputs"]);
    for (const ShaderOutput& o : p->outputs) {
        p->drives_emission = p->drives_emission || o.field == ShaderField::Emission;
        p->drives_normal = p->drives_normal || o.field == ShaderField::Normal;
    }
    for (const ShaderInstr& in : p->code) {
        p->uses_light_path = p->uses_light_path || in.op == ShaderOp::LightPath;
        p->uses_bump = p->uses_bump || in.op == ShaderOp::Bump;
    }
    const SceneShading& sh = self.scene.shading;
    const std::string error = p->validate(sh.textures ? sh.textures->size() : 0, sh.uv_names.size());
    if (!error.empty()) throw py::value_error("program: " + error);
    return p;
}

void bind_shading(py::module_& m) {
    auto scene = py::reinterpret_borrow<py::class_<PyScene>>(m.attr("Scene"));
    scene.def(
        "set_shading_inputs",
        [](PyScene& self, std::vector<std::string> uv_names, bool tangents, bool objects,
           std::vector<std::string> color_names) {
            self.check_mutable("set_shading_inputs");
            if (self.scene.triangle_count() > 0)
                throw py::value_error("set_shading_inputs: call it before add_mesh");
            self.scene.shading.uv_names = std::move(uv_names);
            self.scene.shading.wants_tangents = tangents;
            self.scene.shading.wants_objects = objects;
            self.scene.shading.color_names = std::move(color_names);
        },
        py::kw_only(), py::arg("uv_names") = std::vector<std::string>{}, py::arg("tangents") = false,
        py::arg("objects") = false, py::arg("color_names") = std::vector<std::string>{},
        R"doc(Declares what shader programs read, before any add_mesh: the UV layers
(by name, in the order add_mesh's `uvs` lists them and programs address them),
whether normal maps need tangents, whether object-space coordinates are read, and
the colour attributes (by name, in the order add_mesh's `colors` lists them).)doc");
    scene.def("add_image", &add_image, py::arg("label"), py::kw_only(), py::arg("path") = py::none(),
              py::arg("pixels") = py::none(), py::arg("key") = "", py::arg("associate") = false,
              R"doc(Adds an image for Image Texture instructions; returns its index.
path: an image file OpenImageIO reads (decoded whole while the texture memory
limit allows, else read through its texture cache); or pixels: (H, W, C) with
C in 1..4, first row at the top, uint8 (kept as bytes, read as value / 255) or
float. associate=True: a straight byte colour image (a file, or RGBA uint8
pixels) whose colour Cycles associates with its alpha on load (c * a / 255,
truncated), associated here the same way.
key ("identity\nversion"): the pixels are retained after this scene goes, for
add_retained_image. An unreadable or empty image renders magenta and is listed
in texture_stats()['warnings'] under `label`.)doc");
    scene.def("add_retained_image", &add_retained_image, py::arg("label"), py::arg("key"),
              "Adds the image an earlier add_image retained under `key` (its pixels not handed over again); "
              "returns its index, or None when no image is held under that key.");
    m.def(
        "image_file_format",
        [](const std::string& path) -> py::object {
            ImageFileFormat f;
            if (!read_image_file_format(path, f)) return py::none();
            py::dict d;
            d["channels"] = f.channels;
            d["wide"] = f.wide;
            return d;
        },
        py::arg("path"),
        "{'channels', 'wide'} from an image file's header (OpenImageIO, no pixels decoded); 'wide': values of "
        "more than 8 bits, which Blender holds as float. None when the file cannot be opened.");
    m.def(
        "content_hash",
        [](const py::buffer& data) {
            // C-contiguous or refused: a strided view's bytes are not where its pointer says.
            Py_buffer view;
            if (PyObject_GetBuffer(data.ptr(), &view, PyBUF_C_CONTIGUOUS) != 0) throw py::error_already_set();
            const size_t bytes = size_t(view.len);
            XXH64_hash_t hash;
            {
                // Tens of MB of packed images hash here on every render: let Blender's other threads run.
                py::gil_scoped_release release;
                hash = XXH3_64bits(view.buf, bytes);
            }
            PyBuffer_Release(&view);
            char text[40];
            std::snprintf(text, sizeof text, "%zu %016llx", bytes, static_cast<unsigned long long>(hash));
            return std::string(text);
        },
        py::arg("data"),
        "'<length> <XXH3-64 hex>' of a buffer's bytes (bytes, numpy array, ctypes array: any contiguous buffer), "
        "read in place. The add-on's change detector for images held in Blender's memory (addon/coherent/images.py).");
    m.def(
        "fold_shader_constants",
        [](const py::dict& program) {
            ShaderProgram p;
            p.code = read_code(program["code"]);
            p.constants = read_floats(program, "constants");
            p.data = read_floats(program, "data");
            for (const ShaderInstr& in : p.code)
                if (in.op == ShaderOp::TexCoord || in.op == ShaderOp::ImageTexture || in.op == ShaderOp::NormalMap)
                    throw py::value_error("fold_shader_constants: the program reads geometry or images");
            const std::string error = p.validate(0, 0);
            if (!error.empty()) throw py::value_error("program: " + error);
            std::vector<float> registers = p.constants;
            run_constant_program(p, registers.data());
            return registers;
        },
        py::arg("program"),
        "Runs a program of constant inputs (no geometry, no images); returns its register file. "
        "The shader compiler folds constant subgraphs with it.");
    m.def(
        "random_per_island",
        [](int64_t vertex_count, const IntArray& edges, const IntArray& first_vertex) {
            if (vertex_count < 0 || edges.size() % 2 != 0) throw py::value_error("random_per_island: bad sizes");
            auto in_range = [&](int64_t v) { return v >= 0 && v < vertex_count; };
            std::vector<std::pair<size_t, size_t>> pairs(size_t(edges.size() / 2));
            const int64_t* e = edges.data();
            for (size_t i = 0; i < pairs.size(); ++i) {
                if (!in_range(e[2 * i]) || !in_range(e[2 * i + 1]))
                    throw py::value_error("random_per_island: an edge names a vertex out of range");
                pairs[i] = {size_t(e[2 * i]), size_t(e[2 * i + 1])};
            }
            std::vector<size_t> firsts(size_t(first_vertex.size()));
            for (size_t t = 0; t < firsts.size(); ++t) {
                if (!in_range(first_vertex.data()[t]))
                    throw py::value_error("random_per_island: a triangle names a vertex out of range");
                firsts[t] = size_t(first_vertex.data()[t]);
            }
            const std::vector<float> values = random_per_island(size_t(vertex_count), pairs, firsts);
            return py::array_t<float>(py::ssize_t(values.size()), values.data());
        },
        py::arg("vertex_count"), py::arg("edges"), py::arg("first_vertex"),
        "Geometry > Random Per Island as Cycles 3.4 computes it (scene/mesh_islands.h): per triangle, from the "
        "mesh's edges (vertex index pairs, in edge order) and each triangle's first vertex.");
    scene.def("texture_stats", &texture_stats, "{'images', 'memory_bytes' (OIIO cache), 'buffer_bytes' (in-memory pixels), "
              "'reused' (images add_retained_image found held), 'warnings'} of the scene's images.");
}

}  // namespace coherent::python
