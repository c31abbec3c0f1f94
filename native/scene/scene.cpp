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

float determinant3(const Transform& t) {
    const auto& m = t.m;
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
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
    const bool mirror = determinant3(xf) < 0.0f;

    // Transform each vertex once; a vertex that is non-finite in either space is unusable.
    // With motion, a vertex must be finite at both ends of the shutter.
    std::vector<Vec3f> world(mesh.vertex_count), world_close;
    std::vector<uint8_t> finite(mesh.vertex_count);
    if (mesh.moves) world_close.resize(mesh.vertex_count);
    for (size_t i = 0; i < mesh.vertex_count; ++i) {
        const Vec3f p{mesh.positions[3 * i], mesh.positions[3 * i + 1], mesh.positions[3 * i + 2]};
        world[i] = xf.point(p);
        finite[i] = is_finite(p) && is_finite(world[i]);
        if (mesh.moves) {
            const float* src = mesh.positions_close ? mesh.positions_close : mesh.positions;
            const Vec3f pc{src[3 * i], src[3 * i + 1], src[3 * i + 2]};
            world_close[i] = xf_close.point(pc);
            finite[i] = finite[i] && is_finite(pc) && is_finite(world_close[i]);
        }
    }
    // The first moving mesh turns motion on: earlier triangles stand still.
    if (mesh.moves && motion_vertices.empty()) {
        motion_vertices = vertices;
        motion_normals = normals;
    }
    const bool track_motion = mesh.moves || !motion_vertices.empty();

    size_t nonfinite = 0, out_of_range = 0, degenerate = 0, bad_material = 0, added = 0;
    for (size_t t = 0; t < mesh.triangle_count; ++t) {
        uint32_t idx[3] = {mesh.indices[3 * t], mesh.indices[3 * t + 1], mesh.indices[3 * t + 2]};
        if (idx[0] >= mesh.vertex_count || idx[1] >= mesh.vertex_count || idx[2] >= mesh.vertex_count) {
            ++out_of_range;
            continue;
        }
        if (!finite[idx[0]] || !finite[idx[1]] || !finite[idx[2]]) {
            ++nonfinite;
            continue;
        }
        int corner[3] = {0, 1, 2};
        if (mirror) std::swap(corner[1], corner[2]);
        const Vec3f p0 = world[idx[corner[0]]], p1 = world[idx[corner[1]]], p2 = world[idx[corner[2]]];
        // Zero area in world space (also catches a singular transform). A cross
        // product that overflows is equally useless to the intersector.
        const Vec3f ng = cross(p1 - p0, p2 - p0);
        const float area2 = length(ng);
        if (!(area2 > 0.0f) || !std::isfinite(area2)) {
            ++degenerate;
            continue;
        }
        const Vec3f ng_unit = ng / area2;

        uint32_t material = 0;
        if (!mesh.material_slots.empty()) {
            const uint32_t slot = mesh.material_ids ? mesh.material_ids[t] : 0u;
            if (slot < mesh.material_slots.size() && mesh.material_slots[slot] < materials.size()) {
                material = mesh.material_slots[slot];
            } else {
                ++bad_material;
            }
        } else if (mesh.material_ids && mesh.material_ids[t] != 0) {
            ++bad_material;  // ids given but no slots to resolve them
        }

        vertices.push_back(p0);
        vertices.push_back(p1);
        vertices.push_back(p2);
        bool real_normals = false;
        Vec3f n[3] = {ng_unit, ng_unit, ng_unit};
        if (mesh.normals && normal_xf.valid) {
            real_normals = true;
            for (int k = 0; k < 3; ++k) {
                const float* src = mesh.normals + 9 * t + 3 * corner[k];
                const Vec3f on{src[0], src[1], src[2]};
                const Vec3f wn = is_finite(on) ? normal_xf.apply(on) : Vec3f(NAN);
                // A broken shading normal falls back to the geometric one.
                n[k] = is_finite(wn) ? wn : ng_unit;
            }
        }
        normals.push_back(n[0]);
        normals.push_back(n[1]);
        normals.push_back(n[2]);
        if (track_motion) {
            for (int k = 0; k < 3; ++k) {
                if (!mesh.moves) {
                    motion_vertices.push_back(vertices[vertices.size() - 3 + k]);
                    motion_normals.push_back(n[k]);
                    continue;
                }
                motion_vertices.push_back(world_close[idx[corner[k]]]);
                Vec3f nc = n[k];
                if (real_normals && normal_xf_close.valid) {
                    const float* src = mesh.normals + 9 * t + 3 * corner[k];
                    const Vec3f wn = normal_xf_close.apply(Vec3f{src[0], src[1], src[2]});
                    if (is_finite(wn)) nc = wn;
                }
                motion_normals.push_back(nc);
            }
        }
        has_normals.push_back(real_normals ? 1 : 0);
        material_of.push_back(material);
        ++added;
    }

    dropped.nonfinite_vertices += nonfinite;
    dropped.out_of_range_indices += out_of_range;
    dropped.degenerate_triangles += degenerate;
    dropped.bad_material_ids += bad_material;
    if (nonfinite + out_of_range + degenerate + bad_material > 0) dropped.meshes_with_drops.push_back(name);

    if (added == 0) {
        dropped.skipped_meshes.push_back(name + " (all " + std::to_string(mesh.triangle_count) +
                                         " triangles invalid)");
        return 0;
    }
    const uint32_t object = uint32_t(object_names.size());
    object_names.push_back(name);
    object_of.insert(object_of.end(), added, object);
    return added;
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
