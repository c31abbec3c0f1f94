// Scene construction and validation. Every input array passes through
// add_mesh(), which is the single place that decides what geometry is usable:
// later layers (BVH, integrators) may assume finite, non-degenerate,
// world-space triangles with valid material indices.
#include "scene.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace coherent {

namespace {

// Shading normals transform with the inverse transpose of the linear part.
// We only need its direction, so the cofactor matrix suffices; multiplying by
// sign(det) keeps the orientation that inverse-transpose would give.
struct NormalTransform {
    float c[3][3];
    bool valid = false;

    explicit NormalTransform(const Transform& t) {
        const auto& m = t.m;
        c[0][0] = m[1][1] * m[2][2] - m[1][2] * m[2][1];
        c[0][1] = m[1][2] * m[2][0] - m[1][0] * m[2][2];
        c[0][2] = m[1][0] * m[2][1] - m[1][1] * m[2][0];
        c[1][0] = m[0][2] * m[2][1] - m[0][1] * m[2][2];
        c[1][1] = m[0][0] * m[2][2] - m[0][2] * m[2][0];
        c[1][2] = m[0][1] * m[2][0] - m[0][0] * m[2][1];
        c[2][0] = m[0][1] * m[1][2] - m[0][2] * m[1][1];
        c[2][1] = m[0][2] * m[1][0] - m[0][0] * m[1][2];
        c[2][2] = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        const float det = m[0][0] * c[0][0] + m[0][1] * c[0][1] + m[0][2] * c[0][2];
        valid = std::isfinite(det) && det != 0.0f;
        if (det < 0.0f)
            for (auto& row : c)
                for (float& x : row) x = -x;
    }
    // Unit world-space normal, or a non-finite vector when it cannot be formed.
    Vec3f apply(const Vec3f& n) const {
        const Vec3f w{c[0][0] * n.x + c[0][1] * n.y + c[0][2] * n.z, c[1][0] * n.x + c[1][1] * n.y + c[1][2] * n.z,
                      c[2][0] * n.x + c[2][1] * n.y + c[2][2] * n.z};
        const float len = length(w);
        if (!(len > 0.0f) || !std::isfinite(len)) return Vec3f(NAN);
        return w / len;
    }
};

// A mesh's vertices in world space, transformed once per vertex (with
// motion, also at shutter close). A vertex that is non-finite in either
// space, or at either end of the shutter, is unusable.
struct WorldVertices {
    std::vector<Vec3f> open, close;
    std::vector<uint8_t> finite;
};

WorldVertices world_vertices(const MeshInput& mesh, const Transform& xf, const Transform& xf_close) {
    WorldVertices w;
    w.open.resize(mesh.vertex_count);
    w.finite.resize(mesh.vertex_count);
    if (mesh.moves) w.close.resize(mesh.vertex_count);
    for (size_t i = 0; i < mesh.vertex_count; ++i) {
        const Vec3f p{mesh.positions[3 * i], mesh.positions[3 * i + 1], mesh.positions[3 * i + 2]};
        w.open[i] = xf.point(p);
        w.finite[i] = is_finite(p) && is_finite(w.open[i]);
        if (mesh.moves) {
            const float* src = mesh.positions_close ? mesh.positions_close : mesh.positions;
            const Vec3f pc{src[3 * i], src[3 * i + 1], src[3 * i + 2]};
            w.close[i] = xf_close.point(pc);
            w.finite[i] = w.finite[i] && is_finite(pc) && is_finite(w.close[i]);
        }
    }
    return w;
}

// Triangles of one mesh dropped, by reason.
struct MeshDrops {
    size_t nonfinite = 0, out_of_range = 0, degenerate = 0, bad_material = 0;
    size_t total() const { return nonfinite + out_of_range + degenerate + bad_material; }
};

// The scene material of triangle t; an id without a valid slot gets the
// default material (0) and is counted.
uint32_t triangle_material(const MeshInput& mesh, size_t t, size_t scene_materials, MeshDrops& drops) {
    if (!mesh.material_slots.empty()) {
        const uint32_t slot = mesh.material_ids ? mesh.material_ids[t] : 0u;
        if (slot < mesh.material_slots.size() && mesh.material_slots[slot] < scene_materials)
            return mesh.material_slots[slot];
        ++drops.bad_material;
    } else if (mesh.material_ids && mesh.material_ids[t] != 0) {
        ++drops.bad_material;  // ids given but no slots to resolve them
    }
    return 0;
}

// World-space shading normals of triangle t's corners (in `corner` order);
// returns whether the mesh has usable normals. Without them every corner
// gets the geometric normal, and so does each broken normal.
bool world_normals(const MeshInput& mesh, size_t t, const int corner[3], const NormalTransform& normal_xf,
                   const Vec3f& ng_unit, Vec3f n[3]) {
    n[0] = n[1] = n[2] = ng_unit;
    if (!mesh.normals || !normal_xf.valid) return false;
    for (int k = 0; k < 3; ++k) {
        const float* src = mesh.normals + 9 * t + 3 * corner[k];
        const Vec3f on{src[0], src[1], src[2]};
        const Vec3f wn = is_finite(on) ? normal_xf.apply(on) : Vec3f(NAN);
        n[k] = is_finite(wn) ? wn : ng_unit;
    }
    return true;
}

// Triangle t's corners at shutter close: where it moves, its close pose and
// close-pose normals (a broken one keeps the open pose's); else its open pose.
void append_motion_corners(Scene& scene, const MeshInput& mesh, const WorldVertices& world, size_t t,
                           const uint32_t idx[3], const int corner[3], bool real_normals,
                           const NormalTransform& normal_xf_close, const Vec3f n[3]) {
    for (int k = 0; k < 3; ++k) {
        if (!mesh.moves) {
            scene.motion_vertices.push_back(scene.vertices[scene.vertices.size() - 3 + k]);
            scene.motion_normals.push_back(n[k]);
            continue;
        }
        scene.motion_vertices.push_back(world.close[idx[corner[k]]]);
        Vec3f nc = n[k];
        if (real_normals && normal_xf_close.valid) {
            const float* src = mesh.normals + 9 * t + 3 * corner[k];
            const Vec3f wn = normal_xf_close.apply(Vec3f{src[0], src[1], src[2]});
            if (is_finite(wn)) nc = wn;
        }
        scene.motion_normals.push_back(nc);
    }
}

// Capacity for `extra` more elements, growing geometrically so that many
// small meshes added one by one still cost amortised constant time each.
template <class T>
void reserve_more(std::vector<T>& v, size_t extra) {
    const size_t needed = v.size() + extra;
    if (needed > v.capacity()) v.reserve(std::max(needed, 2 * v.capacity()));
}

// Books a mesh's drops into scene.dropped and, if any triangle was added,
// the mesh as an object of the scene; returns the triangles added.
size_t record_mesh(Scene& scene, const std::string& name, size_t triangles, size_t added, const MeshDrops& drops) {
    DropReport& d = scene.dropped;
    d.nonfinite_vertices += drops.nonfinite;
    d.out_of_range_indices += drops.out_of_range;
    d.degenerate_triangles += drops.degenerate;
    d.bad_material_ids += drops.bad_material;
    if (drops.total() > 0) d.meshes_with_drops.push_back(name);
    if (added == 0) {
        d.skipped_meshes.push_back(name + " (all " + std::to_string(triangles) + " triangles invalid)");
        return 0;
    }
    const uint32_t object = uint32_t(scene.object_names.size());
    scene.object_names.push_back(name);
    scene.object_of.insert(scene.object_of.end(), added, object);
    return added;
}

}  // namespace

