// wide-bench: tree width (2/4/8 single-ray kernels) and breadth-first ray
// streams (batch-size sweep) against Embree 3 rtcIntersect1/rtcOccluded1,
// on the same rays (bench_common.h: primary, AO, diffuse bounce).
//
//   wide-bench SCENE.glb [--threads N] [--width W] [--height H] [--runs R]
//              [--ao-samples S] [--batches 256,1024,...] [--only primary|ao|diffuse]
//              [--csv FILE]
//
// One BVH build per width (same binary tree: the build is deterministic; only
// the traversal layout differs). Every method traces every ray of a set; the
// bench checks that each returns bit-identical hits (t, u, v, prim) and the
// same occlusion as the 8-wide single-ray kernel, and prints the count of
// mismatches (0 expected). Timing: best of R runs; one thread: the thread's
// CPU time; several: wall time (singles over blocks of 1024 rays, streams
// over batches, both in a TBB arena of N threads).
//
// Counters (untimed pass): box and triangle tests per ray, node visits per
// ray (single rays: wide nodes + leaves; width 2: binary nodes), rays per
// node visit (streams: the mean queue length processed at a visit), and the
// fraction of queue entries the early-out array culled.
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "accel/bvh.h"
#include "accel/ray_stream.h"
#include "bench_common.h"
#include "io/gltf.h"
#include "scene/scene.h"
#ifdef COHERENT_HAVE_EMBREE
#include "accel/embree_reference.h"
#endif

using namespace coherent;
using namespace coherent::bench;

namespace {

struct Options {
    std::string scene_path;
    int threads = 1;
    int width = 1024;
    int height = 768;
    int runs = 3;
    int ao_samples = 4;
    std::vector<size_t> batches{256, 1024, 4096, 16384, 65536};
    std::string only;
    std::string csv;
};

[[noreturn]] void usage(const char* msg) {
    if (msg) std::fprintf(stderr, "wide-bench: %s\n", msg);
    std::fprintf(stderr,
                 "usage: wide-bench SCENE.glb [--threads N] [--width W] [--height H] [--runs R] [--ao-samples S]\n"
                 "                  [--batches 256,1024,...] [--only primary|ao|diffuse] [--csv FILE]\n");
    std::exit(2);
}

long parse_long(const char* s, const char* name, long lo, long hi) {
    char* end = nullptr;
    const long v = std::strtol(s, &end, 10);
    if (!end || *end || v < lo || v > hi) {
        std::fprintf(stderr, "wide-bench: %s must be an integer in [%ld, %ld], got '%s'\n", name, lo, hi, s);
        std::exit(2);
    }
    return v;
}

Options parse(int argc, char** argv) {
    Options o;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto value = [&](const char* name) {
            if (i + 1 >= argc) usage((std::string(name) + " needs a value").c_str());
            return argv[++i];
        };
        if (a == "--threads") o.threads = int(parse_long(value("--threads"), "--threads", 1, 1024));
        else if (a == "--width") o.width = int(parse_long(value("--width"), "--width", 1, 16384));
        else if (a == "--height") o.height = int(parse_long(value("--height"), "--height", 1, 16384));
        else if (a == "--runs") o.runs = int(parse_long(value("--runs"), "--runs", 1, 100));
        else if (a == "--ao-samples") o.ao_samples = int(parse_long(value("--ao-samples"), "--ao-samples", 1, 1024));
        else if (a == "--only") o.only = value("--only");
        else if (a == "--csv") o.csv = value("--csv");
        else if (a == "--batches") {
            o.batches.clear();
            std::stringstream ss(value("--batches"));
            std::string item;
            while (std::getline(ss, item, ','))
                o.batches.push_back(size_t(parse_long(item.c_str(), "--batches", 1, 1L << 26)));
            if (o.batches.empty()) usage("--batches needs at least one size");
        } else if (a == "-h" || a == "--help") usage(nullptr);
        else if (!a.empty() && a[0] == '-') usage(("unknown option " + a).c_str());
        else if (o.scene_path.empty()) o.scene_path = a;
        else usage("more than one scene given");
    }
    if (o.scene_path.empty()) usage("no scene given");
    return o;
}

struct Row {
    std::string rays, method;
    int width = 0;       // tree width (streams: 8)
    size_t batch = 0;    // streams only
    double mrays = 0.0;
    double box = -1, tri = -1, visits = -1, rays_per_visit = -1, culled = -1;
    long long mismatches = -1;  // against the 8-wide single-ray kernel; -1: not compared (Embree)
};

bool same_bits(const Hit& a, const Hit& b) {
    return a.prim == b.prim && std::memcmp(&a.t, &b.t, 4) == 0 && std::memcmp(&a.u, &b.u, 4) == 0 &&
           std::memcmp(&a.v, &b.v, 4) == 0;
}

}  // namespace

