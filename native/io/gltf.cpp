// glTF 2.0 loading: tinygltf parses, this file walks the default scene and
// feeds meshes, materials, lights and the first camera into a Scene.
//
// Robustness: tinygltf validates the container (GLB chunks, JSON syntax) but
// not the indices between objects or the byte ranges of accessors. Every
// index into a model array is checked here and every accessor goes through
// gltf_accessor.h, so no input file can make the loader read out of bounds,
// recurse forever or throw; problems become an error line or a DropReport entry.

#include "gltf.h"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <memory>

#include "tinygltf_config.h"

#include "gltf_accessor.h"
#include "gltf_blender.h"
#include "gltf_textures.h"
#include "../shader/program.h"

namespace coherent {
namespace {

using gltf::PunctualLight;

// Node hierarchies deeper than this are treated as malformed (they are
// almost certainly cycles, which the spec forbids). The visit limit stops a
// file whose nodes share children (also forbidden: one parent per node) from
// expanding into exponentially many instances.
constexpr int kMaxNodeDepth = 256;
constexpr size_t kMaxNodeVisits = size_t(1) << 20;
constexpr uint32_t kInvalidIndex = std::numeric_limits<uint32_t>::max();

// tinygltf reports several problems separated by newlines and may quote
// bytes of the (possibly binary) input: keep one printable ASCII line of
// bounded length.
std::string one_line(const std::string& s) {
    constexpr size_t kMaxLength = 300;
    std::string out;
    for (char c : s) {
        if (c == '\n' || c == '\r') {
            if (!out.empty() && out.back() != ' ') out += "; ";
        } else {
            out += (c >= 0x20 && c < 0x7f) ? c : '?';
        }
    }
    while (!out.empty() && (out.back() == ' ' || out.back() == ';')) out.pop_back();
    if (out.size() > kMaxLength) out = out.substr(0, kMaxLength) + "...";
    return out;
}

Transform multiply(const Transform& a, const Transform& b) {
    Transform r;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            double s = 0.0;
            for (int k = 0; k < 4; ++k) s += double(a.m[i][k]) * double(b.m[k][j]);
            r.m[i][j] = float(s);
        }
    return r;
}

// glTF: `matrix` (column-major) or T * R * S with a unit quaternion (x,y,z,w).
Transform local_transform(const tinygltf::Node& node) {
    Transform t;
    if (node.matrix.size() == 16) {
        for (int r = 0; r < 4; ++r)
            for (int c = 0; c < 4; ++c) t.m[r][c] = float(node.matrix[size_t(c * 4 + r)]);
        return t;
    }
    double tx = 0, ty = 0, tz = 0, sx = 1, sy = 1, sz = 1, qx = 0, qy = 0, qz = 0, qw = 1;
    if (node.translation.size() == 3) tx = node.translation[0], ty = node.translation[1], tz = node.translation[2];
    if (node.scale.size() == 3) sx = node.scale[0], sy = node.scale[1], sz = node.scale[2];
    if (node.rotation.size() == 4) {
        qx = node.rotation[0], qy = node.rotation[1], qz = node.rotation[2], qw = node.rotation[3];
        const double n = std::sqrt(qx * qx + qy * qy + qz * qz + qw * qw);
        if (n > 0.0 && std::isfinite(n)) {
            qx /= n, qy /= n, qz /= n, qw /= n;
        } else {
            qx = qy = qz = 0.0, qw = 1.0;
        }
    }
    const double rot[3][3] = {
        {1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)},
        {2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)},
        {2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)},
    };
    const double scale[3] = {sx, sy, sz};
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) t.m[r][c] = float(rot[r][c] * scale[c]);
    t.m[0][3] = float(tx), t.m[1][3] = float(ty), t.m[2][3] = float(tz);
    return t;
}

// Number `key` of a JSON object held in a tinygltf::Value, if present.
bool get_number(const tinygltf::Value& object, const char* key, double& out) {
    if (!object.IsObject() || !object.Has(key)) return false;
    const tinygltf::Value& v = object.Get(key);
    if (!v.IsNumber()) return false;
    out = v.GetNumberAsDouble();
    return std::isfinite(out);
}