Scene::Scene() {
    // Blender renders faces without a material with a plain grey diffuse.
    Material def;
    def.name = "default";
    def.closures[0].base_color = Vec3f(0.8f);
    def.closures[0].specular = 0.0f;
    def.closures[0].roughness = 0.5f;
    materials.push_back(def);
}

uint32_t Scene::add_material(const Material& m) {
    materials.push_back(m);
    return uint32_t(materials.size() - 1);
}

BBox Scene::bounds() const {
    BBox b;
    for (const Vec3f& v : vertices) b.expand(v);
    for (const Instance& inst : instances) b.expand(inst.world_bounds);
    return b;
}

size_t Scene::add_mesh(const MeshInput& mesh) {
    const std::string name = mesh.name.empty() ? std::string("<unnamed>") : mesh.name;
    if (mesh.triangle_count == 0) {
        dropped.skipped_meshes.push_back(name + " (no triangles)");
        return 0;
    }
    if (!mesh.positions || !mesh.indices || mesh.vertex_count == 0) {
        dropped.skipped_meshes.push_back(name + " (missing vertex or index data)");
        return 0;
    }

    const Transform& xf = mesh.object_to_world;
    const NormalTransform normal_xf(xf);
    const Transform& xf_close = mesh.moves ? mesh.object_to_world_close : xf;
    const NormalTransform normal_xf_close(xf_close);
    // A mirroring transform reverses the winding; swap two corners so the
    // geometric normal keeps pointing to the side the shading normals face.
    int corner[3] = {0, 1, 2};
    if (xf.determinant() < 0.0f) std::swap(corner[1], corner[2]);
    const WorldVertices world = world_vertices(mesh, xf, xf_close);
    // The first moving mesh turns motion on: earlier triangles stand still.
    if (mesh.moves && motion_vertices.empty()) {
        motion_vertices = vertices;
        motion_normals = normals;
    }
    const bool track_motion = mesh.moves || !motion_vertices.empty();

    // Room for every triangle up front: a large mesh otherwise regrows
    // (copies and faults in) these arrays a dozen times.
    const size_t corners = 3 * mesh.triangle_count;
    reserve_more(vertices, corners);
    reserve_more(normals, corners);
    reserve_more(has_normals, mesh.triangle_count);
    reserve_more(material_of, mesh.triangle_count);
    if (track_motion) {
        reserve_more(motion_vertices, corners);
        reserve_more(motion_normals, corners);
    }

    MeshDrops drops;
    size_t added = 0;
    for (size_t t = 0; t < mesh.triangle_count; ++t) {
        const uint32_t idx[3] = {mesh.indices[3 * t], mesh.indices[3 * t + 1], mesh.indices[3 * t + 2]};
        if (idx[0] >= mesh.vertex_count || idx[1] >= mesh.vertex_count || idx[2] >= mesh.vertex_count) {
            ++drops.out_of_range;
            continue;
        }
        if (!world.finite[idx[0]] || !world.finite[idx[1]] || !world.finite[idx[2]]) {
            ++drops.nonfinite;
            continue;
        }
        const Vec3f p0 = world.open[idx[corner[0]]], p1 = world.open[idx[corner[1]]], p2 = world.open[idx[corner[2]]];
        // Zero area in world space (also catches a singular transform). A cross
        // product that overflows is equally useless to the intersector.
        const Vec3f ng = cross(p1 - p0, p2 - p0);
        const float area2 = length(ng);
        if (!(area2 > 0.0f) || !std::isfinite(area2)) {
            ++drops.degenerate;
            continue;
        }
        const uint32_t material = triangle_material(mesh, t, materials.size(), drops);
        vertices.push_back(p0);
        vertices.push_back(p1);
        vertices.push_back(p2);
        Vec3f n[3];
        const bool real_normals = world_normals(mesh, t, corner, normal_xf, ng / area2, n);
        normals.push_back(n[0]);
        normals.push_back(n[1]);
        normals.push_back(n[2]);
        if (track_motion) append_motion_corners(*this, mesh, world, t, idx, corner, real_normals, normal_xf_close, n);
        has_normals.push_back(real_normals ? 1 : 0);
        material_of.push_back(material);
        append_shading_corners(shading, mesh, t, corner, n);
        ++added;
    }
    if (added > 0) append_object_shading(shading, mesh);
    const size_t recorded = record_mesh(*this, name, mesh.triangle_count, added, drops);
    if (recorded > 0 && mesh.frame_transforms)
        set_frame_motion(data_passes.object_frame_motion, object_names.size() - 1, xf, mesh.frame_transforms);
    return recorded;
}

