// packet-bench: SIMD packet traversal (traverse_packet.cpp) against our
// single-ray kernel and Embree 3 (rtcIntersect1, and rtcIntersect8 on 4x2
// pixel blocks) on the same rays, one thread.
//
//   packet-bench SCENE.glb [SCENE.glb ...] [--width W] [--height H] [--runs R]
//                [--ao-samples S] [--csv FILE] [--only SET]
//
// Ray sets, per pixel of a W x H (1024 x 768) image of scene.camera:
//   primary      pinhole rays through pixel centres (bench_common.h);
//   ao           S (4) occlusion rays per primary hit, cosine-distributed about
//                the geometric normal, tmax = 0.1 * scene diagonal; every
//                pixel of an 8x8 block uses the same (u1, u2) per sample (CPT);
//   diffuse SPT  one cosine-distributed closest-hit ray per primary hit, an
//                independent (u1, u2) per pixel: incoherent;
//   diffuse CPT  the same, but every pixel of a 4x4 (or 16x16) block uses the
//                same (u1, u2) around its own normal (Coherent Path Tracing):
//                coherent wherever the block sees one surface.
// Secondary origins use bench_common.h's integer-ulp offset. Pixels whose
// primary ray missed have no secondary ray: inactive lanes in packets.
//
// Packets are assembled from pixel blocks inside the timed loop (as a
// renderer would fill them), and so are Embree's RTCRayHit8. Each method is
// timed as the best of R (5) runs of thread CPU time. Reported: Mrays/s,
// ratios to our single-ray kernel and to Embree, box and triangle tests per
// ray, SIMD utilisation (active / computed lanes) and agreement with the
// single-ray hits (bit-identical t, u, v, prim; for Embree: same prim).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "accel/bvh.h"
#include "accel/ray_packet.h"
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
    std::vector<std::string> scenes;
    int width = 1024, height = 768, runs = 5, ao_samples = 4;
    std::string csv;
    std::string only;  // run only the ray set whose name starts with this (profiling)
};

[[noreturn]] void usage(const char* msg) {
    if (msg) std::fprintf(stderr, "packet-bench: %s\n", msg);
    std::fprintf(stderr,
                 "usage: packet-bench SCENE.glb [SCENE.glb ...] [--width W] [--height H] [--runs R] "
                 "[--ao-samples S] [--csv FILE] [--only SET]\n");
    std::exit(2);
}

int parse_int(const char* s, const char* name, int lo, int hi) {
    char* end = nullptr;
    const long v = std::strtol(s, &end, 10);
    if (!end || *end || v < lo || v > hi) usage((std::string(name) + " out of range").c_str());
    return static_cast<int>(v);
}

Options parse(int argc, char** argv) {
    Options o;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto value = [&]() {
            if (i + 1 >= argc) usage((a + " needs a value").c_str());
            return argv[++i];
        };
        if (a == "--width") o.width = parse_int(value(), "--width", 16, 16384);
        else if (a == "--height") o.height = parse_int(value(), "--height", 16, 16384);
        else if (a == "--runs") o.runs = parse_int(value(), "--runs", 1, 100);
        else if (a == "--ao-samples") o.ao_samples = parse_int(value(), "--ao-samples", 1, 64);
        else if (a == "--csv") o.csv = value();
        else if (a == "--only") o.only = value();
        else if (!a.empty() && a[0] == '-') usage(("unknown option " + a).c_str());
        else o.scenes.push_back(a);
    }
    if (o.scenes.empty()) usage("no scene given");
    if (o.width % 16 || o.height % 16) usage("width and height must be multiples of 16");
    return o;
}

// A ray set: `layers` images of W x H rays (layer-major, then row-major);
// valid[i] == 0 where the pixel has no ray.
struct RaySet {
    std::string name;
    bool occlusion = false;
    int layers = 1;
    std::vector<Ray> rays;
    std::vector<uint8_t> valid;
    size_t count() const {
        size_t n = 0;
        for (uint8_t v : valid) n += v;
        return n;
    }
};

