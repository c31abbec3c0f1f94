// Python bindings of the scene layer: Scene.add_mesh / add_material /
// add_light / set_camera / world_color / set_world_map / finalize.
//
// Array policy (applies to every numpy argument): strict on ndim and shape,
// lenient on dtype and memory layout. Float arrays accept any real dtype and
// are converted to float32 (copied only when needed); index arrays must have
// an integer dtype (a float index array is a TypeError, because silently
// truncating 2.7 to 2 hides exporter bugs) and are converted to uint32 with
// out-of-range values mapped to an index the scene validation then drops.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <iterator>
#include <limits>
#include <sstream>
#include <vector>

#include "accel/bvh.h"
#include "render/renderer.h"
#include "bind_shading.h"
#include "bindings.h"

namespace coherent::python {

namespace {

using FloatArray = py::array_t<float, py::array::c_style | py::array::forcecast>;

std::string shape_string(const py::array& a) {
    std::ostringstream s;
    s << "(";
    for (py::ssize_t i = 0; i < a.ndim(); ++i) s << (i ? ", " : "") << a.shape(i);
    s << (a.ndim() == 1 ? ",)" : ")");
    return s.str();
}

std::string dtype_string(const py::array& a) { return py::str(a.dtype()).cast<std::string>(); }

// Converts `obj` to a numpy array without copying when it already is one.
py::array as_array(const py::handle& obj, const char* arg, const char* expected) {
    if (obj.is_none()) throw py::type_error(std::string(arg) + ": expected " + expected + ", got None");
    py::array a = py::array::ensure(obj);
    if (!a) {
        PyErr_Clear();
        throw py::type_error(std::string(arg) + ": expected " + expected + ", got a " +
                             std::string(py::str(py::type::handle_of(obj).attr("__name__"))));
    }
    return a;
}

// Checks ndim and every fixed dimension (-1 = any). Raises ValueError.
void check_shape(const py::array& a, std::initializer_list<py::ssize_t> shape, const char* arg,
                 const char* expected) {
    bool ok = a.ndim() == py::ssize_t(shape.size());
    py::ssize_t i = 0;
    for (py::ssize_t d : shape) {
        if (!ok) break;
        if (d >= 0 && a.shape(i) != d) ok = false;
        ++i;
    }
    if (!ok) throw py::value_error(std::string(arg) + ": expected shape " + expected + ", got " + shape_string(a));
}

FloatArray float_array(const py::handle& obj, std::initializer_list<py::ssize_t> shape, const char* arg,
                       const char* expected_shape) {
    const std::string expected = std::string("a float array of shape ") + expected_shape;
    py::array a = as_array(obj, arg, expected.c_str());
    const char kind = a.dtype().kind();
    if (kind != 'f' && kind != 'i' && kind != 'u')
        throw py::type_error(std::string(arg) + ": expected " + expected + ", got dtype " + dtype_string(a));
    check_shape(a, shape, arg, expected_shape);
    return FloatArray::ensure(a);  // float32, C-contiguous; no copy if it already is
}

// Integer array converted to uint32. `storage` receives converted values when
// the input is not already a contiguous 32-bit integer array; the returned
// pointer is valid as long as `a_out` and `storage` live.
const uint32_t* index_array(const py::handle& obj, std::initializer_list<py::ssize_t> shape, const char* arg,
                            const char* expected_shape, py::array& a_out, std::vector<uint32_t>& storage) {
    const std::string expected = std::string("an integer array of shape ") + expected_shape;
    py::array a = as_array(obj, arg, expected.c_str());
    const char kind = a.dtype().kind();
    if (kind != 'i' && kind != 'u')
        throw py::type_error(std::string(arg) + ": expected " + expected + ", got dtype " + dtype_string(a));
    check_shape(a, shape, arg, expected_shape);

    // int32 and uint32 share the bit pattern we need: a negative int32 reads
    // as a value >= 2^31, which validation drops as out of range.
    if (a.itemsize() == 4 && (a.flags() & py::array::c_style)) {
        a_out = a;
        return static_cast<const uint32_t*>(a.data());
    }
    auto wide = py::array_t<int64_t, py::array::c_style | py::array::forcecast>::ensure(a);
    const int64_t* src = wide.data();
    storage.resize(size_t(wide.size()));
    constexpr int64_t kMax = std::numeric_limits<uint32_t>::max();
    for (size_t i = 0; i < storage.size(); ++i)
        storage[i] = (src[i] < 0 || src[i] > kMax) ? uint32_t(kMax) : uint32_t(src[i]);
    a_out = wide;
    return storage.data();
}

float unit_clamp(double v, const char* arg) { return std::clamp(finite_float(v, arg), 0.0f, 1.0f); }

constexpr const char* kClosureKinds[] = {"principled", "transparent", "translucent", "holdout"};

ClosureKind closure_kind_from(const py::handle& v, const std::string& arg) {
    const std::string name = py::str(v);
    for (size_t k = 0; k < std::size(kClosureKinds); ++k)
        if (name == kClosureKinds[k]) return ClosureKind(k);
    throw py::value_error(arg + ": unknown closure kind '" + name +
                          "' (expected principled, transparent, translucent or holdout)");
}

Closure closure_from_dict(const py::dict& d, size_t index) {
    Closure c;
    for (auto item : d) {
        const std::string key = py::str(item.first);
        const std::string arg = "closures[" + std::to_string(index) + "]['" + key + "']";
        const py::handle v = item.second;
        if (key == "base_color") c.base_color = max(to_vec3(v, arg.c_str()), Vec3f(0.0f));
        else if (key == "metallic") c.metallic = unit_clamp(number_arg(v, arg), arg.c_str());
        else if (key == "roughness") c.roughness = unit_clamp(number_arg(v, arg), arg.c_str());
        else if (key == "specular") c.specular = unit_clamp(number_arg(v, arg), arg.c_str());
        else if (key == "transmission") c.transmission = unit_clamp(number_arg(v, arg), arg.c_str());
        else if (key == "principled_diffuse") {
            if (!PyBool_Check(v.ptr())) throw py::type_error(arg + ": expected True or False");
            c.principled_diffuse = v.cast<bool>();
        }
        else if (key == "kind") c.kind = closure_kind_from(v, arg);
        else if (key == "ior") {
            c.ior = finite_float(number_arg(v, arg), arg.c_str());
            if (!(c.ior > 0.0f)) throw py::value_error(arg + ": index of refraction must be > 0");
        } else {
            throw py::value_error("closures[" + std::to_string(index) + "]: unknown key '" + key +
                                  "' (expected base_color, metallic, roughness, specular, transmission, ior, principled_diffuse, "
                                  "kind)");
        }
    }
    return c;
}

LightType light_type_from(const std::string& s) {
    if (s == "POINT") return LightType::Point;
    if (s == "SPOT") return LightType::Spot;
    if (s == "SUN") return LightType::Sun;
    if (s == "AREA") return LightType::Area;
    throw py::value_error("type: expected 'POINT', 'SPOT', 'SUN' or 'AREA', got '" + s + "'");
}

AreaShape area_shape_from(const std::string& s) {
    if (s == "SQUARE") return AreaShape::Square;
    if (s == "RECTANGLE") return AreaShape::Rectangle;
    if (s == "DISK") return AreaShape::Disk;
    if (s == "ELLIPSE") return AreaShape::Ellipse;
    throw py::value_error("shape: expected 'SQUARE', 'RECTANGLE', 'DISK' or 'ELLIPSE', got '" + s + "'");
}

Vec3f unit_vector(const py::handle& obj, const char* arg) {
    const Vec3f v = to_vec3(obj, arg);
    const float len = length(v);
    if (!(len > 1e-20f)) throw py::value_error(std::string(arg) + ": must be a non-zero vector");
    return v / len;
}

float non_negative(double v, const char* arg) {
    const float f = finite_float(v, arg);
    if (f < 0.0f) throw py::value_error(std::string(arg) + ": must be >= 0");
    return f;
}

float positive(double v, const char* arg) {
    const float f = finite_float(v, arg);
    if (!(f > 0.0f)) throw py::value_error(std::string(arg) + ": must be > 0");
    return f;
}

py::tuple vec_tuple(const Vec3f& v) { return py::make_tuple(v.x, v.y, v.z); }

// One mesh's arrays as a MeshInput that borrows them (kept alive here).
// Shared by add_mesh and add_prototype: the same checks and messages.
struct MeshArgs {
    FloatArray positions, normals;
    py::array indices_keep, ids_keep;
    std::vector<uint32_t> indices_storage, ids_storage;
    MeshInput in;
};

void read_mesh_arrays(MeshArgs& a, const std::string& name, const py::handle& positions_obj,
                      const py::handle& indices_obj, const py::handle& normals_obj,
                      const py::handle& material_ids_obj) {
    MeshInput& in = a.in;
    in.name = name;
    a.positions = float_array(positions_obj, {-1, 3}, "positions", "(N, 3)");
    in.positions = a.positions.data();
    in.vertex_count = size_t(a.positions.shape(0));
    in.indices = index_array(indices_obj, {-1, 3}, "indices", "(M, 3)", a.indices_keep, a.indices_storage);
    in.triangle_count = size_t(a.indices_keep.shape(0));
    if (!normals_obj.is_none()) {
        a.normals = float_array(normals_obj, {-1, 3, 3}, "normals", "(M, 3, 3)");
        if (size_t(a.normals.shape(0)) != in.triangle_count)
            throw py::value_error("normals: expected shape (M, 3, 3) with M = " + std::to_string(in.triangle_count) +
                                  " triangles, got " + shape_string(a.normals));
        in.normals = a.normals.data();
    }
    if (!material_ids_obj.is_none()) {
        in.material_ids = index_array(material_ids_obj, {-1}, "material_ids", "(M,)", a.ids_keep, a.ids_storage);
        if (size_t(a.ids_keep.shape(0)) != in.triangle_count)
            throw py::value_error("material_ids: expected shape (M,) with M = " + std::to_string(in.triangle_count) +
                                  " triangles, got " + shape_string(a.ids_keep));
    }
}

// Scene material indices from a list argument, each checked to exist.
std::vector<uint32_t> read_material_slots(const PyScene& self, const py::handle& obj) {
    std::vector<uint32_t> slots;
    if (obj.is_none()) return slots;
    for (auto item : py::iter(obj)) {
        const auto slot = integer_arg(item, "material_slots");
        if (slot < 0 || size_t(slot) >= self.scene.materials.size())
            throw py::value_error("material_slots: material index " + std::to_string(slot) +
                                  " does not exist (scene has " + std::to_string(self.scene.materials.size()) +
                                  " materials)");
        slots.push_back(uint32_t(slot));
    }
    return slots;
}

// K pairs of finite (4, 4) matrices, read as K x 2 Transforms; shape (2, 4,
// 4) for k < 0 (one pair), else (k, 2, 4, 4).
FloatArray frame_transform_array(const py::handle& obj, py::ssize_t k, const char* what, const char* shape) {
    FloatArray m = k < 0 ? float_array(obj, {2, 4, 4}, what, shape) : float_array(obj, {k, 2, 4, 4}, what, shape);
    for (py::ssize_t i = 0; i < 32 * std::max<py::ssize_t>(k, 1); ++i)
        if (!std::isfinite(m.data()[i])) throw py::value_error(std::string(what) + ": entries must be finite");
    return m;
}

size_t add_mesh(PyScene& self, const std::string& name, const py::handle& positions_obj,
                const py::handle& indices_obj, const py::handle& matrix_obj, const py::handle& normals_obj,
                const py::handle& material_ids_obj, const py::handle& material_slots_obj,
                const py::handle& matrix_close_obj, const py::handle& uvs_obj, const py::handle& tangents_obj,
                const py::handle& generated_obj, const py::handle& colors_obj, const py::handle& frame_matrices_obj) {
    self.check_mutable("add_mesh");
    MeshArgs args;
    read_mesh_arrays(args, name, positions_obj, indices_obj, normals_obj, material_ids_obj);
    MeshInput& in = args.in;

    auto read_matrix = [](const py::handle& obj, const char* what, Transform& out) {
        FloatArray matrix = float_array(obj, {4, 4}, what, "(4, 4)");
        for (int r = 0; r < 4; ++r)
            for (int c = 0; c < 4; ++c) {
                const float v = matrix.at(r, c);
                if (!std::isfinite(v)) throw py::value_error(std::string(what) + ": entries must be finite");
                out.m[r][c] = v;
            }
    };
    read_matrix(matrix_obj, "matrix", in.object_to_world);
    // Object motion blur: the transform at shutter close (`matrix` is the
    // one at shutter open).
    if (!matrix_close_obj.is_none()) {
        read_matrix(matrix_close_obj, "matrix_close", in.object_to_world_close);
        in.moves = true;
    }
    // Vector pass: the transforms one frame earlier and one later.
    Transform frames[2];
    if (!frame_matrices_obj.is_none()) {
        const FloatArray m = frame_transform_array(frame_matrices_obj, -1, "frame_matrices", "(2, 4, 4)");
        std::memcpy(frames, m.data(), sizeof(frames));
        in.frame_transforms = frames;
    }
    in.material_slots = read_material_slots(self, material_slots_obj);

    MeshShadingArrays shading_arrays;
    read_mesh_shading(self, in, uvs_obj, tangents_obj, generated_obj, colors_obj, shading_arrays);

    size_t added;
    {
        py::gil_scoped_release unlocked;  // validation of large meshes takes a while
        added = self.scene.add_mesh(in);
    }
    self.finalized = false;
    self.bvh.reset();  // the triangles changed
    return added;
}

// Scene.add_prototype: a mesh stored once in object space (instance.h).
int64_t add_prototype(PyScene& self, const std::string& name, const py::handle& positions_obj,
                      const py::handle& indices_obj, const py::handle& normals_obj,
                      const py::handle& material_ids_obj, const py::handle& uvs_obj, const py::handle& tangents_obj,
                      const py::handle& generated_obj, const py::handle& colors_obj) {
    self.check_mutable("add_prototype");
    MeshArgs args;
    read_mesh_arrays(args, name, positions_obj, indices_obj, normals_obj, material_ids_obj);
    MeshShadingArrays shading_arrays;  // kept alive until add_prototype copied them
    read_mesh_shading(self, args.in, uvs_obj, tangents_obj, generated_obj, colors_obj, shading_arrays);
    uint32_t id;
    {
        py::gil_scoped_release unlocked;
        id = self.scene.add_prototype(args.in);
    }
    return id == Scene::kNoPrototype ? -1 : int64_t(id);
}

static_assert(sizeof(Transform) == 16 * sizeof(float), "a (K, 4, 4) float32 array is K Transforms");

// Scene.add_instances: one prototype placed by K matrices, read in place.
size_t add_instances(PyScene& self, int64_t prototype, const py::handle& matrices_obj,
                     const py::handle& material_slots_obj, const std::string& name,
                     const py::handle& matrices_close_obj, const py::handle& frame_matrices_obj) {
    self.check_mutable("add_instances");
    if (prototype < 0 || size_t(prototype) >= self.scene.prototypes.size())
        throw py::value_error("prototype: " + std::to_string(prototype) + " does not exist (scene has " +
                              std::to_string(self.scene.prototypes.size()) + " prototypes)");
    FloatArray matrices = float_array(matrices_obj, {-1, 4, 4}, "matrices", "(K, 4, 4)");
    const std::vector<uint32_t> slots = read_material_slots(self, material_slots_obj);
    const auto* transforms = reinterpret_cast<const Transform*>(matrices.data());
    FloatArray close;
    const Transform* close_transforms = nullptr;
    if (!matrices_close_obj.is_none()) {
        close = float_array(matrices_close_obj, {matrices.shape(0), 4, 4}, "matrices_close", "(K, 4, 4) as matrices");
        close_transforms = reinterpret_cast<const Transform*>(close.data());
    }
    FloatArray frames;
    const Transform* frame_transforms = nullptr;
    if (!frame_matrices_obj.is_none()) {
        frames = frame_transform_array(frame_matrices_obj, matrices.shape(0), "frame_matrices", "(K, 2, 4, 4)");
        frame_transforms = reinterpret_cast<const Transform*>(frames.data());
    }
    size_t placed;
    {
        py::gil_scoped_release unlocked;
        placed = self.scene.add_instances(uint32_t(prototype), transforms, size_t(matrices.shape(0)), slots, name,
                                          close_transforms, frame_transforms);
    }
    self.finalized = false;
    self.bvh.reset();  // emissive instances became triangles
    self.instance_bvh.reset();
    return placed;
}

// A validated Material from add_material's / set_material's arguments.
Material material_from_args(const PyScene& self, const std::string& name, const py::handle& closures_obj,
                            const py::handle& weights_obj, const py::handle& emission_obj,
                            const py::handle& program_obj) {
    Material m;
    m.program = program_from_object(self, program_obj);
    m.name = name;

    std::vector<Closure> closures;
    if (!closures_obj.is_none()) {
        for (auto item : py::iter(closures_obj)) {
            if (!py::isinstance<py::dict>(item))
                throw py::type_error("closures[" + std::to_string(closures.size()) + "]: expected a dict");
            closures.push_back(closure_from_dict(item.cast<py::dict>(), closures.size()));
        }
    }
    if (closures.size() > m.closures.size())
        throw py::value_error("closures: at most " + std::to_string(m.closures.size()) + " closures, got " +
                              std::to_string(closures.size()));

    std::vector<float> weights;
    if (!weights_obj.is_none()) {
        for (auto item : py::iter(weights_obj))
            weights.push_back(non_negative(number_arg(item, "weights"), "weights"));
        if (weights.size() != closures.size())
            throw py::value_error("weights: expected " + std::to_string(closures.size()) + " weights (one per closure), got " +
                                  std::to_string(weights.size()));
    } else {
        weights.assign(closures.size(), closures.empty() ? 0.0f : 1.0f / float(closures.size()));
    }

    if (closures.empty()) {
        // A surface with no BSDF (e.g. a pure Emission shader) reflects nothing:
        // one black closure without a specular layer scatters zero energy.
        Closure black;
        black.base_color = Vec3f(0.0f);
        black.specular = 0.0f;
        black.roughness = 1.0f;
        closures.push_back(black);
        weights.assign(1, 1.0f);
    }
    m.closure_count = int(closures.size());
    for (size_t i = 0; i < m.closures.size(); ++i) {
        m.closures[i] = i < closures.size() ? closures[i] : Closure{};
        m.weights[i] = i < weights.size() ? weights[i] : 0.0f;
    }

    m.emission = to_vec3(emission_obj, "emission");
    if (min_component(m.emission) < 0.0f) throw py::value_error("emission: components must be >= 0");
    return m;
}

uint32_t add_material(PyScene& self, const std::string& name, const py::handle& closures_obj,
                      const py::handle& weights_obj, const py::handle& emission_obj, const py::handle& program_obj) {
    self.check_mutable("add_material");
    return self.scene.add_material(material_from_args(self, name, closures_obj, weights_obj, emission_obj, program_obj));
}

// Replaces a material in place: triangles keep their material indices, so
// the BVH stays valid (the features and emitter list are recomputed by
// finalize()).
void set_material(PyScene& self, size_t index, const std::string& name, const py::handle& closures_obj,
                  const py::handle& weights_obj, const py::handle& emission_obj, const py::handle& program_obj) {
    self.check_mutable("set_material");
    if (index >= self.scene.materials.size()) throw py::index_error("set_material: material index out of range");
    self.scene.materials[index] = material_from_args(self, name, closures_obj, weights_obj, emission_obj, program_obj);
    self.finalized = false;
}

size_t add_light(PyScene& self, const std::string& type, const py::handle& color, double power,
                 const py::handle& position, const py::handle& direction, const py::handle& axis_u,
                 const py::handle& axis_v, double radius, double spot_size, double spot_blend, double sun_angle,
                 const std::string& shape, double size_u, double size_v) {
    self.check_mutable("add_light");
    Light l;
    l.type = light_type_from(type);
    l.color = to_vec3(color, "color");
    if (min_component(l.color) < 0.0f) throw py::value_error("color: components must be >= 0");
    l.power = non_negative(power, "power");
    l.position = to_vec3(position, "position");
    l.direction = unit_vector(direction, "direction");
    l.axis_u = unit_vector(axis_u, "axis_u");
    l.axis_v = unit_vector(axis_v, "axis_v");
    l.radius = non_negative(radius, "radius");
    l.spot_size = std::clamp(non_negative(spot_size, "spot_size"), 0.0f, kPi);
    l.spot_blend = unit_clamp(spot_blend, "spot_blend");
    l.sun_angle = std::clamp(non_negative(sun_angle, "sun_angle"), 0.0f, kPi);
    l.shape = area_shape_from(shape);
    l.size_u = non_negative(size_u, "size_u");
    l.size_v = non_negative(size_v, "size_v");
    self.scene.lights.push_back(l);
    self.finalized = false;
    return self.scene.lights.size() - 1;
}

void set_camera(PyScene& self, const std::string& projection, const py::handle& position,
                const py::handle& forward, const py::handle& up, const py::handle& right, double half_width,
                double half_height, double shift_x, double shift_y, double clip_start, double clip_end,
                double aperture_radius, double focus_distance) {
    self.check_mutable("set_camera");
    Camera c;
    if (projection == "PERSP") c.projection = Projection::Perspective;
    else if (projection == "ORTHO") c.projection = Projection::Orthographic;
    else throw py::value_error("projection: expected 'PERSP' or 'ORTHO', got '" + projection + "'");

    c.position = to_vec3(position, "position");
    // Gram-Schmidt so the frame is orthonormal even if the caller's matrix had
    // shear or scale; `right` (optional) only decides handedness and is
    // re-derived from forward and up.
    c.forward = unit_vector(forward, "forward");
    Vec3f u = to_vec3(up, "up");
    u = u - c.forward * dot(u, c.forward);
    if (!(length(u) > 1e-12f)) throw py::value_error("up: must not be parallel to forward");
    c.up = normalize(u);
    c.right = cross(c.forward, c.up);
    if (!right.is_none() && dot(to_vec3(right, "right"), c.right) < 0.0f) c.right = -c.right;

    c.half_width = positive(half_width, "half_width");
    c.half_height = positive(half_height, "half_height");
    c.shift_x = finite_float(shift_x, "shift_x");
    c.shift_y = finite_float(shift_y, "shift_y");
    c.clip_start = non_negative(clip_start, "clip_start");
    c.clip_end = positive(clip_end, "clip_end");
    if (!(c.clip_end > c.clip_start)) throw py::value_error("clip_end: must be greater than clip_start");
    c.aperture_radius = non_negative(aperture_radius, "aperture_radius");
    c.focus_distance = positive(focus_distance, "focus_distance");
    self.scene.camera = c;
    self.finalized = false;
}

// A camera object's world matrix (Blender's: columns right, up, back,
// position) as the frame set_camera derives from the same vectors.
CameraFrame camera_frame(const py::handle& obj, const char* what) {
    const FloatArray m = float_array(obj, {4, 4}, what, "(4, 4)");
    const auto column = [&](int c) { return Vec3f(m.at(0, c), m.at(1, c), m.at(2, c)); };
    CameraFrame f;
    f.position = column(3);
    const Vec3f back = column(2), up = column(1);
    if (!std::isfinite(dot(f.position, f.position) + dot(back, back) + dot(up, up)) || !(length(back) > 0.0f))
        throw py::value_error(std::string(what) + ": expected a finite camera matrix with a view axis");
    f.forward = normalize(-back);
    const Vec3f u = up - f.forward * dot(up, f.forward);
    if (!(length(u) > 1e-12f)) throw py::value_error(std::string(what) + ": up must not be parallel to the view axis");
    f.up = normalize(u);
    f.right = cross(f.forward, f.up);
    if (dot(column(0), f.right) < 0.0f) f.right = -f.right;
    return f;
}

// Scene.set_camera_frames (the Vector pass's camera motion).
void set_camera_frames(PyScene& self, const py::handle& previous, const py::handle& next) {
    self.check_mutable("set_camera_frames");
    DataPassInputs& d = self.scene.data_passes;
    d.camera_previous = camera_frame(previous, "previous");
    d.camera_next = camera_frame(next, "next");
    d.camera_moves = true;
}

py::dict camera_dict(const Camera& c) {
    py::dict d;
    d["projection"] = c.projection == Projection::Perspective ? "PERSP" : "ORTHO";
    d["position"] = vec_tuple(c.position);
    d["forward"] = vec_tuple(c.forward);
    d["up"] = vec_tuple(c.up);
    d["right"] = vec_tuple(c.right);
    d["half_width"] = c.half_width;
    d["half_height"] = c.half_height;
    d["shift_x"] = c.shift_x;
    d["shift_y"] = c.shift_y;
    d["clip_start"] = c.clip_start;
    d["clip_end"] = c.clip_end;
    d["aperture_radius"] = c.aperture_radius;
    d["focus_distance"] = c.focus_distance;
    return d;
}

py::dict dropped_dict(const DropReport& r) {
    py::dict d;
    d["nonfinite_vertices"] = r.nonfinite_vertices;
    d["out_of_range_indices"] = r.out_of_range_indices;
    d["degenerate_triangles"] = r.degenerate_triangles;
    d["bad_material_ids"] = r.bad_material_ids;
    d["total_triangles"] = r.total_triangles();
    d["skipped_meshes"] = r.skipped_meshes;
    return d;
}

py::dict material_dict(const Material& m) {
    py::dict d;
    d["name"] = m.name;
    py::list closures, weights;
    for (int i = 0; i < m.closure_count; ++i) {
        const Closure& c = m.closures[size_t(i)];
        py::dict cd;
        cd["base_color"] = vec_tuple(c.base_color);
        cd["metallic"] = c.metallic;
        cd["roughness"] = c.roughness;
        cd["specular"] = c.specular;
        cd["transmission"] = c.transmission;
        cd["ior"] = c.ior;
        cd["principled_diffuse"] = c.principled_diffuse;
        cd["kind"] = kClosureKinds[size_t(c.kind)];
        closures.append(cd);
        weights.append(m.weights[size_t(i)]);
    }
    d["closures"] = closures;
    d["weights"] = weights;
    d["emission"] = vec_tuple(m.emission);
    return d;
}

// Holds a scene claimed while the GIL is released, as a Renderer claims it:
// nothing may mutate it under a BVH build (PyScene::check_mutable).
class SceneClaim {
public:
    explicit SceneClaim(const PyScene& scene) : scene_(const_cast<PyScene&>(scene)) { scene_.active_renderers.fetch_add(1); }
    ~SceneClaim() { scene_.active_renderers.fetch_sub(1); }
    SceneClaim(const SceneClaim&) = delete;
    SceneClaim& operator=(const SceneClaim&) = delete;

private:
    PyScene& scene_;
};

double seconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

double build_bvh(PyScene& self, bool spatial_splits) {
    BvhBuildOptions options;
    if (!spatial_splits) options.spatial_split_budget = 0.0f;  // plain binned SAH
    self.ensure_finalized();
    std::shared_ptr<Bvh> bvh;
    {
        SceneClaim claim(self);
        py::gil_scoped_release unlocked;
        bvh = Renderer::build_bvh(self.scene, options);  // leaves moving triangles to the MotionBvh
    }
    self.bvh = bvh;
    return bvh->build_stats().seconds;
}

// Scene.refit_bvh_from: `self` holds the same triangles as `previous`, in
// the same order, some of them moved (an interactive transform edit exports
// a new scene from cached meshes). Instead of a rebuild, `self` gets a copy
// of previous's BVH refit to its vertices (Bvh::refit): same exact hits, a
// fraction of the build time.
double refit_bvh_from(PyScene& self, const PyScene& previous) {
    if (!previous.bvh) throw py::value_error("refit_bvh_from: the previous scene has no BVH");
    if (previous.scene.triangle_count() != self.scene.triangle_count())
        throw py::value_error("refit_bvh_from: the previous scene has " +
                              std::to_string(previous.scene.triangle_count()) + " triangles, this one " +
                              std::to_string(self.scene.triangle_count()) + "; only a same-size scene can refit");
    self.ensure_finalized();
    const auto start = std::chrono::steady_clock::now();
    std::shared_ptr<const Bvh> source = previous.bvh;  // kept alive while the GIL is released
    auto bvh = std::make_shared<Bvh>();
    {
        SceneClaim claim(self);
        py::gil_scoped_release unlocked;
        *bvh = *source;
        bvh->refit(self.scene);
    }
    self.bvh = bvh;
    return seconds_since(start);
}

// Scene.build_instance_bvh: the two-level BVH of `self`'s instances, sharing
// the prototype BVHs of `previous` whose triangles did not change
// (InstanceBvh::build_reusing). Persistent data's re-render: only changed
// meshes are built again.
py::dict build_instance_bvh(PyScene& self, const PyScene& previous) {
    if (!previous.instance_bvh)
        throw py::value_error("build_instance_bvh: the previous scene has no instance BVH (render it first)");
    if (&self == &previous) throw py::value_error("build_instance_bvh: previous must be another scene");
    self.ensure_finalized();
    const auto start = std::chrono::steady_clock::now();
    std::shared_ptr<const InstanceBvh> source = previous.instance_bvh;  // kept alive while unlocked
    auto built = std::make_shared<InstanceBvh>();
    {
        SceneClaim claim(self), claim_previous(previous);
        py::gil_scoped_release unlocked;
        built->build_reusing(self.scene, *source, previous.scene);
    }
    self.instance_bvh = built;
    py::dict d;
    d["reused"] = built->reused_prototypes();
    d["built"] = built->built_prototypes();
    d["seconds"] = seconds_since(start);
    return d;
}

// The world's environment map from a numpy image. Returns the number of
// pixel values replaced by 0 (non-finite or negative), for a warning.
size_t set_world_map(PyScene& self, const py::handle& pixels, const py::handle& rotation) {
    self.check_mutable("set_world_map");
    FloatArray a = float_array(pixels, {-1, -1, -1}, "pixels", "(height, width, 3 or 4)");
    const py::ssize_t h = a.shape(0), w = a.shape(1), c = a.shape(2);
    if (c != 3 && c != 4) throw py::value_error("pixels: expected 3 or 4 channels, got " + std::to_string(c));
    if (h < 1 || w < 1) throw py::value_error("pixels: the image is empty, shape " + shape_string(a));
    EnvironmentMap map;
    if (!rotation.is_none()) {
        FloatArray r = float_array(rotation, {3, 3}, "rotation", "(3, 3)");
        for (int i = 0; i < 9; ++i) map.rotation[i] = r.data()[i];
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) {
                float dot_ij = 0.0f;
                for (int k = 0; k < 3; ++k) dot_ij += map.rotation[3 * i + k] * map.rotation[3 * j + k];
                if (!(std::fabs(dot_ij - (i == j ? 1.0f : 0.0f)) < 1e-3f))
                    throw py::value_error("rotation: expected an orthonormal 3x3 rotation matrix");
            }
    }
    map.width = int(w);
    map.height = int(h);
    map.rgb.resize(size_t(w) * size_t(h) * 3);
    size_t replaced = 0;
    const float* src = a.data();
    for (size_t i = 0; i < size_t(w) * size_t(h); ++i)
        for (int ch = 0; ch < 3; ++ch) {
            const float v = src[i * size_t(c) + size_t(ch)];
            const bool ok = std::isfinite(v) && v >= 0.0f;
            replaced += ok ? 0 : 1;
            map.rgb[i * 3 + size_t(ch)] = ok ? v : 0.0f;
        }
    self.scene.world_map = std::move(map);
    self.finalized = false;
    return replaced;
}

// Scene.add_prototype / add_instances and their counts (shared geometry, scene/instance.h).
void bind_instancing(py::class_<PyScene, std::shared_ptr<PyScene>>& scene_class) {
    scene_class
        .def("add_prototype", &add_prototype, py::arg("name"), py::arg("positions"), py::arg("indices"),
             py::arg("normals") = py::none(), py::arg("material_ids") = py::none(), py::kw_only(),
             py::arg("uvs") = py::none(), py::arg("tangents") = py::none(), py::arg("generated") = py::none(),
             py::arg("colors") = py::none(),
             R"doc(Adds a mesh shared by instances, stored once in object space.

Arguments as add_mesh's (no matrix), UVs, tangents, texture space and
colour attributes included: every instance shades with them. Material ids select slots that
each instance maps to scene materials (add_instances). Returns the
prototype's index, or -1 when no triangle was usable (reported in `dropped`).
)doc")
        .def("add_instances", &add_instances, py::arg("prototype"), py::arg("matrices"),
             py::arg("material_slots") = py::none(), py::arg("name") = "", py::arg("matrices_close") = py::none(),
             py::kw_only(), py::arg("frame_matrices") = py::none(),
             R"doc(Places prototype `prototype` once per row-major object-to-world matrix.

matrices: float (K, 4, 4); material_slots: scene material per slot (as add_mesh).
matrices_close: optional float (K, 4, 4), the transforms at shutter close
(motion blur): instance k moves from matrices[k] to matrices_close[k].
frame_matrices: optional float (K, 2, 4, 4), instance k's matrix one frame
earlier and one frame later (the Vector pass; without it, standing still).
Instances with a non-invertible matrix are skipped (reported in `dropped`);
instances of an emissive material become world-space triangles. Returns
the number of instances placed.
)doc")
        .def_property_readonly("prototype_count", [](const PyScene& s) { return s.scene.prototypes.size(); })
        .def_property_readonly("instance_count", [](const PyScene& s) { return s.scene.instances.size(); })
        .def_property_readonly("instanced_triangle_count",
                               [](const PyScene& s) { return s.scene.instanced_triangle_count(); },
                               "Triangles rendered through instances (each instance counts its prototype's).");
}

}  // namespace

