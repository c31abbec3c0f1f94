// Ray reordering for the wavefront pipeline (paper 004, "Ray reordering
// techniques for GPU ray-cast ambient occlusion"; Garanzha & Loop 2010 for
// compress-sort-decompress, Aila & Laine 2009 for 192-bit keys).
//
// A reordering is a permutation: order[i] = index (into the caller's ray
// array) of the ray traced i-th. Nothing here moves rays: keys are sorted
// together with 32-bit ray indices, and the caller either traces through the
// permutation or gathers the rays once (wavefront.cpp; bench/reorder_bench.cpp
// measures both). Every mode returns a permutation of [0, n), so any mode
// computes the same image; modes differ only in coherence and cost.
//
// Orders (ReorderMode, render_modes.h):
//   None      identity: generation order.
//   Static1D  pixels along a 2D Morton curve; the rays of one pixel keep their
//             input order (the paper's static 1D: rays sharing an origin go
//             together, pixel neighbourhoods next to each other).
//   Static3D  the paper's static 3D work groups of 8 x 16 x 1 over the grid
//             (width, height, ray of the pixel), in dispatch order: all rays
//             with the same index within their pixel (the same random-number
//             dimensions, so similar directions on similar surfaces) first,
//             within that tiles of 8 x 16 pixels along a Morton curve, within
//             a tile pixels in row order. No geometric data is read: a pure
//             function of the tags.
//   Hash32    HASHKEY32 (paper Algorithm 1): origin in the rays' origin box,
//             8 bits per axis, Morton-interleaved into bits 0..23; direction
//             as (phi, theta) with 4 bits each, interleaved into bits 24..31,
//             so the sort groups by direction first, then by origin cell.
//   Hash192   HASHKEY192: origin in the origin box scaled to 24 bits per
//             axis, direction (d + 1) / 2 scaled to 21 bits per axis, the six
//             bits interleaved by COLLECTBITS (bit i of component c goes to
//             key bit c + 6 i) into a 192-bit key.
//   Csd32     compress-sort-decompress of the Hash32 keys: runs of equal
//             consecutive keys become one block, blocks are sorted by key
//             (stably, by block start), and an exclusive scan of the sorted
//             block lengths places every block's rays. The result equals the
//             stable sort of the Hash32 keys; only the cost differs.
//
// Every sort is stable, so equal keys keep their input order and the
// permutation is a pure function of (rays, tags, mode): the image and the
// order never depend on timing or threads.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "../core/bbox.h"
#include "../core/ray.h"
#include "render_modes.h"

