// glTF textures as shader programs (native/shader): the material's
// baseColorTexture, metallicRoughnessTexture and emissiveTexture on their
// TEXCOORD sets, times their factors, as Blender's glTF importer wires them. Images come from a file beside the .gltf (by URI)
// or from the bytes embedded in the .glb / a data URI, decoded by
// OpenImageIO; an image that cannot be read renders magenta with a warning.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "scene/scene.h"
#include "tinygltf_config.h"

namespace coherent::gltf {

struct ProgramWriter;  // gltf_textures.cpp

// A tinygltf image loader that decodes nothing: it keeps the encoded bytes of
// embedded images (image.as_is) for TextureImporter.
bool keep_encoded_image(tinygltf::Image* image, const int index, std::string* err, std::string* warn, int width,
                        int height, const unsigned char* bytes, int size, void* user);

class TextureImporter {
public:
    TextureImporter(const tinygltf::Model& model, std::string base_dir, Scene& scene)
        : model_(model), base_dir_(std::move(base_dir)), scene_(scene) {}

    // Gives `m` a shader program for `in`'s base colour, metallic-roughness
    // and emissive textures, where it has usable ones.
    void apply(const tinygltf::Material& in, Material& m);
    // The TEXCOORD sets the programs read: scene UV layer i is TEXCOORD_{uv_sets()[i]}.
    const std::vector<int>& uv_sets() const { return uv_sets_; }

private:
    // The texture's RGB at its TEXCOORD set, in a new vec3 register of `prog`.
    // alpha_used: the alpha output (the next register) is read, so the colour stays straight.
    uint16_t lookup(ProgramWriter& prog, const tinygltf::TextureInfo& info, bool srgb, bool& ok,
                    bool alpha_used = false);
    uint32_t image_index(int texture, bool& ok);
    uint32_t uv_layer(int set);
    uint32_t add_embedded(const tinygltf::Image& image, const std::string& label);

    const tinygltf::Model& model_;
    std::string base_dir_;
    Scene& scene_;
    std::map<int, uint32_t> images_;  // glTF image -> scene image
    std::vector<int> uv_sets_;
};

}  // namespace coherent::gltf
