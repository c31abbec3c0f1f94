// In-memory images of the texture store (native/shader/memory_images.h):
// bytes stay bytes and read as value / 255, and a keyed image outlives its store until a newer version of
// it or the retention limit drops it.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "shader/memory_images.h"
#include "shader/textures.h"

namespace coherent {
namespace {

// 3x2 RGBA bytes, first row at the top.
const std::vector<uint8_t> kBytes = {255, 0,   0,  255, 0,  255, 0,   128, 0,  0,  255, 255,
                                     10,  200, 30, 0,   77, 77,  254, 1,   99, 98, 97,  96};

std::vector<float> as_floats(const std::vector<uint8_t>& bytes) {
    std::vector<float> f;
    for (uint8_t b : bytes) f.push_back(float(b) * (1.0f / 255.0f));  // what Blender's Image.pixels gives
    return f;
}

std::vector<float> lookups(const TextureStore& store, uint32_t image, TextureLookup how) {
    std::vector<float> out;
    for (float u : {0.1f, 0.5f, 0.77f, 0.95f})
        for (float v : {0.2f, 0.5f, 0.9f}) {
            float c[4];
            store.lookup(image, u, v, how, c);
            out.insert(out.end(), c, c + 4);
        }
    return out;
}

TEST(MemoryImages, BytePixelsLookUpAsTheirFloatValues) {
    TextureStore store(64);
    const uint32_t bytes = store.add_bytes("bytes", 3, 2, 4, kBytes.data());
    const std::vector<float> floats_in = as_floats(kBytes);
    const uint32_t floats = store.add_pixels("floats", 3, 2, 4, floats_in.data());
    EXPECT_EQ(store.buffer_bytes(), kBytes.size() * (1 + sizeof(float)));
    TextureLookup closest;
    closest.interp = TextureLookup::Interp::Closest;
    float c[4];
    store.lookup(bytes, 0.5f, 0.75f, closest, c);  // top row, middle texel
    EXPECT_EQ(c[1], 1.0f);
    EXPECT_EQ(c[3], 128.0f / 255.0f);
    for (TextureLookup::Interp interp : {TextureLookup::Interp::Closest, TextureLookup::Interp::Linear}) {
        TextureLookup how;
        how.interp = interp;
        const std::vector<float> a = lookups(store, bytes, how), b = lookups(store, floats, how);
        for (size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(a[i], b[i], 1e-6f) << i;
    }
}

// Odd sizes span several tiles, partly filled at the right and bottom edges
// (100 x 70: 64 x 64 tiles), or one padded tile (1000 x 3: 1024 x 8).
TEST(MemoryImages, EveryTexelOfAnOddSizedImageReadsBack) {
    for (auto [width, height] : {std::pair{100, 70}, std::pair{1000, 3}}) {
        std::vector<uint8_t> bytes(size_t(width) * height * 3);
        for (int y = 0; y < height; ++y)
            for (int x = 0; x < width; ++x)
                for (int c = 0; c < 3; ++c) bytes[(size_t(y) * width + x) * 3 + c] = uint8_t(x * 7 + y * 13 + c * 5);
        TextureStore store(64);
        const uint32_t id = store.add_bytes("odd", width, height, 3, bytes.data());
        TextureLookup closest;
        closest.interp = TextureLookup::Interp::Closest;
        for (int y = 0; y < height; ++y)
            for (int x = 0; x < width; ++x) {
                float c[4];
                // Texel centres; rows run top down, v bottom up.
                store.lookup(id, (x + 0.5f) / width, 1.0f - (y + 0.5f) / height, closest, c);
                for (int k = 0; k < 3; ++k)  // (OIIO's byte to float may be an ulp from value / 255)
                    ASSERT_NEAR(c[k], float(uint8_t(x * 7 + y * 13 + k * 5)) / 255.0f, 1e-7f)
                        << width << " " << x << "," << y;
            }
    }
}

TEST(MemoryImages, KeyedImagesOutliveTheirStoreUntilANewerVersion) {
    const std::string v1 = "MemoryImagesTest|img\nv1", v2 = "MemoryImagesTest|img\nv2";
    const size_t held_before = MemoryImages::instance().retained_count();
    std::vector<float> first;
    {
        TextureStore store(64);
        const uint32_t id = store.add_bytes("img", 3, 2, 4, kBytes.data(), v1);
        first = lookups(store, id, TextureLookup{});
        EXPECT_EQ(store.reused(), 0u);
    }
    EXPECT_EQ(MemoryImages::instance().retained_count(), held_before + 1);
    {
        TextureStore store(64);
        uint32_t id = 0;
        EXPECT_FALSE(store.add_retained("img", v2, id));
        ASSERT_TRUE(store.add_retained("img", v1, id));
        EXPECT_EQ(store.reused(), 1u);
        EXPECT_EQ(store.buffer_bytes(), kBytes.size());
        EXPECT_EQ(lookups(store, id, TextureLookup{}), first);
        // A newer version while v1 is still in use: v1 goes when released.
        std::vector<uint8_t> changed = kBytes;
        changed[0] = 0;
        store.add_bytes("img", 3, 2, 4, changed.data(), v2);
        EXPECT_EQ(MemoryImages::instance().retained_count(), held_before + 2);
    }
    EXPECT_EQ(MemoryImages::instance().retained_count(), held_before + 1);
    TextureStore store(64);
    uint32_t id = 0;
    EXPECT_FALSE(store.add_retained("img", v1, id));
    EXPECT_TRUE(store.add_retained("img", v2, id));
}

TEST(MemoryImages, AReusedImageWarnsAboutItsNonFiniteValuesAgain) {
    const std::string key = "MemoryImagesTest|nan\n1";
    const float pixels[4] = {0.5f, NAN, INFINITY, 1.0f};
    for (int render = 0; render < 2; ++render) {
        TextureStore store(64);
        uint32_t id = 0;
        if (render == 0) id = store.add_pixels("Material 'm', node 'n'", 1, 1, 4, pixels, key);
        else ASSERT_TRUE(store.add_retained("Material 'm', node 'n'", key, id));
        ASSERT_EQ(store.warnings().size(), 1u) << render;
        EXPECT_NE(store.warnings()[0].find("2 NaN or infinite"), std::string::npos) << store.warnings()[0];
        float c[4];
        store.lookup(id, 0.5f, 0.5f, TextureLookup{}, c);
        EXPECT_EQ(c[1], 0.0f);
        EXPECT_EQ(c[2], 0.0f);
    }
}

TEST(MemoryImages, UnusedRetainedBuffersStayWithinTheLimit) {
    MemoryImages& images = MemoryImages::instance();
    auto buffer = std::make_shared<PixelBuffer>();
    buffer->width = buffer->height = buffer->channels = 1;
    buffer->bytes = {42};
    images.set_retention_limit(0);  // drops every unused buffer earlier tests left
    EXPECT_EQ(images.release(images.add(buffer, "LimitTest|flush\n1").name).size(), 1u);
    const size_t held_before = images.retained_count();
    const std::string a = images.add(buffer, "LimitTest|a\n1").name, b = images.add(buffer, "LimitTest|b\n1").name;
    images.set_retention_limit(1);  // one byte: room for one unused buffer
    EXPECT_TRUE(images.release(a).empty());
    const std::vector<std::string> dropped = images.release(b);  // the least recently used goes
    ASSERT_EQ(dropped.size(), 1u);
    EXPECT_EQ(dropped[0], a);
    EXPECT_EQ(images.retained_count(), held_before + 1);
    EXPECT_EQ(images.reuse("LimitTest|a\n1"), "");
    EXPECT_EQ(images.reuse("LimitTest|b\n1"), b);
    images.release(b);
    images.set_retention_limit(size_t(1024) << 20);
}

// Texel buffers of 2 MiB and more start on a huge-page boundary (so the
// kernel can back them with transparent huge pages); smaller ones are
// ordinary allocations. Either way every byte is usable.
TEST(MemoryImages, LargePixelBuffersStartOnAHugePageBoundary) {
    PixelBuffer big, small;
    big.bytes.resize(size_t(3) << 20, 7);
    small.bytes.resize(1000, 9);
    EXPECT_EQ(reinterpret_cast<uintptr_t>(big.bytes.data()) % (size_t(2) << 20), 0u);
    EXPECT_EQ(big.bytes.front() + big.bytes.back(), 14);
    EXPECT_EQ(small.bytes.front() + small.bytes.back(), 18);
    PixelBuffer copy = big;  // the allocator travels with the buffer
    EXPECT_EQ(reinterpret_cast<uintptr_t>(copy.bytes.data()) % (size_t(2) << 20), 0u);
    EXPECT_EQ(copy.bytes, big.bytes);
}

}  // namespace
}  // namespace coherent