// Pixel indices in packet-major order: bw x bh blocks, row-major within a
// block, blocks row-major, layer by layer.
std::vector<uint32_t> block_order(int w, int h, int layers, int bw, int bh) {
    std::vector<uint32_t> order;
    order.reserve(size_t(w) * h * layers);
    for (int l = 0; l < layers; ++l)
        for (int by = 0; by < h; by += bh)
            for (int bx = 0; bx < w; bx += bw)
                for (int y = by; y < by + bh; ++y)
                    for (int x = bx; x < bx + bw; ++x) order.push_back(uint32_t(size_t(l) * w * h + size_t(y) * w + x));
    return order;
}

struct Result {
    std::string scene, set, method, packet;
    size_t rays = 0;
    double seconds = 0.0;
    double box_per_ray = -1.0, tri_per_ray = -1.0, box_util = -1.0, tri_util = -1.0;
    double agreement = -1.0;  // fraction of rays with the single-ray answer
    double mrays() const { return double(rays) / seconds * 1e-6; }
};

struct Outputs {
    std::vector<Hit> hits;
    std::vector<uint8_t> occluded;
};

bool same_hit(const Hit& a, const Hit& b) {
    return a.prim == b.prim && std::memcmp(&a.t, &b.t, 4) == 0 && std::memcmp(&a.u, &b.u, 4) == 0 &&
           std::memcmp(&a.v, &b.v, 4) == 0;
}

class Runner {
public:
    Runner(const Options& opt, const std::string& scene_name, const Bvh& bvh)
        : opt_(opt), scene_(scene_name), bvh_(bvh) {}
#ifdef COHERENT_HAVE_EMBREE
    void set_embree(const EmbreeReference* e) { embree_ = e; }
#endif

    // Our single-ray kernel, rays in row-major order.
    Result single(const RaySet& s, Outputs& out) {
        out.hits.assign(s.rays.size(), Hit{});
        out.occluded.assign(s.rays.size(), 0);
        auto once = [&] {
            for (size_t i = 0; i < s.rays.size(); ++i) {
                if (!s.valid[i]) continue;
                if (s.occlusion) out.occluded[i] = bvh_.occluded(s.rays[i]);
                else bvh_.intersect(s.rays[i], out.hits[i]);
            }
        };
        Result r = base(s, "single ray", "1");
        r.seconds = best_seconds(opt_.runs, 1, scene_ + " " + s.name + " single", once);
        TraversalCounters c;
        for (size_t i = 0; i < s.rays.size(); ++i) {
            if (!s.valid[i]) continue;
            Hit h;
            if (s.occlusion) bvh_.occluded(s.rays[i], &c);
            else bvh_.intersect(s.rays[i], h, &c);
        }
        r.box_per_ray = double(c.box_tests) / double(c.rays);
        r.tri_per_ray = double(c.triangle_tests) / double(c.rays);
        r.agreement = 1.0;
        return r;
    }

