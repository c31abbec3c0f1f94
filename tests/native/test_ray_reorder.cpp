// Ray keys, radix sorts and compress-sort-decompress (render/ray_reorder.h),
// each against an independent oracle: std::stable_sort, a literal
// transcription of the paper's COLLECTBITS loop, and permutation checks.
#include <gtest/gtest.h>

#include <immintrin.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <tuple>
#include <vector>

#include "core/random.h"
#include "render/ray_reorder.h"

namespace coherent {
namespace {

std::vector<uint32_t> stable_order(const std::vector<uint32_t>& keys) {
    std::vector<uint32_t> order(keys.size());
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return keys[a] < keys[b]; });
    return order;
}

// Random keys with many duplicates (few distinct values) or spread over all
// 32 bits, depending on `distinct`.
std::vector<uint32_t> random_keys(size_t n, uint32_t distinct, uint64_t seed) {
    Pcg32 rng(seed);
    std::vector<uint32_t> keys(n);
    for (uint32_t& k : keys) k = distinct ? (rng.next_u32() % distinct) * 0x9e3779b1u : rng.next_u32();
    return keys;
}

bool is_permutation_of_n(const std::vector<uint32_t>& order, size_t n) {
    if (order.size() != n) return false;
    std::vector<uint8_t> seen(n, 0);
    for (uint32_t i : order) {
        if (i >= n || seen[i]) return false;
        seen[i] = 1;
    }
    return true;
}

TEST(RadixSort, EqualsStableSortOnRandomKeys) {
    ReorderWorkspace ws;
    for (size_t n : {size_t(0), size_t(1), size_t(2), size_t(3), size_t(17), size_t(1001), size_t(65537)})
        for (uint32_t distinct : {0u, 1u, 5u, 300u})
            for (int bits : {4, 8, 11, 16}) {
                const std::vector<uint32_t> keys = random_keys(n, distinct, n * 31 + distinct + uint64_t(bits));
                std::vector<uint32_t> k = keys, v(n);
                std::iota(v.begin(), v.end(), 0u);
                radix_sort_pairs(k, v, ws, bits);
                const std::vector<uint32_t> expect = stable_order(keys);
                ASSERT_EQ(v, expect) << "n=" << n << " distinct=" << distinct << " bits=" << bits;
                for (size_t i = 0; i < n; ++i) ASSERT_EQ(k[i], keys[v[i]]);
            }
}

TEST(RadixSort, MultiWordEqualsStableLexicographicSort) {
    ReorderWorkspace ws;
    Pcg32 rng(7);
    for (size_t n : {size_t(0), size_t(1), size_t(9), size_t(4097)}) {
        // 6 words per key, few distinct values per word so ties reach every word.
        std::vector<Key192> keys(n);
        for (Key192& k : keys)
            for (int w = 0; w < 6; ++w) k.w[w] = (w == 5) ? 0u : rng.next_u32() % 3u;
        std::vector<uint32_t> order(n);
        std::iota(order.begin(), order.end(), 0u);
        radix_sort_words(keys.data()->w, 6, order, ws, 8);
        std::vector<uint32_t> expect(n);
        std::iota(expect.begin(), expect.end(), 0u);
        std::stable_sort(expect.begin(), expect.end(), [&](uint32_t a, uint32_t b) { return keys[a] < keys[b]; });
        ASSERT_EQ(order, expect) << "n=" << n;
    }
}

TEST(CompressSortDecompress, EqualsStableSortAndCountsRuns) {
    ReorderWorkspace ws;
    Pcg32 rng(11);
    for (size_t n : {size_t(0), size_t(1), size_t(2), size_t(33), size_t(10000)})
        for (uint32_t distinct : {1u, 4u, 1000u}) {
            // Runs of random length, as background rays or one pixel's rays give.
            std::vector<uint32_t> keys;
            while (keys.size() < n) {
                const uint32_t k = rng.next_u32() % distinct;
                const uint32_t run = 1 + rng.next_u32() % 7;
                for (uint32_t r = 0; r < run && keys.size() < n; ++r) keys.push_back(k);
            }
            size_t runs = 0;
            for (size_t i = 0; i < n; ++i) runs += (i == 0 || keys[i] != keys[i - 1]) ? 1 : 0;
            for (SortAlgorithm alg : {SortAlgorithm::Radix, SortAlgorithm::Comparison}) {
                ReorderOptions opt;
                opt.sort = alg;
                std::vector<uint32_t> order;
                ReorderTimings t;
                const size_t blocks = compress_sort_decompress(keys.data(), n, order, ws, opt, &t);
                EXPECT_EQ(blocks, runs);
                EXPECT_EQ(t.sorted_elements, runs);
                ASSERT_TRUE(is_permutation_of_n(order, n));
                ASSERT_EQ(order, stable_order(keys)) << "n=" << n << " distinct=" << distinct;
            }
        }
}