const tinygltf::Value* get_extension(const tinygltf::ExtensionMap& extensions, const char* name) {
    auto it = extensions.find(name);
    return it == extensions.end() ? nullptr : &it->second;
}

float clamp01(double v) { return float(std::min(std::max(v, 0.0), 1.0)); }

// glTF metallic-roughness material -> the Principled BSDF Blender's importer
// builds (constant inputs only: textures are not used).
Material convert_material(const tinygltf::Material& in) {
    Material m;
    m.name = in.name;
    Closure& c = m.closures[0];
    const auto& pbr = in.pbrMetallicRoughness;
    if (pbr.baseColorFactor.size() >= 3)
        c.base_color = {clamp01(pbr.baseColorFactor[0]), clamp01(pbr.baseColorFactor[1]),
                        clamp01(pbr.baseColorFactor[2])};
    c.metallic = clamp01(pbr.metallicFactor);
    c.roughness = clamp01(pbr.roughnessFactor);
    c.specular = 0.5f;  // Principled default; KHR_materials_specular is not mapped
    c.ior = 1.5f;       // GLTF_IOR: the importer sets it even without KHR_materials_ior
    c.transmission = 0.0f;
    c.principled_diffuse = true;  // Blender imports glTF materials as Principled BSDFs
    double v = 0.0;
    if (const auto* ext = get_extension(in.extensions, "KHR_materials_ior"); ext && get_number(*ext, "ior", v) && v > 0.0)
        c.ior = float(v);
    if (const auto* ext = get_extension(in.extensions, "KHR_materials_transmission");
        ext && get_number(*ext, "transmissionFactor", v))
        c.transmission = clamp01(v);

    double strength = 1.0;
    if (const auto* ext = get_extension(in.extensions, "KHR_materials_emissive_strength"))
        if (!get_number(*ext, "emissiveStrength", strength) || strength < 0.0) strength = 1.0;
    if (in.emissiveFactor.size() >= 3) {
        const auto e = [&](size_t i) {
            const double x = in.emissiveFactor[i] * strength;
            return std::isfinite(x) ? float(std::max(x, 0.0)) : 0.0f;
        };
        m.emission = {e(0), e(1), e(2)};
    }
    m.weights = {1.0f, 0.0f, 0.0f, 0.0f};
    m.closure_count = 1;
    return m;
}

// A glTF mesh decoded once into MeshInput's layout and shared by all the
// nodes that instance it (so a broken mesh is also reported only once).
struct DecodedMesh {
    std::string name;
    std::vector<float> positions;               // vertex_count x 3
    std::vector<uint32_t> indices;              // triangle_count x 3, kInvalidIndex where out of range
    std::vector<float> normals;                 // per corner (triangle_count x 9), or empty
    std::vector<uint32_t> material_ids;         // per triangle: slot
    std::vector<uint32_t> material_slots;       // slot -> scene material
    std::vector<std::vector<float>> uvs;        // per scene UV layer: triangle_count x 3 x 2 (Blender's v), or empty
};

class Loader {
public:
    Loader(const tinygltf::Model& model, Scene& scene, float aspect, const std::string& base_dir)
        : model_(model), scene_(scene), aspect_(aspect), textures_(model, base_dir, scene) {}

    // Returns false with error_ set for structural errors (cycles, bad node indices).
    bool load(GltfLoadResult& result) {
        for (const auto& m : model_.materials) {
            Material converted = convert_material(m);
            material_emissive_.push_back(converted.is_emissive());
            textures_.apply(m, converted);  // before any mesh: it declares the UV layers meshes provide
            material_index_.push_back(scene_.add_material(converted));
        }
        if (!read_punctual_lights()) return false;
        decoded_.resize(model_.meshes.size());
        placements_.resize(model_.meshes.size());

        std::vector<int> roots;
        if (!model_.scenes.empty()) {
            int s = model_.defaultScene;
            if (s < 0 || size_t(s) >= model_.scenes.size()) s = 0;
            roots = model_.scenes[size_t(s)].nodes;
        } else {
            // No scene: every node without a parent is a root (as Blender imports it).
            std::vector<bool> is_child(model_.nodes.size(), false);
            for (const auto& n : model_.nodes)
                for (int c : n.children)
                    if (c >= 0 && size_t(c) < is_child.size()) is_child[size_t(c)] = true;
            for (size_t i = 0; i < model_.nodes.size(); ++i)
                if (!is_child[i]) roots.push_back(int(i));
        }
        for (int root : roots)
            if (!visit(root, Transform{}, 0)) return false;
        for (size_t m = 0; m < decoded_.size(); ++m)
            if (decoded_[m]) add_placements(*decoded_[m], placements_[m]);

        if (!has_camera_) scene_.camera = gltf::framing_camera(scene_.bounds(), aspect_);
        result.had_camera = has_camera_;
        result.had_lights = lights_added_ > 0 || emissive_used_;
        if (!result.had_lights) scene_.world_color = Vec3f(1.0f);
        return true;
    }

