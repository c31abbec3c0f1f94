// traversal-table: every way we trace rays, on the same rays, side by side
// with Embree (issue 5's comparison table).
//
//   traversal-table SCENE.glb [--threads N] [--width W] [--height H] [--runs R]
//
// Ray sets: bench_common.h's primary, AO (16 per hit) and diffuse-bounce
// rays. Methods, each tracing every ray of the set:
//   embree-1        Embree rtcIntersect1 / rtcOccluded1 (high-quality build)
//   single-2/4/8    our single-ray traversal, BVH width 2, 4, 8
//   packet          SIMD packets: primary rays in 8x8 pixel blocks, AO and
//                   diffuse rays in runs of 64 consecutive rays (the order
//                   they were generated in: pixel by pixel)
//   stream          breadth-first ray streams of 4096 rays (ray_stream.h)
//   wavefront-X     the wavefront's reorder stage with key X (ray_reorder.h)
//                   followed by single rays in that order; the sort counts
// Output: CSV on stdout, a table on stderr; Mrays/s and the ratio to
// embree-1, best of R runs; thread CPU time with one thread, wall time with more.
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "accel/ray_stream.h"
#include "bench_common.h"
#include "io/gltf.h"
#include "render/ray_reorder.h"
#ifdef COHERENT_HAVE_EMBREE
#include "accel/embree_reference.h"
#endif

using namespace coherent;
using namespace coherent::bench;

namespace {

struct Options {
    std::string scene_path;
    int threads = 1, width = 1024, height = 768, runs = 3;
};

[[noreturn]] void usage(const char* error) {
    if (error) std::fprintf(stderr, "traversal-table: %s\n", error);
    std::fprintf(stderr, "usage: traversal-table SCENE.glb [--threads N] [--width W] [--height H] [--runs R]\n");
    std::exit(error ? 2 : 0);
}

Options parse(int argc, char** argv) {
    Options o;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto value = [&]() {
            if (i + 1 >= argc) usage((a + " needs a value").c_str());
            const int v = std::atoi(argv[++i]);
            if (v < 1) usage((a + " must be a positive integer").c_str());
            return v;
        };
        if (a == "--threads") o.threads = value();
        else if (a == "--width") o.width = value();
        else if (a == "--height") o.height = value();
        else if (a == "--runs") o.runs = value();
        else if (a == "-h" || a == "--help") usage(nullptr);
        else if (!a.empty() && a[0] == '-') usage(("unknown option " + a).c_str());
        else o.scene_path = a;
    }
    if (o.scene_path.empty()) usage("no scene given");
    return o;
}

// Trace one set with one method: closest hit for primary/diffuse, any hit for AO.
using TraceFn = std::function<void(size_t begin, size_t end)>;

}  // namespace

