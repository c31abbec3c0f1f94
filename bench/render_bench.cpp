// render-bench: what coherent path tracing and packets cost and buy, on whole
// renders (the Renderer, not isolated ray sets), one thread, thread CPU time.
//
//   render-bench speed SCENE.glb [--res W H] [--spp N] [--packet WxH] [--max-bounces B] [--runs R]
//       The coherent path tracing paper's Fig. 6 and Fig. 7: for 0..B bounces,
//       SPT with single rays, and SPT, CPT, ICPT with packets: seconds,
//       Mrays/s, SIMD utilisation (box and triangle tests), box and triangle
//       tests per ray. One CSV row per (bounces, method).
//   render-bench assembly SCENE.glb [--res W H] [--spp N] [--packet WxH] [--max-bounces B]
//       The packets paper's Fig. 8: ray-type versus runs assembly, box and
//       triangle tests per ray and SIMD utilisation at each bounce depth.
//   render-bench error SCENE.glb [--res W H] [--spp N] [--reference-spp M] [--packet WxH]
//       Error versus time: relative RMSE against an SPT reference of M spp
//       after 1, 2, 4, ... passes, against the thread CPU seconds spent so
//       far, for SPT single rays, SPT packets, CPT packets and ICPT packets;
//       and the equal-error time: when each method reaches the RMSE SPT single
//       rays reach at N spp.
//
// Output: CSV on stdout (or --csv PATH), a table on stderr. Bounce limits are
// all set to the bounce count and Russian roulette is off, so "b bounces"
// means every path has b + 1 segments unless it escapes (the papers' setup).
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "bench_common.h"
#include "io/gltf.h"
#include "render/renderer.h"

using namespace coherent;
using namespace coherent::bench;

