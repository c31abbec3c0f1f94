// Ray keys, LSD radix sorts, compress-sort-decompress (see ray_reorder.h).
#include "ray_reorder.h"

#include <immintrin.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

#include "../core/thread_time.h"

namespace coherent {

namespace {

// Starts timing only when someone asked for timings. Thread CPU time:
// reorderings run inside one wave on one thread.
struct Stopwatch {
    explicit Stopwatch(bool on) : on_(on), start_(on ? thread_cpu_seconds() : 0.0) {}
    // Adds the time since the last lap to `acc`.
    void lap(double* acc) {
        if (!on_) return;
        const double now = thread_cpu_seconds();
        *acc += now - start_;
        start_ = now;
    }

private:
    bool on_;
    double start_;
};

// (p - lo) / (hi - lo) per axis in [0, 1]; a flat or empty axis and NaN give 0.
// (Algorithm 1 prints `point - aabb_max`; the min is what maps into [0, 1].)
inline float unit_coordinate(float p, float lo, float hi) {
    const float extent = hi - lo;
    if (!(extent > 0.0f) || !std::isfinite(extent)) return 0.0f;
    const float t = (p - lo) / extent;
    return t > 0.0f ? (t < 1.0f ? t : 1.0f) : 0.0f;  // NaN -> 0
}

// Quantises t in [0, 1] to [0, levels - 1].
inline uint32_t quantise(float t, float levels) {
    const float q = t * levels;
    return q >= levels - 1.0f ? uint32_t(levels - 1.0f) : (q > 0.0f ? uint32_t(q) : 0u);
}

inline Vec3f unit_direction(const Vec3f& d) {
    const float len = length(d);
    if (!(len > 0.0f) || !std::isfinite(len)) return Vec3f(0.0f);
    return d / len;
}

// pdep masks of COLLECTBITS: bit i of component c goes to key bit c + 6 i,
// i < 32. For 64-bit word k, component c owns bits i in [first, first+count).
struct CollectMasks {
    uint64_t mask[6][3] = {};
    int first[6][3] = {}, count[6][3] = {};
    CollectMasks() {
        for (int c = 0; c < 6; ++c)
            for (int i = 0; i < 32; ++i) {
                const int pos = c + 6 * i, k = pos >> 6;
                if (count[c][k] == 0) first[c][k] = i;
                ++count[c][k];
                mask[c][k] |= uint64_t(1) << (pos & 63);
            }
    }
};
const CollectMasks kCollect;

static_assert(sizeof(Key192) == 6 * sizeof(uint32_t), "Key192 arrays are read as tables of 6 words per key");

}  // namespace

ReorderTimings& ReorderTimings::operator+=(const ReorderTimings& o) {
    key_seconds += o.key_seconds;
    compress_seconds += o.compress_seconds;
    sort_seconds += o.sort_seconds;
    decompress_seconds += o.decompress_seconds;
    rays += o.rays;
    sorted_elements += o.sorted_elements;
    return *this;
}

size_t ReorderWorkspace::bytes() const {
    auto b = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
    return b(keys) + b(keys_tmp) + b(values_tmp) + b(histogram) + b(keys192) + b(words) + b(block_start) +
           b(block_key) + b(block_id) + b(block_offset) + b(pairs);
}

// ---- keys -------------------------------------------------------------------

BBox ray_origin_bounds(const Ray* rays, size_t n) {
    BBox box;
    for (size_t i = 0; i < n; ++i)
        if (is_finite(rays[i].o)) box.expand(rays[i].o);
    return box;
}

uint32_t morton2(uint32_t x, uint32_t y) {
    return uint32_t(_pdep_u32(x, 0x55555555u) | _pdep_u32(y, 0xaaaaaaaau));
}

uint32_t morton3_8bit(uint32_t x, uint32_t y, uint32_t z) {
    return uint32_t(_pdep_u32(x, 0x249249u) | _pdep_u32(y, 0x492492u) | _pdep_u32(z, 0x924924u));
}

namespace {

// Exact 4-bit bins of the spherical angles without acos/atan2 (which cost
// more than the whole radix sort): theta = acos(z) is in bin k (k pi / 16 <=
// theta) iff z <= cos(k pi / 16); phi = atan2(y, x) is compared with the
// sector boundaries -pi + j pi / 8 by the sign of a 2D cross product, within
// the half plane (y >= 0 or y < 0) that holds both angles.
struct AngleBins {
    // 16 floats per table so that both fit two / one AVX registers; the
    // unused lanes hold values that never count (see the masks below).
    alignas(32) float cos_theta[16];           // cos(k pi / 16), k = 1..15; lane 15 unused
    alignas(32) float cos_a[8], sin_a[8];      // boundaries j pi / 8, j = 1..7; lane 7 unused
    AngleBins() {
        constexpr double pi = 3.14159265358979323846;
        for (int k = 1; k < 16; ++k) cos_theta[k - 1] = float(std::cos(double(k) * pi / 16.0));
        cos_theta[15] = -INFINITY;  // -inf >= z never holds for z in [-1, 1] (or NaN)
        for (int j = 1; j < 8; ++j) {
            cos_a[j - 1] = float(std::cos(double(j) * pi / 8.0));
            sin_a[j - 1] = float(std::sin(double(j) * pi / 8.0));
        }
        cos_a[7] = sin_a[7] = 0.0f;  // masked off
    }
    // #{k : z <= cos(k pi / 16)}: one broadcast compare per 8 thresholds.
    uint32_t theta_bin(float z) const {
        const __m256 zv = _mm256_set1_ps(z);
        const int lo = _mm256_movemask_ps(_mm256_cmp_ps(_mm256_load_ps(cos_theta), zv, _CMP_GE_OQ));
        const int hi = _mm256_movemask_ps(_mm256_cmp_ps(_mm256_load_ps(cos_theta + 8), zv, _CMP_GE_OQ));
        return uint32_t(_mm_popcnt_u32(uint32_t(lo)) + _mm_popcnt_u32(uint32_t(hi)));
    }
    // Sector of phi = atan2(y, x) in [-pi, pi] split into 16 from -pi.
    // Upper half (y >= 0, phi in [0, pi]): 8 + #{j : phi >= j pi / 8}.
    // Lower half (phi in [-pi, 0)): #{j : phi >= -pi + j pi / 8}, the same
    // test on the vector rotated by pi. Within a half plane, phi >= a iff
    // cross((cos a, sin a), (x, y)) >= 0. A NaN component counts nothing.
    uint32_t phi_bin(float x, float y) const {
        if (x == 0.0f && y == 0.0f) return 8u;  // straight up or down: atan2(0, 0) = 0
        const bool upper = y >= 0.0f && !(y == 0.0f && std::signbit(y));
        const float sx = upper ? x : -x, sy = upper ? y : -y;
        const __m256 cross = _mm256_sub_ps(_mm256_mul_ps(_mm256_load_ps(cos_a), _mm256_set1_ps(sy)),
                                           _mm256_mul_ps(_mm256_load_ps(sin_a), _mm256_set1_ps(sx)));
        const int m = _mm256_movemask_ps(_mm256_cmp_ps(cross, _mm256_setzero_ps(), _CMP_GE_OQ)) & 0x7f;
        return (upper ? 8u : 0u) + uint32_t(_mm_popcnt_u32(uint32_t(m)));
    }
};
const AngleBins kAngleBins;

}  // namespace

namespace {

// The origin box as offsets and scales to the 8-bit grid, computed once per
// reordering: a multiply per axis instead of a divide. A flat or empty axis gets
// scale 0 (every origin in cell 0).
struct KeyFrame32 {
    Vec3f lo{0.0f}, scale{0.0f};
    explicit KeyFrame32(const BBox& box) {
        for (int a = 0; a < 3; ++a) {
            const float extent = box.hi[a] - box.lo[a];
            if (extent > 0.0f && std::isfinite(extent)) {
                lo[a] = box.lo[a];
                scale[a] = 256.0f / extent;
            }
        }
    }
    uint32_t cell(float p, int a) const {
        const float q = (p - lo[a]) * scale[a];
        return q >= 255.0f ? 255u : (q > 0.0f ? uint32_t(q) : 0u);  // NaN -> 0
    }
};

inline uint32_t hash_key32(const KeyFrame32& f, const Ray& ray, Key32Layout layout) {
    // Origin: 8 bits per axis of the origin box (the paper's virtual grid).
    const uint32_t origin = morton3_8bit(f.cell(ray.o.x, 0), f.cell(ray.o.y, 1), f.cell(ray.o.z, 2));
    // Direction: spherical angles, 4 bits each. Algorithm 1 scales by 8,
    // which gives the 9 values 0..8 in its 4-bit fields; we use all 16 values
    // the fields hold. theta only needs z / |d|; phi is scale invariant.
    const float len2 = length_squared(ray.d);
    const float z = len2 > 0.0f ? ray.d.z / std::sqrt(len2) : 0.0f;
    const uint32_t dtheta = kAngleBins.theta_bin(z);
    const uint32_t dphi = kAngleBins.phi_bin(ray.d.x, ray.d.y);
    const uint32_t dir = uint32_t(_pdep_u32(dphi, 0x55u) | _pdep_u32(dtheta, 0xaau));
    return layout == Key32Layout::DirectionMajor ? origin | (dir << 24) : (origin << 8) | dir;
}

}  // namespace

uint32_t hash_key32(const BBox& box, const Ray& ray, Key32Layout layout) {
    return hash_key32(KeyFrame32(box), ray, layout);
}

void hash192_components(const BBox& box, const Ray& ray, uint32_t comp[6]) {
    const Vec3f d = unit_direction(ray.d);
    comp[0] = quantise(unit_coordinate(ray.o.x, box.lo.x, box.hi.x), 16777216.0f);  // 256 * 65536
    comp[1] = quantise(unit_coordinate(ray.o.y, box.lo.y, box.hi.y), 16777216.0f);
    comp[2] = quantise(unit_coordinate(ray.o.z, box.lo.z, box.hi.z), 16777216.0f);
    comp[3] = quantise((d.x + 1.0f) * 0.5f, 2097152.0f);  // 32 * 65536
    comp[4] = quantise((d.y + 1.0f) * 0.5f, 2097152.0f);
    comp[5] = quantise((d.z + 1.0f) * 0.5f, 2097152.0f);
}

Key192 hash_key192(const BBox& box, const Ray& ray) {
    uint32_t comp[6];
    hash192_components(box, ray, comp);
    uint64_t word[3] = {0, 0, 0};
    for (int c = 0; c < 6; ++c)
        for (int k = 0; k < 3; ++k) {
            const int cnt = kCollect.count[c][k];
            if (cnt == 0) continue;
            const uint64_t bits = (uint64_t(comp[c]) >> kCollect.first[c][k]) & ((uint64_t(1) << cnt) - 1);
            word[k] |= _pdep_u64(bits, kCollect.mask[c][k]);
        }
    Key192 key;
    for (int k = 0; k < 3; ++k) {
        key.w[2 * k] = uint32_t(word[k]);
        key.w[2 * k + 1] = uint32_t(word[k] >> 32);
    }
    return key;
}

// ---- sorts ------------------------------------------------------------------

void radix_sort_pairs(std::vector<uint32_t>& keys, std::vector<uint32_t>& values, ReorderWorkspace& ws,
                      int digit_bits) {
    const size_t n = keys.size();
    if (n < 2) return;
    const int bits = std::clamp(digit_bits, 4, 16);
    const int passes = (32 + bits - 1) / bits;
    const uint32_t radix = 1u << bits, mask = radix - 1;

    // All histograms in one read of the keys.
    ws.histogram.assign(size_t(passes) * radix, 0);
    uint32_t* hist = ws.histogram.data();
    for (size_t i = 0; i < n; ++i) {
        const uint32_t k = keys[i];
        for (int p = 0; p < passes; ++p) ++hist[size_t(p) * radix + ((k >> (p * bits)) & mask)];
    }
    ws.keys_tmp.resize(n);
    ws.values_tmp.resize(n);
    for (int p = 0; p < passes; ++p) {
        uint32_t* h = hist + size_t(p) * radix;
        const int shift = p * bits;
        // A digit every key shares leaves the order as it is.
        if (h[(keys[0] >> shift) & mask] == n) continue;
        uint32_t sum = 0;
        for (uint32_t d = 0; d < radix; ++d) {
            const uint32_t c = h[d];
            h[d] = sum;
            sum += c;
        }
        const uint32_t* ks = keys.data();
        const uint32_t* vs = values.data();
        uint32_t* kd = ws.keys_tmp.data();
        uint32_t* vd = ws.values_tmp.data();
        for (size_t i = 0; i < n; ++i) {
            const uint32_t k = ks[i];
            const uint32_t dst = h[(k >> shift) & mask]++;
            kd[dst] = k;
            vd[dst] = vs[i];
        }
        keys.swap(ws.keys_tmp);
        values.swap(ws.values_tmp);
    }
}

void radix_sort_words(const uint32_t* words, int words_per_key, std::vector<uint32_t>& order, ReorderWorkspace& ws,
                      int digit_bits) {
    const size_t n = order.size();
    if (n < 2) return;
    const size_t stride = size_t(words_per_key);
    for (int w = 0; w < words_per_key; ++w) {
        // Skip words on which all keys agree (the top of a 192-bit key is
        // always 0); reading the table in memory order is cheap.
        const uint32_t first = words[w];
        uint32_t differ = 0;
        for (size_t i = 1; i < n; ++i) differ |= words[i * stride + size_t(w)] ^ first;
        if (differ == 0) continue;
        ws.keys.resize(n);
        for (size_t i = 0; i < n; ++i) ws.keys[i] = words[size_t(order[i]) * stride + size_t(w)];
        radix_sort_pairs(ws.keys, order, ws, digit_bits);
    }
}

namespace {

// Comparison sort of 32-bit keys with their indices packed into 64 bits:
// unique pairs, so std::sort gives the stable order.
void comparison_sort32(const uint32_t* keys, size_t n, std::vector<uint32_t>& order, ReorderWorkspace& ws) {
    ws.pairs.resize(n);
    for (size_t i = 0; i < n; ++i) ws.pairs[i] = (uint64_t(keys[i]) << 32) | uint64_t(order[i]);
    std::sort(ws.pairs.begin(), ws.pairs.end());
    for (size_t i = 0; i < n; ++i) order[i] = uint32_t(ws.pairs[i]);
}

// Comparison sort of `order` by multi-word keys, ties by index (stable).
void comparison_sort_words(const uint32_t* words, int words_per_key, std::vector<uint32_t>& order) {
    const size_t stride = size_t(words_per_key);
    std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
        const uint32_t* ka = words + size_t(a) * stride;
        const uint32_t* kb = words + size_t(b) * stride;
        for (int w = words_per_key - 1; w >= 0; --w)
            if (ka[w] != kb[w]) return ka[w] < kb[w];
        return a < b;
    });
}