    const std::string& error() const { return error_; }

private:
    bool fail(std::string message) {
        error_ = std::move(message);
        return false;
    }

    bool read_punctual_lights() {
        const tinygltf::Value* ext = get_extension(model_.extensions, "KHR_lights_punctual");
        if (!ext || !ext->IsObject() || !ext->Has("lights")) return true;
        const tinygltf::Value& list = ext->Get("lights");
        if (!list.IsArray()) return fail("KHR_lights_punctual.lights is not an array");
        for (size_t i = 0; i < list.ArrayLen(); ++i) {
            const tinygltf::Value& l = list.Get(int(i));
            PunctualLight p;
            std::string type = l.Has("type") && l.Get("type").IsString() ? l.Get("type").Get<std::string>() : "";
            if (type == "point") {
                p.type = PunctualLight::Type::Point;
            } else if (type == "spot") {
                p.type = PunctualLight::Type::Spot;
            } else if (type == "directional") {
                p.type = PunctualLight::Type::Directional;
            } else {
                return fail("light " + std::to_string(i) + " has unknown type '" + type + "'");
            }
            double v = 0.0;
            if (get_number(l, "intensity", v)) p.has_intensity = true, p.intensity = float(v);
            if (l.Has("color") && l.Get("color").IsArray() && l.Get("color").ArrayLen() >= 3) {
                const tinygltf::Value& c = l.Get("color");
                if (c.Get(0).IsNumber() && c.Get(1).IsNumber() && c.Get(2).IsNumber()) {
                    p.has_color = true;
                    p.color = {float(c.Get(0).GetNumberAsDouble()), float(c.Get(1).GetNumberAsDouble()),
                               float(c.Get(2).GetNumberAsDouble())};
                    if (!is_finite(p.color)) p.color = Vec3f(1.0f);
                }
            }
            if (l.Has("spot")) {
                const tinygltf::Value& s = l.Get("spot");
                if (get_number(s, "innerConeAngle", v)) p.has_inner_cone = true, p.inner_cone = float(v);
                if (get_number(s, "outerConeAngle", v)) p.has_outer_cone = true, p.outer_cone = float(v);
            }
            punctual_.push_back(p);
        }
        return true;
    }

    bool visit(int node_index, const Transform& parent, int depth) {
        if (node_index < 0 || size_t(node_index) >= model_.nodes.size())
            return fail("node " + std::to_string(node_index) + " does not exist");
        if (depth > kMaxNodeDepth)
            return fail("node hierarchy is deeper than " + std::to_string(kMaxNodeDepth) + " (a cycle?)");
        if (++visits_ > kMaxNodeVisits)
            return fail("more than " + std::to_string(kMaxNodeVisits) + " node instances (nodes with several parents?)");
        const tinygltf::Node& node = model_.nodes[size_t(node_index)];
        const Transform world = multiply(parent, local_transform(node));

        if (node.mesh >= 0) {
            if (size_t(node.mesh) >= model_.meshes.size())
                return fail("node " + std::to_string(node_index) + " refers to missing mesh " + std::to_string(node.mesh));
            std::unique_ptr<DecodedMesh>& mesh = decoded_[size_t(node.mesh)];
            if (!mesh) mesh = std::make_unique<DecodedMesh>(decode_mesh(size_t(node.mesh)));
            placements_[size_t(node.mesh)].push_back(world);
        }
        if (node.camera >= 0 && !has_camera_) {
            if (size_t(node.camera) >= model_.cameras.size())
                return fail("node " + std::to_string(node_index) + " refers to missing camera " +
                            std::to_string(node.camera));
            set_camera(model_.cameras[size_t(node.camera)], world);
        }
        if (const tinygltf::Value* ext = get_extension(node.extensions, "KHR_lights_punctual")) {
            double v = -1.0;
            if (!get_number(*ext, "light", v) || v < 0.0 || v >= double(punctual_.size()))
                return fail("node " + std::to_string(node_index) + " refers to a missing light");
            scene_.lights.push_back(gltf::blender_light(punctual_[size_t(v)], world));
            ++lights_added_;
        }
        for (int child : node.children)
            if (!visit(child, world, depth + 1)) return false;
        return true;
    }