namespace coherent {

// Where a ray came from, for the static orders: its pixel (full-frame
// coordinates) and its index among the rays of that pixel's sample
// (0 = camera ray, k = k-th AO or shadow ray, ...).
struct RayTag {
    uint16_t x = 0, y = 0;
    uint32_t sub = 0;
};

// The sort behind the dynamic orders: LSD radix sort (default) or a
// comparison sort (std::sort of (key, index) pairs, the stand-in for the
// paper's bitonic sort: O(n log n) and key-size independent in passes).
enum class SortAlgorithm : uint8_t { Radix, Comparison };

// Bit layout of the 32-bit keys (Hash32, Csd32):
//   DirectionMajor  the paper's HASHKEY32: direction bins in bits 24..31,
//                   origin cell in bits 0..23 (sort by direction first);
//   OriginMajor     the same 32 bits with the fields swapped: origin cell in
//                   bits 8..31, direction in bits 0..7 (sort by where rays
//                   start first). An experiment for caches (reorder.md).
enum class Key32Layout : uint8_t { DirectionMajor, OriginMajor };

struct ReorderOptions {
    SortAlgorithm sort = SortAlgorithm::Radix;
    // Radix digit width in bits (4..16): 8 gives 4 passes per 32-bit word
    // with 1 KB histograms, 11 gives 3 passes with 8 KB ones.
    int digit_bits = 8;
    Key32Layout key32_layout = Key32Layout::DirectionMajor;
};

// Where the time of one reordering went (seconds of the calling thread).
struct ReorderTimings {
    double key_seconds = 0.0;         // keys (and the origin box) from the rays
    double compress_seconds = 0.0;    // Csd32: run-length blocks
    double sort_seconds = 0.0;        // the sort itself
    double decompress_seconds = 0.0;  // Csd32: scan and expansion
    size_t rays = 0;                  // rays reordered
    size_t sorted_elements = 0;       // elements the sort saw (blocks for Csd32)
    double total() const { return key_seconds + compress_seconds + sort_seconds + decompress_seconds; }
    ReorderTimings& operator+=(const ReorderTimings& o);
};

// A 192-bit key as six 32-bit words, w[0] least significant.
struct Key192 {
    uint32_t w[6] = {};
    friend bool operator==(const Key192& a, const Key192& b) {
        for (int i = 0; i < 6; ++i)
            if (a.w[i] != b.w[i]) return false;
        return true;
    }
    friend bool operator<(const Key192& a, const Key192& b) {
        for (int i = 5; i >= 0; --i)
            if (a.w[i] != b.w[i]) return a.w[i] < b.w[i];
        return false;
    }
};

// ---- keys -------------------------------------------------------------------

// Bounding box of the rays' origins (the paper's aabb_rays). Non-finite
// origins are left out (their keys are clamped, see translate_to_box).
BBox ray_origin_bounds(const Ray* rays, size_t n);

// Interleaves the low 16 bits of x and y (x in the even bits).
uint32_t morton2(uint32_t x, uint32_t y);
// Interleaves the low 8 bits of x, y, z into 24 bits (x in bits 0, 3, ...).
uint32_t morton3_8bit(uint32_t x, uint32_t y, uint32_t z);

// Keys of one ray relative to the origin box `box` (non-empty or empty: an
// empty or flat axis maps to 0). Any finite or non-finite ray gets a key;
// identical rays get identical keys.
uint32_t hash_key32(const BBox& box, const Ray& ray, Key32Layout layout = Key32Layout::DirectionMajor);
Key192 hash_key192(const BBox& box, const Ray& ray);
// The six quantised components HASHKEY192 interleaves: origin x, y, z in
// [0, 2^24), direction x, y, z in [0, 2^21).
void hash192_components(const BBox& box, const Ray& ray, uint32_t comp[6]);

// ---- sorts ------------------------------------------------------------------

// Scratch buffers reused between calls, so a wave allocates once.
struct ReorderWorkspace {
    std::vector<uint32_t> keys, keys_tmp, values_tmp, histogram;
    std::vector<Key192> keys192;
    std::vector<uint32_t> words;  // Static3D keys, 3 words per ray
    std::vector<uint32_t> block_start, block_key, block_id, block_offset;
    std::vector<uint64_t> pairs;  // comparison sort of 32-bit keys
    size_t bytes() const;         // capacity held, for bytes-per-path reports
};

// Stable LSD radix sort of `keys` carrying `values` along (both size n).
// Digits whose value is the same for every key are skipped. The results may
// end up in swapped buffers: `keys`/`values` hold them on return.
void radix_sort_pairs(std::vector<uint32_t>& keys, std::vector<uint32_t>& values, ReorderWorkspace& ws,
                      int digit_bits = 8);

// Stable sort of `order` (indices into a key table of `words_per_key`
// 32-bit words per key, word 0 least significant) by those keys: one radix
// pass per word, least significant first, over (word, index) pairs; words on
// which every key agrees are skipped. `order` must hold a permutation.
void radix_sort_words(const uint32_t* words, int words_per_key, std::vector<uint32_t>& order, ReorderWorkspace& ws,
                      int digit_bits = 8);

// Compress-sort-decompress of 32-bit keys in input order: writes to `order`
// the stable sort of [0, n) by keys[i]. Returns the number of blocks.
size_t compress_sort_decompress(const uint32_t* keys, size_t n, std::vector<uint32_t>& order, ReorderWorkspace& ws,
                                const ReorderOptions& opt = {}, ReorderTimings* t = nullptr);

// ---- the reordering ---------------------------------------------------------

// Fills `order` with the permutation of [0, n) of `mode` (see top of file).
// `tags` is read only by Static1D and Static3D (may be null otherwise).
void compute_ray_order(const Ray* rays, const RayTag* tags, size_t n, ReorderMode mode, ReorderWorkspace& ws,
                       std::vector<uint32_t>& order, ReorderTimings* t = nullptr, const ReorderOptions& opt = {});

// Key width in bits of a mode (for plots: 0 for None and static orders).
int reorder_key_bits(ReorderMode mode);

}  // namespace coherent