void sort32(const uint32_t* keys, size_t n, std::vector<uint32_t>& order, ReorderWorkspace& ws,
            const ReorderOptions& opt) {
    // `order` holds the identity on entry.
    if (opt.sort == SortAlgorithm::Comparison) {
        comparison_sort32(keys, n, order, ws);
        return;
    }
    if (ws.keys.data() != keys) ws.keys.assign(keys, keys + n);
    radix_sort_pairs(ws.keys, order, ws, opt.digit_bits);
}

}  // namespace

namespace {

// Compress: one block per run of equal consecutive keys, into
// ws.block_key / ws.block_start (with a sentinel n, so that block b's length
// is start[b + 1] - start[b]); returns the number of blocks. Eight keys at a
// time are compared with their predecessors: long runs (background) cost one
// vector compare per eight rays; in mixed groups every ray writes a
// candidate block, which only a key change keeps (branch-free: runs on
// foreground geometry are short and random).
size_t compress_runs(const uint32_t* keys, size_t n, ReorderWorkspace& ws) {
    ws.block_start.resize(n + 1);
    ws.block_key.resize(n + 1);
    ws.block_start[0] = 0;
    ws.block_key[0] = keys[0];
    size_t blocks = 1;
    size_t i = 1;
    for (; i + 8 <= n; i += 8) {
        const __m256i cur = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(keys + i));
        const __m256i prev = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(keys + i - 1));
        if (_mm256_movemask_epi8(_mm256_cmpeq_epi32(cur, prev)) == -1) continue;  // one run goes on
        for (size_t j = i; j < i + 8; ++j) {
            ws.block_start[blocks] = uint32_t(j);
            ws.block_key[blocks] = keys[j];
            blocks += keys[j] != keys[j - 1] ? 1 : 0;
        }
    }
    for (; i < n; ++i) {
        ws.block_start[blocks] = uint32_t(i);
        ws.block_key[blocks] = keys[i];
        blocks += keys[i] != keys[i - 1] ? 1 : 0;
    }
    ws.block_start[blocks] = uint32_t(n);
    ws.block_key.resize(blocks);
    return blocks;
}

