// The one way to include tinygltf in this project: the configuration macros
// change the TinyGLTF class's default members, so every translation unit
// must see the same ones (tinygltf_impl.cpp compiles the implementation).
//
// Images are decoded by OpenImageIO (gltf_textures.cpp), so no image decoder is compiled in;
// gltf.cpp installs an image loader that keeps embedded bytes undecoded, so an
// image that is missing or undecodable never makes a loadable scene fail.
#pragma once

#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>
