// SIMD wrapper types (core/simd.h): every lane of every operation against
// the scalar operation on the same floats (the oracle), bit for bit, on
// ordinary values and on the special ones the kernels rely on (NaN, +-inf,
// -0, denormals); masks against their lane-by-lane meaning.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "accel/box4.h"
#include "core/float_bounds.h"
#include "core/simd.h"

using namespace coherent;
using namespace coherent::simd;

namespace {

uint32_t bits(float x) {
    uint32_t b;
    std::memcpy(&b, &x, 4);
    return b;
}

// 8 * k floats: specials first, then random values of mixed magnitude and sign.
std::vector<float> test_values(int k, uint32_t seed) {
    const float inf = std::numeric_limits<float>::infinity();
    const float nan = std::numeric_limits<float>::quiet_NaN();
    std::vector<float> v = {0.0f, -0.0f, 1.0f, -1.0f, inf, -inf, nan, 1e-40f, -1e-40f, 3.5f, 1e30f, -2.5e-3f};
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> mant(-1.0f, 1.0f);
    std::uniform_int_distribution<int> ex(-20, 20);
    while (v.size() < size_t(8 * k)) v.push_back(std::ldexp(mant(rng), ex(rng)));
    std::shuffle(v.begin(), v.end(), rng);
    return v;
}

struct alignas(32) Lanes8 {
    float f[8];
};

Lanes8 lanes(vfloat8 x) {
    Lanes8 l;
    store(l.f, x);
    return l;
}

}  // namespace

TEST(Simd, Float8ArithmeticMatchesScalarBitForBit) {
    const auto a = test_values(32, 1), b = test_values(32, 2), c = test_values(32, 3);
    for (size_t o = 0; o < a.size(); o += 8) {
        const vfloat8 va = vfloat8::loadu(&a[o]), vb = vfloat8::loadu(&b[o]), vc = vfloat8::loadu(&c[o]);
        const Lanes8 sum = lanes(va + vb), diff = lanes(va - vb), prod = lanes(va * vb), quot = lanes(va / vb);
        const Lanes8 fms = lanes(fmsub(va, vb, vc)), mn = lanes(min(va, vb)), mx = lanes(max(va, vb));
        const Lanes8 ab = lanes(abs(va));
        for (int i = 0; i < 8; ++i) {
            const float x = a[o + i], y = b[o + i], z = c[o + i];
            // NaN results: any NaN will do (the payload is not part of the contract).
            auto same = [](float got, float want) {
                return std::isnan(want) ? std::isnan(got) : bits(got) == bits(want);
            };
            EXPECT_TRUE(same(sum.f[i], x + y)) << x << " + " << y;
            EXPECT_TRUE(same(diff.f[i], x - y)) << x << " - " << y;
            EXPECT_TRUE(same(prod.f[i], x * y)) << x << " * " << y;
            EXPECT_TRUE(same(quot.f[i], x / y)) << x << " / " << y;
            EXPECT_TRUE(same(fms.f[i], std::fma(x, y, -z))) << x << " * " << y << " - " << z;
            // The x86 rule: the second operand when either is NaN.
            EXPECT_TRUE(same(mn.f[i], x < y ? x : y)) << "min " << x << " " << y;
            EXPECT_TRUE(same(mx.f[i], x > y ? x : y)) << "max " << x << " " << y;
            EXPECT_TRUE(same(ab.f[i], std::fabs(x))) << x;
        }
    }
}

TEST(Simd, Float8ComparisonsFollowCppRules) {
    const auto a = test_values(32, 4), b = test_values(32, 5);
    for (size_t o = 0; o < a.size(); o += 8) {
        const vfloat8 va = vfloat8::loadu(&a[o]), vb = vfloat8::loadu(&b[o]);
        const int lt = movemask(va < vb), le = movemask(va <= vb), gt = movemask(va > vb), ge = movemask(va >= vb);
        const int eq = movemask(va == vb), ne = movemask(va != vb), fin = movemask(isfinite(va));
        const int sign = movemask(signbit(va));
        for (int i = 0; i < 8; ++i) {
            const float x = a[o + i], y = b[o + i];
            EXPECT_EQ((lt >> i) & 1, x < y ? 1 : 0);
            EXPECT_EQ((le >> i) & 1, x <= y ? 1 : 0);
            EXPECT_EQ((gt >> i) & 1, x > y ? 1 : 0);
            EXPECT_EQ((ge >> i) & 1, x >= y ? 1 : 0);
            EXPECT_EQ((eq >> i) & 1, x == y ? 1 : 0);
            EXPECT_EQ((ne >> i) & 1, x != y ? 1 : 0);  // true for NaN
            EXPECT_EQ((fin >> i) & 1, std::isfinite(x) ? 1 : 0);
            EXPECT_EQ((sign >> i) & 1, std::signbit(x) ? 1 : 0);  // -0 included
        }
    }
}