int main(int argc, char** argv) {
    const Options opt = parse(argc, argv);
    const std::string name = std::filesystem::path(opt.scene_path).stem().string();

    Scene scene;
    if (!load_scene(opt.scene_path, float(opt.width) / float(opt.height), "wide-bench", scene)) return 1;
    const size_t tris = scene.vertices.size() / 3;
    if (tris == 0) {
        std::fprintf(stderr, "wide-bench: %s has no triangles\n", opt.scene_path.c_str());
        return 1;
    }

    tbb::task_arena arena(opt.threads);
    const int widths[3] = {2, 4, 8};
    Bvh bvh[3];
    for (int w = 0; w < 3; ++w) {
        Progress p("building BVH, width " + std::to_string(widths[w]));
        BvhBuildOptions bo;
        bo.width = widths[w];
        arena.execute([&] { bvh[w].build(scene, bo); });
    }
    const Bvh& ref = bvh[2];
    std::printf("scene %s: %zu triangles, %d x %d, %d thread(s), best of %d\n", name.c_str(), tris, opt.width,
                opt.height, opt.threads, opt.runs);
    std::printf("  nodes: binary %zu, 4-wide %zu, 8-wide %zu; visit estimate 4-wide %.2f, 8-wide %.2f\n",
                bvh[0].build_stats().nodes, bvh[1].build_stats().wide4_nodes, bvh[2].build_stats().wide_nodes,
                bvh[1].build_stats().wide_node_visit_estimate, bvh[2].build_stats().wide_node_visit_estimate);

#ifdef COHERENT_HAVE_EMBREE
    const std::string config = "threads=" + std::to_string(opt.threads);
    std::unique_ptr<EmbreeReference> embree;
    {
        Progress p("building Embree scene (high quality)");
        embree = std::make_unique<EmbreeReference>(scene.vertices.data(), tris, config.c_str(), false,
                                                   RTC_BUILD_QUALITY_HIGH);
    }
#endif

    const RaySets sets = make_rays(scene, ref, opt.width, opt.height, opt.ao_samples);
    std::printf("  rays: primary %zu, ao %zu (%d per hit), diffuse %zu\n", sets.primary.size(), sets.ao.size(),
                opt.ao_samples, sets.diffuse.size());

    struct SetDesc {
        const char* name;
        const std::vector<Ray>* rays;
        bool occlusion;
    };
    const SetDesc descs[] = {{"primary", &sets.primary, false}, {"ao", &sets.ao, true}, {"diffuse", &sets.diffuse, false}};
    std::vector<Row> rows;
    for (const SetDesc& set : descs) {
        const std::vector<Ray>& rays = *set.rays;
        const size_t n = rays.size();
        if (n == 0 || (!opt.only.empty() && opt.only != set.name)) continue;

        // The reference answers: 8-wide single rays.
        std::vector<Hit> expected(n);
        std::vector<uint8_t> expected_occ(n);
        for (size_t i = 0; i < n; ++i) {
            if (set.occlusion) expected_occ[i] = ref.occluded(rays[i]);
            else if (!ref.intersect(rays[i], expected[i])) expected[i] = Hit{};
        }
        std::vector<Hit> hits(n);
        std::vector<uint8_t> occ(n);
        auto mismatches = [&] {
            size_t m = 0;
            for (size_t i = 0; i < n; ++i)
                m += set.occlusion ? (occ[i] != expected_occ[i]) : !same_bits(hits[i], expected[i]);
            return m;
        };

        // Single rays, width 2 / 4 / 8.
        for (int w = 0; w < 3; ++w) {
            const Bvh& b = bvh[w];
            const int width = widths[w];
            const char* method = "single";
            TraversalCounters c;
            for (size_t i = 0; i < n; ++i) {
                Hit h;
                if (set.occlusion) b.occluded(rays[i], &c);
                else b.intersect(rays[i], h, &c);
            }
            const double secs = best_seconds(
                opt.runs, opt.threads, std::string(set.name) + ": " + method + ", width " + std::to_string(width), [&] {
                    arena.execute([&] {
                        run_blocks(n, opt.threads, [&](size_t lo, size_t hi) {
                            if (set.occlusion)
                                for (size_t i = lo; i < hi; ++i) occ[i] = b.occluded(rays[i]);
                            else
                                for (size_t i = lo; i < hi; ++i)
                                    if (!b.intersect(rays[i], hits[i])) hits[i] = Hit{};
                        });
                    });
                });
            Row r{set.name, method, width, 0, n / secs * 1e-6};
            r.box = double(c.box_tests) / n;
            r.tri = double(c.triangle_tests) / n;
            r.visits = double(c.node_visits) / n;
            r.rays_per_visit = 1.0;
            r.mismatches = static_cast<long long>(mismatches());
            rows.push_back(r);
        }

        // Streams over the 8-wide layout, batch-size sweep.
        for (size_t batch : opt.batches) {
            StreamOptions so;
            so.slice_size = batch;
            so.parallel = opt.threads > 1;
            StreamStats st;
            if (set.occlusion) occluded_stream(ref, rays.data(), n, occ.data(), &st, so);
            else intersect_stream(ref, rays.data(), n, hits.data(), &st, so);
            const double secs = best_seconds(
                opt.runs, opt.threads, std::string(set.name) + ": stream, batch " + std::to_string(batch), [&] {
                    arena.execute([&] {
                        if (set.occlusion) occluded_stream(ref, rays.data(), n, occ.data(), nullptr, so);
                        else intersect_stream(ref, rays.data(), n, hits.data(), nullptr, so);
                    });
                });
            Row r{set.name, "stream", 8, batch, n / secs * 1e-6};
            r.box = st.box_tests_per_ray();
            r.tri = st.triangle_tests_per_ray();
            r.visits = double(st.ray_node_visits) / n;
            r.rays_per_visit = st.rays_per_visit();
            r.culled = st.ray_node_visits + st.culled ? double(st.culled) / double(st.ray_node_visits + st.culled) : 0.0;
            r.mismatches = static_cast<long long>(mismatches());
            rows.push_back(r);
        }

#ifdef COHERENT_HAVE_EMBREE
        {
            const double secs = best_seconds(opt.runs, opt.threads, std::string(set.name) + ": embree", [&] {
                run_blocks(n, opt.threads, [&](size_t lo, size_t hi) {
                    if (set.occlusion)
                        for (size_t i = lo; i < hi; ++i) occ[i] = embree->occluded(rays[i]);
                    else
                        for (size_t i = lo; i < hi; ++i) {
                            hits[i] = Hit{};
                            embree->intersect(rays[i], hits[i]);
                        }
                });
            });
            Row r{set.name, "embree", 0, 0, n / secs * 1e-6};
            // Embree may pick another triangle on exact ties and round t
            // differently: not bit-identical by design, so not counted.
            rows.push_back(r);
        }
#endif
    }

    // Table and CSV. ratio = Mrays/s over Embree's on the same ray set.
    FILE* csv = nullptr;
    if (!opt.csv.empty()) {
        const bool exists = std::filesystem::exists(opt.csv);
        csv = std::fopen(opt.csv.c_str(), "a");
        if (!csv) {
            std::fprintf(stderr, "wide-bench: cannot write %s\n", opt.csv.c_str());
            return 1;
        }
        if (!exists)
            std::fprintf(csv, "scene,rays,threads,method,width,batch,mrays_per_s,ratio_vs_embree,box_tests_per_ray,"
                              "triangle_tests_per_ray,node_visits_per_ray,rays_per_node_visit,culled_fraction,"
                              "mismatches\n");
    }
    std::printf("\n  %-8s %-7s %5s %6s %9s %7s %8s %8s %9s %10s %7s %6s\n", "rays", "method", "width", "batch",
                "Mrays/s", "ratio", "box/ray", "tri/ray", "visit/ray", "rays/visit", "culled", "diffs");
    for (const Row& r : rows) {
        double embree_mrays = -1;
        for (const Row& o : rows)
            if (o.rays == r.rays && o.method == "embree") embree_mrays = o.mrays;
        const double ratio = embree_mrays > 0 ? r.mrays / embree_mrays : -1;
        std::printf("  %-8s %-7s %5d %6zu %9.3f %7.3f %8.1f %8.1f %9.1f %10.1f %7.3f %6lld\n", r.rays.c_str(),
                    r.method.c_str(), r.width, r.batch, r.mrays, ratio, r.box, r.tri, r.visits, r.rays_per_visit,
                    r.culled, r.mismatches);
        if (csv)
            std::fprintf(csv, "%s,%s,%d,%s,%d,%zu,%.4f,%.4f,%.2f,%.2f,%.2f,%.2f,%.4f,%lld\n", name.c_str(),
                         r.rays.c_str(), opt.threads, r.method.c_str(), r.width, r.batch, r.mrays, ratio, r.box,
                         r.tri, r.visits, r.rays_per_visit, r.culled, r.mismatches);
    }
    if (csv) std::fclose(csv);
    long long total_mismatches = 0;
    for (const Row& r : rows) total_mismatches += std::max(0LL, r.mismatches);
    if (total_mismatches) {
        std::fprintf(stderr, "wide-bench: %lld results differ from the 8-wide single-ray kernel\n", total_mismatches);
        return 3;
    }
    return 0;
}