void PyScene::check_mutable(const char* what) const {
    if (active_renderers.load() > 0)
        throw std::runtime_error(std::string("Scene.") + what +
                                 ": the scene is in use by a Renderer; delete the Renderer before changing the scene");
}

void PyScene::ensure_finalized() {
    if (finalized) return;
    py::gil_scoped_release unlocked;
    scene.finalize();
    finalized = true;
}

// The world: constant colour and environment map.
void bind_world(py::class_<PyScene, std::shared_ptr<PyScene>>& cls) {
    cls.def_property(
           "world_color", [](const PyScene& s) { return vec_tuple(s.scene.world_color); },
            [](PyScene& s, const py::handle& v) {
                s.check_mutable("world_color");
                const Vec3f c = to_vec3(v, "world_color");
                if (min_component(c) < 0.0f) throw py::value_error("world_color: components must be >= 0");
                s.scene.world_color = c;
                s.finalized = false;
            },
            "Constant environment radiance (r, g, b).")
        .def("set_world_map", &set_world_map, py::arg("pixels"), py::arg("rotation") = py::none(),
             "Makes the world an equirectangular environment map: pixels (height, width, 3 or 4) linear RGB(A), "
             "rows bottom to top as Blender's Image.pixels; rotation: 3x3 taking world directions to the map's "
             "frame. World radiance = world_color x map. Non-finite or negative values become 0; returns "
             "how many did.")
        .def("clear_world_map", [](PyScene& s) {
                s.check_mutable("clear_world_map");
                s.scene.world_map = EnvironmentMap{};
                s.finalized = false;
            }, "Back to the constant world_color.")
        .def_property_readonly("world_map_size", [](const PyScene& s) {
                return py::make_tuple(s.scene.world_map.width, s.scene.world_map.height);
            }, "(width, height) of the world's environment map; (0, 0) for none.");
}

