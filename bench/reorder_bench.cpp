// reorder-bench: paper 004's Table 1 / Fig. 6 on our scenes. Ray-cast
// ambient occlusion (1 camera ray + S AO rays per pixel) through the
// wavefront pipeline (render/wavefront.h) with every reordering mode, and
// the reorder cost of whole-frame ray sets (plain radix sort vs
// compress-sort-decompress, radix vs comparison sort).
//
//   reorder-bench [SCENE.glb ...] [--width W] [--height H] [--ao-samples S]
//                 [--threads 1,2] [--wave-sizes 65536] [--modes none,static1d,...]
//                 [--runs R] [--packet N] [--no-gather] [--digit-bits B]
//                 [--key-layout direction|origin]
//                 [--skip-render] [--skip-sort] [--csv PREFIX]
//
// Experiments (one CSV row each, `experiment` column):
//   render  one AO frame through the wavefront per (scene, threads, wave
//           size, mode): total time (`seconds`: 1 thread: thread CPU seconds
//           of the whole pass; 2+ threads: wall seconds), the CPU seconds of
//           all threads in the pipeline (`cpu_seconds`, the best-of-R key),
//           and the CPU seconds spent tracing and reordering inside it. Every mode must produce the
//           same image (checked: the bench aborts otherwise).
//   sort    the reorder step alone on the frame's AO rays at once, as the
//           paper sorts them: `full` = width x height x S slots in pixel
//           order, background pixels' slots holding an identical null ray
//           (the paper's layout, where c.s.d. wins); `compact` = only the
//           rays of pixels that hit (our wavefront's layout). One thread,
//           thread CPU seconds, best of R.
// Defaults: the three public scenes, 1024 x 1024, S = 16, threads 1 and 2,
// wave size 65536, all modes, R = 3, single-ray tracing with gather.
#include <tbb/enumerable_thread_specific.h>

#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "bench_common.h"
#include "io/gltf.h"
#include "render/light_sampling.h"
#include "render/ray_reorder.h"
#include "render/wavefront.h"
#include "sample/image_sampler.h"

using namespace coherent;
using namespace coherent::bench;

namespace {

struct Options {
    std::vector<std::string> scenes;
    int width = 1024, height = 1024, ao_samples = 16, runs = 3, packet = 0, digit_bits = 8;
    std::vector<int> threads{1, 2};
    std::vector<int> wave_sizes{1 << 16};
    std::vector<ReorderMode> modes{ReorderMode::None,   ReorderMode::Static1D, ReorderMode::Static3D,
                                   ReorderMode::Hash32, ReorderMode::Hash192,  ReorderMode::Csd32};
    bool gather = true, render = true, sort = true;
    Key32Layout layout = Key32Layout::DirectionMajor;
    std::string csv;
};

std::vector<std::string> split(const std::string& s) {
    std::vector<std::string> out;
    std::stringstream ss(s);
    std::string item;
    while (std::getline(ss, item, ',')) out.push_back(item);
    return out;
}

[[noreturn]] void usage(const char* msg) {
    std::fprintf(stderr, "reorder-bench: %s\n", msg);
    std::exit(2);
}

Options parse(int argc, char** argv) {
    Options o;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto next = [&]() -> std::string {
            if (i + 1 >= argc) usage(("missing value after " + a).c_str());
            return argv[++i];
        };
        if (a == "--width") o.width = std::stoi(next());
        else if (a == "--height") o.height = std::stoi(next());
        else if (a == "--ao-samples") o.ao_samples = std::stoi(next());
        else if (a == "--runs") o.runs = std::max(1, std::stoi(next()));
        else if (a == "--packet") o.packet = std::stoi(next());
        else if (a == "--digit-bits") o.digit_bits = std::stoi(next());
        else if (a == "--no-gather") o.gather = false;
        else if (a == "--key-layout") {
            const std::string v = next();
            if (v == "direction") o.layout = Key32Layout::DirectionMajor;
            else if (v == "origin") o.layout = Key32Layout::OriginMajor;
            else usage("--key-layout: direction or origin");
        }
        else if (a == "--skip-render") o.render = false;
        else if (a == "--skip-sort") o.sort = false;
        else if (a == "--csv") o.csv = next();
        else if (a == "--threads") {
            o.threads.clear();
            for (const auto& t : split(next())) o.threads.push_back(std::stoi(t));
        } else if (a == "--wave-sizes") {
            o.wave_sizes.clear();
            for (const auto& t : split(next())) o.wave_sizes.push_back(std::stoi(t));
        } else if (a == "--modes") {
            o.modes.clear();
            for (const auto& t : split(next())) {
                const auto m = parse_reorder(t);
                if (!m) usage(("unknown mode " + t).c_str());
                o.modes.push_back(*m);
            }
        } else if (a.rfind("--", 0) == 0) usage(("unknown option " + a).c_str());
        else o.scenes.push_back(a);
    }
    if (o.scenes.empty())
        for (const char* s : {"crytek_sponza", "stanford_dragon", "stanford_bunny"})
            o.scenes.push_back(std::string("../shared/scenes/") + s + ".glb");
    return o;
}

