// Shared by the bench executables (one per bench/*.cpp): progress on
// stderr, the standard ray sets (primary, AO, diffuse bounce) generated from
// our own closest hits, and CPU-time measurement. Every bench that compares
// traversal methods replays these same rays through each method.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <functional>
#include <string>
#include <vector>

#include "accel/bvh.h"
#include "core/ray.h"
#include "core/thread_time.h"
#include "core/vec.h"
#include "io/gltf.h"
#include "scene/scene.h"

namespace coherent::bench {

// ---- progress on stderr -----------------------------------------------------

class Progress {
public:
    explicit Progress(std::string phase) : phase_(std::move(phase)), tty_(isatty(STDERR_FILENO)) {
        if (!tty_) std::fprintf(stderr, "%s...\n", phase_.c_str());
        else update(0.0);
    }
    void update(double fraction) {
        if (!tty_) return;
        std::fprintf(stderr, "\r  %-40s %5.1f%%", phase_.c_str(), 100.0 * fraction);
        std::fflush(stderr);
    }
    ~Progress() {
        if (tty_) std::fprintf(stderr, "\r  %-40s done  \n", phase_.c_str());
    }

private:
    std::string phase_;
    bool tty_;
};

// ---- ray generation ---------------------------------------------------------

// Integer-ulp offset along n (Waechter & Binder 2019, Ray Tracing Gems ch. 6).
inline Vec3f offset_origin(const Vec3f& p, const Vec3f& n) {
    constexpr float kOrigin = 1.0f / 32.0f, kFloatScale = 1.0f / 65536.0f, kIntScale = 256.0f;
    Vec3f out;
    for (int a = 0; a < 3; ++a) {
        const int32_t of = static_cast<int32_t>(kIntScale * n[a]);
        const float pa = p[a];
        int32_t bits;
        std::memcpy(&bits, &pa, 4);
        bits += pa < 0.0f ? -of : of;
        float moved;
        std::memcpy(&moved, &bits, 4);
        out[a] = std::fabs(pa) < kOrigin ? pa + kFloatScale * n[a] : moved;
    }
    return out;
}

// Small counter-based generator: the same numbers for a given (stream, index)
// regardless of threads (PCG-style hash of a 64-bit counter).
struct Rng {
    uint64_t state;
    explicit Rng(uint64_t seed) : state(seed * 0x9E3779B97F4A7C15ull + 0x2545F4914F6CDD1Dull) {}
    float next() {
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        uint32_t x = static_cast<uint32_t>(((state >> 18u) ^ state) >> 27u);
        const uint32_t rot = static_cast<uint32_t>(state >> 59u);
        x = (x >> rot) | (x << ((32 - rot) & 31));
        return static_cast<float>(x >> 8) * 0x1p-24f;
    }
};

inline Vec3f cosine_direction(const Vec3f& n, float u1, float u2) {
    const float r = std::sqrt(u1), phi = 2.0f * kPi * u2;
    const float x = r * std::cos(phi), y = r * std::sin(phi), z = std::sqrt(std::max(0.0f, 1.0f - u1));
    Vec3f t, b;
    make_basis(n, t, b);
    return t * x + b * y + n * z;
}

struct RaySets {
    std::vector<Ray> primary, ao, diffuse;
};

inline RaySets make_rays(const Scene& scene, const Bvh& bvh, int width, int height, int ao_samples) {
    RaySets s;
    const Camera& cam = scene.camera;
    const int w = width, h = height;
    s.primary.resize(static_cast<size_t>(w) * h);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const float sx = (2.0f * (x + 0.5f) / w - 1.0f) * cam.half_width;
            const float sy = (1.0f - 2.0f * (y + 0.5f) / h) * cam.half_height;
            Ray r;
            if (cam.projection == Projection::Orthographic) {
                r.o = cam.position + cam.right * sx + cam.up * sy;
                r.d = cam.forward;
            } else {
                r.o = cam.position;
                r.d = cam.forward + cam.right * sx + cam.up * sy;
            }
            r.tmin = 0.0f;
            r.tmax = kInf;
            s.primary[static_cast<size_t>(y) * w + x] = r;
        }

    std::vector<Hit> hits(s.primary.size());
    {
        Progress p("generating secondary rays");
        tbb::parallel_for(size_t(0), s.primary.size(), [&](size_t i) { bvh.intersect(s.primary[i], hits[i]); });
    }
    const BBox bounds = scene.bounds();
    const float ao_radius = 0.1f * length(bounds.extent());
    for (size_t i = 0; i < hits.size(); ++i) {
        const Hit& hit = hits[i];
        if (!hit.valid()) continue;
        const Vec3f* v = &scene.vertices[3 * size_t(hit.prim)];
        Vec3f n = cross(v[1] - v[0], v[2] - v[0]);
        const float len = length(n);
        if (!(len > 0.0f) || !std::isfinite(len)) continue;
        n = n / len;
        if (dot(n, s.primary[i].d) > 0.0f) n = -n;  // face the incoming ray
        const Vec3f p = v[0] * (1.0f - hit.u - hit.v) + v[1] * hit.u + v[2] * hit.v;
        const Vec3f o = offset_origin(p, n);
        Rng rng(i);
        for (int k = 0; k < ao_samples; ++k) {
            const float u1 = rng.next(), u2 = rng.next();
            Ray r;
            r.o = o;
            r.d = cosine_direction(n, u1, u2);
            r.tmax = ao_radius;
            s.ao.push_back(r);
        }
        const float u1 = rng.next(), u2 = rng.next();
        Ray r;
        r.o = o;
        r.d = cosine_direction(n, u1, u2);
        s.diffuse.push_back(r);
    }
    return s;
}

// ---- timing -------------------------------------------------------------------

// Runs `body(begin, end)` over [0, n) on `threads` threads (blocks of rays).
// `grain`: the smallest block handed to one task (items that are themselves
// big, e.g. whole streams or waves, want 1).
inline void run_blocks(size_t n, int threads, const std::function<void(size_t, size_t)>& body, size_t grain = 1024) {
    if (threads == 1) {
        body(0, n);
        return;
    }
    tbb::task_arena arena(threads);
    arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n, grain),
                          [&](const tbb::blocked_range<size_t>& r) { body(r.begin(), r.end()); });
    });
}

inline double wall_seconds() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Best time of `runs` runs of the whole ray set: thread CPU time with one
// thread (all work runs on this thread), wall time with several.
inline double best_seconds(int runs, int threads, const std::string& label, const std::function<void()>& once) {
    double best = kInf;
    Progress p(label);
    for (int i = 0; i < runs; ++i) {
        const double start = threads == 1 ? thread_cpu_seconds() : wall_seconds();
        once();
        const double end = threads == 1 ? thread_cpu_seconds() : wall_seconds();
        best = std::min(best, end - start);
        p.update(double(i + 1) / runs);
    }
    return best;
}

// Loads a glTF scene for a bench (camera aspect width / height) and
// finalizes it, showing progress; on failure prints "TOOL: cannot load PATH:
// why" and returns false.
inline bool load_scene(const std::string& path, float aspect, const char* tool, Scene& scene) {
    Progress p("loading " + path);
    const GltfLoadResult res = load_gltf(path, scene, aspect);
    if (!res.ok) {
        std::fprintf(stderr, "%s: cannot load %s: %s\n", tool, path.c_str(), res.error.c_str());
        return false;
    }
    scene.finalize();
    return true;
}

}  // namespace coherent::bench