// The paper's COLLECTBITS, transcribed literally (one bit at a time), over
// the engine's quantised components.
Key192 literal_collectbits(const uint32_t comp[6]) {
    Key192 h;
    for (uint32_t idx = 0; idx < 6; ++idx)
        for (uint32_t i = 0; i < 32; ++i) {
            const uint32_t k = (idx + i * 6) >> 5;
            h.w[k] |= ((comp[idx] >> i) & 1u) << ((idx + i * 6) & 31);
        }
    return h;
}

Ray random_ray(Pcg32& rng) {
    Ray r;
    r.o = {rng.next_float() * 10.0f - 5.0f, rng.next_float() * 2.0f, rng.next_float() * 4.0f - 1.0f};
    Vec3f d;
    do d = {rng.next_float() * 2.0f - 1.0f, rng.next_float() * 2.0f - 1.0f, rng.next_float() * 2.0f - 1.0f};
    while (length(d) < 0.1f || length(d) > 1.0f);
    r.d = d / length(d);
    r.tmin = 0.0f;
    r.tmax = 1.0f;
    return r;
}

TEST(RayKeys, HashKey192MatchesLiteralCollectBits) {
    Pcg32 rng(3);
    BBox box;
    box.lo = {-5.0f, 0.0f, -1.0f};
    box.hi = {5.0f, 2.0f, 3.0f};
    for (int i = 0; i < 2000; ++i) {
        const Ray r = random_ray(rng);
        uint32_t comp[6];
        hash192_components(box, r, comp);
        // Components: the paper's scalings, computed here in double (+-1 for rounding).
        const double expect[6] = {(r.o.x + 5.0) / 10.0 * 16777216.0, (r.o.y - 0.0) / 2.0 * 16777216.0,
                                  (r.o.z + 1.0) / 4.0 * 16777216.0,  (r.d.x + 1.0) * 0.5 * 2097152.0,
                                  (r.d.y + 1.0) * 0.5 * 2097152.0,   (r.d.z + 1.0) * 0.5 * 2097152.0};
        for (int c = 0; c < 6; ++c) ASSERT_NEAR(double(comp[c]), std::floor(expect[c]), 1.0) << "component " << c;
        const Key192 a = hash_key192(box, r), b = literal_collectbits(comp);
        for (int w = 0; w < 6; ++w) ASSERT_EQ(a.w[w], b.w[w]) << "ray " << i << " word " << w;
    }
    // Bits 141 and up are always 0: origin bits end at 2 + 6 * 23 = 140.
    const Key192 top = hash_key192(box, Ray{{5.0f, 2.0f, 3.0f}, 0.0f, {0.0f, 0.0f, 1.0f}, 1.0f});
    EXPECT_EQ(top.w[5], 0u);
    EXPECT_EQ(top.w[4] >> (141 - 128), 0u);
}

TEST(RayKeys, HashKey32DirectionBinsMatchAcosAtan2) {
    // The key's angle bins are computed without acos/atan2; away from bin
    // boundaries they must equal the paper's formulas (16 bins each).
    Pcg32 rng(13);
    BBox box;
    box.lo = Vec3f(0.0f);
    box.hi = Vec3f(1.0f);
    int checked = 0;
    for (int i = 0; i < 20000; ++i) {
        Ray r = random_ray(rng);
        r.d = r.d * (0.5f + rng.next_float());  // keys must not depend on |d|
        const Vec3f d = r.d / length(r.d);
        const double theta = std::acos(double(d.z)), phi = std::atan2(double(d.y), double(d.x));
        const double tb = theta / kPi * 16.0, pb = (phi + kPi) / (2.0 * kPi) * 16.0;
        if (std::fabs(tb - std::round(tb)) < 1e-4 || std::fabs(pb - std::round(pb)) < 1e-4) continue;
        const uint32_t dir = hash_key32(box, r) >> 24;
        EXPECT_EQ(_pext_u32(dir, 0xaau), uint32_t(std::min(15.0, tb))) << "theta of ray " << i;
        EXPECT_EQ(_pext_u32(dir, 0x55u), uint32_t(std::min(15.0, pb))) << "phi of ray " << i;
        ++checked;
    }
    EXPECT_GT(checked, 19000);
}

