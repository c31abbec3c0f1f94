// Scene::add_prototype / add_instances (instance.h): shared geometry stored
// once in object space, placed by validated, invertible transforms.
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "scene.h"

namespace coherent {

bool invert_affine(const Transform& t, Transform& inv) {
    double m[3][3];
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) m[r][c] = t.m[r][c];
    const double c00 = m[1][1] * m[2][2] - m[1][2] * m[2][1];
    const double c01 = m[1][2] * m[2][0] - m[1][0] * m[2][2];
    const double c02 = m[1][0] * m[2][1] - m[1][1] * m[2][0];
    const double det = m[0][0] * c00 + m[0][1] * c01 + m[0][2] * c02;
    if (!(std::fabs(det) > 0.0) || !std::isfinite(det)) return false;
    const double a[3][3] = {
        {c00, m[0][2] * m[2][1] - m[0][1] * m[2][2], m[0][1] * m[1][2] - m[0][2] * m[1][1]},
        {c01, m[0][0] * m[2][2] - m[0][2] * m[2][0], m[0][2] * m[1][0] - m[0][0] * m[1][2]},
        {c02, m[0][1] * m[2][0] - m[0][0] * m[2][1], m[0][0] * m[1][1] - m[0][1] * m[1][0]}};
    inv = Transform{};
    for (int r = 0; r < 3; ++r) {
        double translate = 0.0;
        for (int c = 0; c < 3; ++c) {
            const double x = a[r][c] / det;
            inv.m[r][c] = float(x);
            translate -= x * t.m[c][3];
            if (!std::isfinite(inv.m[r][c])) return false;
        }
        inv.m[r][3] = float(translate);
        if (!std::isfinite(inv.m[r][3])) return false;
    }
    return true;
}

Transform normal_transform(const Transform& t) {
    const auto& m = t.m;
    Transform n;
    n.m[0][0] = m[1][1] * m[2][2] - m[1][2] * m[2][1];
    n.m[0][1] = m[1][2] * m[2][0] - m[1][0] * m[2][2];
    n.m[0][2] = m[1][0] * m[2][1] - m[1][1] * m[2][0];
    n.m[1][0] = m[0][2] * m[2][1] - m[0][1] * m[2][2];
    n.m[1][1] = m[0][0] * m[2][2] - m[0][2] * m[2][0];
    n.m[1][2] = m[0][1] * m[2][0] - m[0][0] * m[2][1];
    n.m[2][0] = m[0][1] * m[1][2] - m[0][2] * m[1][1];
    n.m[2][1] = m[0][2] * m[1][0] - m[0][0] * m[1][2];
    n.m[2][2] = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    const float det = m[0][0] * n.m[0][0] + m[0][1] * n.m[0][1] + m[0][2] * n.m[0][2];
    if (det < 0.0f)
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) n.m[r][c] = -n.m[r][c];
    return n;
}