std::string scene_name(const std::string& path) {
    std::string n = path.substr(path.find_last_of('/') + 1);
    return n.substr(0, n.find('.'));
}

// CSV files PREFIX_render.csv and PREFIX_sort.csv (--csv PREFIX); rows also go to stdout.
std::string g_csv_prefix;
std::map<std::string, FILE*> g_csv;
void row(const std::string& line) {
    std::printf("%s\n", line.c_str());
    std::fflush(stdout);
    if (g_csv_prefix.empty()) return;
    const std::string kind = line.substr(0, line.find(','));
    const std::string experiment = kind == "experiment" ? (line.find(",layout,") != std::string::npos ? "sort" : "render") : kind;
    FILE*& f = g_csv[experiment];
    if (!f) f = std::fopen((g_csv_prefix + "_" + experiment + ".csv").c_str(), "w");
    if (!f) usage(("cannot write " + g_csv_prefix + "_" + experiment + ".csv").c_str());
    std::fprintf(f, "%s\n", line.c_str());
    std::fflush(f);
}

// FNV-1a over the AO image's bits: every mode must give the same image.
uint64_t image_hash(const std::vector<float>& v) {
    uint64_t h = 1469598103934665603ull;
    const auto* bytes = reinterpret_cast<const unsigned char*>(v.data());
    for (size_t i = 0; i < v.size() * sizeof(float); ++i) h = (h ^ bytes[i]) * 1099511628211ull;
    return h;
}

struct RenderResult {
    double seconds = 0.0;  // 1 thread: thread CPU; else wall
    WavefrontStats wave;   // summed over threads
    RenderStats stats;
    uint64_t hash = 0;
};

RenderResult render_ao(const PathContext& ctx, const SamplerConfig& cfg, const Options& o, int threads,
                       const WavefrontOptions& wopt) {
    const int w = o.width, h = o.height;
    std::vector<float> image(size_t(w) * size_t(h), -1.0f);
    const ImageSampler sampler(cfg, 0, 1);
    auto output = [&](int x, int y, const PathOutput& out, uint32_t) { image[size_t(y) * size_t(w) + size_t(x)] = out.radiance.x; };
    RenderResult r;
    if (threads == 1) {
        WavefrontRenderer wr(ctx, wopt, false, false, false);
        const double t0 = thread_cpu_seconds();
        wr.render_pass(sampler, 0, 0, 0, w, h, {}, output, r.stats);
        r.seconds = thread_cpu_seconds() - t0;
        r.wave = wr.stats();
    } else {
        // Bands of whole rows, about one wave each, one renderer per thread.
        const int band = std::max(1, wopt.wave_size / w);
        const int bands = (h + band - 1) / band;
        tbb::enumerable_thread_specific<std::unique_ptr<WavefrontRenderer>> renderers;
        tbb::enumerable_thread_specific<RenderStats> stats;
        tbb::task_arena arena(threads);
        const double t0 = wall_seconds();
        arena.execute([&] {
            tbb::parallel_for(tbb::blocked_range<int>(0, bands, 1), [&](const tbb::blocked_range<int>& rg) {
                auto& wr = renderers.local();
                if (!wr) wr = std::make_unique<WavefrontRenderer>(ctx, wopt, false, false, false);
                for (int b = rg.begin(); b != rg.end(); ++b)
                    wr->render_pass(sampler, 0, 0, b * band, w, std::min(h, (b + 1) * band), {}, output, stats.local());
            });
        });
        r.seconds = wall_seconds() - t0;
        for (auto& wr : renderers) {
            const WavefrontStats& s = wr->stats();
            r.wave.reorder += s.reorder;
            r.wave.trace_seconds += s.trace_seconds;
            r.wave.total_seconds += s.total_seconds;
            r.wave.waves += s.waves;
            r.wave.rays += s.rays;
            r.wave.max_paths = std::max(r.wave.max_paths, s.max_paths);
            r.wave.peak_bytes = std::max(r.wave.peak_bytes, s.peak_bytes);
        }
        for (const RenderStats& s : stats) r.stats += s;
    }
    r.hash = image_hash(image);
    return r;
}

