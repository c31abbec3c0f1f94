// The wavefront pipeline (render/wavefront.h): its ambient occlusion equals
// a straightforward per-pixel AO loop over Bvh::intersect / Bvh::occluded
// with the same random numbers, bit for bit; its path tracing equals the
// depth-first driver (trace_path); every reorder mode, gathered or not,
// single rays or packets, gives the same image; the rays it traces are the
// same rays (same counts and traversal work); and its memory is bounded by
// the wave size, not the image.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "render/light_sampling.h"
#include "render/path_tracer.h"
#include "render/wavefront.h"
#include "sample/image_sampler.h"
#include "test_render_helpers.h"

namespace coherent {
namespace {

using test::add_quad;
using test::add_sphere;
using test::diffuse_material;
using test::emission_material;
using test::principled;

// Occluders of every kind AO and path tracing care about (contact
// occlusion, mirror, glass, an area light) and background around them.
Scene wave_scene() { return test::lobes_scene(false, 9.0f); }

RenderSettings wave_settings(Integrator integrator) {
    RenderSettings rs;
    rs.width = 37;  // odd sizes: waves end mid-row
    rs.height = 29;
    rs.spp = 2;
    rs.seed = 11;
    rs.integrator = integrator;
    rs.ao_samples = 8;
    rs.max_bounces = 6;
    return rs;
}

// One image: every pixel's PathOutput of every pass, pass-major.
using Image = std::vector<PathOutput>;

struct WaveSetup {
    const Scene& scene;
    RenderSettings rs;
    Bvh bvh;
    LightSet lights;
    PathContext ctx;
    SamplerConfig cfg;
    WaveSetup(const Scene& s, const RenderSettings& settings) : scene(s), rs(settings), lights(s), ctx{} {
        bvh.build(scene);
        ctx = PathContext{&scene, &bvh, &lights, &rs};
        ctx.ao_distance = resolve_ao_distance(rs, scene);
        cfg.type = rs.resolved_sampler();
        cfg.seed = rs.seed;
        cfg.dims = PathDims::count(rs.max_bounces);
    }
    size_t index(int pass, int x, int y) const {
        return (size_t(pass) * size_t(rs.height) + size_t(y)) * size_t(rs.width) + size_t(x);
    }
};

// The scene has glass and lights, no depth of field: the kernel <true, false, true>.
Image render_wavefront(WaveSetup& su, const WavefrontOptions& opt, RenderStats* stats = nullptr,
                       WavefrontStats* wstats = nullptr) {
    Image img(size_t(su.rs.spp) * size_t(su.rs.width) * size_t(su.rs.height));
    std::vector<int> written(img.size(), 0);
    WavefrontRenderer wr(su.ctx, opt, true, false, true);
    RenderStats st;
    for (int pass = 0; pass < su.rs.spp; ++pass) {
        const ImageSampler sampler(su.cfg, uint32_t(pass), 1);
        const bool ok = wr.render_pass(
            sampler, uint32_t(pass), 0, 0, su.rs.width, su.rs.height, {},
            [&](int x, int y, const PathOutput& o, uint32_t) {
                img[su.index(pass, x, y)] = o;
                ++written[su.index(pass, x, y)];
            },
            st);
        EXPECT_TRUE(ok);
    }
    for (int w : written) EXPECT_EQ(w, 1);  // every pixel output exactly once
    if (stats) *stats = st;
    if (wstats) *wstats = wr.stats();
    return img;
}

// The depth-first reference driver.
Image render_single(WaveSetup& su, RenderStats* stats = nullptr) {
    Image img(size_t(su.rs.spp) * size_t(su.rs.width) * size_t(su.rs.height));
    RenderStats st;
    for (int pass = 0; pass < su.rs.spp; ++pass) {
        const ImageSampler sampler(su.cfg, uint32_t(pass), 1);
        for (int y = 0; y < su.rs.height; ++y)
            for (int x = 0; x < su.rs.width; ++x) {
                const PathSampler ps(sampler, uint32_t(x), uint32_t(y), uint32_t(pass));
                img[su.index(pass, x, y)] = trace_path<true, false, true>(su.ctx, ps, x, y, st);
            }
    }
    if (stats) *stats = st;
    return img;
}

// Ambient occlusion written out directly: camera ray, closest hit, geometric
// normal facing the camera, ao_samples cosine rays from the offset hit point
// (ray_offset.h), fraction unoccluded; a miss is unoccluded (1). Shares only
// primitives with the engine (camera ray, offset, cosine warp), not the
// path state machine.
Image render_ao_oracle(WaveSetup& su) {
    const Scene& scene = su.scene;
    Image img(size_t(su.rs.spp) * size_t(su.rs.width) * size_t(su.rs.height));
    for (int pass = 0; pass < su.rs.spp; ++pass) {
        const ImageSampler sampler(su.cfg, uint32_t(pass), 1);
        for (int y = 0; y < su.rs.height; ++y)
            for (int x = 0; x < su.rs.width; ++x) {
                const auto stream = sampler.stream(uint32_t(x), uint32_t(y), uint32_t(pass));
                const float fx = float(x) + stream.get(PathDims::kPixelX);
                const float fy = float(y) + stream.get(PathDims::kPixelY);
                const Ray cam =
                    generate_camera_ray<false>(scene.camera, fx, fy, su.rs.width, su.rs.height, 0.5f, 0.5f).ray;
                Hit hit;
                PathOutput& o = img[su.index(pass, x, y)];
                if (!su.bvh.intersect(cam, hit)) {
                    o.radiance = Vec3f(1.0f);
                    continue;
                }
                const Vec3f* v = &scene.vertices[3 * size_t(hit.prim)];
                Vec3f err;
                const Vec3f p = triangle_point(v[0], v[1], v[2], hit.u, hit.v, err);
                Vec3f n = scene.geometric_normals[hit.prim];
                if (dot(n, cam.d) > 0.0f) n = -n;
                const Vec3f origin = offset_ray_origin(p, err, n, n);
                Vec3f t, b;
                make_basis(n, t, b);
                int unoccluded = 0;
                for (int i = 0; i < su.rs.ao_samples; ++i) {
                    const float u1 = stream.get(PathDims::bounce(i, PathDims::kBsdfU));
                    const float u2 = stream.get(PathDims::bounce(i, PathDims::kBsdfV));
                    // The engine's cosine warp (concentric disk): the same
                    // numbers must give the same directions for bit equality.
                    const Vec3f local = sample_cosine_hemisphere(u1, u2);
                    Ray ao;
                    ao.o = origin;
                    ao.d = t * local.x + b * local.y + n * local.z;
                    ao.tmin = std::numeric_limits<float>::min();
                    ao.tmax = su.ctx.ao_distance;
                    unoccluded += su.bvh.occluded(ao) ? 0 : 1;
                }
                o.radiance = Vec3f(float(unoccluded) / float(su.rs.ao_samples));
            }
    }
    return img;
}

bool same_bits(float a, float b) { return std::memcmp(&a, &b, sizeof(float)) == 0; }
bool same_bits(const Vec3f& a, const Vec3f& b) { return same_bits(a.x, b.x) && same_bits(a.y, b.y) && same_bits(a.z, b.z); }

// Number of samples whose outputs differ in any bit.
size_t differing(const Image& a, const Image& b, bool radiance_only = false) {
    EXPECT_EQ(a.size(), b.size());
    size_t d = 0;
    for (size_t i = 0; i < a.size() && i < b.size(); ++i) {
        bool same = same_bits(a[i].radiance, b[i].radiance);
        if (!radiance_only)
            same = same && same_bits(a[i].alpha, b[i].alpha) && same_bits(a[i].depth, b[i].depth) &&
                   same_bits(a[i].normal, b[i].normal);
        d += same ? 0 : 1;
    }
    return d;
}

constexpr ReorderMode kModes[] = {ReorderMode::None,   ReorderMode::Static1D, ReorderMode::Static3D,
                                  ReorderMode::Hash32, ReorderMode::Hash192,  ReorderMode::Csd32};

TEST(Wavefront, AoEqualsStraightforwardPerPixelAo) {
    const Scene scene = wave_scene();
    RenderSettings rs = wave_settings(Integrator::AmbientOcclusion);
    rs.ao_distance = 2.5f;  // long enough that spheres and wall occlude the floor widely
    WaveSetup su(scene, rs);
    const Image oracle = render_ao_oracle(su);
    // The image is not trivial: some AO rays are occluded, some pixels miss.
    size_t partial = 0, background = 0;
    for (const PathOutput& o : oracle) {
        partial += (o.radiance.x > 0.0f && o.radiance.x < 1.0f) ? 1 : 0;
        background += std::isinf(o.depth) ? 1 : 0;
    }
    EXPECT_GT(partial, oracle.size() / 10);
    EXPECT_GT(background, 0u);
    for (ReorderMode mode : kModes) {
        WavefrontOptions opt;
        opt.reorder = mode;
        opt.wave_size = 100;  // several waves, the last one partial
        const Image img = render_wavefront(su, opt);
        EXPECT_EQ(differing(img, oracle, true), 0u) << reorder_name(mode);
    }
}

TEST(Wavefront, EveryModeEqualsTheDepthFirstDriver) {
    const Scene scene = wave_scene();
    for (Integrator integrator : {Integrator::AmbientOcclusion, Integrator::PathTrace, Integrator::Whitted}) {
        WaveSetup su(scene, wave_settings(integrator));
        RenderStats ref_stats;
        const Image ref = render_single(su, &ref_stats);
        for (ReorderMode mode : kModes)
            for (int variant = 0; variant < 4; ++variant) {
                WavefrontOptions opt;
                opt.reorder = mode;
                opt.wave_size = variant == 3 ? 1 : 257;
                opt.gather = variant != 1;
                opt.packet_size = variant == 2 ? 8 : 0;
                opt.reorder_camera_rays = variant == 2;
                if (variant == 3 && mode != ReorderMode::Hash32) continue;  // wave of 1 path: slow, one mode
                RenderStats st;
                const Image img = render_wavefront(su, opt, &st);
                EXPECT_EQ(differing(img, ref), 0u)
                    << integrator_name(integrator) << " " << reorder_name(mode) << " variant " << variant;
                // The same rays were traced: same counts by type, and for single
                // rays the same traversal work.
                for (size_t t = 0; t < size_t(RayType::Count); ++t)
                    EXPECT_EQ(st.rays[t], ref_stats.rays[t]) << ray_type_name(RayType(t));
                if (opt.packet_size == 0) {
                    EXPECT_EQ(st.traversal.node_visits, ref_stats.traversal.node_visits);
                    EXPECT_EQ(st.traversal.triangle_tests, ref_stats.traversal.triangle_tests);
                }
                for (int b = 0; b < kStatBounces; ++b) EXPECT_EQ(st.bounces[b].rays, ref_stats.bounces[b].rays);
            }
    }
}

TEST(Wavefront, MemoryIsBoundedByTheWaveNotTheImage) {
    const Scene scene = wave_scene();
    WavefrontOptions opt;
    opt.reorder = ReorderMode::Csd32;
    opt.wave_size = 64;
    size_t peak[2] = {0, 0};
    for (int k = 0; k < 2; ++k) {
        RenderSettings rs = wave_settings(Integrator::AmbientOcclusion);
        rs.width = rs.height = k == 0 ? 24 : 96;  // 16x the pixels
        rs.spp = 1;
        WaveSetup su(scene, rs);
        WavefrontStats ws;
        render_wavefront(su, opt, nullptr, &ws);
        EXPECT_EQ(ws.max_paths, 64u);
        EXPECT_EQ(ws.waves, uint64_t((rs.width * rs.height + 63) / 64));
        peak[k] = ws.peak_bytes;
        // Per path: its state, sampler and pixel, plus at most ao_samples
        // occlusion rays with their tags, keys, order and results; a generous
        // constant per ray, but one that does not grow with the image.
        const size_t per_ray = sizeof(Ray) * 2 + sizeof(RayTag) + 64;
        const size_t bound = size_t(opt.wave_size) *
                                 (sizeof(PathState) + 128 + size_t(rs.ao_samples + 1) * per_ray) +
                             sizeof(RayPacket) + sizeof(HitPacket) + 64 * 1024;  // + radix histograms
        EXPECT_LE(ws.peak_bytes, bound);
        EXPECT_GT(ws.bytes_per_path(), double(sizeof(PathState)));
    }
    // The 16x larger image needs no more memory (vector growth may differ by
    // rounding only if a wave's ray count differs; allow 2x).
    EXPECT_LE(peak[1], 2 * peak[0] + 4096);
}

TEST(Wavefront, SkipAndCancel) {
    const Scene scene = wave_scene();
    WaveSetup su(scene, wave_settings(Integrator::AmbientOcclusion));
    WavefrontOptions opt;
    opt.wave_size = 50;
    WavefrontRenderer wr(su.ctx, opt, true, false, true);
    const ImageSampler sampler(su.cfg, 0, 1);
    RenderStats st;
    int outputs = 0;
    // Skipped pixels are neither traced nor output.
    EXPECT_TRUE(wr.render_pass(sampler, 0, 0, 0, su.rs.width, su.rs.height, [](int x, int) { return x % 2 == 0; },
                               [&](int x, int, const PathOutput&, uint32_t) {
                                   EXPECT_EQ(x % 2, 1);
                                   ++outputs;
                               },
                               st));
    EXPECT_EQ(outputs, (su.rs.width / 2) * su.rs.height);
    EXPECT_EQ(st.rays[size_t(RayType::Camera)], uint64_t(outputs));
    // A cancelled pass returns false and outputs nothing.
    std::atomic<bool> cancelled{true};
    outputs = 0;
    EXPECT_FALSE(wr.render_pass(sampler, 0, 0, 0, su.rs.width, su.rs.height, {},
                                [&](int, int, const PathOutput&, uint32_t) { ++outputs; }, st, &cancelled));
    EXPECT_EQ(outputs, 0);
}

}  // namespace
}  // namespace coherent