namespace {

// The world box of object box `b` under `t` (its eight corners), widened
// by a few ulps of its magnitude so that rounding in the ray transform can
// never carry a hit outside it.
BBox transformed_bounds(const BBox& b, const Transform& t) {
    BBox w;
    for (int i = 0; i < 8; ++i)
        w.expand(t.point({(i & 1) ? b.hi.x : b.lo.x, (i & 2) ? b.hi.y : b.lo.y, (i & 4) ? b.hi.z : b.lo.z}));
    const Vec3f pad = max(abs(w.lo), abs(w.hi)) * 0x1p-20f;
    w.lo = w.lo - pad;
    w.hi = w.hi + pad;
    return w;
}

// The prototype's triangles as add_mesh input (identity transform).
struct PrototypeMesh {
    std::vector<uint32_t> indices;
    std::vector<float> tangents;  // x, y, z, sign per corner (MeshShadingInput's layout)
    MeshInput in;
};

PrototypeMesh as_mesh_input(const Prototype& p, const Transform& xf, const Transform* close,
                            const std::vector<uint32_t>& slots, const std::string& name) {
    PrototypeMesh pm;
    pm.indices.resize(p.vertices.size());
    std::iota(pm.indices.begin(), pm.indices.end(), 0u);
    pm.in.name = name;
    pm.in.positions = &p.vertices[0].x;
    pm.in.vertex_count = p.vertices.size();
    pm.in.indices = pm.indices.data();
    pm.in.triangle_count = p.triangle_count();
    bool any_normals = false;
    for (uint8_t h : p.has_normals) any_normals = any_normals || h;
    if (any_normals) pm.in.normals = &p.normals[0].x;
    pm.in.material_ids = p.slot_of.data();
    pm.in.material_slots = slots;
    for (const auto& layer : p.uvs) pm.in.shading.uvs.push_back(layer.empty() ? nullptr : &layer[0].x);
    for (const auto& layer : p.colors) pm.in.shading.colors.push_back(layer.empty() ? nullptr : layer.data());
    if (!p.tangents.empty()) {
        pm.tangents.reserve(4 * p.tangents.size());
        for (size_t c = 0; c < p.tangents.size(); ++c)
            pm.tangents.insert(pm.tangents.end(), {p.tangents[c].x, p.tangents[c].y, p.tangents[c].z, p.tangent_signs[c]});
        pm.in.shading.tangents = pm.tangents.data();
    }
    pm.in.shading.generated_scale = p.generated_scale;
    pm.in.shading.generated_offset = p.generated_offset;
    pm.in.object_to_world = xf;
    if (close) {
        pm.in.moves = true;
        pm.in.object_to_world_close = *close;
    }
    return pm;
}

bool same_transform(const Transform& a, const Transform& b) {
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c)
            if (a.m[r][c] != b.m[r][c]) return false;
    return true;
}

}  // namespace

static_assert(sizeof(Vec3f) == 3 * sizeof(float), "prototype arrays are passed on as float triples");
static_assert(sizeof(Vec2f) == 2 * sizeof(float), "prototype UVs are passed on as float pairs");

uint32_t Scene::add_prototype(const MeshInput& mesh) {
    // Validated by add_mesh itself, in object space, with each material id
    // resolving to itself: one set of rules for flattened and shared meshes.
    Scene object_space;
    object_space.shading.uv_names = shading.uv_names;  // UVs and tangents as the programs want them
    object_space.shading.wants_tangents = shading.wants_tangents;
    object_space.shading.color_names = shading.color_names;
    MeshInput in = mesh;
    in.object_to_world = Transform{};
    in.moves = false;
    in.positions_close = nullptr;
    uint32_t slots = 1;
    if (mesh.material_ids)
        for (size_t t = 0; t < mesh.triangle_count; ++t) slots = std::max(slots, mesh.material_ids[t] + 1);
    object_space.materials.resize(slots);
    in.material_slots.resize(slots);
    std::iota(in.material_slots.begin(), in.material_slots.end(), 0u);
    object_space.add_mesh(in);

    DropReport& d = object_space.dropped;
    dropped.nonfinite_vertices += d.nonfinite_vertices;
    dropped.out_of_range_indices += d.out_of_range_indices;
    dropped.degenerate_triangles += d.degenerate_triangles;
    dropped.meshes_with_drops.insert(dropped.meshes_with_drops.end(), d.meshes_with_drops.begin(),
                                     d.meshes_with_drops.end());
    dropped.skipped_meshes.insert(dropped.skipped_meshes.end(), d.skipped_meshes.begin(), d.skipped_meshes.end());
    if (object_space.triangle_count() == 0) return kNoPrototype;

    Prototype p;
    p.name = mesh.name;
    p.vertices = std::move(object_space.vertices);
    p.normals = std::move(object_space.normals);
    p.has_normals = std::move(object_space.has_normals);
    p.slot_of = std::move(object_space.material_of);
    p.uvs = std::move(object_space.shading.uvs);
    p.tangents = std::move(object_space.shading.tangents);
    p.tangent_signs = std::move(object_space.shading.tangent_signs);
    p.colors = std::move(object_space.shading.colors);
    p.generated_scale = mesh.shading.generated_scale;
    p.generated_offset = mesh.shading.generated_offset;
    for (const Vec3f& v : p.vertices) p.bounds.expand(v);
    prototypes.push_back(std::move(p));
    return uint32_t(prototypes.size() - 1);
}