namespace {

struct Options {
    std::string mode, scene_path, csv_path;
    int width = 128, height = 128;
    int spp = 64;
    int reference_spp = 4096;
    int packet_w = 4, packet_h = 4;
    int max_bounces = 4;
    int runs = 1;
    int threads = 1;
    uint64_t seed = 1;
    float min_coherence = RenderSettings{}.packet_min_coherence;
};

[[noreturn]] void usage(const char* error) {
    if (error) std::fprintf(stderr, "render-bench: %s\n", error);
    std::fprintf(stderr,
                 "usage: render-bench speed|assembly|error SCENE.glb [--res W H] [--spp N] [--packet WxH]\n"
                 "                    [--max-bounces B] [--reference-spp M] [--runs R] [--seed S] [--csv PATH]\n"
                 "                    [--min-coherence C]  (packets traced as packets only if |mean direction| >= C)\n");
    std::exit(error ? 2 : 0);
}

int parse_int(const char* s, const char* what, int lo, int hi) {
    char* end = nullptr;
    const long v = std::strtol(s, &end, 10);
    if (!end || *end || v < lo || v > hi) usage((std::string(what) + " must be an integer in [" +
                                                 std::to_string(lo) + ", " + std::to_string(hi) + "]").c_str());
    return int(v);
}

Options parse(int argc, char** argv) {
    Options o;
    if (argc < 3) usage(argc > 1 && (!std::strcmp(argv[1], "-h") || !std::strcmp(argv[1], "--help")) ? nullptr
                                                                                                      : "missing arguments");
    o.mode = argv[1];
    if (o.mode != "speed" && o.mode != "assembly" && o.mode != "error") usage("mode must be speed, assembly or error");
    o.scene_path = argv[2];
    for (int i = 3; i < argc; ++i) {
        const std::string a = argv[i];
        auto value = [&](const char* name) {
            if (i + 1 >= argc) usage((std::string(name) + " needs a value").c_str());
            return argv[++i];
        };
        if (a == "--res") {
            o.width = parse_int(value("--res"), "--res W", 1, 8192);
            o.height = parse_int(value("--res"), "--res H", 1, 8192);
        } else if (a == "--spp") o.spp = parse_int(value("--spp"), "--spp", 1, 1 << 20);
        else if (a == "--reference-spp") o.reference_spp = parse_int(value("--reference-spp"), "--reference-spp", 1, 1 << 24);
        else if (a == "--max-bounces") o.max_bounces = parse_int(value("--max-bounces"), "--max-bounces", 0, 64);
        else if (a == "--runs") o.runs = parse_int(value("--runs"), "--runs", 1, 100);
        else if (a == "--seed") o.seed = uint64_t(parse_int(value("--seed"), "--seed", 0, 1 << 30));
        else if (a == "--csv") o.csv_path = value("--csv");
        else if (a == "--min-coherence") o.min_coherence = std::strtof(value("--min-coherence"), nullptr);
        else if (a == "--packet") {
            const std::string p = value("--packet");
            const size_t x = p.find('x');
            if (x == std::string::npos) usage("--packet must be WxH, e.g. 4x4");
            o.packet_w = parse_int(p.substr(0, x).c_str(), "--packet W", 1, 16);
            o.packet_h = parse_int(p.substr(x + 1).c_str(), "--packet H", 1, 16);
        } else if (a == "-h" || a == "--help") usage(nullptr);
        else usage(("unknown option " + a).c_str());
    }
    return o;
}

struct Method {
    const char* name;
    SamplerType sampler;
    Traversal traversal;
    PacketAssembly assembly = PacketAssembly::RayType;
};

RenderSettings base_settings(const Options& o, int bounces) {
    RenderSettings rs;
    rs.width = o.width;
    rs.height = o.height;
    rs.spp = o.spp;
    rs.seed = o.seed;
    rs.threads = o.threads;
    rs.max_bounces = rs.diffuse_bounces = rs.glossy_bounces = rs.transmission_bounces = bounces;
    rs.rr_min_bounces = 1024;  // no Russian roulette (the table's largest value, above any bounce limit): fixed path lengths
    rs.packet_width = o.packet_w;
    rs.packet_height = o.packet_h;
    rs.packet_min_coherence = o.min_coherence;
    return rs;
}

RenderSettings method_settings(const Options& o, int bounces, const Method& m) {
    RenderSettings rs = base_settings(o, bounces);
    rs.sampler = m.sampler;
    rs.traversal = m.traversal;
    rs.assembly = m.assembly;
    return rs;
}

struct Timed {
    double seconds = kInf;  // best thread CPU seconds
    RenderStats stats;
};

Timed timed_render(const Scene& scene, const RenderSettings& rs, std::shared_ptr<const Bvh> bvh, int runs,
                   const std::string& label) {
    Timed t;
    bench::Progress p(label);
    for (int r = 0; r < runs; ++r) {
        Renderer renderer(scene, rs, bvh);
        const double start = thread_cpu_seconds();
        renderer.render();
        const double s = thread_cpu_seconds() - start;
        if (s < t.seconds) {
            t.seconds = s;
            t.stats = renderer.stats();
        }
        p.update(double(r + 1) / runs);
    }
    return t;
}

double ratio(uint64_t a, uint64_t b) { return b ? double(a) / double(b) : 0.0; }

std::string scene_name(const std::string& path) { return std::filesystem::path(path).stem().string(); }

// Relative RMSE of `img` against `ref` (RGBA, RGB compared): sqrt(mean
// squared difference) / mean of the reference.
double relative_rmse(const std::vector<float>& img, const std::vector<float>& ref) {
    double se = 0.0, mean = 0.0;
    size_t n = 0;
    for (size_t i = 0; i < ref.size(); i += 4)
        for (int c = 0; c < 3; ++c) {
            const double d = double(img[i + c]) - double(ref[i + c]);
            se += d * d;
            mean += ref[i + c];
            ++n;
        }
    return n && mean > 0.0 ? std::sqrt(se / double(n)) / (mean / double(n)) : 0.0;
}

void run_speed(const Options& o, const Scene& scene, std::shared_ptr<const Bvh> bvh, FILE* csv) {
    const Method methods[] = {
        {"spt-single", SamplerType::Spt, Traversal::Single},
        {"spt-packet", SamplerType::Spt, Traversal::Packet},
        {"cpt-packet", SamplerType::Cpt, Traversal::Packet},
        {"icpt-packet", SamplerType::Icpt, Traversal::Packet},
    };
    std::fprintf(csv, "scene,bounces,method,packet,seconds,rays,mrays_per_s,box_utilisation,triangle_utilisation,"
                      "box_tests_per_ray,triangle_tests_per_ray\n");
    std::fprintf(stderr, "%-8s %-12s %9s %9s %8s %8s %9s %9s\n", "bounces", "method", "seconds", "Mrays/s",
                 "box util", "tri util", "box/ray", "tri/ray");
    for (int b = 0; b <= o.max_bounces; ++b)
        for (const Method& m : methods) {
            const Timed t = timed_render(scene, method_settings(o, b, m), bvh, o.runs,
                                         std::to_string(b) + " bounces, " + m.name);
            const BounceStats s = t.stats.bounce_total();
            const double mrays = double(s.rays) / t.seconds * 1e-6;
            const double bu = ratio(s.box_lanes_active, s.box_lanes), tu = ratio(s.triangle_lanes_active, s.triangle_lanes);
            std::fprintf(csv, "%s,%d,%s,%dx%d,%.4f,%llu,%.4f,%.4f,%.4f,%.3f,%.3f\n", scene_name(o.scene_path).c_str(), b,
                         m.name, o.packet_w, o.packet_h, t.seconds, (unsigned long long)s.rays, mrays, bu, tu,
                         ratio(s.box_tests, s.rays), ratio(s.triangle_tests, s.rays));
            std::fprintf(stderr, "%-8d %-12s %9.3f %9.3f %8.3f %8.3f %9.2f %9.2f\n", b, m.name, t.seconds, mrays, bu, tu,
                         ratio(s.box_tests, s.rays), ratio(s.triangle_tests, s.rays));
            std::fflush(csv);
        }
}

void run_assembly(const Options& o, const Scene& scene, std::shared_ptr<const Bvh> bvh, FILE* csv) {
    const Method methods[] = {
        {"types", SamplerType::Cpt, Traversal::Packet, PacketAssembly::RayType},
        {"runs", SamplerType::Cpt, Traversal::Packet, PacketAssembly::Runs},
        {"types-spt", SamplerType::Spt, Traversal::Packet, PacketAssembly::RayType},
        {"runs-spt", SamplerType::Spt, Traversal::Packet, PacketAssembly::Runs},
        {"single", SamplerType::Cpt, Traversal::Single},
    };
    std::fprintf(csv, "scene,assembly,depth,rays,box_tests_per_ray,triangle_tests_per_ray,box_utilisation,"
                      "triangle_utilisation,seconds\n");
    for (const Method& m : methods) {
        const Timed t = timed_render(scene, method_settings(o, o.max_bounces, m), bvh, o.runs, m.name);
        for (int d = 0; d <= std::min(o.max_bounces, kStatBounces - 1); ++d) {
            const BounceStats& s = t.stats.bounces[size_t(d)];
            std::fprintf(csv, "%s,%s,%d,%llu,%.3f,%.3f,%.4f,%.4f,%.4f\n", scene_name(o.scene_path).c_str(), m.name, d,
                         (unsigned long long)s.rays, ratio(s.box_tests, s.rays), ratio(s.triangle_tests, s.rays),
                         ratio(s.box_lanes_active, s.box_lanes), ratio(s.triangle_lanes_active, s.triangle_lanes),
                         t.seconds);
            std::fprintf(stderr, "%-10s depth %d: %10llu rays, %7.2f box/ray %7.2f tri/ray, util %.3f / %.3f\n",
                         m.name, d, (unsigned long long)s.rays, ratio(s.box_tests, s.rays),
                         ratio(s.triangle_tests, s.rays), ratio(s.box_lanes_active, s.box_lanes),
                         ratio(s.triangle_lanes_active, s.triangle_lanes));
        }
        std::fflush(csv);
    }
}

void run_error(const Options& o, const Scene& scene, std::shared_ptr<const Bvh> bvh, FILE* csv) {
    // The reference: SPT, single rays, every core, its own seed.
    std::vector<float> reference;
    {
        RenderSettings rs = base_settings(o, o.max_bounces);
        rs.spp = o.reference_spp;
        rs.seed = o.seed + 1000003;
        rs.threads = 0;
        rs.sampler = SamplerType::Spt;
        Renderer r(scene, rs, bvh);
        bench::Progress p("reference, " + std::to_string(o.reference_spp) + " spp");
        r.render([&](const coherent::Progress& pr) {
            p.update(pr.fraction);
            return true;
        });
        reference = r.film().resolve(PassType::Combined);
    }
    const Method methods[] = {
        {"spt-single", SamplerType::Spt, Traversal::Single},
        {"spt-packet", SamplerType::Spt, Traversal::Packet},
        {"cpt-packet", SamplerType::Cpt, Traversal::Packet},
        {"icpt-packet", SamplerType::Icpt, Traversal::Packet},
    };
    std::fprintf(csv, "scene,method,spp,seconds,relative_rmse\n");
    struct Curve {
        std::vector<double> seconds, rmse;
    };
    std::vector<Curve> curves;
    for (const Method& m : methods) {
        RenderSettings rs = method_settings(o, o.max_bounces, m);
        Renderer r(scene, rs, bvh);
        Curve c;
        bench::Progress p(m.name);
        // Thread CPU time of the render alone: the RMSE evaluation in the
        // callback is measured and left out.
        double excluded = 0.0;
        const double start = thread_cpu_seconds();
        r.render([&](const coherent::Progress& pr) {
            p.update(pr.fraction);
            const int n = pr.samples_done;
            if (n == 0 || (n & (n - 1)) != 0 || pr.fraction > double(n) / rs.spp + 1e-9) return true;  // powers of two, at pass ends
            const double t0 = thread_cpu_seconds();
            const double e = relative_rmse(r.film().resolve(PassType::Combined), reference);
            const double t1 = thread_cpu_seconds();
            c.seconds.push_back(t0 - start - excluded);
            c.rmse.push_back(e);
            excluded += t1 - t0;
            std::fprintf(csv, "%s,%s,%d,%.5f,%.6f\n", scene_name(o.scene_path).c_str(), m.name, n, c.seconds.back(), e);
            return true;
        });
        curves.push_back(c);
        std::fflush(csv);
    }
    // Equal-error time: the first time each method's (log-log interpolated)
    // curve reaches SPT single rays' error at the full spp.
    const double target = curves[0].rmse.back();
    std::fprintf(stderr, "\nequal-error time (relative RMSE %.4f = spt-single at %d spp):\n", target, o.spp);
    for (size_t k = 0; k < curves.size(); ++k) {
        const Curve& c = curves[k];
        double t = -1.0;
        for (size_t i = 0; i < c.rmse.size(); ++i) {
            if (c.rmse[i] > target) continue;
            if (i == 0) {
                t = c.seconds[0];
            } else {
                const double a = std::log(c.rmse[i - 1] / target) / std::log(c.rmse[i - 1] / c.rmse[i]);
                t = std::exp(std::log(c.seconds[i - 1]) + a * (std::log(c.seconds[i]) - std::log(c.seconds[i - 1])));
            }
            break;
        }
        // Not reached within the run: extrapolate from the last point along
        // the Monte Carlo rate, error ~ t^-1/2 (marked as such).
        const bool extrapolated = t < 0.0;
        if (extrapolated) t = c.seconds.back() * (c.rmse.back() / target) * (c.rmse.back() / target);
        std::fprintf(stderr, "  %-12s %8.3f s  (%.2fx of spt-single's %.3f s)%s\n", methods[k].name, t,
                     t / curves[0].seconds.back(), curves[0].seconds.back(),
                     extrapolated ? ", extrapolated by t^-1/2" : "");
        std::fprintf(csv, "%s,%s-equal-error%s,%d,%.5f,%.6f\n", scene_name(o.scene_path).c_str(), methods[k].name,
                     extrapolated ? "-extrapolated" : "", o.spp, t, target);
    }
}

}  // namespace

int main(int argc, char** argv) {
    const Options o = parse(argc, argv);
    Scene scene;
    if (!load_scene(o.scene_path, float(o.width) / float(o.height), "render-bench", scene)) return 1;
    std::shared_ptr<Bvh> bvh = std::make_shared<Bvh>();
    {
        bench::Progress p("building BVH");
        bvh->build(scene);
    }
    FILE* csv = stdout;
    if (!o.csv_path.empty()) {
        csv = std::fopen(o.csv_path.c_str(), "w");
        if (!csv) {
            std::fprintf(stderr, "render-bench: cannot write %s\n", o.csv_path.c_str());
            return 1;
        }
    }
    if (o.mode == "speed") run_speed(o, scene, bvh, csv);
    else if (o.mode == "assembly") run_assembly(o, scene, bvh, csv);
    else run_error(o, scene, bvh, csv);
    if (csv != stdout) std::fclose(csv);
    return 0;
}
