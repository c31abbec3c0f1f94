// The shader program interpreter. See program.h for the layout and the
// invariants validate() establishes; this file relies on them and does no
// bounds checks of its own.
#include "eval.h"

#include <algorithm>
#include <cstring>
#include <optional>

#include "../scene/scene.h"
#include "node_adjust.h"
#include "node_color.h"
#include "node_math.h"
#include "node_procedural.h"
#include "eval_registers.h"
#include "program.h"
#include "sky_model.h"
#include "textures.h"

namespace coherent {

using namespace shader;
using eval_detail::image_lookup_of;
using eval_detail::Registers;

TextureLookup eval_detail::image_lookup_of(const ShaderInstr& in) {
    TextureLookup how;
    const int interp = in.mode & kImageInterpMask;
    how.interp = interp == 1 ? TextureLookup::Interp::Closest
                             : (interp >= 2 ? TextureLookup::Interp::Cubic : TextureLookup::Interp::Linear);
    how.extension = TextureLookup::Extension((in.mode & kImageExtensionMask) >> kImageExtensionShift);
    return how;
}

namespace {

template <class T>
T corner_lerp(const T* c, float u, float v) {
    return c[0] * (1.0f - u - v) + c[1] * u + c[2] * v;
}

// The per-corner attributes of g's triangle: the flattened scene's, or on an
// instance its prototype's (object space).
struct CornerSource {
    const std::vector<std::vector<Vec2f>>& uvs;
    const std::vector<Vec3f>& tangents;
    const std::vector<float>& tangent_signs;
    const std::vector<std::vector<float>>& colors;
    size_t tri;
};

CornerSource corners_of(const Scene& scene, const ShadingGeometry& g) {
    if (g.prototype) {
        const Prototype& p = *g.prototype;
        return {p.uvs, p.tangents, p.tangent_signs, p.colors, g.prim};
    }
    const SceneShading& sh = scene.shading;
    return {sh.uvs, sh.tangents, sh.tangent_signs, sh.colors, g.tri};
}

Vec3f uv_coordinate(const Scene& scene, const ShadingGeometry& g, uint32_t layer) {
    const CornerSource src = corners_of(scene, g);
    if (layer >= src.uvs.size() || src.uvs[layer].size() < 3 * src.tri + 3) return Vec3f(0.0f);
    const Vec2f* c = &src.uvs[layer][3 * src.tri];
    const float w = 1.0f - g.u - g.v;
    return {c[0].x * w + c[1].x * g.u + c[2].x * g.v, c[0].y * w + c[1].y * g.u + c[2].y * g.v, 0.0f};
}

// The object's texture space at g (none for a point outside any object).
std::optional<ObjectShading> object_of(const Scene& scene, const ShadingGeometry& g) {
    if (g.prototype) return ObjectShading{g.world_to_object, g.prototype->generated_scale, g.prototype->generated_offset};
    const auto& objects = scene.shading.objects;
    const uint32_t o = g.tri < scene.object_of.size() ? scene.object_of[g.tri] : 0u;
    if (o >= objects.size()) return std::nullopt;
    return objects[o];
}

Vec3f texture_coordinate(const Scene& scene, const ShadingGeometry& g, TexCoordKind kind, uint32_t layer) {
    if (kind == TexCoordKind::Uv) return uv_coordinate(scene, g, layer);  // the common case needs no object
    const std::optional<ObjectShading> object = object_of(scene, g);
    switch (kind) {
        case TexCoordKind::Uv: break;
        case TexCoordKind::Generated:
            if (!object) return g.p;
            return object->world_to_object.point(g.p) * object->generated_scale + object->generated_offset;
        case TexCoordKind::Object: return object ? object->world_to_object.point(g.p) : g.p;
        case TexCoordKind::Normal: return safe_normalize(object ? object->world_to_object.vector(g.n) : g.n);
        case TexCoordKind::Position: return g.p;
        case TexCoordKind::Incoming: return g.wo;
    }
    return Vec3f(0.0f);
}

// Cycles' svm_node_normal_map, with the object-space maths done in world space.
Vec3f normal_map(const Scene& scene, const ShadingGeometry& g, NormalMapSpace space, float strength, Vec3f color) {
    color = color * 2.0f - Vec3f(1.0f);
    Vec3f n;
    if (space == NormalMapSpace::Tangent) {
        const CornerSource src = corners_of(scene, g);
        if (src.tangents.size() < 3 * src.tri + 3) return g.n;
        const Vec3f unflipped = g.front ? g.n : -g.n;
        Vec3f tangent = corner_lerp(&src.tangents[3 * src.tri], g.u, g.v);
        float sign = src.tangent_signs[3 * src.tri];
        if (g.prototype) {
            // To the world as the flattened mesh's tangents are: then
            // orthogonal to the shading normal, mirrored with the instance.
            tangent = g.object_to_world.vector(tangent);
            tangent = safe_normalize(tangent - unflipped * dot(unflipped, tangent));
            if (g.object_to_world.determinant() < 0.0f) sign = -sign;
        }
        const Vec3f bitangent = sign * cross(unflipped, tangent);
        n = safe_normalize(color.x * tangent + color.y * bitangent + color.z * unflipped);
    } else if (space == NormalMapSpace::Object) {
        const std::optional<ObjectShading> object = object_of(scene, g);
        const Transform* w = object ? &object->world_to_object : nullptr;
        n = w ? Vec3f{w->m[0][0] * color.x + w->m[1][0] * color.y + w->m[2][0] * color.z,
                      w->m[0][1] * color.x + w->m[1][1] * color.y + w->m[2][1] * color.z,
                      w->m[0][2] * color.x + w->m[1][2] * color.y + w->m[2][2] * color.z}
              : color;
        n = safe_normalize(n);
    } else {
        n = safe_normalize(color);
    }
    if (!g.front) n = -n;
    if (strength != 1.0f) n = safe_normalize(g.n + (n - g.n) * std::max(strength, 0.0f));
    if (is_black(n) || !is_finite(n)) return g.n;
    // As svm_node_normal_map ends: a mapped normal whose mirror direction
    // would point under the surface is tilted back towards Ng.
    return ensure_valid_reflection(g.ng, g.wo, n);
}

void image_texture(const Scene& scene, const ShaderInstr& in, const Registers& r) {
    const Vec3f co = r.v(in.in[0]);
    const TextureLookup how = image_lookup_of(in);
    float c[4];
    if (scene.shading.textures) scene.shading.textures->lookup(in.data, co.x, co.y, how, c);
    else std::memcpy(c, kMissingTexture, sizeof(c));
    if (in.mode & kImageIgnoreAlpha) c[3] = 1.0f;
    const float alpha = c[3];
    if ((in.mode & kImageUnassociate) && alpha != 1.0f && alpha != 0.0f)
        for (int k = 0; k < 3; ++k) c[k] /= alpha;
    if (in.mode & kImagePremultiply)
        for (int k = 0; k < 3; ++k) {
            c[k] *= alpha;
            // Cycles: byte = byte * alpha_byte / 255 in integers (truncated); the
            // epsilon keeps exact quotients from landing a float ulp below.
            if (in.mode & kImageBytes) c[k] = std::floor(255.0f * std::clamp(c[k], 0.0f, 1.0f) + 1e-3f) / 255.0f;
        }
    if (in.mode & kImageSrgb) srgb_to_linear_image4(c);  // c[3] is not read again: alpha is kept above
    r.set(in.out[0], Vec3f{c[0], c[1], c[2]});
    r.set(in.out[1], alpha);
}

void mix(const ShaderInstr& in, const Registers& r) {
    const bool clamp_factor = (in.mode & kClampFactorBit) != 0;
    if (in.op == ShaderOp::MixColor) {
        float t = r.f(in.in[0]);
        if (clamp_factor) t = saturatef(t);
        Vec3f c = svm_mix(MixBlend(in.mode & 0xFF), t, r.v(in.in[1]), r.v(in.in[2]));
        if (in.mode & kClampResultBit) c = saturate(c);
        r.set(in.out[0], c);
    } else if (in.op == ShaderOp::MixFloat) {
        float t = r.f(in.in[0]);
        if (clamp_factor) t = saturatef(t);
        r.set(in.out[0], r.f(in.in[1]) * (1.0f - t) + r.f(in.in[2]) * t);
    } else {
        Vec3f t = (in.mode & kNonUniformBit) ? r.v(in.in[0]) : Vec3f(r.f(in.in[0]));
        if (clamp_factor) t = saturate(t);
        r.set(in.out[0], r.v(in.in[1]) * (Vec3f(1.0f) - t) + r.v(in.in[2]) * t);
    }
}

// -- Colour adjustments, inputs and bump ----------------------------------------

// Cycles' primitive_tangent for meshes: around the object's generated-
// coordinate z axis, orthogonal to the shading normal.
Vec3f geometry_tangent(const Scene& scene, const ShadingGeometry& g) {
    const Vec3f gen = texture_coordinate(scene, g, TexCoordKind::Generated, 0);
    Vec3f t{-(gen.y - 0.5f), gen.x - 0.5f, 0.0f};
    if (const std::optional<ObjectShading> object = object_of(scene, g)) {
        const auto& m = object->world_to_object.m;  // normals go to the world by its transpose
        t = safe_normalize(Vec3f{m[0][0] * t.x + m[1][0] * t.y + m[2][0] * t.z,
                                 m[0][1] * t.x + m[1][1] * t.y + m[2][1] * t.z,
                                 m[0][2] * t.x + m[1][2] * t.y + m[2][2] * t.z});
    }
    return cross(g.n, safe_normalize(cross(t, g.n)));
}

void geometry(const Scene& scene, const ShadingGeometry& g, GeometryKind kind, const Registers& r, uint16_t out) {
    switch (kind) {
        case GeometryKind::Position: r.set(out, g.p); break;
        case GeometryKind::Normal: r.set(out, g.n); break;
        case GeometryKind::Tangent: r.set(out, geometry_tangent(scene, g)); break;
        case GeometryKind::TrueNormal: r.set(out, g.ng); break;
        case GeometryKind::Incoming: r.set(out, g.wo); break;
        // The weights of corners 0 and 1 (Cycles' 1 - u - v, u: the same convention as ours).
        case GeometryKind::Parametric: r.set(out, Vec3f{1.0f - g.u - g.v, g.u, 0.0f}); break;
        case GeometryKind::Backfacing: r.set(out, g.front ? 0.0f : 1.0f); break;
        case GeometryKind::Count: break;
    }
}

// A colour attribute interpolated over the triangle (0 where the scene has none).
void attribute(const Scene& scene, const ShadingGeometry& g, uint32_t layer, const Registers& r, const ShaderInstr& in) {
    const CornerSource src = corners_of(scene, g);
    if (layer >= src.colors.size() || src.colors[layer].size() < 12 * src.tri + 12) {
        r.set(in.out[0], Vec3f(0.0f));
        r.set(in.out[1], 0.0f);
        return;
    }
    const float* c = &src.colors[layer][12 * src.tri];
    const float w = 1.0f - g.u - g.v;
    float v[4];
    for (int k = 0; k < 4; ++k) v[k] = c[k] * w + c[4 + k] * g.u + c[8 + k] * g.v;
    r.set(in.out[0], Vec3f{v[0], v[1], v[2]});
    r.set(in.out[1], v[3]);
}

// Cycles' make_orthonormals.
void orthonormals(const Vec3f& n, Vec3f& a, Vec3f& b) {
    if (n.x != n.y || n.x != n.z) a = Vec3f{n.z - n.y, n.x - n.z, n.y - n.x};
    else a = Vec3f{n.z - n.y, n.x + n.z, -n.y - n.x};
    a = normalize(a);
    b = cross(n, a);
}

// Cycles' differential_from_compact(Ng, dP): the offsets Bump samples the height at.
void bump_offsets(const ShadingGeometry& g, Vec3f& dx, Vec3f& dy) {
    orthonormals(g.ng, dx, dy);
    dx = dx * g.footprint;
    dy = dy * g.footprint;
}

// g moved along the surface by Bump's offset `axis` (1: dx, 2: dy), its
// barycentrics moved with it (Cycles' du/dv differentials).
ShadingGeometry bump_shifted(const Scene& scene, const ShadingGeometry& g, int axis) {
    if (axis == 0) return g;
    Vec3f dx, dy;
    bump_offsets(g, dx, dy);
    const Vec3f d = axis == 1 ? dx : dy;
    ShadingGeometry s = g;
    s.p = g.p + d;
    if (size_t(g.tri) * 3 + 3 > scene.vertices.size()) return s;
    const Vec3f* v = &scene.vertices[3 * size_t(g.tri)];
    const Vec3f e1 = v[1] - v[0], e2 = v[2] - v[0];
    // Solve d = du e1 + dv e2 in the plane of the triangle (d lies in it).
    const float d11 = dot(e1, e1), d12 = dot(e1, e2), d22 = dot(e2, e2);
    const float det = d11 * d22 - d12 * d12;
    if (!(std::fabs(det) > 0.0f)) return s;
    const float b1 = dot(d, e1), b2 = dot(d, e2);
    s.u = g.u + (b1 * d22 - b2 * d12) / det;
    s.v = g.v + (b2 * d11 - b1 * d12) / det;
    return s;
}

// svm_node_set_bump (world space): the normal of the height field sampled
// at the point and one footprint along dx and dy.
Vec3f bump_normal(const ShadingGeometry& g, bool invert, float strength, float scale, const Vec3f& normal_in,
                  const Vec3f& heights) {
    Vec3f dx, dy;
    bump_offsets(g, dx, dy);
    const Vec3f rx = cross(dy, normal_in), ry = cross(normal_in, dx);
    const float det = dot(dx, rx);
    const Vec3f surfgrad = (heights.y - heights.x) * rx + (heights.z - heights.x) * ry;
    const float absdet = std::fabs(det);
    if (invert) scale *= -1.0f;
    strength = std::max(strength, 0.0f);
    const float sign = det > 0.0f ? 1.0f : (det < 0.0f ? -1.0f : 0.0f);
    Vec3f out = safe_normalize(absdet * normal_in - scale * sign * surfgrad);
    out = is_black(out) ? normal_in : normalize(strength * out + (1.0f - strength) * normal_in);
    return ensure_valid_reflection(g.ng, g.wo, out);
}

// svm_node_light_path.
float light_path(const LightPathInfo* path, LightPathKind kind) {
    if (!path) return 0.0f;
    auto flag = [&](uint8_t f) { return (path->flags & f) ? 1.0f : 0.0f; };
    switch (kind) {
        case LightPathKind::IsCamera: return flag(LightPathInfo::kCamera);
        case LightPathKind::IsShadow: return flag(LightPathInfo::kShadow);
        case LightPathKind::IsDiffuse: return flag(LightPathInfo::kDiffuse);
        case LightPathKind::IsGlossy: return flag(LightPathInfo::kGlossy);
        case LightPathKind::IsSingular: return flag(LightPathInfo::kSingular);
        case LightPathKind::IsReflection: return flag(LightPathInfo::kReflect);
        case LightPathKind::IsTransmission: return flag(LightPathInfo::kTransmit);
        case LightPathKind::RayLength: return path->ray_length;
        case LightPathKind::RayDepth: return float(path->depth) + flag(LightPathInfo::kShadow);
        case LightPathKind::DiffuseDepth: return float(path->diffuse_depth);
        case LightPathKind::GlossyDepth: return float(path->glossy_depth);
        case LightPathKind::TransparentDepth: return float(path->transparent_depth);
        case LightPathKind::TransmissionDepth: return float(path->transmission_depth);
        case LightPathKind::Count: break;
    }
    return 0.0f;
}

void vector_map_range(const ShaderInstr& in, const Registers& r) {
    if (in.op == ShaderOp::VectorMapRangeFactor) {
        const MapRangeType type = MapRangeType(in.mode);
        const Vec3f v = r.v(in.in[0]), lo = r.v(in.in[1]), hi = r.v(in.in[2]), steps = r.v(in.in[3]);
        r.set(in.out[0], Vec3f{vector_map_range_factor(type, v.x, lo.x, hi.x, steps.x),
                               vector_map_range_factor(type, v.y, lo.y, hi.y, steps.y),
                               vector_map_range_factor(type, v.z, lo.z, hi.z, steps.z)});
        return;
    }
    const bool clamp = (in.mode & kClampBit) != 0;
    const Vec3f f = r.v(in.in[0]), lo = r.v(in.in[1]), hi = r.v(in.in[2]);
    r.set(in.out[0], Vec3f{vector_map_range_apply(f.x, lo.x, hi.x, clamp), vector_map_range_apply(f.y, lo.y, hi.y, clamp),
                           vector_map_range_apply(f.z, lo.z, hi.z, clamp)});
}

void run_adjust(const Scene& scene, const ShaderProgram& prog, const ShadingGeometry& g, const ShaderInstr& in,
                const Registers& r) {
    const bool extrapolate = (in.mode & 1) != 0;
    switch (in.op) {
        case ShaderOp::Curves:
            r.set(in.out[0], svm_curves(prog.data.data() + in.data, kCurveTableSize, r.f(in.in[0]), r.v(in.in[1]),
                                        extrapolate));
            break;
        case ShaderOp::FloatCurve:
            r.set(in.out[0], svm_float_curve(prog.data.data() + in.data, kCurveTableSize, r.f(in.in[0]),
                                             r.f(in.in[1]), extrapolate));
            break;
        case ShaderOp::HueSatVal: {
            const Vec3f hsv = r.v(in.in[2]);
            r.set(in.out[0], svm_hsv(r.f(in.in[0]), r.v(in.in[1]), hsv.x, hsv.y, hsv.z));
            break;
        }
        case ShaderOp::Gamma: r.set(in.out[0], svm_gamma(r.v(in.in[0]), r.f(in.in[1]))); break;
        case ShaderOp::BrightContrast:
            r.set(in.out[0], svm_brightness_contrast(r.v(in.in[0]), r.f(in.in[1]), r.f(in.in[2])));
            break;
        case ShaderOp::MapRange: {
            const Vec3f to = r.v(in.in[3]);
            r.set(in.out[0], svm_map_range(MapRangeType(in.mode), r.f(in.in[0]), r.f(in.in[1]), r.f(in.in[2]), to.x,
                                           to.y, to.z));
            break;
        }
        case ShaderOp::VectorMapRangeFactor:
        case ShaderOp::VectorMapRangeApply: vector_map_range(in, r); break;
        case ShaderOp::ColorConvert: r.set(in.out[0], convert_color(ColorConversion(in.mode), r.v(in.in[0]))); break;
        case ShaderOp::Fresnel:
            r.set(in.out[0], svm_fresnel(FresnelKind(in.mode), r.f(in.in[0]), r.v(in.in[1]), g.wo, !g.front));
            break;
        case ShaderOp::Geometry:
            geometry(scene, bump_shifted(scene, g, in.mode >> kBumpAxisShift), GeometryKind(in.mode & 0xFF), r,
                     in.out[0]);
            break;
        case ShaderOp::LightPath: r.set(in.out[0], light_path(g.path, LightPathKind(in.mode))); break;
        case ShaderOp::Attribute: attribute(scene, bump_shifted(scene, g, in.mode), in.data, r, in); break;
        case ShaderOp::BumpTexCoord:
            r.set(in.out[0], texture_coordinate(scene, bump_shifted(scene, g, in.mode >> kBumpAxisShift),
                                                TexCoordKind(in.mode & 0xFF), in.data));
            break;
        case ShaderOp::Bump:
            r.set(in.out[0], bump_normal(g, in.mode & 1, r.f(in.in[0]), r.f(in.in[1]), r.v(in.in[2]), r.v(in.in[3])));
            break;
        default: break;
    }
}

}  // namespace

namespace eval_detail {

void run_instruction(const Scene& scene, const ShaderProgram& prog, const ShadingGeometry& g, const ShaderInstr& in,
                     const Registers& r) {
    switch (in.op) {
        case ShaderOp::Math: {
            float x = svm_math(MathOp(in.mode & 0xFF), r.f(in.in[0]), r.f(in.in[1]), r.f(in.in[2]));
            if (in.mode & kClampBit) x = saturatef(x);
            r.set(in.out[0], x);
            break;
        }
        case ShaderOp::VectorMath: {
            Vec3f vec;
            float value;
            svm_vector_math(VectorMathOp(in.mode), r.v(in.in[0]), r.v(in.in[1]), r.v(in.in[2]), r.f(in.in[3]),
                            vec, value);
            r.set(in.out[0], vec);
            r.set(in.out[1], value);
            break;
        }
        case ShaderOp::MixColor:
        case ShaderOp::MixFloat:
        case ShaderOp::MixVector: mix(in, r); break;
        case ShaderOp::Mapping:
            r.set(in.out[0], svm_mapping(in.mode, r.v(in.in[0]), r.v(in.in[1]), r.v(in.in[2]), r.v(in.in[3])));
            break;
        case ShaderOp::ColorRamp: {
            Vec3f color;
            float alpha;
            ramp_lookup(prog.data.data() + in.data, kRampTableSize, r.f(in.in[0]), in.mode != 0, color, alpha);
            r.set(in.out[0], color);
            r.set(in.out[1], alpha);
            break;
        }
        case ShaderOp::Invert: {
            const Vec3f c = r.v(in.in[1]);
            r.set(in.out[0], interp(c, Vec3f(1.0f) - c, r.f(in.in[0])));
            break;
        }
        case ShaderOp::RgbToBw: r.set(in.out[0], rgb_to_gray(r.v(in.in[0]))); break;
        case ShaderOp::Combine: r.set(in.out[0], Vec3f{r.f(in.in[0]), r.f(in.in[1]), r.f(in.in[2])}); break;
        case ShaderOp::Checker: {
            const float f = svm_checker(r.v(in.in[0]) * r.f(in.in[3]));
            r.set(in.out[0], f == 1.0f ? r.v(in.in[1]) : r.v(in.in[2]));
            r.set(in.out[1], f);
            break;
        }
        case ShaderOp::ImageTexture: image_texture(scene, in, r); break;
        case ShaderOp::TexCoord: r.set(in.out[0], texture_coordinate(scene, g, TexCoordKind(in.mode), in.data)); break;
        case ShaderOp::NormalMap:
            r.set(in.out[0], normal_map(scene, g, NormalMapSpace(in.mode), r.f(in.in[0]), r.v(in.in[1])));
            break;
        case ShaderOp::Clamp: r.set(in.out[0], svm_clamp(in.mode, r.f(in.in[0]), r.f(in.in[1]), r.f(in.in[2]))); break;
        // Procedural textures
        case ShaderOp::TexWhiteNoise:
        case ShaderOp::TexNoise:
        case ShaderOp::TexVoronoi:
        case ShaderOp::TexMusgrave:
        case ShaderOp::TexWave:
        case ShaderOp::TexGradient:
        case ShaderOp::TexMagic:
        case ShaderOp::TexBrick: run_procedural(in, prog.data.data(), r.r, r.stride); break;
        // Colour adjustments, inputs and bump
        case ShaderOp::Curves:
        case ShaderOp::FloatCurve:
        case ShaderOp::HueSatVal:
        case ShaderOp::Gamma:
        case ShaderOp::BrightContrast:
        case ShaderOp::MapRange:
        case ShaderOp::VectorMapRangeFactor:
        case ShaderOp::VectorMapRangeApply:
        case ShaderOp::ColorConvert:
        case ShaderOp::Fresnel:
        case ShaderOp::Geometry:
        case ShaderOp::LightPath:
        case ShaderOp::Attribute:
        case ShaderOp::BumpTexCoord:
        case ShaderOp::Bump: run_adjust(scene, prog, g, in, r); break;
        case ShaderOp::SkyTexture: r.set(in.out[0], eval_packed_sky(prog.data.data() + in.data, r.v(in.in[0]))); break;
        case ShaderOp::Count: break;
    }
}

void prefetch_instruction(const Scene& scene, const ShaderInstr& in, const Registers& r) {
    if (in.op != ShaderOp::ImageTexture || !scene.shading.textures) return;
    const Vec3f co = r.v(in.in[0]);
    scene.shading.textures->prefetch(in.data, co.x, co.y, image_lookup_of(in));
}

}  // namespace eval_detail

namespace {

float finite_or(float x, float fallback) { return std::isfinite(x) ? x : fallback; }
// Non-negative, with non-finite components 0 (each on its own, as a NaN in
// one channel of a Cycles closure leaves the others).
Vec3f non_negative(const Vec3f& v) {
    return {std::max(finite_or(v.x, 0.0f), 0.0f), std::max(finite_or(v.y, 0.0f), 0.0f),
            std::max(finite_or(v.z, 0.0f), 0.0f)};
}

}  // namespace

namespace eval_detail {

void apply_output(const ShaderOutput& o, const Registers& r, const ShadingGeometry& g, Material& out, Vec3f& n) {
    Closure& c = out.closures[o.closure];
    auto unit = [&](float fallback) { return std::clamp(finite_or(r.f(o.reg), fallback), 0.0f, 1.0f); };
    switch (o.field) {
        case ShaderField::BaseColor: c.base_color = non_negative(r.v(o.reg)); break;
        case ShaderField::Metallic: c.metallic = unit(0.0f); break;
        case ShaderField::Roughness: c.roughness = unit(0.5f); break;
        case ShaderField::Specular: c.specular = unit(0.5f); break;
        case ShaderField::Transmission: c.transmission = unit(0.0f); break;
        case ShaderField::Ior: c.ior = std::max(finite_or(r.f(o.reg), 1.45f), 1e-3f); break;
        case ShaderField::Weight: out.weights[o.closure] = std::max(finite_or(r.f(o.reg), 0.0f), 0.0f); break;
        case ShaderField::Emission: out.emission = non_negative(r.v(o.reg)); break;
        case ShaderField::Normal: {
            const Vec3f v = r.v(o.reg);
            // A normal facing away from the viewer cannot shade it (as for
            // interpolated normals, path_state.h).
            if (is_finite(v) && dot(v, g.wo) > 1e-4f) n = normalize(v);
            break;
        }
        case ShaderField::Count: break;
    }
}

void start_output(const Material& mat, const ShadingGeometry& g, Material& out, Vec3f& n) {
    out.closures = mat.closures;
    out.weights = mat.weights;
    out.closure_count = mat.closure_count;
    out.emission = mat.emission;
    n = g.n;
}

}  // namespace eval_detail

namespace {

void run(const Scene& scene, const ShaderProgram& prog, const ShadingGeometry& g, const Registers& r) {
    for (const ShaderInstr& in : prog.code) eval_detail::run_instruction(scene, prog, g, in, r);
}

}  // namespace

void run_constant_program(const ShaderProgram& program, float* registers) {
    static const Scene empty;
    run(empty, program, ShadingGeometry{}, Registers{registers});
}

void evaluate_material(const Scene& scene, const Material& mat, const ShadingGeometry& g, Material& out, Vec3f& n) {
    const ShaderProgram& prog = *mat.program;
    eval_detail::start_output(mat, g, out, n);
    float storage[kMaxShaderRegisters];
    std::memcpy(storage, prog.constants.data(), prog.constants.size() * sizeof(float));
    const Registers r{storage};
    run(scene, prog, g, r);
    for (const ShaderOutput& o : prog.outputs) eval_detail::apply_output(o, r, g, out, n);
}

}  // namespace coherent