// The BVHs a scene keeps for its Renderers, and their reuse across scenes.
void bind_bvh(py::class_<PyScene, std::shared_ptr<PyScene>>& cls) {
    cls.def_property_readonly("has_bvh", [](const PyScene& s) { return s.bvh != nullptr; },
                              "Whether a BVH over the current triangles is kept for the next Renderer.")
        .def_property_readonly("has_instance_bvh", [](const PyScene& s) { return s.instance_bvh != nullptr; },
                              "Whether the instances' two-level BVH is kept for the next Renderer.")
        .def("build_bvh", &build_bvh, py::arg("spatial_splits") = true, R"doc(
Builds the BVH over the current triangles now and keeps it for the next
Renderers (which otherwise build one with spatial splits). Without spatial
splits the build is several times faster and traversal somewhat slower: the
trade interactive viewports want after a geometry edit. Returns build seconds.)doc")
        .def("refit_bvh_from", &refit_bvh_from, py::arg("previous"), R"doc(
Keeps a copy of `previous`'s BVH refit to this scene's triangles instead of
building one: for a scene with the same triangles in the same order, some of
them moved (a transform edit re-exported from cached meshes). Hits are exact
either way; the refit tree keeps the old topology, so it traces somewhat
slower when objects moved far. Raises ValueError if `previous` has no BVH or
a different triangle count. Returns seconds (copy + refit).)doc")
        .def("build_instance_bvh", &build_instance_bvh, py::arg("previous"), R"doc(
Builds this scene's instance BVH now, taking from `previous` (a scene a
Renderer has rendered) the BVH of every prototype whose object-space
triangles are exactly the same; only the others and the top level over the
instances are built. Returns {"reused": n, "built": m, "seconds": s}.)doc");
}