    // Our packet kernel on bw x bh pixel blocks.
    Result packets(const RaySet& s, int bw, int bh, const Outputs& reference) {
        const std::vector<uint32_t> order = block_order(opt_.width, opt_.height, s.layers, bw, bh);
        const int n = bw * bh;
        Outputs out;
        out.hits.assign(s.rays.size(), Hit{});
        out.occluded.assign(s.rays.size(), 0);
        auto run = [&](PacketCounters* counters) {
            RayPacket p;
            HitPacket h;
            for (size_t first = 0; first < order.size(); first += n) {
                p.clear();
                for (int i = 0; i < n; ++i) {
                    const uint32_t k = order[first + i];
                    p.set(i, s.rays[k]);
                    p.active[i >> 5] |= uint32_t(s.valid[k]) << (i & 31);
                }
                p.size = n;
                if (s.occlusion) {
                    OcclusionMask m;
                    bvh_.occluded(p, m, counters);
                    for (int i = 0; i < n; ++i) out.occluded[order[first + i]] = m.test(i);
                } else {
                    h.reset(n);
                    bvh_.intersect(p, h, counters);
                    for (int i = 0; i < n; ++i) out.hits[order[first + i]] = h.hit(i);
                }
            }
        };
        Result r = base(s, "packet", std::to_string(bw) + "x" + std::to_string(bh));
        r.seconds = best_seconds(opt_.runs, 1, scene_ + " " + s.name + " packets " + r.packet, [&] { run(nullptr); });
        PacketCounters c;
        run(&c);
        r.box_per_ray = double(c.box_tests) / double(c.rays);
        r.tri_per_ray = double(c.triangle_tests) / double(c.rays);
        r.box_util = c.box_utilisation();
        r.tri_util = c.triangle_utilisation();
        r.agreement = agreement(s, out, reference, true);
        return r;
    }

#ifdef COHERENT_HAVE_EMBREE
    // rtcIntersect1 / rtcOccluded1, row-major.
    Result embree1(const RaySet& s, const Outputs& reference) {
        Outputs out;
        out.hits.assign(s.rays.size(), Hit{});
        out.occluded.assign(s.rays.size(), 0);
        auto once = [&] {
            for (size_t i = 0; i < s.rays.size(); ++i) {
                if (!s.valid[i]) continue;
                if (s.occlusion) out.occluded[i] = embree_->occluded(s.rays[i]);
                else embree_->intersect(s.rays[i], out.hits[i]);
            }
        };
        Result r = base(s, "Embree rtcIntersect1", "1");
        r.seconds = best_seconds(opt_.runs, 1, scene_ + " " + s.name + " embree1", once);
        r.agreement = agreement(s, out, reference, false);
        return r;
    }

    // rtcIntersect8 / rtcOccluded8 on 4x2 pixel blocks with valid masks.
    Result embree8(const RaySet& s, const Outputs& reference) {
        const std::vector<uint32_t> order = block_order(opt_.width, opt_.height, s.layers, 4, 2);
        Outputs out;
        out.hits.assign(s.rays.size(), Hit{});
        out.occluded.assign(s.rays.size(), 0);
        auto once = [&] {
            Ray rays[8];
            Hit hits[8];
            int valid[8];
            for (size_t first = 0; first < order.size(); first += 8) {
                int any = 0;
                for (int i = 0; i < 8; ++i) {
                    const uint32_t k = order[first + i];
                    rays[i] = s.rays[k];
                    valid[i] = s.valid[k] ? -1 : 0;
                    any |= valid[i];
                }
                if (!any) continue;
                if (s.occlusion) {
                    const int m = embree_->occluded8(valid, rays);
                    for (int i = 0; i < 8; ++i) out.occluded[order[first + i]] = (m >> i) & 1;
                } else {
                    for (Hit& hit : hits) hit = Hit{};
                    embree_->intersect8(valid, rays, hits);
                    for (int i = 0; i < 8; ++i) out.hits[order[first + i]] = hits[i];
                }
            }
        };
        Result r = base(s, "Embree rtcIntersect8", "4x2");
        r.seconds = best_seconds(opt_.runs, 1, scene_ + " " + s.name + " embree8", once);
        r.agreement = agreement(s, out, reference, false);
        return r;
    }
#endif

private:
    Result base(const RaySet& s, const char* method, const std::string& packet) const {
        Result r;
        r.scene = scene_;
        r.set = s.name;
        r.method = method;
        r.packet = packet;
        r.rays = s.count();
        return r;
    }
    // Exact (ours) or same-primitive (Embree: its own arithmetic) agreement.
    static double agreement(const RaySet& s, const Outputs& out, const Outputs& ref, bool exact) {
        size_t same = 0, n = 0;
        for (size_t i = 0; i < s.rays.size(); ++i) {
            if (!s.valid[i]) continue;
            ++n;
            if (s.occlusion) same += out.occluded[i] == ref.occluded[i];
            else if (exact) same += same_hit(out.hits[i], ref.hits[i]);
            else same += out.hits[i].prim == ref.hits[i].prim;
        }
        return n ? double(same) / double(n) : 1.0;
    }