// Decompress: the running (exclusive) sum of the sorted blocks' lengths is
// each block's first output slot; its rays follow consecutively. Four slots
// are written unconditionally per block (the next blocks overwrite the
// excess, which falls in the 4 slots of padding at the end at worst), so the
// common short blocks cost no branch miss.
void decompress_blocks(const ReorderWorkspace& ws, size_t blocks, size_t n, std::vector<uint32_t>& order) {
    order.resize(n + 4);
    uint32_t offset = 0;
    for (size_t b = 0; b < blocks; ++b) {
        const uint32_t id = ws.block_id[b];
        const uint32_t start = ws.block_start[id], len = ws.block_start[id + 1] - start;
        uint32_t* dst = order.data() + offset;
        _mm_storeu_si128(reinterpret_cast<__m128i*>(dst),
                         _mm_add_epi32(_mm_set1_epi32(int(start)), _mm_setr_epi32(0, 1, 2, 3)));
        for (uint32_t i = 4; i < len; ++i) dst[i] = start + i;
        offset += len;
    }
    order.resize(n);
}

// Static3D keys as three words per ray, least significant first: pixel
// within its 8 x 16 tile, tile along the Morton curve, ray index within the
// pixel.
void static3d_words(const RayTag* tags, size_t n, std::vector<uint32_t>& words) {
    words.resize(3 * n);
    for (size_t i = 0; i < n; ++i) {
        const RayTag& g = tags[i];
        words[3 * i + 0] = (uint32_t(g.y) & 15u) * 8u + (uint32_t(g.x) & 7u);
        words[3 * i + 1] = morton2(uint32_t(g.x) >> 3, uint32_t(g.y) >> 4);
        words[3 * i + 2] = g.sub;
    }
}

}  // namespace