void set_frame_motion(std::vector<FrameMotion>& list, size_t index, const Transform& now, const Transform* frames) {
    Transform inverse;
    if (!invert_affine(now, inverse)) return;
    // a * b for affine transforms (bottom rows 0 0 0 1).
    const auto compose = [](const Transform& a, const Transform& b) {
        Transform t;
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 4; ++c)
                t.m[r][c] = a.m[r][0] * b.m[0][c] + a.m[r][1] * b.m[1][c] + a.m[r][2] * b.m[2][c] +
                            (c == 3 ? a.m[r][3] : 0.0f);
        return t;
    };
    if (list.size() <= index) list.resize(index + 1);
    list[index] = {compose(frames[0], inverse), compose(frames[1], inverse)};
}

void Scene::finalize() {
    const size_t n = triangle_count();
    geometric_normals.resize(n);
    emissive_triangles.clear();
    for (size_t t = 0; t < n; ++t) {
        geometric_normals[t] = normalize(cross(vertices[3 * t + 1] - vertices[3 * t], vertices[3 * t + 2] - vertices[3 * t]));
        if (materials[material_of[t]].is_emissive()) emissive_triangles.push_back(uint32_t(t));
    }
    moving_triangles.clear();
    moving_flag.clear();
    if (motion_vertices.size() == vertices.size() && !vertices.empty()) {
        moving_flag.assign(n, 0);
        for (size_t t = 0; t < n; ++t)
            for (int k = 0; k < 3; ++k)
                if (motion_vertices[3 * t + k].x != vertices[3 * t + k].x ||
                    motion_vertices[3 * t + k].y != vertices[3 * t + k].y ||
                    motion_vertices[3 * t + k].z != vertices[3 * t + k].z)
                    moving_flag[t] = 1;
        for (size_t t = 0; t < n; ++t)
            if (moving_flag[t]) moving_triangles.push_back(uint32_t(t));
        if (moving_triangles.empty()) moving_flag.clear();
    }
    // Moving emitters are not sampled by next-event estimation (the light
    // sampler knows one pose only); paths still reach them by BSDF sampling,
    // with full weight (triangle_pdf is 0 for a triangle not in this list).
    if (!moving_flag.empty())
        emissive_triangles.erase(std::remove_if(emissive_triangles.begin(), emissive_triangles.end(),
                                                [&](uint32_t t) { return moving_flag[t] != 0; }),
                                 emissive_triangles.end());
    features = compute_features(*this);
}