    const Options& opt_;
    std::string scene_;
    const Bvh& bvh_;
#ifdef COHERENT_HAVE_EMBREE
    const EmbreeReference* embree_ = nullptr;
#endif
};

// Secondary ray sets from the primary hits. `block` > 0: CPT, one (u1, u2)
// per block x block pixels (and per layer); 0: SPT, one per pixel.
RaySet secondary(const char* name, const Scene& scene, const std::vector<Ray>& primary,
                 const std::vector<Hit>& hits, int w, int h, int layers, int block, float tmax, bool occlusion,
                 uint64_t seed) {
    RaySet s;
    s.name = name;
    s.occlusion = occlusion;
    s.layers = layers;
    const size_t pixels = size_t(w) * h;
    s.rays.assign(pixels * layers, Ray{});
    s.valid.assign(pixels * layers, 0);
    for (size_t i = 0; i < pixels; ++i) {
        const Hit& hit = hits[i];
        if (!hit.valid()) continue;
        const Vec3f* v = &scene.vertices[3 * size_t(hit.prim)];
        Vec3f n = cross(v[1] - v[0], v[2] - v[0]);
        const float len = length(n);
        if (!(len > 0.0f) || !std::isfinite(len)) continue;
        n = n / len;
        if (dot(n, primary[i].d) > 0.0f) n = -n;
        const Vec3f p = v[0] * (1.0f - hit.u - hit.v) + v[1] * hit.u + v[2] * hit.v;
        const Vec3f o = offset_origin(p, n);
        const int x = int(i % w), y = int(i / w);
        for (int l = 0; l < layers; ++l) {
            const uint64_t stream = block > 0 ? uint64_t((y / block) * (w / block) + x / block) : uint64_t(i);
            Rng rng(seed + 0x10000ull * uint64_t(l) * pixels + stream);
            const float u1 = rng.next(), u2 = rng.next();
            Ray r;
            r.o = o;
            r.d = cosine_direction(n, u1, u2);
            r.tmax = tmax;
            s.rays[size_t(l) * pixels + i] = r;
            s.valid[size_t(l) * pixels + i] = 1;
        }
    }
    return s;
}