size_t Scene::add_instances(uint32_t prototype, const Transform* transforms, size_t count,
                            const std::vector<uint32_t>& material_slots, const std::string& name,
                            const Transform* close_transforms,
                            const Transform* frame_transforms) {
    if (prototype >= prototypes.size())
        throw std::invalid_argument("add_instances: prototype " + std::to_string(prototype) + " does not exist (scene has " +
                                    std::to_string(prototypes.size()) + ")");
    bool emissive = false;
    for (uint32_t m : material_slots) {
        if (m >= materials.size())
            throw std::invalid_argument("add_instances: material " + std::to_string(m) + " does not exist");
        emissive = emissive || materials[m].is_emissive();
    }
    const std::string label = name.empty() ? prototypes[prototype].name : name;
    size_t placed = 0, singular = 0;
    if (emissive) {
        for (size_t i = 0; i < count; ++i) {
            const Transform* close = close_transforms ? &close_transforms[i] : nullptr;
            PrototypeMesh pm = as_mesh_input(prototypes[prototype], transforms[i], close, material_slots, label);
            pm.in.frame_transforms = frame_transforms ? frame_transforms + 2 * i : nullptr;
            placed += add_mesh(pm.in) > 0 ? 1 : 0;
        }
        return placed;
    }
    const uint32_t first_material = uint32_t(instance_materials.size());
    instance_materials.insert(instance_materials.end(), material_slots.begin(), material_slots.end());
    const uint32_t object = uint32_t(object_names.size());
    object_names.push_back(label);
    instances.reserve(instances.size() + count);
    for (size_t i = 0; i < count; ++i) {
        Instance inst;
        inst.prototype = prototype;
        inst.object_to_world = transforms[i];
        if (!invert_affine(inst.object_to_world, inst.world_to_object)) {
            ++singular;
            continue;
        }
        inst.normal_to_world = normal_transform(inst.object_to_world);
        inst.first_material = first_material;
        inst.material_count = uint32_t(material_slots.size());
        inst.object = object;
        inst.world_bounds = transformed_bounds(prototypes[prototype].bounds, inst.object_to_world);
        if (close_transforms && !same_transform(close_transforms[i], inst.object_to_world)) {
            const Transform& close = close_transforms[i];
            Transform inv;
            if (!invert_affine(close, inv) ||
                !invert_affine(instance_transform_at(inst.object_to_world, close, 0.5f), inv)) {
                ++singular;
                continue;
            }
            // Each object point moves on a segment between its two world
            // positions: the two boxes' union holds it all shutter long.
            inst.world_bounds.expand(transformed_bounds(prototypes[prototype].bounds, close));
            inst.motion = uint32_t(instance_close.size());
            instance_close.push_back(close);
        }
        instances.push_back(inst);
        if (frame_transforms)
            set_frame_motion(data_passes.instance_frame_motion, instances.size() - 1, inst.object_to_world,
                             frame_transforms + 2 * i);
        ++placed;
    }
    if (singular > 0)
        dropped.skipped_meshes.push_back(label + " (" + std::to_string(singular) + " instance" +
                                         (singular == 1 ? "" : "s") + " with a non-invertible transform)");
    return placed;
}

size_t Scene::instanced_triangle_count() const {
    size_t n = 0;
    for (const Instance& inst : instances) n += prototypes[inst.prototype].triangle_count();
    return n;
}

}  // namespace coherent