TEST(RayKeys, HashKey32Layout) {
    BBox box;
    box.lo = {0.0f, 0.0f, 0.0f};
    box.hi = {1.0f, 1.0f, 1.0f};
    Ray r{{0.0f, 0.0f, 0.0f}, 0.0f, {0.0f, 0.0f, 1.0f}, 1.0f};
    // theta = 0, phi = atan2(0, 0) = 0 -> phi bin 8 (middle of [-pi, pi]).
    const uint32_t k0 = hash_key32(box, r);
    EXPECT_EQ(k0 & 0xffffffu, 0u);
    EXPECT_EQ(k0 >> 24, uint32_t(_pdep_u32(8u, 0x55u)));
    // The far corner of the box is in the top cell of every axis.
    r.o = {1.0f, 1.0f, 1.0f};
    EXPECT_EQ(hash_key32(box, r) & 0xffffffu, 0xffffffu);
    // x alone moves the even-of-three bits.
    r.o = {0.999f, 0.0f, 0.0f};
    EXPECT_EQ(hash_key32(box, r) & 0xffffffu, morton3_8bit(255u, 0u, 0u));
    EXPECT_EQ(morton3_8bit(1u, 0u, 0u), 1u);
    EXPECT_EQ(morton3_8bit(0u, 1u, 0u), 2u);
    EXPECT_EQ(morton3_8bit(0u, 0u, 1u), 4u);
    EXPECT_EQ(morton2(3u, 0u), 5u);
    EXPECT_EQ(morton2(0u, 1u), 2u);
    // Straight down (theta = pi) is the last theta bin.
    r.d = {0.0f, 0.0f, -1.0f};
    EXPECT_EQ((hash_key32(box, r) >> 24) & 0xaau, uint32_t(_pdep_u32(15u, 0xaau)));
}

TEST(RayKeys, OriginMajorLayoutSwapsTheFields) {
    Pcg32 rng(17);
    std::vector<Ray> rays;
    for (int i = 0; i < 500; ++i) rays.push_back(random_ray(rng));
    const BBox box = ray_origin_bounds(rays.data(), rays.size());
    for (const Ray& r : rays) {
        const uint32_t dm = hash_key32(box, r, Key32Layout::DirectionMajor);
        EXPECT_EQ(hash_key32(box, r, Key32Layout::OriginMajor), (dm << 8) | (dm >> 24));
    }
    // compute_ray_order sorts by the chosen layout.
    std::vector<RayTag> tags(rays.size());
    ReorderWorkspace ws;
    std::vector<uint32_t> order;
    ReorderOptions opt;
    opt.key32_layout = Key32Layout::OriginMajor;
    compute_ray_order(rays.data(), tags.data(), rays.size(), ReorderMode::Hash32, ws, order, nullptr, opt);
    for (size_t i = 1; i < order.size(); ++i)
        ASSERT_LE(hash_key32(box, rays[order[i - 1]], Key32Layout::OriginMajor),
                  hash_key32(box, rays[order[i]], Key32Layout::OriginMajor));
}

TEST(RayKeys, IdenticalRaysGetEqualKeysAndNonFiniteRaysGetKeys) {
    Pcg32 rng(5);
    std::vector<Ray> rays;
    for (int i = 0; i < 100; ++i) rays.push_back(random_ray(rng));
    const BBox box = ray_origin_bounds(rays.data(), rays.size());
    for (const Ray& r : rays) {
        Ray copy = r;
        copy.tmax = 123.0f;  // keys depend on origin and direction only
        EXPECT_EQ(hash_key32(box, r), hash_key32(box, copy));
        EXPECT_TRUE(hash_key192(box, r) == hash_key192(box, copy));
    }
    Ray bad;
    bad.o = {NAN, INFINITY, -INFINITY};
    bad.d = {NAN, 0.0f, 0.0f};
    (void)hash_key32(box, bad);  // must not crash or trap; any key is valid
    (void)hash_key192(box, bad);
    // An empty box (no finite origin) maps every origin to cell 0.
    EXPECT_EQ(hash_key32(BBox{}, rays[0]) & 0xffffffu, 0u);
}

constexpr ReorderMode kAllModes[] = {ReorderMode::None,   ReorderMode::Static1D, ReorderMode::Static3D,
                                     ReorderMode::Hash32, ReorderMode::Hash192,  ReorderMode::Csd32};

struct RaySet {
    std::vector<Ray> rays;
    std::vector<RayTag> tags;
};

