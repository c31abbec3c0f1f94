// Memory accounting and the check before a render's large allocations
// (render/memory_budget.h): sizes parse and print, a render over its limit
// fails before building with an error naming the sizes, the BVH estimate
// bounds what a build really holds, and the statistics report sane sizes.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "denoise/denoiser.h"
#include "render/memory_budget.h"
#include "render/renderer.h"
#include "test_render_helpers.h"
#include "bvh_test_meshes.h"

namespace coherent {
namespace {

using test::sphere_on_floor_scene;
using testing_meshes::random_soup;

// Sets an environment variable for one scope.
class ScopedEnv {
public:
    ScopedEnv(const char* name, const char* value) : name_(name) {
        if (const char* old = std::getenv(name)) old_ = old, had_ = true;
        ::setenv(name, value, 1);
    }
    ~ScopedEnv() { had_ ? ::setenv(name_, old_.c_str(), 1) : ::unsetenv(name_); }

private:
    const char* name_;
    std::string old_;
    bool had_ = false;
};

uint64_t status_bytes(const std::string& key) {
    std::ifstream in("/proc/self/status");
    std::string line;
    while (std::getline(in, line))
        if (line.rfind(key + ":", 0) == 0) return std::stoull(line.substr(key.size() + 1)) * 1024;
    return 0;
}

RenderSettings small_render() {
    RenderSettings rs;
    rs.width = 32;
    rs.height = 24;
    rs.spp = 2;
    return rs;
}

TEST(MemoryBudget, ParsesAndFormatsSizes) {
    EXPECT_EQ(parse_byte_size("1000000"), 1000000u);
    EXPECT_EQ(parse_byte_size("512M"), 512ull << 20);
    EXPECT_EQ(parse_byte_size("2G"), 2ull << 30);
    EXPECT_EQ(parse_byte_size("1.5GiB"), 3ull << 29);
    EXPECT_EQ(parse_byte_size("64 KB"), 64ull << 10);
    EXPECT_EQ(parse_byte_size("3t"), 3ull << 40);
    for (const char* bad : {"", "G", "-1G", "0", "12Q", "1e30", "nan", "2GG"})
        EXPECT_THROW(parse_byte_size(bad), std::invalid_argument) << bad;
    EXPECT_EQ(format_bytes(900), "900 B");
    EXPECT_EQ(format_bytes(12ull << 20), "12.0 MiB");
    EXPECT_EQ(format_bytes(3ull << 29), "1.5 GiB");
}

TEST(MemoryBudget, CheckComparesTheRightPartWithTheLimit) {
    MemoryEstimate e;
    e.scene = 1000;
    e.bvh = 500;
    e.film = 100;
    e.triangles = 10;
    // Available memory: the scene is already resident, only BVH + film must fit.
    EXPECT_NO_THROW(check_memory(e, {600, false, "free"}));
    EXPECT_THROW(check_memory(e, {599, false, "free"}), OutOfMemoryBudget);
    // A budget covers the whole render.
    EXPECT_NO_THROW(check_memory(e, {1600, true, "budget"}));
    EXPECT_THROW(check_memory(e, {1599, true, "budget"}), OutOfMemoryBudget);
    EXPECT_NO_THROW(check_memory(e, {0, false, "unknown"}));  // nothing known: no check
}

TEST(MemoryBudget, WithoutABudgetTheLimitIsTheAvailableMemory) {
    ScopedEnv no_budget("COHERENT_MEMORY_LIMIT", "");  // empty: no budget
    const MemoryLimit limit = memory_limit();
    std::ifstream meminfo("/proc/meminfo");
    std::string key;
    uint64_t available_kib = 0;
    while (meminfo >> key && key != "MemAvailable:") meminfo.ignore(256, '\n');
    meminfo >> available_kib;
    ASSERT_GT(available_kib, 0u);
    EXPECT_FALSE(limit.whole_render);
    EXPECT_GT(limit.bytes, 0u);
    // MemAvailable moves between the two reads; the cgroup may only lower it.
    EXPECT_LE(limit.bytes, available_kib * 1024 + (256u << 20)) << limit.source;
    EXPECT_TRUE(limit.source.find("MemAvailable") != std::string::npos ||
                limit.source.find("cgroup") != std::string::npos) << limit.source;
}

TEST(MemoryBudget, ARenderOverTheLimitFailsBeforeBuildingAndNamesTheSizes) {
    const Scene scene = sphere_on_floor_scene();
    ScopedEnv limit("COHERENT_MEMORY_LIMIT", "64K");
    try {
        Renderer r(scene, small_render());
        FAIL() << "a render of " << scene.triangle_count() << " triangles fit in 64 KiB";
    } catch (const OutOfMemoryBudget& e) {
        const std::string message = e.what();
        EXPECT_NE(message.find("COHERENT_MEMORY_LIMIT=64K"), std::string::npos) << message;
        EXPECT_NE(message.find("64.0 KiB"), std::string::npos) << message;
        EXPECT_NE(message.find(std::to_string(scene.triangle_count()) + " triangles"), std::string::npos) << message;
        EXPECT_NE(message.find("BVH "), std::string::npos) << message;
    }
}

TEST(MemoryBudget, AMalformedLimitIsAnErrorNamingTheVariable) {
    const Scene scene = sphere_on_floor_scene();
    ScopedEnv limit("COHERENT_MEMORY_LIMIT", "lots");
    try {
        Renderer r(scene, small_render());
        FAIL() << "COHERENT_MEMORY_LIMIT=lots was accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("COHERENT_MEMORY_LIMIT: 'lots'"), std::string::npos) << e.what();
    }
}

// Resets the resident-set high-water mark to the current RSS (clear_refs 5,
// Linux 4.0+) and returns that RSS, so that VmHWM - it is what runs next
// takes at its peak; 0 (after a failure) when it could not be reset.
uint64_t reset_peak_rss() {
    {
        std::ofstream reset("/proc/self/clear_refs");
        reset << "5";
        if (!reset.good()) {
            ADD_FAILURE() << "cannot reset the peak RSS through /proc/self/clear_refs";
            return 0;
        }
    }
    const uint64_t before = status_bytes("VmRSS");
    if (status_bytes("VmHWM") > before + (1u << 20)) {
        ADD_FAILURE() << "the peak RSS was not reset";
        return 0;
    }
    return before;
}

// The estimate must bound the memory a build really takes at its peak, or
// the check would let through renders that then fail in the build. Measured
// as the growth of the resident-set high-water mark over the build, after
// resetting it (clear_refs 5, Linux 4.0+), on a random soup whose large
// overlapping triangles make spatial-split duplicates (measured: 214-232
// bytes per triangle at the peak for triangle sizes 0.2 to 4, 72-84 kept).
TEST(MemoryBudget, BvhEstimateBoundsThePeakOfARealBuild) {
    constexpr size_t kTriangles = 60000;
    const std::vector<Vec3f> soup = random_soup(kTriangles, 7, 10.0f, 1.0f);
    const uint64_t before = reset_peak_rss();
    ASSERT_GT(before, 0u);
    Bvh bvh;
    bvh.build(soup);
    const uint64_t peak = status_bytes("VmHWM") - before;
    const uint64_t estimate = bvh_build_bytes_estimate(kTriangles);
    EXPECT_GE(estimate, peak) << "the build's peak grew the RSS by " << peak << " bytes";
    EXPECT_GE(estimate, bvh.build_stats().bytes);
    // ... and not so far above it that the check refuses scenes that fit.
    EXPECT_LE(estimate, 3 * std::max<uint64_t>(peak, bvh.build_stats().bytes)) << "peak " << peak;
}

TEST(MemoryBudget, RenderStatsReportTheSizes) {
    const Scene scene = sphere_on_floor_scene();
    Renderer r(scene, small_render());
    ASSERT_TRUE(r.render());
    const MemoryStats& m = r.stats().memory;
    EXPECT_EQ(m.triangles, scene.triangle_count());
    EXPECT_EQ(m.bvh_bytes, r.bvh().build_stats().bytes);
    // At least the vertices, 36 bytes per triangle.
    EXPECT_GE(m.scene_bytes, scene.triangle_count() * 3 * sizeof(Vec3f));
    EXPECT_EQ(m.film_bytes, film_bytes(small_render()));
    EXPECT_EQ(m.film_bytes, r.film().bytes());
    ASSERT_TRUE(m.bytes_per_triangle());
    EXPECT_GT(*m.bytes_per_triangle(), 36.0);
    EXPECT_LT(*m.bytes_per_triangle(), 2000.0);
    EXPECT_GE(m.estimate_bytes, m.scene_bytes + m.bvh_bytes + m.film_bytes);
    EXPECT_GT(m.limit_bytes, 0u);  // MemAvailable is known on Linux
    EXPECT_GE(m.peak_rss_bytes, m.scene_bytes + m.bvh_bytes);
}

// The film's estimate is what the film then holds, byte for byte, whatever
// its settings enable: the check sees the passes, the denoising features
// and the denoised image as well as Combined.
TEST(MemoryBudget, FilmEstimateIsWhatTheFilmHolds) {
    const Scene scene = sphere_on_floor_scene();
    std::vector<std::pair<const char*, RenderSettings>> cases;
    RenderSettings rs = small_render();
    cases.emplace_back("plain", rs);
    rs.heatmaps = true;
    cases.emplace_back("heatmaps", rs);
    rs = small_render();
    rs.denoise = true;
    cases.emplace_back("denoised", rs);
    rs = small_render();
    rs.denoising_data = true;
    rs.passes = pass_mask_from_names({"diffdir", "glossind", "mist", "uv", "vector"});  // DiffCol, GlossCol come too
    cases.emplace_back("features and passes", rs);
    rs = small_render();
    rs.cryptomatte = (1u << int(CryptoType::Object)) | (1u << int(CryptoType::Material));
    rs.cryptomatte_levels = 5;  // rounded up to 6 slots
    cases.emplace_back("cryptomatte", rs);
    uint64_t plain = 0;
    for (const auto& [name, settings] : cases) {
        Renderer r(scene, settings);
        ASSERT_TRUE(r.render()) << name;
        EXPECT_EQ(film_bytes(settings), r.film().bytes()) << name;
        EXPECT_EQ(r.stats().memory.film_bytes, r.film().bytes()) << name;
        if (!plain) plain = r.film().bytes();
        else EXPECT_GT(r.film().bytes(), plain) << name;
    }
}

// The denoiser's estimate bounds what a real denoise takes at its peak (the
// resident-set high-water mark's growth, reset first as for the BVH build
// above) and is not far above it, or the check would refuse renders that fit.
TEST(MemoryBudget, DenoiserEstimateBoundsThePeakOfARealDenoise) {
    constexpr int kWidth = 640, kHeight = 480;
    Film film(kWidth, kHeight);
    film.enable_denoising_features();
    for (uint32_t pass = 0; pass < 2; ++pass)
        for (int y = 0; y < kHeight; ++y)
            for (int x = 0; x < kWidth; ++x) {
                const Vec3f c(float((x * 7 + y * 13 + int(pass) * 5) % 17) / 17.0f);
                film.add_sample(x, y, c, 1.0f, 1.0f, Vec3f(0.0f, 0.0f, -1.0f), pass);
                film.add_denoising_features(x, y, Vec3f(0.5f), Vec3f(0.0f, 0.0f, -1.0f), 1.0f, pass);
                film.add_direct_light(x, y, c * 0.5f, pass);
            }
    const uint64_t before = reset_peak_rss();
    ASSERT_GT(before, 0u);
    const DenoiseResult d = denoise(film);
    ASSERT_EQ(d.rgb.size(), size_t(3 * kWidth * kHeight));
    const uint64_t peak = status_bytes("VmHWM") - before;
    const uint64_t estimate = denoise_working_bytes(kWidth, kHeight);
    std::printf("denoise %dx%d: peak RSS growth %.1f MiB, estimate %.1f MiB\n", kWidth, kHeight,
                double(peak) / (1 << 20), double(estimate) / (1 << 20));
    EXPECT_GE(estimate, peak);
    EXPECT_LE(estimate, 3 * peak);
}

}  // namespace
}  // namespace coherent
