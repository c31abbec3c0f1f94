#include "gltf_accessor.h"

#include <algorithm>
#include <cstring>

namespace coherent::gltf {
namespace {

// Larger accessors are refused rather than allocated: no real scene comes
// close, and an accessor without a buffer view (all zeros by the spec) could
// otherwise ask for any amount of memory.
constexpr uint64_t kMaxElements = uint64_t(1) << 28;

int component_size(int component_type) {
    switch (component_type) {
        case TINYGLTF_COMPONENT_TYPE_BYTE:
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
        case TINYGLTF_COMPONENT_TYPE_SHORT:
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
        case TINYGLTF_COMPONENT_TYPE_INT:
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
        case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
        case TINYGLTF_COMPONENT_TYPE_DOUBLE: return 8;
        default: return 0;
    }
}

int type_components(int type) {
    switch (type) {
        case TINYGLTF_TYPE_SCALAR: return 1;
        case TINYGLTF_TYPE_VEC2: return 2;
        case TINYGLTF_TYPE_VEC3: return 3;
        case TINYGLTF_TYPE_VEC4: return 4;
        case TINYGLTF_TYPE_MAT2: return 4;
        case TINYGLTF_TYPE_MAT3: return 9;
        case TINYGLTF_TYPE_MAT4: return 16;
        default: return 0;
    }
}

template <typename T>
T load(const unsigned char* p) {
    T v;
    std::memcpy(&v, p, sizeof(T));  // buffers carry no alignment guarantee
    return v;
}

// One component as a float, with glTF's normalisation rules for integers.
float load_component(const unsigned char* p, int component_type, bool normalized) {
    switch (component_type) {
        case TINYGLTF_COMPONENT_TYPE_FLOAT: return load<float>(p);
        case TINYGLTF_COMPONENT_TYPE_DOUBLE: return float(load<double>(p));
        case TINYGLTF_COMPONENT_TYPE_BYTE: {
            const float v = float(load<int8_t>(p));
            return normalized ? std::max(v / 127.0f, -1.0f) : v;
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: {
            const float v = float(load<uint8_t>(p));
            return normalized ? v / 255.0f : v;
        }
        case TINYGLTF_COMPONENT_TYPE_SHORT: {
            const float v = float(load<int16_t>(p));
            return normalized ? std::max(v / 32767.0f, -1.0f) : v;
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
            const float v = float(load<uint16_t>(p));
            return normalized ? v / 65535.0f : v;
        }
        case TINYGLTF_COMPONENT_TYPE_INT: return float(load<int32_t>(p));
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return float(load<uint32_t>(p));
        default: return 0.0f;
    }
}

uint32_t load_index(const unsigned char* p, int component_type) {
    switch (component_type) {
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return load<uint8_t>(p);
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return load<uint16_t>(p);
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return load<uint32_t>(p);
        default: return 0;
    }
}

// A validated strided view of `count` elements of `element_size` bytes.
struct Strided {
    const unsigned char* base = nullptr;
    uint64_t stride = 0;
    const unsigned char* at(uint64_t i) const { return base + i * stride; }
};

// Locates `count` elements starting `byte_offset` bytes into buffer view
// `view_index`. The view must lie inside its buffer and every element inside
// the view. `explicit_stride` = 0 means the view's stride (or tight packing).
bool locate(const tinygltf::Model& model, int view_index, uint64_t byte_offset, uint64_t count,
            uint64_t element_size, bool use_view_stride, Strided& out, std::string& why) {
    if (view_index < 0 || size_t(view_index) >= model.bufferViews.size()) {
        why = "buffer view " + std::to_string(view_index) + " does not exist";
        return false;
    }
    const tinygltf::BufferView& view = model.bufferViews[size_t(view_index)];
    if (view.buffer < 0 || size_t(view.buffer) >= model.buffers.size()) {
        why = "buffer view " + std::to_string(view_index) + " refers to missing buffer " +
              std::to_string(view.buffer);
        return false;
    }
    const std::vector<unsigned char>& data = model.buffers[size_t(view.buffer)].data;
    const uint64_t view_offset = view.byteOffset, view_length = view.byteLength;
    if (view_offset > data.size() || view_length > data.size() - view_offset) {
        why = "buffer view " + std::to_string(view_index) + " (offset " + std::to_string(view_offset) +
              ", length " + std::to_string(view_length) + ") overruns its buffer of " +
              std::to_string(data.size()) + " bytes";
        return false;
    }
    uint64_t stride = element_size;
    if (use_view_stride && view.byteStride != 0) {
        stride = view.byteStride;
        if (stride < element_size || stride > 252) {
            why = "buffer view " + std::to_string(view_index) + " has invalid byteStride " +
                  std::to_string(stride);
            return false;
        }
    }
    // Bytes needed: the last element starts at (count-1)*stride. All terms are
    // bounded (count <= 2^28, stride <= 252, offsets <= buffer size) so no
    // 64-bit overflow is possible.
    const uint64_t needed = count == 0 ? 0 : (count - 1) * stride + element_size;
    if (byte_offset > view_length || needed > view_length - byte_offset) {
        why = std::to_string(count) + " elements at offset " + std::to_string(byte_offset) +
              " do not fit in buffer view " + std::to_string(view_index) + " of " +
              std::to_string(view_length) + " bytes";
        return false;
    }
    out.base = data.data() + view_offset + byte_offset;
    out.stride = stride;
    return true;
}

// Shared by read_floats and read_indices: validates the accessor header.
const tinygltf::Accessor* find_accessor(const tinygltf::Model& model, int index, std::string& why) {
    if (index < 0 || size_t(index) >= model.accessors.size()) {
        why = "accessor " + std::to_string(index) + " does not exist";
        return nullptr;
    }
    const tinygltf::Accessor& a = model.accessors[size_t(index)];
    if (component_size(a.componentType) == 0 || type_components(a.type) == 0) {
        why = "accessor " + std::to_string(index) + " has an invalid component type or type";
        return nullptr;
    }
    if (uint64_t(a.count) > kMaxElements) {
        why = "accessor " + std::to_string(index) + " has too many elements (" + std::to_string(a.count) + ")";
        return nullptr;
    }
    return &a;
}

}  // namespace

bool read_floats(const tinygltf::Model& model, int index, int components, std::vector<float>& out,
                 std::string& why) {
    const tinygltf::Accessor* a = find_accessor(model, index, why);
    if (!a) return false;
    if (type_components(a->type) != components) {
        why = "accessor " + std::to_string(index) + " has " + std::to_string(type_components(a->type)) +
              " components per element, expected " + std::to_string(components);
        return false;
    }
    const uint64_t count = a->count;
    const uint64_t csize = uint64_t(component_size(a->componentType));
    const uint64_t element_size = csize * uint64_t(components);
    out.assign(size_t(count * uint64_t(components)), 0.0f);  // no buffer view => zeros (spec)

    auto read_elements = [&](const Strided& src, uint64_t n, auto&& destination) {
        for (uint64_t i = 0; i < n; ++i) {
            float* dst = destination(i);
            const unsigned char* p = src.at(i);
            for (int c = 0; c < components; ++c)
                dst[c] = load_component(p + uint64_t(c) * csize, a->componentType, a->normalized);
        }
    };

    if (a->bufferView >= 0) {
        Strided src;
        if (!locate(model, a->bufferView, a->byteOffset, count, element_size, true, src, why)) {
            why = "accessor " + std::to_string(index) + ": " + why;
            return false;
        }
        read_elements(src, count, [&](uint64_t i) { return out.data() + i * uint64_t(components); });
    }

    if (a->sparse.isSparse) {
        const auto& sp = a->sparse;
        const int icomp = sp.indices.componentType;
        if (sp.count <= 0 || uint64_t(sp.count) > count ||
            (icomp != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && icomp != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
             icomp != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)) {
            why = "accessor " + std::to_string(index) + " has an invalid sparse section";
            return false;
        }
        Strided idx, val;
        if (!locate(model, sp.indices.bufferView, uint64_t(std::max(sp.indices.byteOffset, 0)), uint64_t(sp.count),
                    uint64_t(component_size(icomp)), false, idx, why) ||
            !locate(model, sp.values.bufferView, uint64_t(std::max(sp.values.byteOffset, 0)), uint64_t(sp.count),
                    element_size, false, val, why)) {
            why = "accessor " + std::to_string(index) + " sparse: " + why;
            return false;
        }
        for (uint64_t i = 0; i < uint64_t(sp.count); ++i) {
            const uint64_t target = load_index(idx.at(i), icomp);
            if (target >= count) {
                why = "accessor " + std::to_string(index) + " sparse index " + std::to_string(target) +
                      " is out of range";
                return false;
            }
            const unsigned char* p = val.at(i);
            float* dst = out.data() + target * uint64_t(components);
            for (int c = 0; c < components; ++c)
                dst[c] = load_component(p + uint64_t(c) * csize, a->componentType, a->normalized);
        }
    }
    return true;
}

bool read_indices(const tinygltf::Model& model, int index, std::vector<uint32_t>& out, std::string& why) {
    const tinygltf::Accessor* a = find_accessor(model, index, why);
    if (!a) return false;
    const int ct = a->componentType;
    if (a->type != TINYGLTF_TYPE_SCALAR ||
        (ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
         ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)) {
        why = "index accessor " + std::to_string(index) + " is not a scalar of unsigned integers";
        return false;
    }
    if (a->sparse.isSparse) {
        // Sparse index buffers do not occur in practice; converting through
        // floats would lose indices above 2^24, so refuse instead.
        why = "index accessor " + std::to_string(index) + " is sparse (not supported)";
        return false;
    }
    if (a->bufferView < 0) {
        why = "index accessor " + std::to_string(index) + " has no buffer view";
        return false;
    }
    Strided src;
    if (!locate(model, a->bufferView, a->byteOffset, a->count, uint64_t(component_size(ct)), true, src, why)) {
        why = "index accessor " + std::to_string(index) + ": " + why;
        return false;
    }
    out.resize(a->count);
    for (size_t i = 0; i < out.size(); ++i) out[i] = load_index(src.at(i), ct);
    return true;
}

}  // namespace coherent::gltf
