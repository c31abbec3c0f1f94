// coherent-bench: single-ray traversal throughput of our BVH against Embree 3
// on the same rays.
//
//   coherent-bench SCENE.glb [--threads N] [--json] [--width W] [--height H]
//                  [--runs R] [--ao-samples S] [--spatial-budget F] [--bvh-width 2|4|8]
//
// Ray sets (all generated once, from our own closest hits, and replayed
// identically through both implementations):
//   primary  1 spp pinhole rays through pixel centres of scene.camera;
//   ao       S (16) cosine-distributed occlusion rays per primary hit, about
//            the geometric normal facing the camera, tmax = 0.1 * scene
//            bounding-box diagonal (the usual "local" AO radius);
//   diffuse  one cosine-distributed closest-hit ray per primary hit.
// Secondary origins are pushed off the surface with the integer-ulp offset of
// Waechter and Binder (Ray Tracing Gems, ch. 6), which scales with the
// magnitude of the hit point, so no ray starts behind its own surface.
//
// Each (ray set, implementation) is timed as the best of R (3) runs. The
// bench reports Mrays/s, the coherent/embree ratio, build times, our bytes per
// triangle, the agreement rate between the two implementations and our
// traversal counters (box and triangle tests per ray).
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "accel/bvh.h"
#include "bench_common.h"
#include "core/ray.h"
#include "core/vec.h"
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
    bool json = false;
    int width = 1024;
    int height = 768;
    int runs = 3;
    int ao_samples = 16;
    float spatial_budget = BvhBuildOptions{}.spatial_split_budget;
    // Build tuning, for experiments (defaults: BvhBuildOptions).
    int bins = BvhBuildOptions{}.bins;
    int max_leaf = BvhBuildOptions{}.max_leaf_size;
    float traversal_cost = BvhBuildOptions{}.traversal_cost;
    float spatial_alpha = BvhBuildOptions{}.spatial_split_alpha;
    bool optimal_collapse = BvhBuildOptions{}.optimal_collapse;
    int bvh_width = BvhBuildOptions{}.width;  // tree width single rays traverse: 2, 4 or 8
    std::string only;  // time only this ray set (empty: all)
};

[[noreturn]] void usage(const char* msg) {
    if (msg) std::fprintf(stderr, "coherent-bench: %s\n", msg);
    std::fprintf(stderr,
                 "usage: coherent-bench SCENE.glb [--threads N] [--json] [--width W] [--height H] [--runs R] "
                 "[--ao-samples S] [--spatial-budget F]\n"
                 "       [--bins B] [--max-leaf L] [--traversal-cost C] [--spatial-alpha A]\n"
                 "       [--greedy-collapse]   (build tuning, for experiments)\n"
                 "       [--bvh-width 2|4|8]   (tree width of the single-ray kernel; default 8)\n"
                 "       [--only primary|ao|diffuse]\n");
    std::exit(2);
}

int parse_int(const char* s, const char* name, int lo, int hi) {
    char* end = nullptr;
    const long v = std::strtol(s, &end, 10);
    if (!end || *end || v < lo || v > hi) {
        std::fprintf(stderr, "coherent-bench: %s must be an integer in [%d, %d], got '%s'\n", name, lo, hi, s);
        std::exit(2);
    }
    return static_cast<int>(v);
}

Options parse(int argc, char** argv) {
    Options o;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto value = [&](const char* name) {
            if (i + 1 >= argc) usage((std::string(name) + " needs a value").c_str());
            return argv[++i];
        };
        if (a == "--json") o.json = true;
        else if (a == "--threads") o.threads = parse_int(value("--threads"), "--threads", 1, 1024);
        else if (a == "--width") o.width = parse_int(value("--width"), "--width", 1, 16384);
        else if (a == "--height") o.height = parse_int(value("--height"), "--height", 1, 16384);
        else if (a == "--runs") o.runs = parse_int(value("--runs"), "--runs", 1, 100);
        else if (a == "--ao-samples") o.ao_samples = parse_int(value("--ao-samples"), "--ao-samples", 1, 1024);
        else if (a == "--spatial-budget") {
            char* end = nullptr;
            const char* v = value("--spatial-budget");
            o.spatial_budget = std::strtof(v, &end);
            if (!end || *end || !(o.spatial_budget >= 0.0f && o.spatial_budget <= 4.0f))
                usage("--spatial-budget must be a number in [0, 4]");
        } else if (a == "--bins") o.bins = parse_int(value("--bins"), "--bins", 2, 64);
        else if (a == "--only") o.only = value("--only");
        else if (a == "--greedy-collapse") o.optimal_collapse = false;
        else if (a == "--bvh-width") {
            o.bvh_width = parse_int(value("--bvh-width"), "--bvh-width", 2, 8);
            if (o.bvh_width != 2 && o.bvh_width != 4 && o.bvh_width != 8) usage("--bvh-width must be 2, 4 or 8");
        }
        else if (a == "--max-leaf") o.max_leaf = parse_int(value("--max-leaf"), "--max-leaf", 1, 64);
        else if (a == "--spatial-alpha") {
            char* end = nullptr;
            const char* v = value("--spatial-alpha");
            o.spatial_alpha = std::strtof(v, &end);
            if (!end || *end || !(o.spatial_alpha >= 0.0f && o.spatial_alpha <= 1.0f))
                usage("--spatial-alpha must be a number in [0, 1]");
        } else if (a == "--traversal-cost") {
            char* end = nullptr;
            const char* v = value("--traversal-cost");
            o.traversal_cost = std::strtof(v, &end);
            if (!end || *end || !(o.traversal_cost > 0.0f && o.traversal_cost < 100.0f))
                usage("--traversal-cost must be a number in (0, 100)");
        } else if (a == "-h" || a == "--help") usage(nullptr);
        else if (!a.empty() && a[0] == '-') usage(("unknown option " + a).c_str());
        else if (o.scene_path.empty()) o.scene_path = a;
        else usage("more than one scene given");
    }
    if (o.scene_path.empty()) usage("no scene given");
    return o;
}