    void set_camera(const tinygltf::Camera& cam, const Transform& world) {
        Camera& c = scene_.camera;
        c = Camera{};
        gltf::set_camera_frame(world, c);
        if (cam.type == "orthographic") {
            const auto& o = cam.orthographic;
            gltf::resolve_orthographic(float(o.xmag), float(o.ymag), aspect_, c);
            c.clip_start = float(o.znear);
            c.clip_end = float(o.zfar);
        } else {
            const auto& p = cam.perspective;
            gltf::resolve_perspective(float(p.yfov), aspect_, c);
            c.clip_start = float(p.znear);
            c.clip_end = p.zfar > 0.0 ? float(p.zfar) : 1e12f;  // Blender's "infinite"
        }
        // A malformed camera must not poison every ray: fall back field by field.
        const Camera d;
        if (!(c.half_width > 0.0f && std::isfinite(c.half_width) && c.half_height > 0.0f && std::isfinite(c.half_height))) {
            c.half_width = d.half_width * (aspect_ >= 1.0f ? aspect_ : 1.0f);
            c.half_height = d.half_height / (aspect_ >= 1.0f ? 1.0f : aspect_);
        }
        if (!(c.clip_start >= 0.0f && std::isfinite(c.clip_start))) c.clip_start = d.clip_start;
        if (!(c.clip_end > c.clip_start)) c.clip_end = d.clip_end;
        if (!is_finite(c.position)) c.position = d.position;
        has_camera_ = true;
    }

    // One primitive's data, before concatenation into its mesh.
    struct PrimitiveData {
        std::vector<float> positions;  // vertex_count x 3
        std::vector<uint32_t> indices;  // local to the primitive; a trailing partial triangle is ignored
        std::vector<float> normals;     // per vertex, or empty (unusable normals fall back to flat shading)
        std::vector<std::vector<float>> uvs;  // per scene UV layer: per vertex (u, v) as in the file, or empty
        size_t vertex_count = 0, triangles = 0;
    };

    // Reads a primitive of a mesh that already holds `mesh_vertices`
    // vertices. One that cannot be used is reported in
    // dropped.skipped_meshes (as `where`) and false returned.
    bool read_primitive(const tinygltf::Primitive& prim, const std::string& where, size_t mesh_vertices,
                        PrimitiveData& out) {
        auto skip = [&](const std::string& why) {
            scene_.dropped.skipped_meshes.push_back(where + " (" + why + ")");
            return false;
        };
        if (prim.mode != TINYGLTF_MODE_TRIANGLES && prim.mode != -1)
            return skip("mode " + std::to_string(prim.mode) + " is not TRIANGLES; only triangles are supported");
        if (get_extension(prim.extensions, "KHR_draco_mesh_compression"))
            return skip("KHR_draco_mesh_compression is not supported");
        auto pos_it = prim.attributes.find("POSITION");
        if (pos_it == prim.attributes.end()) return skip("no POSITION attribute");
        std::string why;
        if (!gltf::read_floats(model_, pos_it->second, 3, out.positions, why)) return skip(why);
        out.vertex_count = out.positions.size() / 3;
        if (mesh_vertices + out.vertex_count >= size_t(kInvalidIndex))
            return skip("more than 2^32 vertices in one mesh");
        if (prim.indices >= 0) {
            if (!gltf::read_indices(model_, prim.indices, out.indices, why)) return skip(why);
        } else {
            out.indices.resize(out.vertex_count);
            for (size_t i = 0; i < out.vertex_count; ++i) out.indices[i] = uint32_t(i);
        }
        out.triangles = out.indices.size() / 3;
        if (out.triangles == 0) return skip("no triangles");
        if (auto it = prim.attributes.find("NORMAL"); it != prim.attributes.end()) {
            // Unusable normals fall back to flat shading, as Blender does without normals.
            const bool usable = gltf::read_floats(model_, it->second, 3, out.normals, why) &&
                                out.normals.size() == out.positions.size();
            if (!usable) out.normals.clear();
        }
        for (int set : textures_.uv_sets()) {
            out.uvs.emplace_back();
            auto it = prim.attributes.find("TEXCOORD_" + std::to_string(set));
            if (it != prim.attributes.end() &&
                !(gltf::read_floats(model_, it->second, 2, out.uvs.back(), why) &&
                  out.uvs.back().size() == 2 * out.vertex_count))
                out.uvs.back().clear();
        }
        return true;
    }