std::string DropReport::summary() const {
    if (empty()) return {};
    std::ostringstream s;
    bool first_clause = true;
    if (total_triangles() > 0) {
        s << "dropped " << total_triangles() << " triangle" << (total_triangles() == 1 ? "" : "s") << " (";
        bool first = true;
        auto part = [&](size_t count, const char* singular, const char* plural) {
            if (count == 0) return;
            s << (first ? "" : ", ") << count << ' ' << (count == 1 ? singular : plural);
            first = false;
        };
        part(nonfinite_vertices, "non-finite vertex", "non-finite vertex");
        part(out_of_range_indices, "out-of-range index", "out-of-range index");
        part(degenerate_triangles, "degenerate", "degenerate");
        s << ')';
        first_clause = false;
    }
    if (bad_material_ids > 0) {
        s << (first_clause ? "" : "; ") << bad_material_ids << " triangle" << (bad_material_ids == 1 ? "" : "s")
          << " with invalid material id (default material used)";
        first_clause = false;
    }
    if (!meshes_with_drops.empty()) {
        s << " in meshes: ";
        for (size_t i = 0; i < meshes_with_drops.size(); ++i) s << (i ? ", " : "") << meshes_with_drops[i];
    }
    if (!skipped_meshes.empty()) {
        s << (first_clause ? "" : "; ") << "skipped meshes: ";
        for (size_t i = 0; i < skipped_meshes.size(); ++i) s << (i ? ", " : "") << skipped_meshes[i];
    }
    return s.str();
}

}  // namespace coherent