int main(int argc, char** argv) {
    const Options o = parse(argc, argv);
    const std::string name = std::filesystem::path(o.scene_path).stem().string();
    Scene scene;
    if (!load_scene(o.scene_path, float(o.width) / float(o.height), "traversal-table", scene)) return 1;
    Bvh bvh[3];  // widths 2, 4, 8
    const int widths[3] = {2, 4, 8};
    for (int k = 0; k < 3; ++k) {
        bench::Progress p("building BVH, width " + std::to_string(widths[k]));
        BvhBuildOptions opt;
        opt.width = widths[k];
        bvh[k].build(scene, opt);
    }
    const Bvh& wide = bvh[2];
    const RaySets sets = make_rays(scene, wide, o.width, o.height, 16);
#ifdef COHERENT_HAVE_EMBREE
    std::unique_ptr<EmbreeReference> embree;
    {
        bench::Progress p("building Embree scene");
        const std::string config = "threads=" + std::to_string(o.threads);
        embree = std::make_unique<EmbreeReference>(scene.vertices.data(), scene.vertices.size() / 3, config.c_str());
    }
#endif

    std::printf("scene,rays,method,threads,mrays_per_s,ratio_to_embree\n");
    std::fprintf(stderr, "%-9s %-16s %10s %8s\n", "rays", "method", "Mrays/s", "/embree");
    struct Set {
        const char* name;
        const std::vector<Ray>* rays;
        bool occlusion;
        bool pixel_grid;  // rays are the width x height primary grid (packets by pixel block)
    };
    const Set set_list[] = {{"primary", &sets.primary, false, true},
                            {"ao", &sets.ao, true, false},
                            {"diffuse", &sets.diffuse, false, false}};
    for (const Set& set : set_list) {
        const std::vector<Ray>& rays = *set.rays;
        const size_t n = rays.size();
        if (n == 0) continue;
        std::vector<Hit> hits(n);
        std::vector<uint8_t> occluded(n);
        double embree_mrays = -1.0;
        auto report = [&](const std::string& method, double seconds) {
            const double mrays = double(n) / seconds * 1e-6;
            if (method == "embree-1") embree_mrays = mrays;
            const double ratio = embree_mrays > 0 ? mrays / embree_mrays : -1.0;
            std::printf("%s,%s,%s,%d,%.4f,%.4f\n", name.c_str(), set.name, method.c_str(), o.threads, mrays, ratio);
            std::fprintf(stderr, "%-9s %-16s %10.3f %8.3f\n", set.name, method.c_str(), mrays, ratio);
            std::fflush(stdout);
        };
        auto time_blocks = [&](const std::string& method, const std::function<void(size_t, size_t)>& body) {
            report(method, best_seconds(o.runs, o.threads, std::string(set.name) + ": " + method,
                                        [&] { run_blocks(n, o.threads, body); }));
        };
#ifdef COHERENT_HAVE_EMBREE
        time_blocks("embree-1", [&](size_t b, size_t e) {
            for (size_t i = b; i < e; ++i) {
                if (set.occlusion) occluded[i] = embree->occluded(rays[i]);
                else embree->intersect(rays[i], hits[i]);
            }
        });
#endif
        for (int k = 0; k < 3; ++k)
            time_blocks("single-" + std::to_string(widths[k]), [&](size_t b, size_t e) {
                for (size_t i = b; i < e; ++i) {
                    if (set.occlusion) occluded[i] = bvh[k].occluded(rays[i]);
                    else bvh[k].intersect(rays[i], hits[i]);
                }
            });
        // Packets: primary rays by 8x8 pixel blocks; the others by runs of 64.
        {
            std::vector<uint32_t> order(n);
            if (set.pixel_grid) {
                size_t j = 0;
                for (int by = 0; by < o.height; by += 8)
                    for (int bx = 0; bx < o.width; bx += 8)
                        for (int y = by; y < std::min(by + 8, o.height); ++y)
                            for (int x = bx; x < std::min(bx + 8, o.width); ++x) order[j++] = uint32_t(y * o.width + x);
            } else {
                for (size_t i = 0; i < n; ++i) order[i] = uint32_t(i);
            }
            const size_t groups = (n + 63) / 64;
            report("packet", best_seconds(o.runs, o.threads, std::string(set.name) + ": packet", [&] {
                       run_blocks(groups, o.threads, [&](size_t gb, size_t ge) {
                           auto pk = std::make_unique<RayPacket>();
                           auto hp = std::make_unique<HitPacket>();
                           for (size_t g = gb; g < ge; ++g) {
                               pk->clear();
                               const size_t first = g * 64, last = std::min(n, first + 64);
                               for (size_t i = first; i < last; ++i) pk->push(rays[order[i]]);
                               if (set.occlusion) {
                                   OcclusionMask m;
                                   wide.occluded(*pk, m);
                                   for (size_t i = first; i < last; ++i) occluded[order[i]] = m.test(int(i - first));
                               } else {
                                   hp->reset(pk->size);
                                   wide.intersect(*pk, *hp);
                                   for (size_t i = first; i < last; ++i) hits[order[i]] = hp->hit(int(i - first));
                               }
                           }
                       }, 16);
                   }));
        }
        // Streams of 4096 rays (run_blocks hands each task whole streams).
        {
            StreamOptions so;
            so.slice_size = 0;
            so.parallel = false;
            const size_t streams = (n + 4095) / 4096;
            report("stream", best_seconds(o.runs, o.threads, std::string(set.name) + ": stream", [&] {
                       run_blocks(streams, o.threads, [&](size_t sb, size_t se) {
                           for (size_t s = sb; s < se; ++s) {
                               const size_t first = s * 4096, count = std::min(n, first + 4096) - first;
                               if (set.occlusion)
                                   occluded_stream(wide, rays.data() + first, count, occluded.data() + first, nullptr, so);
                               else
                                   intersect_stream(wide, rays.data() + first, count, hits.data() + first, nullptr, so);
                           }
                       }, 1);
                   }));
        }
        // Wavefront reorder stage + single rays in the sorted order, per wave of 65536 rays.
        for (ReorderMode mode : {ReorderMode::Hash32, ReorderMode::Hash192, ReorderMode::Csd32}) {
            const size_t wave = 1 << 16, waves = (n + wave - 1) / wave;
            report(std::string("wavefront-") + std::string(reorder_name(mode)),
                   best_seconds(o.runs, o.threads, std::string(set.name) + ": wavefront", [&] {
                       run_blocks(waves, o.threads, [&](size_t wb, size_t we) {
                           ReorderWorkspace ws;
                           std::vector<uint32_t> order;
                           for (size_t w = wb; w < we; ++w) {
                               const size_t first = w * wave, count = std::min(n, first + wave) - first;
                               compute_ray_order(rays.data() + first, nullptr, count, mode, ws, order);
                               for (uint32_t i : order) {
                                   if (set.occlusion) occluded[first + i] = wide.occluded(rays[first + i]);
                                   else wide.intersect(rays[first + i], hits[first + i]);
                               }
                           }
                       }, 1);
                   }));
        }
    }
    return 0;
}