    // Material slot of a primitive. An invalid material index gets an
    // invalid slot, which add_mesh counts and replaces by the default.
    uint32_t primitive_slot(const tinygltf::Primitive& prim, std::vector<uint32_t>& slots) {
        if (prim.material < 0) return slot_for(slots, 0);
        if (size_t(prim.material) >= material_index_.size()) return kInvalidIndex;
        if (material_emissive_[size_t(prim.material)]) emissive_used_ = true;
        return slot_for(slots, material_index_[size_t(prim.material)]);
    }

    // Where each primitive concatenated into a mesh starts, and its own
    // per-vertex normals (empty where it has none).
    struct PrimitiveRanges {
        std::vector<size_t> first_triangle;
        std::vector<uint32_t> vertex_base;
        std::vector<std::vector<float>> normals;
    };

    // Unit normal of triangle `tri` (mesh vertex indices), +z when it has
    // no area or an index is invalid.
    static Vec3f face_normal(const std::vector<float>& positions, const uint32_t* tri) {
        Vec3f face{0.0f, 0.0f, 1.0f};
        if (tri[0] == kInvalidIndex || tri[1] == kInvalidIndex || tri[2] == kInvalidIndex) return face;
        const auto vertex = [&](uint32_t v) {
            return Vec3f{positions[size_t(v) * 3], positions[size_t(v) * 3 + 1], positions[size_t(v) * 3 + 2]};
        };
        const Vec3f a = vertex(tri[0]);
        const Vec3f c = cross(vertex(tri[1]) - a, vertex(tri[2]) - a);
        const float len = length(c);
        if (len > 0.0f && std::isfinite(len)) face = c / len;
        return face;
    }

    // Per-corner normals, as MeshInput expects. Corners without a usable
    // file normal get the face normal (flat shading, Blender's default).
    static std::vector<float> corner_normals(const std::vector<float>& positions, const std::vector<uint32_t>& indices,
                                             const PrimitiveRanges& prims) {
        const size_t tri_count = indices.size() / 3;
        std::vector<float> normals(tri_count * 9);
        size_t prim = 0;
        for (size_t t = 0; t < tri_count; ++t) {
            while (prim + 1 < prims.first_triangle.size() && t >= prims.first_triangle[prim + 1]) ++prim;
            const std::vector<float>& pn = prims.normals[prim];
            const uint32_t* tri = &indices[t * 3];
            const bool valid = tri[0] != kInvalidIndex && tri[1] != kInvalidIndex && tri[2] != kInvalidIndex;
            const Vec3f face = face_normal(positions, tri);
            for (int k = 0; k < 3; ++k) {
                Vec3f nk = face;
                if (valid && !pn.empty()) {
                    const size_t local = size_t(tri[k] - prims.vertex_base[prim]);
                    const Vec3f file_normal{pn[local * 3], pn[local * 3 + 1], pn[local * 3 + 2]};
                    const float len = length(file_normal);
                    if (len > 1e-12f && std::isfinite(len)) nk = file_normal / len;
                }
                normals[t * 9 + size_t(k) * 3 + 0] = nk.x;
                normals[t * 9 + size_t(k) * 3 + 1] = nk.y;
                normals[t * 9 + size_t(k) * 3 + 2] = nk.z;
            }
        }
        return normals;
    }