size_t compress_sort_decompress(const uint32_t* keys, size_t n, std::vector<uint32_t>& order, ReorderWorkspace& ws,
                                const ReorderOptions& opt, ReorderTimings* t) {
    Stopwatch sw(t != nullptr);
    order.resize(n);
    if (n == 0) return 0;
    const size_t blocks = compress_runs(keys, n, ws);
    sw.lap(t ? &t->compress_seconds : nullptr);
    // Sort the blocks by key; ties keep block order, so the whole result is
    // the stable sort of the rays.
    ws.block_id.resize(blocks);
    std::iota(ws.block_id.begin(), ws.block_id.end(), 0u);
    if (opt.sort == SortAlgorithm::Comparison) comparison_sort32(ws.block_key.data(), blocks, ws.block_id, ws);
    else radix_sort_pairs(ws.block_key, ws.block_id, ws, opt.digit_bits);
    sw.lap(t ? &t->sort_seconds : nullptr);
    decompress_blocks(ws, blocks, n, order);
    sw.lap(t ? &t->decompress_seconds : nullptr);
    if (t) t->sorted_elements += blocks;
    return blocks;
}

// ---- the reordering ---------------------------------------------------------

void compute_ray_order(const Ray* rays, const RayTag* tags, size_t n, ReorderMode mode, ReorderWorkspace& ws,
                       std::vector<uint32_t>& order, ReorderTimings* t, const ReorderOptions& opt) {
    Stopwatch sw(t != nullptr);
    order.resize(n);
    std::iota(order.begin(), order.end(), 0u);
    if (t) t->rays += n;
    if (n < 2 || mode == ReorderMode::None) return;

    switch (mode) {
        case ReorderMode::None: break;
        case ReorderMode::Static1D: {
            ws.keys.resize(n);
            for (size_t i = 0; i < n; ++i) ws.keys[i] = morton2(tags[i].x, tags[i].y);
            sw.lap(t ? &t->key_seconds : nullptr);
            sort32(ws.keys.data(), n, order, ws, opt);
            sw.lap(t ? &t->sort_seconds : nullptr);
            if (t) t->sorted_elements += n;
            break;
        }
        case ReorderMode::Static3D: {
            static3d_words(tags, n, ws.words);
            sw.lap(t ? &t->key_seconds : nullptr);
            if (opt.sort == SortAlgorithm::Comparison) comparison_sort_words(ws.words.data(), 3, order);
            else radix_sort_words(ws.words.data(), 3, order, ws, opt.digit_bits);
            sw.lap(t ? &t->sort_seconds : nullptr);
            if (t) t->sorted_elements += n;
            break;
        }
        case ReorderMode::Hash32:
        case ReorderMode::Csd32: {
            const KeyFrame32 frame(ray_origin_bounds(rays, n));
            ws.keys.resize(n);
            for (size_t i = 0; i < n; ++i) ws.keys[i] = hash_key32(frame, rays[i], opt.key32_layout);
            sw.lap(t ? &t->key_seconds : nullptr);
            if (mode == ReorderMode::Hash32) {
                sort32(ws.keys.data(), n, order, ws, opt);
                sw.lap(t ? &t->sort_seconds : nullptr);
                if (t) t->sorted_elements += n;
            } else {
                // (The block sort works on ws.block_key, never on ws.keys.)
                compress_sort_decompress(ws.keys.data(), n, order, ws, opt, t);
            }
            break;
        }
        case ReorderMode::Hash192: {
            const BBox box = ray_origin_bounds(rays, n);
            ws.keys192.resize(n);
            for (size_t i = 0; i < n; ++i) ws.keys192[i] = hash_key192(box, rays[i]);
            sw.lap(t ? &t->key_seconds : nullptr);
            const uint32_t* words = ws.keys192.data()->w;
            if (opt.sort == SortAlgorithm::Comparison) comparison_sort_words(words, 6, order);
            else radix_sort_words(words, 6, order, ws, opt.digit_bits);
            sw.lap(t ? &t->sort_seconds : nullptr);
            if (t) t->sorted_elements += n;
            break;
        }
    }
}

int reorder_key_bits(ReorderMode mode) {
    switch (mode) {
        case ReorderMode::Hash32:
        case ReorderMode::Csd32: return 32;
        case ReorderMode::Hash192: return 192;
        default: return 0;
    }
}

}  // namespace coherent