// AO-like rays: 16 per pixel of a 37 x 23 image, pixel-major, origins on a
// bumpy surface, some pixels empty (background).
RaySet ao_like_rays() {
    RaySet s;
    Pcg32 rng(9);
    for (uint16_t y = 0; y < 23; ++y)
        for (uint16_t x = 0; x < 37; ++x) {
            if ((x * 7 + y * 3) % 5 == 0) continue;
            const Vec3f o{float(x) * 0.1f, std::sin(float(x + y)), float(y) * 0.1f};
            for (uint32_t k = 0; k < 16; ++k) {
                Ray r = random_ray(rng);
                r.o = o;
                s.rays.push_back(r);
                s.tags.push_back(RayTag{x, y, k});
            }
        }
    return s;
}

TEST(RayOrder, EveryModeReturnsAPermutationWithSortedKeys) {
    const RaySet s = ao_like_rays();
    const size_t n = s.rays.size();
    ReorderWorkspace ws;
    const BBox box = ray_origin_bounds(s.rays.data(), n);
    for (ReorderMode mode : kAllModes)
        for (SortAlgorithm alg : {SortAlgorithm::Radix, SortAlgorithm::Comparison}) {
            ReorderOptions opt;
            opt.sort = alg;
            std::vector<uint32_t> order;
            ReorderTimings t;
            compute_ray_order(s.rays.data(), s.tags.data(), n, mode, ws, order, &t, opt);
            ASSERT_TRUE(is_permutation_of_n(order, n)) << reorder_name(mode);
            EXPECT_EQ(t.rays, n);
            EXPECT_GE(t.total(), 0.0);
            for (size_t i = 1; i < n; ++i) {
                const uint32_t a = order[i - 1], b = order[i];
                switch (mode) {
                    case ReorderMode::None: ASSERT_EQ(b, i); break;
                    case ReorderMode::Static1D: {
                        const uint32_t ka = morton2(s.tags[a].x, s.tags[a].y), kb = morton2(s.tags[b].x, s.tags[b].y);
                        ASSERT_TRUE(ka < kb || (ka == kb && a < b));
                        break;
                    }
                    case ReorderMode::Static3D: {
                        // Sub-major, then 8x16 tile along Morton, then row order in the tile.
                        auto key = [&](uint32_t j) {
                            const RayTag& g = s.tags[j];
                            return std::make_tuple(g.sub, morton2(g.x >> 3, g.y >> 4), (g.y & 15u) * 8u + (g.x & 7u), j);
                        };
                        ASSERT_LT(key(a), key(b));
                        break;
                    }
                    case ReorderMode::Hash32:
                    case ReorderMode::Csd32: {
                        const uint32_t ka = hash_key32(box, s.rays[a]), kb = hash_key32(box, s.rays[b]);
                        ASSERT_TRUE(ka < kb || (ka == kb && a < b)) << reorder_name(mode) << " at " << i;
                        break;
                    }
                    case ReorderMode::Hash192: {
                        const Key192 ka = hash_key192(box, s.rays[a]), kb = hash_key192(box, s.rays[b]);
                        ASSERT_TRUE(ka < kb || (ka == kb && a < b)) << "at " << i;
                        break;
                    }
                }
            }
        }
}

TEST(RayOrder, CsdEqualsPlainHash32Sort) {
    const RaySet s = ao_like_rays();
    ReorderWorkspace ws;
    std::vector<uint32_t> plain, csd;
    ReorderTimings tp, tc;
    compute_ray_order(s.rays.data(), s.tags.data(), s.rays.size(), ReorderMode::Hash32, ws, plain, &tp);
    compute_ray_order(s.rays.data(), s.tags.data(), s.rays.size(), ReorderMode::Csd32, ws, csd, &tc);
    EXPECT_EQ(plain, csd);
    EXPECT_EQ(tp.sorted_elements, s.rays.size());
    EXPECT_LE(tc.sorted_elements, s.rays.size());
}

TEST(RayOrder, TinyInputs) {
    ReorderWorkspace ws;
    std::vector<uint32_t> order{5, 6, 7};
    for (ReorderMode mode : kAllModes) {
        compute_ray_order(nullptr, nullptr, 0, mode, ws, order);
        EXPECT_TRUE(order.empty());
        Ray r;
        r.d = {0.0f, 1.0f, 0.0f};
        RayTag tag;
        compute_ray_order(&r, &tag, 1, mode, ws, order);
        ASSERT_EQ(order.size(), 1u);
        EXPECT_EQ(order[0], 0u);
    }
}

}  // namespace
}  // namespace coherent