void render_experiment(const std::string& name, const PathContext& ctx, const SamplerConfig& cfg, const Options& o) {
    for (int threads : o.threads)
        for (int wave : o.wave_sizes) {
            double none_seconds = 0.0, none_trace = 0.0, none_cpu = 0.0;
            uint64_t reference_hash = 0;
            for (ReorderMode mode : o.modes) {
                WavefrontOptions wopt;
                wopt.reorder = mode;
                wopt.wave_size = wave;
                wopt.gather = o.gather;
                wopt.packet_size = o.packet;
                wopt.counters = false;  // timing only; the counters are the same rays in any order
                wopt.sort.digit_bits = o.digit_bits;
                wopt.sort.key32_layout = o.layout;
                RenderResult best;
                best.seconds = kInf;
                {
                    Progress p(name + " render " + std::string(reorder_name(mode)) + " t" + std::to_string(threads) +
                               " w" + std::to_string(wave));
                    for (int run = 0; run < o.runs; ++run) {
                        RenderResult r = render_ao(ctx, cfg, o, threads, wopt);
                        // Best run by CPU seconds: on a shared machine wall
                        // time with 2+ threads mostly measures the neighbours.
                        if (best.seconds == kInf || r.wave.total_seconds < best.wave.total_seconds) best = r;
                        p.update(double(run + 1) / o.runs);
                    }
                }
                if (reference_hash == 0) reference_hash = best.hash;
                if (best.hash != reference_hash) {
                    std::fprintf(stderr, "reorder-bench: %s gives a different image than %s\n",
                                 std::string(reorder_name(mode)).c_str(), std::string(reorder_name(o.modes[0])).c_str());
                    std::exit(1);
                }
                const double reorder_s = best.wave.reorder.total();
                if (mode == ReorderMode::None) {
                    none_seconds = best.seconds;
                    none_trace = best.wave.trace_seconds;
                    none_cpu = best.wave.total_seconds;
                }
                char buf[1024];
                std::snprintf(buf, sizeof buf,
                              "render,%s,%d,%d,%d,%s,%s,%d,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%llu,%llu,%.1f,%.3f,%.3f,"
                              "%016llx,%.4f,%.3f",
                              name.c_str(), threads, wave, o.packet, std::string(reorder_name(mode)).c_str(),
                              o.layout == Key32Layout::OriginMajor ? "origin" : "direction", reorder_key_bits(mode), best.seconds, best.wave.trace_seconds, reorder_s,
                              best.wave.reorder.key_seconds, best.wave.reorder.compress_seconds,
                              best.wave.reorder.sort_seconds, best.wave.reorder.decompress_seconds,
                              (unsigned long long)best.wave.rays, (unsigned long long)best.wave.reorder.sorted_elements,
                              best.wave.bytes_per_path(), none_seconds > 0 ? none_seconds / best.seconds : 0.0,
                              none_trace > 0 ? none_trace / best.wave.trace_seconds : 0.0,
                              (unsigned long long)best.hash, best.wave.total_seconds,
                              none_cpu > 0 ? none_cpu / best.wave.total_seconds : 0.0);
                row(buf);
            }
        }
}