TEST(Simd, Float4MatchesFloat8LaneForLane) {
    const auto a = test_values(16, 6), b = test_values(16, 7);
    for (size_t o = 0; o < a.size(); o += 8) {
        for (size_t h = 0; h < 8; h += 4) {
            const vfloat4 x = vfloat4::loadu(&a[o + h]), y = vfloat4::loadu(&b[o + h]);
            const vfloat8 x8(x, x), y8(y, y);
            alignas(16) float r4[4];
            const Lanes8 r8 = lanes(fmsub(x8, y8, x8) + abs(x8) / y8);
            store(r4, fmsub(x, y, x) + abs(x) / y);
            for (int i = 0; i < 4; ++i) {
                EXPECT_TRUE(std::isnan(r4[i]) ? std::isnan(r8.f[i]) : bits(r4[i]) == bits(r8.f[i]));
                EXPECT_TRUE(std::isnan(r4[i]) ? std::isnan(r8.f[i + 4]) : bits(r4[i]) == bits(r8.f[i + 4]));
            }
            EXPECT_EQ(movemask(x < y) | movemask(x < y) << 4, movemask(x8 < y8));
            EXPECT_EQ(movemask(x != y) | movemask(x != y) << 4, movemask(x8 != y8));
            EXPECT_EQ(movemask(min(x, y) == max(x, y)) * 0x11, movemask(min(x8, y8) == max(x8, y8)));
        }
    }
}

TEST(Simd, MasksSelectAndCount) {
    const vfloat8 t = vfloat8::loadu(std::vector<float>{0, 1, 2, 3, 4, 5, 6, 7}.data());
    const vfloat8 f = -1.0f;
    for (int m = 0; m < 256; ++m) {
        const vbool8 b = vbool8::from_bits(m);
        ASSERT_EQ(movemask(b), m);
        EXPECT_EQ(popcount(b), __builtin_popcount(m));
        EXPECT_EQ(any(b), m != 0);
        EXPECT_EQ(all(b), m == 0xff);
        EXPECT_EQ(none(b), m == 0);
        EXPECT_EQ(movemask(~b), ~m & 0xff);
        const vbool8 other = vbool8::from_bits(0x5a);
        EXPECT_EQ(movemask(b & other), m & 0x5a);
        EXPECT_EQ(movemask(b | other), m | 0x5a);
        EXPECT_EQ(movemask(b ^ other), m ^ 0x5a);
        EXPECT_EQ(movemask(andnot(b, other)), m & ~0x5a);
        const Lanes8 s = lanes(select(b, t, f));
        for (int i = 0; i < 8; ++i) EXPECT_EQ(s.f[i], (m >> i) & 1 ? float(i) : -1.0f);
        const vint8 si = select(b, vint8(7), vint8(-3));
        alignas(32) int32_t is[8];
        store(is, si);
        for (int i = 0; i < 8; ++i) EXPECT_EQ(is[i], (m >> i) & 1 ? 7 : -3);
    }
    // A sign-bit mask selects like a comparison mask.
    const float sign_values[8] = {-0.0f, 0.0f, -1.0f, 2.0f, -1e-40f, 1e-40f, -5.0f, 5.0f};
    const vfloat8 signs = vfloat8::loadu(sign_values);
    EXPECT_EQ(movemask(signbit(signs)), 0x55);
    const Lanes8 s = lanes(select(signbit(signs), t, f));
    for (int i = 0; i < 8; ++i) EXPECT_EQ(s.f[i], i % 2 == 0 ? float(i) : -1.0f);
    const vbool4 b4(true, false, false, true);
    EXPECT_EQ(movemask(b4), 0x9);
    EXPECT_EQ(movemask(~b4), 0x6);
}

TEST(Simd, IntegerLanes) {
    alignas(32) uint32_t u[8] = {0u, 1u, 0x7fffffffu, 0x80000000u, 0xffffffffu, 5u, 6u, 7u};
    const vint8 a = vint8::load(u), b = vint8(static_cast<int32_t>(0x80000001u));
    alignas(32) uint32_t out[8];
    store(out, min_u32(a, b));
    for (int i = 0; i < 8; ++i) EXPECT_EQ(out[i], std::min(u[i], 0x80000001u)) << i;
    EXPECT_EQ(movemask(a == vint8(6)), 1 << 6);
    store(out, (a << 2) | (a & vint8(1)));
    for (int i = 0; i < 8; ++i) EXPECT_EQ(out[i], (u[i] << 2) | (u[i] & 1u)) << i;
    alignas(16) int32_t q[4] = {3, -1, 3, 0};
    EXPECT_EQ(movemask(vint4::load(q) == vint4(3)), 0x5);
}

TEST(Simd, PermuteInLanesPicksPerLane) {
    const vfloat4 xyz(10.0f, 20.0f, 30.0f, 0.0f);
    const vfloat8 table(xyz, xyz);
    alignas(32) int32_t idx[8] = {0, 1, 2, 3, 2, 1, 0, 2};
    const Lanes8 p = lanes(permute_in_lanes(table, vint8::load(idx)));
    const float want[4] = {10.0f, 20.0f, 30.0f, 0.0f};
    for (int i = 0; i < 8; ++i) EXPECT_EQ(p.f[i], want[idx[i]]) << i;
}

