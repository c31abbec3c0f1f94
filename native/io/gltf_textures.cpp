// glTF textures as shader programs. See gltf_textures.h.
#include "gltf_textures.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <filesystem>
#include <memory>

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
    TextureStore& store = store_of(scene_);
    OIIO::Filesystem::IOMemReader reader(image.image.data(), image.image.size());
    auto in = OIIO::ImageInput::open("embedded" + extension_for(image.mimeType), nullptr, &reader);
    if (!in) return store.add_pixels(label, 0, 0, 4, nullptr);
    const OIIO::ImageSpec& spec = in->spec();
    std::vector<float> pixels(size_t(spec.width) * size_t(spec.height) * size_t(spec.nchannels));
    const bool ok = in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, pixels.data());
    if (!ok || spec.nchannels < 1 || spec.nchannels > 4) return store.add_pixels(label, 0, 0, 4, nullptr);
    return store.add_pixels(label, spec.width, spec.height, spec.nchannels, pixels.data());
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

void TextureImporter::apply(const tinygltf::Material& in, Material& m) {
    const tinygltf::TextureInfo& info = in.pbrMetallicRoughness.baseColorTexture;
    bool ok = false;
    const uint32_t image = image_index(info.index, ok);
    if (!ok || info.texCoord < 0) return;
    uint16_t flags = kImageSrgb | kImagePremultiply;  // as Blender imports it: sRGB, alpha output unused
    const int sampler = model_.textures[size_t(info.index)].sampler;
    if (sampler >= 0 && size_t(sampler) < model_.samplers.size()) {
        const tinygltf::Sampler& s = model_.samplers[size_t(sampler)];
        if (s.magFilter == kNearest) flags |= 1;  // closest
        if (s.wrapS == kClampToEdge) flags |= 1 << kImageExtensionShift;
    }
    auto p = std::make_shared<ShaderProgram>();
    // r0-2 uv, r3-5 texture colour, r6 alpha, r7-9 factor, r10-12 base colour.
    p->constants.assign(13, 0.0f);
    const Vec3f factor = m.closures[0].base_color;
    p->constants[7] = factor.x;
    p->constants[8] = factor.y;
    p->constants[9] = factor.z;
    ShaderInstr coord;
    coord.op = ShaderOp::TexCoord;
    coord.mode = uint16_t(TexCoordKind::Uv);
    coord.data = uv_layer(info.texCoord);
    coord.out[0] = 0;
    ShaderInstr tex;
    tex.op = ShaderOp::ImageTexture;
    tex.mode = flags;
    tex.data = image;
    tex.in[0] = 0;
    tex.out[0] = 3;
    tex.out[1] = 6;
    ShaderInstr mul;
    mul.op = ShaderOp::VectorMath;
    mul.mode = 2;  // Multiply
    mul.in[0] = 3;
    mul.in[1] = 7;
    mul.in[2] = 7;
    mul.in[3] = 6;
    mul.out[0] = 10;
    p->code = {coord, tex, mul};
    p->outputs.push_back({ShaderField::BaseColor, 0, 10});
    p->uses_uv = true;
    if (p->validate(store_of(scene_).size(), scene_.shading.uv_names.size()).empty()) m.program = std::move(p);
}

}  // namespace coherent::gltf