    // One glTF mesh -> one object's arrays; each primitive is a material
    // slot of it. Primitives that cannot be used are reported in
    // dropped.skipped_meshes and the rest of the mesh is kept.
    DecodedMesh decode_mesh(size_t mesh_index) {
        const tinygltf::Mesh& mesh = model_.meshes[mesh_index];
        DecodedMesh out;
        out.name = mesh.name.empty() ? "mesh " + std::to_string(mesh_index) : mesh.name;
        PrimitiveRanges prims;
        bool any_normals = false;
        if (mesh.primitives.empty()) scene_.dropped.skipped_meshes.push_back(out.name + " (no primitives)");
        for (size_t pi = 0; pi < mesh.primitives.size(); ++pi) {
            const tinygltf::Primitive& prim = mesh.primitives[pi];
            PrimitiveData d;
            if (!read_primitive(prim, out.name + " primitive " + std::to_string(pi), out.positions.size() / 3, d))
                continue;
            const uint32_t slot = primitive_slot(prim, out.material_slots);
            // Concatenate: indices are rebased into the mesh's vertex array. An
            // index outside this primitive's own vertices becomes kInvalidIndex,
            // which add_mesh drops and counts as out of range (it must not reach
            // another primitive's vertices).
            const uint32_t base = uint32_t(out.positions.size() / 3);
            prims.first_triangle.push_back(out.indices.size() / 3);
            prims.vertex_base.push_back(base);
            for (size_t i = 0; i < d.triangles * 3; ++i)
                out.indices.push_back(d.indices[i] < d.vertex_count ? base + d.indices[i] : kInvalidIndex);
            out.material_ids.insert(out.material_ids.end(), d.triangles, slot);
            append_corner_uvs(d, out);
            out.positions.insert(out.positions.end(), d.positions.begin(), d.positions.end());
            any_normals |= !d.normals.empty();
            prims.normals.push_back(std::move(d.normals));
        }
        if (!out.indices.empty() && any_normals) out.normals = corner_normals(out.positions, out.indices, prims);
        return out;
    }

    // The primitive's per-corner UVs, flipped to Blender's v (0 at the
    // bottom of the image) as its importer does; (0, 0) where it has none.
    static void append_corner_uvs(const PrimitiveData& d, DecodedMesh& out) {
        out.uvs.resize(d.uvs.size());
        for (size_t layer = 0; layer < d.uvs.size(); ++layer) {
            const std::vector<float>& uv = d.uvs[layer];
            for (size_t i = 0; i < d.triangles * 3; ++i) {
                const uint32_t v = d.indices[i];
                const bool has = !uv.empty() && v < d.vertex_count;
                out.uvs[layer].push_back(has ? uv[2 * size_t(v)] : 0.0f);
                out.uvs[layer].push_back(has ? 1.0f - uv[2 * size_t(v) + 1] : 0.0f);
            }
        }
    }

    // A mesh that several nodes place is stored once and instanced (its BVH
    // built once: scene/instance.h), as Blender's importer links them to one
    // mesh datablock. A mesh placed once stays world-space triangles (faster
    // to trace), and so does one whose materials read UVs or tangents
    // (prototypes carry no shading attributes yet).
    void add_placements(const DecodedMesh& mesh, const std::vector<Transform>& worlds) {
        if (mesh.indices.empty() || worlds.empty()) return;
        if (worlds.size() == 1 || reads_mesh_attributes(mesh)) {
            for (const Transform& world : worlds) add_instance(mesh, world);
            return;
        }
        const MeshInput input = mesh_input(mesh, Transform{});
        const uint32_t prototype = scene_.add_prototype(input);
        if (prototype != Scene::kNoPrototype)
            scene_.add_instances(prototype, worlds.data(), worlds.size(), mesh.material_slots, mesh.name);
    }

    bool reads_mesh_attributes(const DecodedMesh& mesh) const {
        for (uint32_t m : mesh.material_slots) {
            if (m >= scene_.materials.size()) continue;
            const auto& program = scene_.materials[m].program;
            if (program && (program->uses_uv || program->uses_tangents)) return true;
        }
        return false;
    }