TEST(Simd, LoadsStoresAndReductions) {
    alignas(32) float src[9] = {3, -1, 4, 1, -5, 9, 2, 6, 5};
    const vfloat8 a = vfloat8::load(src), u = vfloat8::loadu(src + 1);
    EXPECT_EQ(reduce_min(a), -5.0f);
    EXPECT_EQ(reduce_max(a), 9.0f);
    EXPECT_EQ(reduce_min(u), -5.0f);
    EXPECT_EQ(reduce_max(u), 9.0f);
    float dst[9] = {};
    storeu(dst + 1, u);
    for (int i = 0; i < 8; ++i) EXPECT_EQ(dst[i + 1], src[i + 1]);
    // Masked stores leave the other lanes untouched.
    alignas(32) float m[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    store(vbool8::from_bits(0x81), m, a);
    for (int i = 0; i < 8; ++i) EXPECT_EQ(m[i], (i == 0 || i == 7) ? src[i] : 0.0f);
    alignas(32) uint32_t mi[8] = {};
    store(vbool8::from_bits(0x02), mi, vint8(42));
    for (int i = 0; i < 8; ++i) EXPECT_EQ(mi[i], i == 1 ? 42u : 0u);
}

TEST(FloatBounds, SharedConstantsKeepTheirValues) {
    // The values every kernel used before they shared one definition.
    EXPECT_EQ(bits(gamma_bound(3)), bits((3.0f * 0x1p-24f) / (1.0f - 3.0f * 0x1p-24f)));
    EXPECT_EQ(bits(gamma_bound(7)), bits((7.0f * 0x1p-24f) / (1.0f - 7.0f * 0x1p-24f)));
    EXPECT_EQ(bits(kFarScale), bits(1.0f + 2.0f * (3.0f * 0x1p-24f) / (1.0f - 3.0f * 0x1p-24f)));
    EXPECT_EQ(kCullSlack, 0x1p-12f);
    // gamma(n) bounds n roundings: (1 + eps)^n - 1 <= gamma(n) in exact arithmetic.
    for (int n = 1; n <= 8; ++n) EXPECT_LE(std::pow(1.0L + 0x1p-24L, n) - 1.0L, (long double)gamma_bound(n)) << n;
}

// The builders bin with Box4 (accel/box4.h) where they used BBox: expand,
// centre and bin index must give the scalar code's bits, signed zeros and
// infinities included, or trees (and images) would change with the switch.
TEST(Box4, MatchesScalarBBoxBitForBit) {
    const std::vector<float> v = test_values(64, 17);
    std::vector<BBox> boxes;
    for (size_t i = 0; i + 5 < v.size(); i += 6) {
        BBox b;
        b.lo = {v[i], v[i + 1], v[i + 2]};
        b.hi = {v[i + 3], v[i + 4], v[i + 5]};
        if (!is_finite(b.lo) || !is_finite(b.hi)) continue;  // builders only see finite boxes
        boxes.push_back(b);
    }
    ASSERT_GT(boxes.size(), 40u);
    const Vec3f map_lo{-3.0f, -0.0f, 0.0f}, map_scale{16.0f / 7.0f, 0.0f, 1e30f};
    const BinIndex4 index(map_lo, map_scale, 16);
    BBox acc;
    Box4 acc4 = Box4::empty();
    for (const BBox& b : boxes) {
        const Box4 b4 = Box4::load(b);
        const BBox back = b4.to_bbox();
        for (int a = 0; a < 3; ++a) {
            EXPECT_EQ(bits(back.lo[a]), bits(b.lo[a]));
            EXPECT_EQ(bits(back.hi[a]), bits(b.hi[a]));
        }
        acc.expand(b);
        acc4.expand(b4);
        const BBox got = acc4.to_bbox();
        alignas(16) float c4[4];
        store(c4, b4.center());
        int32_t bin[4];
        index.bins(b4.center(), bin);
        const Vec3f c = b.center();
        for (int a = 0; a < 3; ++a) {
            EXPECT_EQ(bits(got.lo[a]), bits(acc.lo[a])) << "lo axis " << a;
            EXPECT_EQ(bits(got.hi[a]), bits(acc.hi[a])) << "hi axis " << a;
            EXPECT_EQ(bits(c4[a]), bits(c[a])) << "centre axis " << a;
            const int scalar = std::clamp(static_cast<int>((c[a] - map_lo[a]) * map_scale[a]), 0, 15);
            if (std::fabs((c[a] - map_lo[a]) * map_scale[a]) < 2e9f)  // static_cast is defined there
                EXPECT_EQ(bin[a], scalar) << "bin axis " << a << " centre " << c[a];
            else
                EXPECT_TRUE(bin[a] == 0 || bin[a] == 15);
        }
    }
    // A point expansion with signed zeros keeps the first zero, as std::min does.
    Box4 z = Box4::empty();
    z.expand_point(vfloat4(0.0f));
    z.expand_point(vfloat4(-0.0f));
    EXPECT_EQ(bits(z.to_bbox().lo.x), bits(0.0f));
    EXPECT_EQ(bits(z.to_bbox().hi.x), bits(0.0f));
}
