// glTF textures as shader programs. See gltf_textures.h.
#include "gltf_textures.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>

#include "shader/node_math.h"
#include "shader/program.h"
#include "shader/textures.h"

namespace coherent::gltf {

namespace {

// glTF sampler constants.
constexpr int kNearest = 9728, kClampToEdge = 33071;

// %XX escapes of a URI path, decoded.
std::string decode_uri(const std::string& uri) {
    std::string out;
    for (size_t i = 0; i < uri.size(); ++i) {
        if (uri[i] == '%' && i + 2 < uri.size() && std::isxdigit((unsigned char)uri[i + 1]) && std::isxdigit((unsigned char)uri[i + 2])) {
            out += char(std::stoi(uri.substr(i + 1, 2), nullptr, 16));
            i += 2;
        } else {
            out += uri[i];
        }
    }
    return out;
}

std::string extension_for(const std::string& mime) {
    if (mime == "image/jpeg") return ".jpg";
    if (mime == "image/png") return ".png";
    if (mime == "image/webp") return ".webp";
    return ".png";
}

// A finite number, or `fallback`.
double number_or(const tinygltf::Value& v, double fallback) {
    return v.IsNumber() && std::isfinite(v.GetNumberAsDouble()) ? v.GetNumberAsDouble() : fallback;
}

// KHR_texture_transform of a texture reference: uv' = T R S uv in glTF's UV
// space (origin at the top left), and the TEXCOORD set it may override.
struct UvTransform {
    double offset[2] = {0.0, 0.0}, rotation = 0.0, scale[2] = {1.0, 1.0};
    int tex_coord = -1;
    bool identity() const {
        return offset[0] == 0.0 && offset[1] == 0.0 && rotation == 0.0 && scale[0] == 1.0 && scale[1] == 1.0;
    }
};

UvTransform uv_transform(const tinygltf::TextureInfo& info) {
    UvTransform t;
    auto it = info.extensions.find("KHR_texture_transform");
    if (it == info.extensions.end() || !it->second.IsObject()) return t;
    const tinygltf::Value& ext = it->second;
    auto pair = [&](const char* key, double out[2]) {
        if (!ext.Has(key) || !ext.Get(key).IsArray() || ext.Get(key).ArrayLen() != 2) return;
        for (int k = 0; k < 2; ++k) out[k] = number_or(ext.Get(key).Get(k), out[k]);
    };
    pair("offset", t.offset);
    pair("scale", t.scale);
    if (ext.Has("rotation")) t.rotation = number_or(ext.Get("rotation"), 0.0);
    if (ext.Has("texCoord")) t.tex_coord = int(number_or(ext.Get("texCoord"), -1.0));
    return t;
}

TextureStore& store_of(Scene& scene) {
    if (!scene.shading.textures) scene.shading.textures = std::make_shared<TextureStore>();
    return *scene.shading.textures;
}

}  // namespace

bool keep_encoded_image(tinygltf::Image* image, const int, std::string*, std::string*, int, int,
                        const unsigned char* bytes, int size, void*) {
    if (image && bytes && size > 0) {
        image->image.assign(bytes, bytes + size);
        image->as_is = true;
    }
    return true;  // a broken image must not make the scene fail: it renders magenta
}

uint32_t TextureImporter::add_embedded(const tinygltf::Image& image, const std::string& label) {
    return store_of(scene_).add_encoded(label, "embedded" + extension_for(image.mimeType), image.image.data(),
                                        image.image.size());
}

uint32_t TextureImporter::image_index(int texture, bool& ok) {
    ok = false;
    if (texture < 0 || size_t(texture) >= model_.textures.size()) return 0;
    const int source = model_.textures[size_t(texture)].source;
    if (source < 0 || size_t(source) >= model_.images.size()) return 0;
    ok = true;
    if (auto it = images_.find(source); it != images_.end()) return it->second;
    const tinygltf::Image& image = model_.images[size_t(source)];
    const std::string label = "glTF image " + std::to_string(source) + (image.name.empty() ? "" : " '" + image.name + "'");
    uint32_t index;
    if (!image.image.empty()) {
        index = add_embedded(image, label);
    } else if (!image.uri.empty()) {
        index = store_of(scene_).add_file((std::filesystem::path(base_dir_) / decode_uri(image.uri)).string(), label);
    } else {
        index = store_of(scene_).add_pixels(label, 0, 0, 4, nullptr);
    }
    images_[source] = index;
    return index;
}

uint32_t TextureImporter::uv_layer(int set) {
    auto it = std::find(uv_sets_.begin(), uv_sets_.end(), set);
    if (it != uv_sets_.end()) return uint32_t(it - uv_sets_.begin());
    uv_sets_.push_back(set);
    scene_.shading.uv_names.push_back("TEXCOORD_" + std::to_string(set));
    return uint32_t(uv_sets_.size() - 1);
}

// Registers and instructions of one material's program.
struct ProgramWriter {
    std::shared_ptr<ShaderProgram> p = std::make_shared<ShaderProgram>();

