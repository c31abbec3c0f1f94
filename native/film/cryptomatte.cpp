// Cryptomatte names and ids, bit-for-bit as Cycles computes them.
#include "cryptomatte.h"

#include <cstdio>
#include <cstring>
#include <set>
#include <stdexcept>

namespace coherent {

const char* crypto_pass_prefix(CryptoType t) {
    static const char* names[] = {"CryptoObject", "CryptoMaterial", "CryptoAsset"};
    return names[int(t)];
}

namespace {
inline uint32_t rotl32(uint32_t x, int r) { return (x << r) | (x >> (32 - r)); }
}  // namespace

uint32_t murmur_hash3(std::string_view key, uint32_t seed) {
    const auto* data = reinterpret_cast<const uint8_t*>(key.data());
    const size_t len = key.size(), blocks = len / 4;
    constexpr uint32_t c1 = 0xcc9e2d51u, c2 = 0x1b873593u;
    uint32_t h = seed;
    for (size_t i = 0; i < blocks; ++i) {
        uint32_t k;
        std::memcpy(&k, data + 4 * i, 4);  // little-endian, as Cycles on x86
        k = rotl32(k * c1, 15) * c2;
        h = rotl32(h ^ k, 13) * 5 + 0xe6546b64u;
    }
    const uint8_t* tail = data + 4 * blocks;
    uint32_t k = 0;
    switch (len & 3) {
        case 3: k ^= uint32_t(tail[2]) << 16; [[fallthrough]];
        case 2: k ^= uint32_t(tail[1]) << 8; [[fallthrough]];
        case 1:
            k ^= tail[0];
            h ^= rotl32(k * c1, 15) * c2;
    }
    h ^= uint32_t(len);
    h ^= h >> 16;
    h *= 0x85ebca6bu;
    h ^= h >> 13;
    h *= 0xc2b2ae35u;
    h ^= h >> 16;
    return h;
}

float hash_to_float(uint32_t hash) {
    const uint32_t mantissa = hash & ((1u << 23) - 1);
    uint32_t exponent = (hash >> 23) & 0xffu;
    exponent = exponent < 1 ? 1 : (exponent > 254 ? 254 : exponent);
    const uint32_t bits = (hash & 0x80000000u) | (exponent << 23) | mantissa;
    float f;
    std::memcpy(&f, &bits, 4);
    return f;
}

std::string cryptomatte_manifest(const std::vector<std::string>& names) {
    std::string out = "{";
    std::set<std::string> seen;
    for (const std::string& name : names) {
        if (!seen.insert(name).second) continue;
        if (out.size() > 1) out += ",";
        out += '"';
        for (char c : name) {
            if (c == '"' || c == '\\') out += '\\';
            out += c;
        }
        char hex[16];
        std::snprintf(hex, sizeof hex, "%08x", murmur_hash3(name));
        out += std::string("\":\"") + hex + "\"";
    }
    return out + "}";
}

uint32_t crypto_mask_from_names(const std::vector<std::string>& names) {
    uint32_t mask = 0;
    for (const std::string& name : names) {
        if (name == "object") mask |= 1u << int(CryptoType::Object);
        else if (name == "material") mask |= 1u << int(CryptoType::Material);
        else if (name == "asset") mask |= 1u << int(CryptoType::Asset);
        else throw std::invalid_argument("unknown cryptomatte type '" + name + "' (expected object, material or asset)");
    }
    return mask;
}

}  // namespace coherent