// What Cycles' data passes read besides geometry (film/passes.h).
void set_data_passes(PyScene& s, const py::dict& object_pass_index, const std::vector<float>& material_pass_index,
                     float mist_start, float mist_depth, float mist_falloff, float ao_distance,
                     const std::vector<std::string>& crypto_object_names,
                     const std::vector<std::string>& crypto_asset_names) {
    s.check_mutable("set_data_passes");
    if (!(mist_falloff > 0.0f) || !std::isfinite(mist_start) || !(mist_depth >= 0.0f) || !std::isfinite(ao_distance))
        throw py::value_error("set_data_passes: mist_falloff must be > 0, mist_depth >= 0, the others finite");
    DataPassInputs& d = s.scene.data_passes;
    d.object_pass_index.assign(s.scene.object_names.size(), 0.0f);
    for (size_t i = 0; i < s.scene.object_names.size(); ++i) {
        const py::str name(s.scene.object_names[i]);
        if (object_pass_index.contains(name)) d.object_pass_index[i] = object_pass_index[name].cast<float>();
    }
    d.material_pass_index = material_pass_index;
    d.mist_start = mist_start;
    d.mist_depth = mist_depth;
    d.mist_falloff = mist_falloff;
    d.ao_distance = ao_distance;
    d.crypto_object_names = crypto_object_names;
    d.crypto_asset_names = crypto_asset_names;
}