void print_table(const std::vector<Result>& rs) {
    std::printf("| scene | rays | method | packet | Mrays/s | vs single | vs Embree 1 | vs Embree 8 | box/ray | tri/ray "
                "| box util | tri util | agreement |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (const Result& r : rs) {
        double single = 0, e1 = 0, e8 = 0;
        for (const Result& q : rs) {
            if (q.scene != r.scene || q.set != r.set) continue;
            if (q.method == "single ray") single = q.mrays();
            if (q.method == "Embree rtcIntersect1") e1 = q.mrays();
            if (q.method == "Embree rtcIntersect8") e8 = q.mrays();
        }
        auto ratio = [&](double d) {
            char b[32];
            if (d > 0) std::snprintf(b, sizeof b, "%.2f", r.mrays() / d);
            else std::snprintf(b, sizeof b, "-");
            return std::string(b);
        };
        auto num = [](double v, const char* fmt) {
            char b[32];
            if (v >= 0) std::snprintf(b, sizeof b, fmt, v);
            else std::snprintf(b, sizeof b, "-");
            return std::string(b);
        };
        std::printf("| %s | %s | %s | %s | %.2f | %s | %s | %s | %s | %s | %s | %s | %s |\n", r.scene.c_str(),
                    r.set.c_str(), r.method.c_str(), r.packet.c_str(), r.mrays(), ratio(single).c_str(),
                    ratio(e1).c_str(), ratio(e8).c_str(), num(r.box_per_ray, "%.1f").c_str(),
                    num(r.tri_per_ray, "%.1f").c_str(), num(r.box_util, "%.2f").c_str(),
                    num(r.tri_util, "%.2f").c_str(), num(100.0 * r.agreement, "%.2f%%").c_str());
    }
    std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
    const Options opt = parse(argc, argv);
    const int w = opt.width, h = opt.height;
    std::vector<Result> all;
    for (const std::string& path : opt.scenes) {
        const std::string name = std::filesystem::path(path).stem().string();
        Scene scene;
        if (!load_scene(path, float(w) / float(h), "packet-bench", scene)) return 1;
        Bvh bvh;
        bvh.build(scene);
        std::fprintf(stderr, "%s: %zu triangles, BVH %zu nodes\n", name.c_str(), scene.vertices.size() / 3,
                     bvh.nodes().size());
        const RaySets base = make_rays(scene, bvh, w, h, 1);

        RaySet primary;
        primary.name = "primary";
        primary.rays = base.primary;
        primary.valid.assign(primary.rays.size(), 1);
        std::vector<Hit> hits(primary.rays.size());
        for (size_t i = 0; i < hits.size(); ++i) bvh.intersect(primary.rays[i], hits[i]);
        const float ao_radius = 0.1f * length(scene.bounds().extent());
        std::vector<RaySet> sets;
        sets.push_back(std::move(primary));
        sets.push_back(secondary("AO (CPT 8x8)", scene, sets[0].rays, hits, w, h, opt.ao_samples, 8, ao_radius, true, 1));
        sets.push_back(secondary("diffuse SPT", scene, sets[0].rays, hits, w, h, 1, 0, kInf, false, 2));
        sets.push_back(secondary("diffuse CPT 4x4", scene, sets[0].rays, hits, w, h, 1, 4, kInf, false, 3));
        sets.push_back(secondary("diffuse CPT 16x16", scene, sets[0].rays, hits, w, h, 1, 16, kInf, false, 4));

#ifdef COHERENT_HAVE_EMBREE
        EmbreeReference embree(scene.vertices.data(), scene.vertices.size() / 3, "threads=1");
#endif
        Runner run(opt, name, bvh);
#ifdef COHERENT_HAVE_EMBREE
        run.set_embree(&embree);
#endif
        std::vector<Result> rs;
        for (const RaySet& s : sets) {
            if (!opt.only.empty() && s.name.rfind(opt.only, 0) != 0) continue;
            Outputs ref;
            rs.push_back(run.single(s, ref));
            std::vector<std::pair<int, int>> shapes;
            if (s.name == "primary") shapes = {{2, 2}, {4, 2}, {4, 4}, {8, 8}, {16, 16}};
            else if (s.name == "AO (CPT 8x8)") shapes = {{4, 2}, {8, 8}};
            else if (s.name == "diffuse SPT") shapes = {{4, 2}, {4, 4}};
            else if (s.name == "diffuse CPT 4x4") shapes = {{4, 2}, {4, 4}};
            else shapes = {{4, 4}, {8, 8}, {16, 16}};
            for (auto [bw, bh] : shapes) rs.push_back(run.packets(s, bw, bh, ref));
#ifdef COHERENT_HAVE_EMBREE
            rs.push_back(run.embree1(s, ref));
            rs.push_back(run.embree8(s, ref));
#endif
        }
        print_table(rs);
        all.insert(all.end(), rs.begin(), rs.end());
    }
    if (!opt.csv.empty()) {
        FILE* f = std::fopen(opt.csv.c_str(), "w");
        if (!f) {
            std::fprintf(stderr, "packet-bench: cannot write %s\n", opt.csv.c_str());
            return 1;
        }
        std::fprintf(f, "scene,rays,method,packet,ray_count,seconds,mrays_per_s,box_per_ray,tri_per_ray,box_util,"
                        "tri_util,agreement\n");
        for (const Result& r : all)
            std::fprintf(f, "%s,%s,%s,%s,%zu,%.6f,%.4f,%.3f,%.3f,%.4f,%.4f,%.6f\n", r.scene.c_str(), r.set.c_str(),
                         r.method.c_str(), r.packet.c_str(), r.rays, r.seconds, r.mrays(), r.box_per_ray,
                         r.tri_per_ray, r.box_util, r.tri_util, r.agreement);
        std::fclose(f);
    }
    return 0;
}