struct Row {
    std::string rays, impl;
    double mrays = 0.0;
    double ratio_avx2 = -1.0;  // coherent rows: against Embree restricted to AVX2
    double agreement = -1.0;  // fraction of rays where both agree (coherent rows)
    double box_tests = -1.0, tri_tests = -1.0;  // per ray (coherent rows)
    double node_visits = -1.0;  // wide nodes + leaves visited per ray (coherent rows)
};

std::string scene_name(const std::string& path) { return std::filesystem::path(path).stem().string(); }

}  // namespace

int main(int argc, char** argv) {
    const Options opt = parse(argc, argv);
    const std::string name = scene_name(opt.scene_path);
    // The console table goes to stdout, or to stderr when stdout carries JSON.
    FILE* table = opt.json ? stderr : stdout;

    Scene scene;
    if (!load_scene(opt.scene_path, float(opt.width) / float(opt.height), "coherent-bench", scene)) return 1;
    const size_t tris = scene.vertices.size() / 3;
    if (tris == 0) {
        std::fprintf(stderr, "coherent-bench: %s has no triangles\n", opt.scene_path.c_str());
        return 1;
    }

    tbb::task_arena arena(opt.threads);
    Bvh bvh;
    {
        Progress p("building coherent BVH");
        BvhBuildOptions bo;
        bo.spatial_split_budget = opt.spatial_budget;
        bo.bins = opt.bins;
        bo.max_leaf_size = opt.max_leaf;
        bo.traversal_cost = opt.traversal_cost;
        bo.spatial_split_alpha = opt.spatial_alpha;
        bo.optimal_collapse = opt.optimal_collapse;
        bo.width = opt.bvh_width;
        arena.execute([&] { bvh.build(scene, bo); });
    }
    const BvhBuildStats& bs = bvh.build_stats();
    std::fprintf(table, "scene %s: %zu triangles, %d x %d, %d thread(s), BVH width %d\n", name.c_str(), tris,
                 opt.width, opt.height, opt.threads, opt.bvh_width);
    std::fprintf(table,
                 "  coherent build: %.3f s, %zu nodes, %zu leaves, depth %d, %.1f bytes/triangle, %zu references "
                 "(spatial-split budget %.2f)\n"
                 "  wide nodes: %zu (%s collapse), SAH estimate of wide-node visits per ray entering the root %.2f\n",
                 bs.seconds, bs.nodes, bs.leaves, bs.depth, double(bs.bytes) / tris, bs.references,
                 double(opt.spatial_budget), bs.wide_nodes, opt.optimal_collapse ? "optimal" : "greedy",
                 bs.wide_node_visit_estimate);
    if (opt.json)
        std::printf("{\"scene\": \"%s\", \"rays\": \"build\", \"impl\": \"coherent\", \"threads\": %d, "
                    "\"build_seconds\": %.4f, \"bytes_per_triangle\": %.2f, \"triangles\": %zu, \"references\": %zu, "
                    "\"spatial_split_budget\": %.2f, \"collapse\": \"%s\", \"wide_nodes\": %zu, "
                    "\"wide_node_visit_estimate\": %.3f}\n",
                    name.c_str(), opt.threads, bs.seconds, double(bs.bytes) / tris, tris, bs.references,
                    double(opt.spatial_budget), opt.optimal_collapse ? "optimal" : "greedy", bs.wide_nodes,
                    bs.wide_node_visit_estimate);

#ifdef COHERENT_HAVE_EMBREE
    const std::string config = "threads=" + std::to_string(opt.threads);
    std::unique_ptr<EmbreeReference> embree;
    {
        Progress p("building Embree scene (high quality)");
        embree = std::make_unique<EmbreeReference>(scene.vertices.data(), tris, config.c_str(), false,
                                                   RTC_BUILD_QUALITY_HIGH);
    }
    std::fprintf(table, "  embree build:   %.3f s (RTC_BUILD_QUALITY_HIGH, %s)\n", embree->build_seconds(),
                 config.c_str());
    if (opt.json)
        std::printf("{\"scene\": \"%s\", \"rays\": \"build\", \"impl\": \"embree\", \"threads\": %d, "
                    "\"build_seconds\": %.4f}\n",
                    name.c_str(), opt.threads, embree->build_seconds());
    // The same build restricted to AVX2 kernels: Embree picks AVX-512 where
    // the CPU has it, while our kernels are AVX2; this is the same-ISA column.
    const std::string config_avx2 = config + ",isa=avx2";
    std::unique_ptr<EmbreeReference> embree_avx2;
    {
        Progress p("building Embree scene (high quality, AVX2)");
        embree_avx2 = std::make_unique<EmbreeReference>(scene.vertices.data(), tris, config_avx2.c_str(), false,
                                                        RTC_BUILD_QUALITY_HIGH);
    }
    std::fprintf(table, "  embree build:   %.3f s (RTC_BUILD_QUALITY_HIGH, %s)\n", embree_avx2->build_seconds(),
                 config_avx2.c_str());
    if (opt.json)
        std::printf("{\"scene\": \"%s\", \"rays\": \"build\", \"impl\": \"embree-avx2\", \"threads\": %d, "
                    "\"build_seconds\": %.4f}\n",
                    name.c_str(), opt.threads, embree_avx2->build_seconds());
#endif

    const RaySets sets = make_rays(scene, bvh, opt.width, opt.height, opt.ao_samples);
    std::fprintf(table, "  timing: best of %d runs, %s\n", opt.runs,
                 opt.threads == 1 ? "thread CPU time (CLOCK_THREAD_CPUTIME_ID)" : "wall time");
    std::fprintf(table, "  rays: primary %zu, ao %zu (%d per hit, tmax %.4g), diffuse %zu\n", sets.primary.size(),
                 sets.ao.size(), opt.ao_samples, 0.1f * length(scene.bounds().extent()), sets.diffuse.size());

    std::vector<Row> rows;
    struct SetDesc {
        const char* name;
        const std::vector<Ray>* rays;
        bool occlusion;
    };
    const SetDesc descs[] = {{"primary", &sets.primary, false}, {"ao", &sets.ao, true}, {"diffuse", &sets.diffuse, false}};
    for (const SetDesc& set : descs) {
        const std::vector<Ray>& rays = *set.rays;
        const size_t n = rays.size();
        if (n == 0 || (!opt.only.empty() && opt.only != set.name)) continue;
        std::vector<Hit> ours(n);
        std::vector<uint8_t> ours_occ(n);

        // Counters come from a separate, untimed pass.
        TraversalCounters counters;
        for (size_t i = 0; i < n; ++i) {
            Hit h;
            if (set.occlusion) bvh.occluded(rays[i], &counters);
            else bvh.intersect(rays[i], h, &counters);
        }

        const double t_ours = best_seconds(opt.runs, opt.threads, std::string(set.name) + ": coherent", [&] {
            run_blocks(n, opt.threads, [&](size_t b, size_t e) {
                if (set.occlusion)
                    for (size_t i = b; i < e; ++i) ours_occ[i] = bvh.occluded(rays[i]);
                else
                    for (size_t i = b; i < e; ++i) {
                        ours[i] = Hit{};
                        bvh.intersect(rays[i], ours[i]);
                    }
            });
        });
        Row ro{set.name, "coherent", n / t_ours * 1e-6};
        ro.box_tests = double(counters.box_tests) / n;
        ro.tri_tests = double(counters.triangle_tests) / n;
        ro.node_visits = double(counters.node_visits) / n;

#ifdef COHERENT_HAVE_EMBREE
        std::vector<Hit> theirs(n);
        std::vector<uint8_t> theirs_occ(n);
        const double t_embree = best_seconds(opt.runs, opt.threads, std::string(set.name) + ": embree", [&] {
            run_blocks(n, opt.threads, [&](size_t b, size_t e) {
                if (set.occlusion)
                    for (size_t i = b; i < e; ++i) theirs_occ[i] = embree->occluded(rays[i]);
                else
                    for (size_t i = b; i < e; ++i) {
                        theirs[i] = Hit{};
                        embree->intersect(rays[i], theirs[i]);
                    }
            });
        });
        // Agreement: same hit/miss; for closest hits also the same t (within
        // 1e-4 relative) -- the triangle may differ only on exact ties.
        size_t agree = 0, only_ours = 0, only_theirs = 0, t_differs = 0;
        for (size_t i = 0; i < n; ++i) {
            const bool a = set.occlusion ? ours_occ[i] != 0 : ours[i].valid();
            const bool b = set.occlusion ? theirs_occ[i] != 0 : theirs[i].valid();
            if (a != b) {
                (a ? only_ours : only_theirs)++;
            } else if (!set.occlusion && a &&
                       std::fabs(ours[i].t - theirs[i].t) > 1e-4f * std::max(1.0f, std::fabs(ours[i].t))) {
                ++t_differs;
            } else {
                ++agree;
            }
        }
        ro.agreement = double(agree) / n;
        const double t_embree_avx2 =
            best_seconds(opt.runs, opt.threads, std::string(set.name) + ": embree (avx2)", [&] {
                run_blocks(n, opt.threads, [&](size_t b, size_t e) {
                    if (set.occlusion)
                        for (size_t i = b; i < e; ++i) theirs_occ[i] = embree_avx2->occluded(rays[i]);
                    else
                        for (size_t i = b; i < e; ++i) {
                            theirs[i] = Hit{};
                            embree_avx2->intersect(rays[i], theirs[i]);
                        }
                });
            });
        ro.ratio_avx2 = t_embree_avx2 / t_ours;
        std::fprintf(table, "  %s: %zu rays, disagreements: hit only by coherent %zu, only by embree %zu, t differs %zu\n",
                     set.name, n, only_ours, only_theirs, t_differs);
        rows.push_back(ro);
        rows.push_back(Row{set.name, "embree", n / t_embree * 1e-6});
        rows.push_back(Row{set.name, "embree-avx2", n / t_embree_avx2 * 1e-6});
#else
        rows.push_back(ro);
#endif
    }

    std::fprintf(table, "\n  %-16s %-8s %-12s %10s %8s %10s %10s %10s %10s %10s\n", "scene", "rays", "impl",
                 "Mrays/s", "ratio", "ratio-avx2", "agree", "box/ray", "tri/ray", "visits/ray");
    for (const Row& r : rows) {
        double ratio = -1.0;
        for (const Row& o : rows)
            if (o.rays == r.rays && o.impl == "embree" && r.impl == "coherent") ratio = r.mrays / o.mrays;
        char ratio_s[16] = "", ratio2_s[16] = "", agree_s[16] = "", box_s[16] = "", tri_s[16] = "",
             visit_s[16] = "";
        if (ratio >= 0) std::snprintf(ratio_s, sizeof ratio_s, "%.2f", ratio);
        if (r.ratio_avx2 >= 0) std::snprintf(ratio2_s, sizeof ratio2_s, "%.2f", r.ratio_avx2);
        if (r.agreement >= 0) std::snprintf(agree_s, sizeof agree_s, "%.5f", r.agreement);
        if (r.box_tests >= 0) std::snprintf(box_s, sizeof box_s, "%.1f", r.box_tests);
        if (r.tri_tests >= 0) std::snprintf(tri_s, sizeof tri_s, "%.1f", r.tri_tests);
        if (r.node_visits >= 0) std::snprintf(visit_s, sizeof visit_s, "%.1f", r.node_visits);
        std::fprintf(table, "  %-16s %-8s %-12s %10.2f %8s %10s %10s %10s %10s %10s\n", name.c_str(),
                     r.rays.c_str(), r.impl.c_str(), r.mrays, ratio_s, ratio2_s, agree_s, box_s, tri_s, visit_s);
        if (opt.json) {
            std::printf("{\"scene\": \"%s\", \"rays\": \"%s\", \"impl\": \"%s\", \"traversal\": \"single\", "
                        "\"threads\": %d, \"mrays_per_s\": %.3f",
                        name.c_str(), r.rays.c_str(), r.impl.c_str(), opt.threads, r.mrays);
            if (r.impl == "coherent") std::printf(", \"bvh_width\": %d", opt.bvh_width);
            if (ratio >= 0) std::printf(", \"ratio_vs_embree\": %.3f", ratio);
            if (r.ratio_avx2 >= 0) std::printf(", \"ratio_vs_embree_avx2\": %.3f", r.ratio_avx2);
            if (r.agreement >= 0) std::printf(", \"agreement\": %.6f", r.agreement);
            if (r.box_tests >= 0)
                std::printf(", \"box_tests_per_ray\": %.2f, \"triangle_tests_per_ray\": %.2f, "
                            "\"node_visits_per_ray\": %.2f",
                            r.box_tests, r.tri_tests, r.node_visits);
            std::printf("}\n");
        }
    }
    std::fflush(stdout);
    return 0;
}
