// Bounds-checked reading of glTF accessors.
//
// tinygltf parses the JSON and loads the buffers but does not check that an
// accessor's elements lie inside its buffer view and buffer; a malformed file
// could make a naive reader run off the end of a buffer. Every read here
// validates the whole byte range (in 64-bit arithmetic, so that huge counts or
// offsets cannot wrap) before touching a byte, and reports why it refused.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "tinygltf_config.h"

namespace coherent::gltf {

// Reads accessor `index` as `components` floats per element (row-major,
// count x components). Integer component types are converted as the glTF
// spec says: normalized ones to [0,1] / [-1,1], others as plain numbers.
// Sparse accessors are applied on top of their base (or of zeros).
// Returns false with `why` set when the accessor is missing, has a different
// number of components, or does not fit in its buffer.
bool read_floats(const tinygltf::Model& model, int index, int components,
                 std::vector<float>& out, std::string& why);

// Reads a SCALAR accessor of unsigned byte/short/int as 32-bit indices.
bool read_indices(const tinygltf::Model& model, int index, std::vector<uint32_t>& out,
                  std::string& why);

}  // namespace coherent::gltf
