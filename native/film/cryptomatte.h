// Cryptomatte (Cycles 3.4, kernel/film/cryptomatte.h and util/murmurhash):
// every camera sample's first hit names an object, a material and an
// asset (the object's top-level parent); each name's id is the float whose
// bits come from MurmurHash3_x86_32(name, seed 0) (util_hash_to_float). Per
// pixel the film accumulates a coverage weight per id in 2 x ceil(levels/2)
// slots (ids beyond them are dropped, as in Cycles) and resolves them
// ranked by coverage: layer k ("CryptoObject00", ...) holds the ids and
// coverages (over the pixel's samples) of ranks 2k and 2k+1 as RGBA.
// The manifest ({"name":"hash hex",...}) goes into the file's metadata.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace coherent {

enum class CryptoType : uint8_t { Object, Material, Asset };
constexpr int kCryptoTypeCount = 3;
const char* crypto_pass_prefix(CryptoType t);  // "CryptoObject", "CryptoMaterial", "CryptoAsset"

uint32_t murmur_hash3(std::string_view key, uint32_t seed = 0);
// Cycles' util_hash_to_float: the hash's bits as a float, exponent kept
// within [1, 254] (no zero, denormal, inf or NaN ids).
float hash_to_float(uint32_t hash);
inline float cryptomatte_id(std::string_view name) { return hash_to_float(murmur_hash3(name)); }

// {"name":"0123abcd",...} over the distinct names, JSON-escaped.
std::string cryptomatte_manifest(const std::vector<std::string>& names);

// "object,material" / Blender-style names: a bit per CryptoType; throws
// std::invalid_argument naming an unknown one.
uint32_t crypto_mask_from_names(const std::vector<std::string>& names);

}  // namespace coherent