// Cycles' per-object Shadow Terminator Geometry Offset (render/shadow_terminator.h).
void set_shadow_terminator(PyScene& s, const py::dict& offsets) {
    s.check_mutable("set_shadow_terminator");
    std::vector<float> per_object(s.scene.object_names.size(), kDefaultTerminatorOffset);
    for (size_t i = 0; i < per_object.size(); ++i) {
        const py::str name(s.scene.object_names[i]);
        if (!offsets.contains(name)) continue;
        const float value = offsets[name].cast<float>();
        if (!(value >= 0.0f && value <= 1.0f))
            throw py::value_error("set_shadow_terminator: the offset of object '" + s.scene.object_names[i] +
                                  "' must be in [0, 1], got " + std::to_string(value));
        per_object[i] = value;
    }
    s.scene.object_terminator_offset = std::move(per_object);
}

// Scene.set_data_passes (film/passes.h).
void bind_data_passes(py::class_<PyScene, std::shared_ptr<PyScene>>& cls) {
    cls.def("set_data_passes", &set_data_passes, py::kw_only(), py::arg("object_pass_index") = py::dict(),
            py::arg("material_pass_index") = std::vector<float>{}, py::arg("mist_start") = 5.0f,
            py::arg("mist_depth") = 25.0f, py::arg("mist_falloff") = 2.0f, py::arg("ao_distance") = 0.0f,
            py::arg("crypto_object_names") = std::vector<std::string>{},
            py::arg("crypto_asset_names") = std::vector<std::string>{}, R"doc(
What Cycles' data passes read: object_pass_index {object name: pass_index}
(IndexOB; call after adding the objects), material_pass_index (IndexMA, per
scene material index), the World's mist (start, depth, falloff exponent: 2
quadratic, 1 linear, 0.5 inverse quadratic) and AO distance (AO pass; <= 0:
the ao_distance setting's resolved length). Unset indices are 0.
crypto_object_names / crypto_asset_names: per object (object_names order)
the names Cryptomatte hashes (empty: the object's name).)doc");
    cls.def("set_shadow_terminator", &set_shadow_terminator, py::arg("offsets"), R"doc(
Cycles' Shadow Terminator Geometry Offset per object {object name: offset in
[0, 1]} (call after adding the objects; others keep Cycles' default 0.1, and 0
turns it off): shadow rays that graze a smooth-shaded triangle start from the
smooth surface its vertex normals describe.)doc");
    cls.def_static("cryptomatte_hash", [](const std::string& name) { return murmur_hash3(name); }, py::arg("name"),
                   "Cycles' Cryptomatte hash of a name (MurmurHash3_x86_32, seed 0).");
    cls.def_static("cryptomatte_manifest", &cryptomatte_manifest, py::arg("names"),
                   "The Cryptomatte manifest JSON {name: hash hex} of `names`.");
}

void bind_scene(py::module_& m) {
    py::class_<PyScene, std::shared_ptr<PyScene>> scene_class(m, "Scene", R"doc(
A scene under construction: world-space triangles, shared meshes placed by
instances, materials, lights, camera and world colour. Fill it with
add_material/add_mesh/add_prototype/add_instances/add_light/set_camera,
then pass it to Renderer (which calls finalize() if needed). Material 0 is the
default grey diffuse.
)doc");
    bind_instancing(scene_class);
    bind_data_passes(scene_class);
    scene_class
        .def(py::init<>())
        .def("add_mesh", &add_mesh, py::arg("name"), py::arg("positions"), py::arg("indices"), py::arg("matrix"),
             py::arg("normals") = py::none(), py::arg("material_ids") = py::none(),
             py::arg("material_slots") = py::none(), py::arg("matrix_close") = py::none(), py::kw_only(),
             py::arg("uvs") = py::none(), py::arg("tangents") = py::none(), py::arg("generated") = py::none(),
             py::arg("colors") = py::none(), py::arg("frame_matrices") = py::none(),
             R"doc(Adds a triangle mesh, transformed to world space by `matrix`.

positions: float (N, 3) object-space vertices (any real dtype, converted to float32)
indices: integer (M, 3) vertex indices
matrix: float (4, 4) row-major object-to-world transform
normals: optional float (M, 3, 3) per-corner shading normals (object space)
material_ids: optional integer (M,) per-triangle index into material_slots
material_slots: optional list of scene material indices; empty -> material 0
matrix_close: optional float (4, 4) transform at shutter close (object motion
  blur): the mesh moves linearly from `matrix` (shutter open) to it
uvs: optional list, one per set_shading_inputs UV name, of float (M, 3, 2)
  per-corner UVs (None where the mesh lacks that layer)
tangents: optional float (M, 3, 4) per-corner object-space tangent and bitangent sign
generated: optional (scale, offset) of Blender's texture space
colors: optional list, one per set_shading_inputs colour name, of float (M, 3, 4)
  per-corner linear RGBA (None where the mesh lacks that attribute)
frame_matrices: optional float (2, 4, 4): the object-to-world transform one
  frame earlier and one frame later (the Vector pass; without it, still)
Bad triangles (non-finite, out-of-range index, zero area) are dropped and
counted in `dropped`. Returns the number of triangles added.)doc")
        .def("add_material", &add_material, py::arg("name"), py::arg("closures") = py::none(),
             py::arg("weights") = py::none(), py::arg("emission") = py::make_tuple(0.0, 0.0, 0.0),
             py::arg("program") = py::none(),
             R"doc(Adds a material; returns its index.

closures: up to 4 dicts with keys base_color, metallic, roughness, specular,
transmission, ior, principled_diffuse (missing keys take Principled BSDF defaults,
except principled_diffuse: False is Lambert, True Cycles' Principled diffuse; [0,1] values
are clamped), kind ('principled' default; 'transparent', 'translucent': Cycles' closures of
colour base_color; 'holdout'). An empty list means no BSDF (black, e.g. pure emission).
weights: one non-negative weight per closure (default: equal, summing to 1).
emission: emitted radiance (colour x strength).
program: optional shader program dict (code, constants, data, outputs; see
native/shader/program.h) whose outputs override the constants per shading point.)doc")
        .def("set_material", &set_material, py::arg("index"), py::arg("name"), py::arg("closures") = py::none(),
             py::arg("weights") = py::none(), py::arg("emission") = py::make_tuple(0.0, 0.0, 0.0),
             py::arg("program") = py::none(),
             "Replaces material `index` (arguments as add_material). Keeps the BVH: no triangle changes.")
        .def("clear_lights", [](PyScene& s) {
                s.check_mutable("clear_lights");
                s.scene.lights.clear();
                s.finalized = false;
            }, "Removes every light (add_light adds them again). Keeps the BVH.")
        .def("add_light", &add_light, py::arg("type") = "POINT", py::kw_only(),
             py::arg("color") = py::make_tuple(1.0, 1.0, 1.0), py::arg("power") = 10.0,
             py::arg("position") = py::make_tuple(0.0, 0.0, 0.0), py::arg("direction") = py::make_tuple(0.0, 0.0, -1.0),
             py::arg("axis_u") = py::make_tuple(1.0, 0.0, 0.0), py::arg("axis_v") = py::make_tuple(0.0, 1.0, 0.0),
             py::arg("radius") = 0.0, py::arg("spot_size") = 0.785, py::arg("spot_blend") = 0.15,
             py::arg("sun_angle") = 0.0, py::arg("shape") = "SQUARE", py::arg("size_u") = 1.0,
             py::arg("size_v") = 1.0,
             "Adds a light in Blender units (W for point/spot/area, W/m^2 for sun); returns its index.")
        .def("set_camera_frames", &set_camera_frames, py::arg("previous"), py::arg("next"), R"doc(
The camera object's world matrix (float (4, 4), row-major, Blender's
matrix_world) one frame earlier and one frame later, for the Vector pass;
the lens stays set_camera's (as in Cycles). Without it the camera stands still.)doc")
        .def("set_camera", &set_camera, py::kw_only(), py::arg("projection") = "PERSP",
             py::arg("position") = py::make_tuple(0.0, 0.0, 5.0), py::arg("forward") = py::make_tuple(0.0, 0.0, -1.0),
             py::arg("up") = py::make_tuple(0.0, 1.0, 0.0), py::arg("right") = py::none(),
             py::arg("half_width") = 0.41421356, py::arg("half_height") = 0.41421356, py::arg("shift_x") = 0.0,
             py::arg("shift_y") = 0.0, py::arg("clip_start") = 1e-3, py::arg("clip_end") = 1e30,
             py::arg("aperture_radius") = 0.0, py::arg("focus_distance") = 10.0,
             "Sets the camera (world-space frame; half extents of the image plane at distance 1, "
             "or in world units for 'ORTHO').")
        .def_property_readonly("camera", [](const PyScene& s) { return camera_dict(s.scene.camera); })
        .def("finalize", &PyScene::ensure_finalized,
             "Computes scene features and the emissive triangle list. Renderer calls it if needed.")
        .def_property_readonly("finalized", [](const PyScene& s) { return s.finalized; })
        .def_property_readonly("triangle_count", [](const PyScene& s) { return s.scene.triangle_count(); })
        .def_property_readonly("material_count", [](const PyScene& s) { return s.scene.materials.size(); })
        .def_property_readonly("light_count", [](const PyScene& s) { return s.scene.lights.size(); })
        .def_property_readonly("object_names", [](const PyScene& s) { return s.scene.object_names; })
        .def("material", [](const PyScene& s, size_t i) {
                if (i >= s.scene.materials.size()) throw py::index_error("material index out of range");
                return material_dict(s.scene.materials[i]);
            }, py::arg("index"), "The material at `index` as a dict (as stored, after clamping).")
        .def_property_readonly("bounds", [](const PyScene& s) {
                const BBox b = s.scene.bounds();
                return py::make_tuple(vec_tuple(b.lo), vec_tuple(b.hi));
            })
        .def_property_readonly("dropped", [](const PyScene& s) { return dropped_dict(s.scene.dropped); },
                               "What validation removed, per reason.")
        .def_property_readonly("dropped_summary", [](const PyScene& s) { return s.scene.dropped.summary(); },
                               "One human-readable line; empty when nothing was dropped.")
        .def_property_readonly("features", [](PyScene& s) {
                s.ensure_finalized();
                return s.scene.features.names();
            }, "Names of the effects this scene needs (finalizes the scene).")
        .def("__repr__", [](const PyScene& s) {
            return "<coherent.Scene: " + std::to_string(s.scene.triangle_count()) + " triangles, " +
                   std::to_string(s.scene.materials.size()) + " materials, " + std::to_string(s.scene.lights.size()) +
                   " lights>";
        });
    bind_world(scene_class);
    bind_bvh(scene_class);
}

}  // namespace coherent::python