    void add_instance(const DecodedMesh& mesh, const Transform& world) {
        const MeshInput input = mesh_input(mesh, world);
        scene_.add_mesh(input);
    }

    // `mesh` as add_mesh/add_prototype read it (pointers into `mesh`).
    static MeshInput mesh_input(const DecodedMesh& mesh, const Transform& world) {
        MeshInput input;
        input.name = mesh.name;
        input.object_to_world = world;
        input.positions = mesh.positions.data();
        input.vertex_count = mesh.positions.size() / 3;
        input.indices = mesh.indices.data();
        input.triangle_count = mesh.indices.size() / 3;
        input.material_ids = mesh.material_ids.data();
        input.material_slots = mesh.material_slots;
        input.normals = mesh.normals.empty() ? nullptr : mesh.normals.data();
        for (const auto& uv : mesh.uvs) input.shading.uvs.push_back(uv.size() == mesh.indices.size() * 2 ? uv.data() : nullptr);
        return input;
    }

    static uint32_t slot_for(std::vector<uint32_t>& slots, uint32_t scene_material) {
        for (size_t i = 0; i < slots.size(); ++i)
            if (slots[i] == scene_material) return uint32_t(i);
        slots.push_back(scene_material);
        return uint32_t(slots.size() - 1);
    }

    const tinygltf::Model& model_;
    Scene& scene_;
    float aspect_;
    std::vector<uint32_t> material_index_;  // glTF material -> scene material
    std::vector<bool> material_emissive_;
    gltf::TextureImporter textures_;
    std::vector<PunctualLight> punctual_;
    std::vector<std::unique_ptr<DecodedMesh>> decoded_;  // per glTF mesh, filled on first use
    std::vector<std::vector<Transform>> placements_;     // per glTF mesh: the nodes' world transforms
    bool has_camera_ = false;
    size_t visits_ = 0;
    int lights_added_ = 0;
    bool emissive_used_ = false;
    std::string error_;
};

}  // namespace

GltfLoadResult load_gltf(const std::string& path, Scene& scene, float aspect) {
    GltfLoadResult result;
    auto fail = [&](const std::string& what) {
        result.ok = false;
        result.error = path + ": " + one_line(what);
        return result;
    };
    if (!(aspect > 0.0f) || !std::isfinite(aspect)) aspect = 1.0f;

    std::error_code ec;
    if (std::filesystem::is_directory(path, ec)) return fail("is a directory, not a glTF file");
    std::vector<unsigned char> bytes;
    try {
        std::ifstream file(path, std::ios::binary);
        if (!file) return fail(std::string("cannot open file (") + std::strerror(errno) + ")");
        bytes.assign(std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>());
        if (file.bad()) return fail("read error");
    } catch (const std::exception& e) {
        return fail(std::string("read error: ") + e.what());
    }
    if (bytes.empty()) return fail("file is empty");
    if (bytes.size() > std::numeric_limits<unsigned int>::max()) return fail("file is larger than 4 GB");

    tinygltf::TinyGLTF parser;
    parser.SetImageLoader(gltf::keep_encoded_image, nullptr);
    tinygltf::Model model;
    std::string err, warn;
    bool parsed = false;
    const std::string base_dir = std::filesystem::path(path).parent_path().string();
    try {
        // Binary or JSON is decided by content (the GLB magic), not by extension.
        if (bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0) {
            parsed = parser.LoadBinaryFromMemory(&model, &err, &warn, bytes.data(), unsigned(bytes.size()), base_dir);
        } else {
            parsed = parser.LoadASCIIFromString(&model, &err, &warn, reinterpret_cast<const char*>(bytes.data()),
                                                unsigned(bytes.size()), base_dir);
        }
    } catch (const std::exception& e) {
        return fail(std::string("malformed glTF: ") + e.what());
    }
    if (!parsed) return fail("malformed glTF: " + (err.empty() ? std::string("unknown error") : err));

    try {
        Loader loader(model, scene, aspect, base_dir);
        if (!loader.load(result)) return fail(loader.error());
    } catch (const std::exception& e) {
        return fail(std::string("cannot load: ") + e.what());
    }
    result.ok = true;
    return result;
}

}  // namespace coherent
