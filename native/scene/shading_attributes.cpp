// Filling SceneShading from add_mesh's input. See shading_attributes.h.
#include "shading_attributes.h"

#include <cmath>

#include "scene.h"

namespace coherent {

namespace {

// The inverse of an affine transform (identity when it is singular: such a
// mesh has no triangles left anyway).
Transform inverse_affine(const Transform& t) {
    const auto& m = t.m;
    float c[3][3];
    c[0][0] = m[1][1] * m[2][2] - m[1][2] * m[2][1];
    c[0][1] = m[0][2] * m[2][1] - m[0][1] * m[2][2];
    c[0][2] = m[0][1] * m[1][2] - m[0][2] * m[1][1];
    c[1][0] = m[1][2] * m[2][0] - m[1][0] * m[2][2];
    c[1][1] = m[0][0] * m[2][2] - m[0][2] * m[2][0];
    c[1][2] = m[0][2] * m[1][0] - m[0][0] * m[1][2];
    c[2][0] = m[1][0] * m[2][1] - m[1][1] * m[2][0];
    c[2][1] = m[0][1] * m[2][0] - m[0][0] * m[2][1];
    c[2][2] = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    const float det = m[0][0] * c[0][0] + m[0][1] * c[1][0] + m[0][2] * c[2][0];
    Transform inv;
    if (!(std::fabs(det) > 0.0f) || !std::isfinite(det)) return inv;
    for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 3; ++k) inv.m[r][k] = c[r][k] / det;
    for (int r = 0; r < 3; ++r)
        inv.m[r][3] = -(inv.m[r][0] * m[0][3] + inv.m[r][1] * m[1][3] + inv.m[r][2] * m[2][3]);
    return inv;
}

}  // namespace

void append_shading_corners(SceneShading& shading, const MeshInput& mesh, size_t t, const int corner[3],
                            const Vec3f normals[3]) {
    const MeshShadingInput& in = mesh.shading;
    shading.uvs.resize(shading.uv_names.size());
    for (size_t layer = 0; layer < shading.uvs.size(); ++layer) {
        const float* src = layer < in.uvs.size() ? in.uvs[layer] : nullptr;
        for (int k = 0; k < 3; ++k) {
            Vec2f uv;
            if (src) {
                uv = {src[6 * t + 2 * corner[k]], src[6 * t + 2 * corner[k] + 1]};
                if (!std::isfinite(uv.x) || !std::isfinite(uv.y)) uv = {};
            }
            shading.uvs[layer].push_back(uv);
        }
    }
    if (!shading.wants_tangents) return;
    const float mirror = mesh.object_to_world.determinant() < 0.0f ? -1.0f : 1.0f;
    for (int k = 0; k < 3; ++k) {
        Vec3f tangent(0.0f);
        float sign = 1.0f;
        if (in.tangents) {
            const float* src = in.tangents + 12 * t + 4 * corner[k];
            tangent = mesh.object_to_world.vector(Vec3f{src[0], src[1], src[2]});
            sign = src[3] < 0.0f ? -1.0f : 1.0f;
        }
        // Orthogonal to the shading normal, as Blender's MikkTSpace tangents are.
        tangent = tangent - normals[k] * dot(normals[k], tangent);
        const float len = length(tangent);
        shading.tangents.push_back(len > 0.0f && std::isfinite(len) ? tangent / len : Vec3f(0.0f));
        shading.tangent_signs.push_back(sign * mirror);
    }
}

void append_object_shading(SceneShading& shading, const MeshInput& mesh) {
    if (!shading.wants_objects) return;
    ObjectShading o;
    o.world_to_object = inverse_affine(mesh.object_to_world);
    o.generated_scale = mesh.shading.generated_scale;
    o.generated_offset = mesh.shading.generated_offset;
    shading.objects.push_back(o);
}

}  // namespace coherent