// The frame's AO rays at once: camera hits first (untimed), then the rays
// in pixel order, 16 per pixel. full: background pixels keep their 16 slots
// with a null ray (origin 0, direction 0: one shared key), as in a GPU
// pipeline with fixed ray slots; compact: only hit pixels' rays.
void sort_experiment(const std::string& name, const PathContext& ctx, const SamplerConfig& cfg, const Options& o) {
    const int w = o.width, h = o.height, S = o.ao_samples;
    const ImageSampler sampler(cfg, 0, 1);
    std::vector<Ray> full, compact;
    std::vector<RayTag> full_tags, compact_tags;
    {
        Progress p(name + " AO rays of the frame");
        full.reserve(size_t(w) * size_t(h) * size_t(S));
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                const PathSampler ps(sampler, uint32_t(x), uint32_t(y), 0);
                PathState s;
                start_path<false>(ctx, ps, x, y, s);
                Hit hit;
                const bool found = ctx.bvh->intersect(s.ray, hit);
                shade_hit<false, false>(ctx, ps, s, found, hit);
                for (int k = 0; k < S; ++k) {
                    const RayTag tag{uint16_t(x), uint16_t(y), uint32_t(k + 1)};
                    if (k < s.ao_rays) {
                        const Ray r = ao_ray(ctx, ps, s, k);
                        full.push_back(r);
                        compact.push_back(r);
                        compact_tags.push_back(tag);
                    } else {
                        Ray null_ray;
                        null_ray.o = Vec3f(0.0f);
                        null_ray.d = Vec3f(0.0f);
                        null_ray.tmax = 0.0f;
                        full.push_back(null_ray);
                    }
                    full_tags.push_back(tag);
                }
            }
    }
    for (int layout = 0; layout < 2; ++layout) {
        const std::vector<Ray>& rays = layout == 0 ? full : compact;
        const std::vector<RayTag>& tags = layout == 0 ? full_tags : compact_tags;
        for (ReorderMode mode : o.modes) {
            if (mode == ReorderMode::None) continue;
            for (SortAlgorithm alg : {SortAlgorithm::Radix, SortAlgorithm::Comparison}) {
                for (int bits : {8, 11}) {
                    if (alg == SortAlgorithm::Comparison && bits != 8) continue;
                    ReorderOptions ropt;
                    ropt.sort = alg;
                    ropt.digit_bits = bits;
                    ropt.key32_layout = o.layout;
                    ReorderWorkspace ws;
                    std::vector<uint32_t> order;
                    ReorderTimings best;
                    double best_total = kInf;
                    double gather_best = kInf;
                    std::vector<Ray> gathered(rays.size());
                    Progress p(name + " sort " + (layout == 0 ? "full " : "compact ") + std::string(reorder_name(mode)) +
                               (alg == SortAlgorithm::Radix ? " radix" + std::to_string(bits) : " comparison"));
                    for (int run = 0; run < o.runs; ++run) {
                        ReorderTimings t;
                        compute_ray_order(rays.data(), tags.data(), rays.size(), mode, ws, order, &t, ropt);
                        if (t.total() < best_total) {
                            best_total = t.total();
                            best = t;
                        }
                        // Moving whole rays into the order once (what sorting
                        // rays instead of indices would save at best).
                        const double g0 = thread_cpu_seconds();
                        for (size_t j = 0; j < rays.size(); ++j) gathered[j] = rays[order[j]];
                        gather_best = std::min(gather_best, thread_cpu_seconds() - g0);
                        p.update(double(run + 1) / o.runs);
                    }
                    char buf[512];
                    std::snprintf(buf, sizeof buf, "sort,%s,%s,%s,%s,%s,%d,%d,%zu,%zu,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f",
                                  name.c_str(), layout == 0 ? "full" : "compact", std::string(reorder_name(mode)).c_str(),
                                  o.layout == Key32Layout::OriginMajor ? "origin" : "direction",
                                  alg == SortAlgorithm::Radix ? "radix" : "comparison", bits, reorder_key_bits(mode),
                                  rays.size(), best.sorted_elements, best.total(), best.key_seconds,
                                  best.compress_seconds, best.sort_seconds, best.decompress_seconds, gather_best);
                    row(buf);
                }
            }
        }
    }
}

}  // namespace

int main(int argc, char** argv) {
    const Options o = parse(argc, argv);
    g_csv_prefix = o.csv;
    if (o.render)
        row("experiment,scene,threads,wave_size,packet,mode,key_layout,key_bits,seconds,trace_seconds,reorder_seconds,"
            "key_seconds,compress_seconds,sort_seconds,decompress_seconds,rays,sorted_elements,bytes_per_path,"
            "speedup_vs_none,trace_speedup_vs_none,image_hash,cpu_seconds,cpu_speedup_vs_none");
    for (const std::string& path : o.scenes) {
        Scene scene;
        if (!load_scene(path, float(o.width) / float(o.height), "reorder-bench", scene)) return 1;
        Bvh bvh;
        {
            Progress p(scene_name(path) + " BVH");
            bvh.build(scene);
        }
        RenderSettings rs;
        rs.width = o.width;
        rs.height = o.height;
        rs.integrator = Integrator::AmbientOcclusion;
        rs.ao_samples = o.ao_samples;
        rs.spp = 1;
        const LightSet lights(scene);
        PathContext ctx{&scene, &bvh, &lights, &rs};
        ctx.ao_distance = resolve_ao_distance(rs, scene);
        SamplerConfig cfg;
        cfg.type = SamplerType::Spt;
        cfg.dims = PathDims::count(o.ao_samples);
        std::fprintf(stderr, "%s: %zu triangles, AO distance %.4g\n", scene_name(path).c_str(),
                     scene.vertices.size() / 3, ctx.ao_distance);
        if (o.render) render_experiment(scene_name(path), ctx, cfg, o);
        if (o.sort) {
            static bool header = false;
            if (!header) {
                row("experiment,scene,layout,mode,key_layout,sort,digit_bits,key_bits,rays,sorted_elements,reorder_seconds,"
                    "key_seconds,compress_seconds,sort_seconds,decompress_seconds,gather_rays_seconds");
                header = true;
            }
            sort_experiment(scene_name(path), ctx, cfg, o);
        }
    }
    for (auto& [kind, f] : g_csv) std::fclose(f);
    return 0;
}