    uint16_t alloc(int width) {
        const size_t r = p->constants.size();
        p->constants.resize(r + size_t(width), 0.0f);
        return uint16_t(r);
    }
    uint16_t constant(const Vec3f& v) {
        const uint16_t r = alloc(3);
        p->constants[r] = v.x;
        p->constants[r + 1u] = v.y;
        p->constants[r + 2u] = v.z;
        return r;
    }
    uint16_t constant(float v) {
        const uint16_t r = alloc(1);
        p->constants[r] = v;
        return r;
    }
    ShaderInstr& emit(ShaderOp op, uint16_t mode, uint32_t data = 0) {
        ShaderInstr in;
        in.op = op;
        in.mode = mode;
        in.data = data;
        p->code.push_back(in);
        return p->code.back();
    }
    // a * b + c of vec3 registers (VectorMath Multiply Add), into a new register.
    uint16_t multiply_add(uint16_t a, uint16_t b, uint16_t c) {
        const uint16_t out = alloc(3), unused = constant(0.0f);
        ShaderInstr& in = emit(ShaderOp::VectorMath, 26);  // Multiply Add
        in.in[0] = a;
        in.in[1] = b;
        in.in[2] = c;
        in.in[3] = unused;
        in.out[0] = out;
        return out;
    }
    // (x, x, 0) from float register x.
    uint16_t splat2(uint16_t x) {
        const uint16_t out = alloc(3), zero = constant(0.0f);
        ShaderInstr& in = emit(ShaderOp::Combine, 0);
        in.in[0] = x;
        in.in[1] = x;
        in.in[2] = zero;
        in.out[0] = out;
        return out;
    }
    // Math node `op` of float registers a and b, into a new register.
    uint16_t math(shader::MathOp op, uint16_t a, uint16_t b) {
        const uint16_t out = alloc(1);
        ShaderInstr& in = emit(ShaderOp::Math, uint16_t(op));
        in.in[0] = a;
        in.in[1] = b;
        in.in[2] = b;
        in.out[0] = out;
        return out;
    }
    // Component-wise product of vec3 registers a and b, into a new register.
    uint16_t multiply(uint16_t a, uint16_t b) {
        const uint16_t out = alloc(3), unused = constant(0.0f);
        ShaderInstr& in = emit(ShaderOp::VectorMath, 2);  // Multiply
        in.in[0] = a;
        in.in[1] = b;
        in.in[2] = b;
        in.in[3] = unused;
        in.out[0] = out;
        return out;
    }
};

uint16_t TextureImporter::lookup(ProgramWriter& prog, const tinygltf::TextureInfo& info, bool srgb, bool& ok,
                                 bool alpha_used) {
    const uint32_t image = image_index(info.index, ok);
    if (!ok || info.texCoord < 0) {
        ok = false;
        return 0;
    }
    // As Blender imports it: colour textures sRGB, data linear. An unused alpha
    // output leaves Cycles' colour associated (premultiplied); a used one straight.
    uint16_t flags = srgb ? uint16_t(kImageSrgb | (alpha_used ? 0 : kImagePremultiply)) : uint16_t(0);
    const int sampler = model_.textures[size_t(info.index)].sampler;
    if (sampler >= 0 && size_t(sampler) < model_.samplers.size()) {
        const tinygltf::Sampler& s = model_.samplers[size_t(sampler)];
        if (s.magFilter == kNearest) flags |= 1;  // closest
        if (s.wrapS == kClampToEdge) flags |= 1 << kImageExtensionShift;
    }
    const UvTransform xf = uv_transform(info);
    uint16_t uv = prog.alloc(3);
    ShaderInstr& coord = prog.emit(ShaderOp::TexCoord, uint16_t(TexCoordKind::Uv),
                                   uv_layer(xf.tex_coord >= 0 ? xf.tex_coord : info.texCoord));
    coord.out[0] = uv;
    if (!xf.identity()) {
        // The extension's T R S (its GLSL matrices are column-major: u' = ox + c sx u - s sy v,
        // v' = oy + s sx u + c sy v), written for Blender's v (= 1 - glTF v):
        // u' = c sx u + s sy v + ox - s sy;  v' = -s sx u + c sy v + 1 - oy - c sy.
        const double c = std::cos(xf.rotation), sn = std::sin(xf.rotation);
        const double sx = xf.scale[0], sy = xf.scale[1], ox = xf.offset[0], oy = xf.offset[1];
        const uint16_t along_u = prog.constant(Vec3f{float(c * sx), float(-sn * sx), 0.0f});
        const uint16_t along_v = prog.constant(Vec3f{float(sn * sy), float(c * sy), 0.0f});
        const uint16_t shift = prog.constant(Vec3f{float(ox - sn * sy), float(1.0 - oy - c * sy), 0.0f});
        const uint16_t partial = prog.multiply_add(prog.splat2(uv), along_u, shift);
        uv = prog.multiply_add(prog.splat2(uint16_t(uv + 1)), along_v, partial);
    }
    const uint16_t color = prog.alloc(3), alpha = prog.alloc(1);
    ShaderInstr& tex = prog.emit(ShaderOp::ImageTexture, flags, image);
    tex.in[0] = uv;
    tex.out[0] = color;
    tex.out[1] = alpha;
    return color;
}

// Closure weights alpha (Principled) and 1 - alpha (Transparent) from the
// texture's alpha register times the factor, cut at alphaCutoff for MASK.
static void texture_alpha(const tinygltf::Material& in, uint16_t texture_alpha, ProgramWriter& prog) {
    const auto& factor = in.pbrMetallicRoughness.baseColorFactor;
    uint16_t alpha = prog.math(shader::MathOp::Multiply, texture_alpha,
                               prog.constant(factor.size() >= 4 ? float(std::clamp(factor[3], 0.0, 1.0)) : 1.0f));
    const uint16_t one = prog.constant(1.0f);
    if (in.alphaMode == "MASK")
        alpha = prog.math(shader::MathOp::Subtract, one, prog.math(shader::MathOp::LessThan, alpha, prog.constant(float(in.alphaCutoff))));
    prog.p->outputs.push_back({ShaderField::Weight, 0, alpha});
    prog.p->outputs.push_back({ShaderField::Weight, 1, prog.math(shader::MathOp::Subtract, one, alpha)});
}

void TextureImporter::apply(const tinygltf::Material& in, Material& m) {
    ProgramWriter prog;
    Closure& c = m.closures[0];
    bool ok = false;
    const auto& pbr = in.pbrMetallicRoughness;
    // convert_alpha() gave alpha-blended and masked materials their transparent closure.
    const bool alpha_used = m.closure_count == 2 && m.closures[1].kind == ClosureKind::Transparent;
    if (const uint16_t color = lookup(prog, pbr.baseColorTexture, true, ok, alpha_used); ok) {
        prog.p->outputs.push_back({ShaderField::BaseColor, 0, prog.multiply(color, prog.constant(c.base_color))});
        if (alpha_used) texture_alpha(in, uint16_t(color + 3), prog);  // lookup's alpha follows its colour
    }
    // metallicRoughnessTexture: roughness in G, metalness in B (glTF), times the factors.
    if (const uint16_t mr = lookup(prog, pbr.metallicRoughnessTexture, false, ok); ok) {
        const uint16_t scaled = prog.multiply(mr, prog.constant(Vec3f{1.0f, c.roughness, c.metallic}));
        prog.p->outputs.push_back({ShaderField::Roughness, 0, uint16_t(scaled + 1)});
        prog.p->outputs.push_back({ShaderField::Metallic, 0, uint16_t(scaled + 2)});
    }
    if (const uint16_t e = lookup(prog, in.emissiveTexture, true, ok); ok) {
        prog.p->outputs.push_back({ShaderField::Emission, 0, prog.multiply(e, prog.constant(m.emission))});
        prog.p->drives_emission = true;
        m.emission = Vec3f(0.0f);  // a textured emitter is reached by BSDF sampling, not light sampling
    }
    if (prog.p->outputs.empty()) return;
    prog.p->uses_uv = true;
    if (prog.p->validate(store_of(scene_).size(), scene_.shading.uv_names.size()).empty()) m.program = std::move(prog.p);
}

}  // namespace coherent::gltf
