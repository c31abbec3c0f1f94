// Packet traversal (traverse_packet.cpp): every active ray of a packet must
// get bit for bit the result of the single-ray kernel (Bvh::intersect and
// Bvh::occluded, themselves checked against brute force in test_bvh.cpp and
// test_traversal_robustness.cpp), whatever the packet's size, coherence,
// octants, invalid or inactive lanes; inactive lanes' records are untouched;
// and the counters describe the work (coherent packets take fewer box tests
// per ray than single rays: the point of the method).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "accel/bvh.h"
#include "accel/ray_packet.h"
#include "bvh_test_meshes.h"
#include "test_fixtures.h"
#include "scene/scene.h"

using namespace coherent;
using namespace coherent::testing_meshes;

namespace {

uint32_t bits(float f) {
    uint32_t b;
    std::memcpy(&b, &f, 4);
    return b;
}

constexpr float kSentinelT = -7.5f;
constexpr uint32_t kSentinelPrim = 0xdeadbeefu;

struct CheckStats {
    size_t rays = 0, hits = 0, occluded = 0;
};

// Traces rays[first, first + n) as one packet (lanes whose bit in `inactive`
// is set are left out) with both packet kernels and compares every lane
// with the single-ray kernels. Inactive lanes must keep sentinel records.
void check_packet(const Bvh& bvh, const std::vector<Ray>& rays, size_t first, int n, CheckStats& stats,
                  const std::vector<bool>& inactive = {}, PacketCounters* counters = nullptr) {
    RayPacket p;
    p.clear();
    for (int i = 0; i < n; ++i) {
        if (!inactive.empty() && inactive[i]) {
            p.set(p.size++, rays[first + i]);  // present but not active
        } else {
            p.push(rays[first + i]);
        }
    }
    HitPacket h;
    for (int i = 0; i < kMaxPacketRays; ++i) {
        h.t[i] = kSentinelT;
        h.u[i] = h.v[i] = kSentinelT;
        h.prim[i] = kSentinelPrim;
    }
    bvh.intersect(p, h, counters);
    OcclusionMask occ;
    bvh.occluded(p, occ, counters);
    for (int i = 0; i < kMaxPacketRays; ++i) {
        const Ray* r = i < n ? &rays[first + i] : nullptr;
        const bool active = i < n && (inactive.empty() || !inactive[i]);
        if (!active) {
            ASSERT_EQ(h.prim[i], kSentinelPrim) << "inactive lane " << i << " written";
            ASSERT_EQ(bits(h.t[i]), bits(kSentinelT)) << i;
            ASSERT_FALSE(occ.test(i)) << "inactive lane " << i << " occluded";
            continue;
        }
        Hit expected;
        const bool hit = bvh.intersect(*r, expected);
        const bool blocked = bvh.occluded(*r);
        ++stats.rays;
        stats.hits += hit;
        stats.occluded += blocked;
        ASSERT_EQ(occ.test(i), blocked) << "lane " << i << " of " << n;
        if (!hit) {
            ASSERT_EQ(h.prim[i], kSentinelPrim) << "lane " << i << " of " << n << " hit prim " << h.prim[i];
            continue;
        }
        ASSERT_EQ(h.prim[i], expected.prim) << "lane " << i << " of " << n;
        ASSERT_EQ(bits(h.t[i]), bits(expected.t)) << "lane " << i << " t " << h.t[i] << " vs " << expected.t;
        ASSERT_EQ(bits(h.u[i]), bits(expected.u)) << "lane " << i;
        ASSERT_EQ(bits(h.v[i]), bits(expected.v)) << "lane " << i;
    }
}

// Packs consecutive rays into packets of `n` (the last one partial).
void check_all(const Bvh& bvh, const std::vector<Ray>& rays, int n, CheckStats& stats) {
    for (size_t first = 0; first < rays.size(); first += n) {
        const int k = static_cast<int>(std::min<size_t>(n, rays.size() - first));
        check_packet(bvh, rays, first, k, stats);
        if (::testing::Test::HasFatalFailure()) return;
    }
}

const int kSizes[] = {1, 2, 3, 4, 7, 8, 9, 15, 16, 17, 31, 32, 33, 63, 64, 65, 100, 127, 128, 200, 255, 256};

// Coherent rays: from near one origin toward a small patch (a pixel block).
std::vector<Ray> coherent_rays(std::mt19937& rng, int n, const Vec3f& origin, const Vec3f& target, float spread) {
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    std::vector<Ray> rays(n);
    for (auto& r : rays) {
        r.o = origin + Vec3f(u(rng), u(rng), u(rng)) * (0.01f * spread);
        r.d = (target + Vec3f(u(rng), u(rng), u(rng)) * spread) - r.o;
    }
    return rays;
}

}  // namespace

TEST(PacketTraversal, RandomSoupEveryPacketSize) {
    const auto soup = random_soup(3000, 7, 10.0f, 1.5f);
    Bvh bvh;
    bvh.build(soup);
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f), t(0.0f, 30.0f);
    CheckStats s;
    for (int n : kSizes) {
        // Coherent packet (one octant, mostly).
        auto rays = coherent_rays(rng, n, random_unit(rng) * 25.0f, Vec3f(u(rng), u(rng), u(rng)) * 8.0f, 2.0f);
        check_packet(bvh, rays, 0, n, s);
        ASSERT_FALSE(HasFatalFailure()) << "coherent, size " << n;
        // Incoherent: random origins inside the soup, random directions and bounds.
        std::vector<Ray> wild(n);
        for (auto& r : wild) {
            r.o = Vec3f(u(rng), u(rng), u(rng)) * 12.0f;
            r.d = random_unit(rng) * (0.5f + 2.0f * (u(rng) + 1.0f));
            r.tmin = u(rng) > 0.5f ? 0.1f * t(rng) : 0.0f;
            r.tmax = u(rng) > 0.0f ? kInf : r.tmin + t(rng);
        }
        check_packet(bvh, wild, 0, n, s);
        ASSERT_FALSE(HasFatalFailure()) << "incoherent, size " << n;
    }
    EXPECT_GT(s.hits, s.rays / 4);
    EXPECT_LT(s.hits, s.rays);
}

TEST(PacketTraversal, SharedEdgesAndVertices) {
    // Rays through the exact vertices and edge midpoints of closed meshes,
    // from inside: ties between neighbours must resolve as for single rays,
    // and no ray may leak out (every one hits).
    for (int mesh = 0; mesh < 2; ++mesh) {
        const Vec3f centre = mesh == 0 ? Vec3f(1.0f, -2.0f, 0.5f) : Vec3f(0.0f, 0.0f, 0.0f);
        const IndexedMesh m = mesh == 0 ? icosphere(3, 3.0f, centre) : tessellated_cube(6, 1.0f, Vec3f(-3.0f, -3.0f, -3.0f));
        const auto soup = m.soup();
        Bvh bvh;
        bvh.build(soup);
        std::vector<Vec3f> targets = m.positions;
        for (const auto& [a, b] : m.edges()) targets.push_back((m.positions[a] + m.positions[b]) * 0.5f);
        std::mt19937 rng(3 + mesh);
        std::vector<Ray> rays;
        for (const Vec3f& target : targets) {
            Ray r;
            r.o = centre;  // one origin (packets of rays to neighbouring targets)
            r.d = target - r.o;
            rays.push_back(r);
            Ray s;
            s.o = centre + random_unit(rng) * 1.5f;  // and from anywhere inside: mixed octants
            s.d = target - s.o;
            rays.push_back(s);
        }
        CheckStats s;
        for (int n : {8, 64, 256}) check_all(bvh, rays, n, s);
        ASSERT_FALSE(HasFatalFailure());
        EXPECT_EQ(s.hits, s.rays) << "a ray from inside a closed mesh through a vertex or an edge escaped";
        EXPECT_EQ(s.occluded, s.rays);
    }
}

TEST(PacketTraversal, AxisParallelRaysWithOriginsOnNodePlanes) {
    // Integer grid: node planes are integers, so are the origins, and zero
    // direction components (+0 and -0) make 0 * inf = NaN in the slab test.
    const auto soup = tessellated_cube(8, 1.0f, Vec3f(0, 0, 0)).soup();
    Bvh bvh;
    bvh.build(soup);
    std::mt19937 rng(5);
    std::uniform_int_distribution<int> cell(-1, 9);
    std::uniform_real_distribution<float> dir(-1.0f, 1.0f);
    std::vector<Ray> rays;
    for (int i = 0; i < 6000; ++i) {
        Ray r;
        r.o = Vec3f(float(cell(rng)), float(cell(rng)), float(cell(rng)));
        Vec3f d(dir(rng), dir(rng), dir(rng));
        const int zeros = 1 + i % 2;
        for (int k = 0; k < zeros; ++k) d[(i / 2 + k) % 3] = (i / 4) % 2 ? 0.0f : -0.0f;
        r.d = d;
        rays.push_back(r);
    }
    CheckStats s;
    for (int n : {5, 8, 64, 256}) check_all(bvh, rays, n, s);
    ASSERT_FALSE(HasFatalFailure());
    EXPECT_GT(s.hits, s.rays / 4);
    // Same-direction packets with zero components (uniform octant, infinite
    // 1/d: the interval test must stand aside).
    std::vector<Ray> parallel;
    for (int y = -1; y <= 9; ++y)
        for (int z = -1; z <= 9; ++z) {
            Ray r;
            r.o = Vec3f(-2.0f, float(y), float(z));
            r.d = Vec3f(1.0f, 0.0f, -0.0f);
            parallel.push_back(r);
            r.o = Vec3f(-2.0f, y + 0.5f, z + 0.5f);
            parallel.push_back(r);
        }
    check_all(bvh, parallel, 64, s);
    ASSERT_FALSE(HasFatalFailure());
}

TEST(PacketTraversal, GrazingRaysInFacePlanes) {
    const auto soup = tessellated_cube(4, 1.0f, Vec3f(0, 0, 0)).soup();
    Bvh bvh;
    bvh.build(soup);
    std::vector<Ray> rays;
    for (float y : {0.0f, 0.25f, 0.5f, 1.0f, 2.0f, 3.5f, 4.0f})
        for (float z : {0.0f, -0.0f, 4.0f, 1e-7f, -1e-7f}) {
            Ray r;
            r.o = Vec3f(-1.0f, y, z);
            r.d = Vec3f(1.0f, 0.0f, 0.0f);
            rays.push_back(r);
            r.d = Vec3f(1.0f, 1e-8f, -1e-9f);
            rays.push_back(r);
        }
    CheckStats s;
    for (int n : {1, 8, 70}) check_all(bvh, rays, n, s);
    ASSERT_FALSE(HasFatalFailure());
}

TEST(PacketTraversal, HugeAndTinyCoordinates) {
    for (float scale : {1e-20f, 1e-6f, 1e6f, 1e18f}) {
        IndexedMesh m = icosphere(2, 1.0f, Vec3f(0.25f, 0.5f, -0.125f));
        for (auto& p : m.positions) p = p * scale;
        const auto soup = m.soup();
        Bvh bvh;
        bvh.build(soup);
        std::mt19937 rng(17);
        std::vector<Ray> rays;
        for (int i = 0; i < 512; ++i) {
            Ray r;
            r.o = random_unit(rng) * (4.0f * scale);
            r.d = (random_unit(rng) * (0.5f * scale)) - r.o;
            if (i % 3 == 0) r.d = r.d * 1e-10f;  // tiny direction magnitudes too
            rays.push_back(r);
        }
        CheckStats s;
        for (int n : {8, 64, 256}) check_all(bvh, rays, n, s);
        ASSERT_FALSE(HasFatalFailure()) << "scale " << scale;
        EXPECT_GT(s.hits, s.rays / 4) << "scale " << scale;
    }
}

TEST(PacketTraversal, InvalidAndInactiveLanes) {
    const auto soup = icosphere(3, 2.0f, Vec3f(0, 0, 0)).soup();
    Bvh bvh;
    bvh.build(soup);
    std::mt19937 rng(23);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (int n : {8, 13, 64, 256}) {
        auto rays = coherent_rays(rng, n, Vec3f(0, 0, 10), Vec3f(0, 0, 0), 1.5f);
        std::vector<bool> inactive(n, false);
        for (int i = 0; i < n; ++i) {
            switch (i % 11) {
                case 1: rays[i].o.x = nan; break;
                case 2: rays[i].d.y = nan; break;
                case 3: rays[i].d = Vec3f(0.0f, 0.0f, 0.0f); break;
                case 4: rays[i].d.z = kInf; break;
                case 5: rays[i].tmin = 5.0f; rays[i].tmax = 1.0f; break;  // tmin > tmax
                case 6: rays[i].tmax = nan; break;
                case 7: inactive[i] = true; break;
                case 8: rays[i].o.z = -kInf; break;
                case 9: rays[i].tmin = nan; break;
                default: break;
            }
        }
        CheckStats s;
        check_packet(bvh, rays, 0, n, s, inactive);
        ASSERT_FALSE(HasFatalFailure()) << n;
        EXPECT_GT(s.hits, 0u);
    }
    // A packet with no valid ray, and an empty packet: nothing is written.
    std::vector<Ray> bad(16);
    for (auto& r : bad) r.d = Vec3f(0, 0, 0);
    CheckStats s;
    check_packet(bvh, bad, 0, 16, s);
    check_packet(bvh, bad, 0, 0, s);
    ASSERT_FALSE(HasFatalFailure());
    EXPECT_EQ(s.hits, 0u);
}

TEST(PacketTraversal, MixedOctantsAndOcclusionBounds) {
    // Rays from the centre of a closed sphere in all directions (every
    // octant in one packet), with finite tmax on both sides of the surface:
    // the occlusion answer flips exactly where the single-ray one does.
    const IndexedMesh m = icosphere(3, 5.0f, Vec3f(0, 0, 0));
    const auto soup = m.soup();
    Bvh bvh;
    bvh.build(soup);
    std::mt19937 rng(29);
    std::uniform_real_distribution<float> u(4.0f, 6.0f);
    std::vector<Ray> rays;
    for (int i = 0; i < 2048; ++i) {
        Ray r;
        r.o = random_unit(rng) * 0.5f;
        r.d = random_unit(rng);
        r.tmax = u(rng);
        rays.push_back(r);
    }
    CheckStats s;
    for (int n : {8, 64, 256}) check_all(bvh, rays, n, s);
    ASSERT_FALSE(HasFatalFailure());
    EXPECT_GT(s.occluded, s.rays / 5);
    EXPECT_LT(s.occluded, s.rays * 4 / 5);

    // Mixed-octant packets are traced as one sub-packet per octant: the
    // per-ray visit counts still land on the right lanes.
    RayPacket p;
    for (int i = 0; i < 200; ++i) p.push(rays[i]);
    p.active[0] &= ~1u;  // lane 0 inactive
    std::vector<uint32_t> visits(kMaxPacketRays, 0u);
    PacketCounters pc;
    pc.ray_node_visits = visits.data();
    HitPacket h;
    h.reset(200);
    bvh.intersect(p, h, &pc);
    EXPECT_EQ(pc.packets, 1u);
    EXPECT_EQ(pc.rays, 199u);
    EXPECT_EQ(visits[0], 0u);
    uint64_t sum = 0;
    for (int i = 1; i < 200; ++i) {
        EXPECT_GE(visits[i], 1u) << i;
        sum += visits[i];
    }
    for (int i = 200; i < kMaxPacketRays; ++i) EXPECT_EQ(visits[i], 0u);
    EXPECT_GE(sum, pc.node_visits);
}

TEST(PacketTraversal, SingleLeafTreeAndEmptyBvh) {
    const std::vector<Vec3f> tri = {Vec3f(-1, -1, 0), Vec3f(1, -1, 0), Vec3f(0, 1, 0)};
    Bvh bvh;
    bvh.build(tri);
    std::mt19937 rng(31);
    auto rays = coherent_rays(rng, 40, Vec3f(0, 0, 3), Vec3f(0, 0, 0), 0.8f);
    CheckStats s;
    check_all(bvh, rays, 16, s);
    ASSERT_FALSE(HasFatalFailure());
    EXPECT_GT(s.hits, 0u);

    Bvh empty;
    empty.build(std::vector<Vec3f>{});
    CheckStats e;
    check_all(empty, rays, 16, e);
    ASSERT_FALSE(HasFatalFailure());
    EXPECT_EQ(e.hits, 0u);
}

TEST(PacketTraversal, CountersDescribeTheWork) {
    const IndexedMesh m = icosphere(3, 3.0f, Vec3f(0, 0, 0));
    const auto soup = m.soup();
    Bvh bvh;
    bvh.build(soup);
    // 8x8 pixel blocks aimed at the sphere, each a few triangles wide:
    // coherent packets.
    std::vector<Ray> rays;
    const Vec3f eye(0.3f, 0.2f, 12.0f);
    for (int by = 0; by < 4; ++by)
        for (int bx = 0; bx < 4; ++bx)
            for (int y = 0; y < 8; ++y)
                for (int x = 0; x < 8; ++x) {
                    Ray r;
                    r.o = eye;
                    r.d = Vec3f(-0.064f + 0.004f * (8 * bx + x), -0.064f + 0.004f * (8 * by + y), -1.0f);
                    rays.push_back(r);
                }
    PacketCounters pc;
    std::vector<uint32_t> visits(64, 0);
    uint64_t visit_sum = 0;
    CheckStats s;
    for (size_t first = 0; first < rays.size(); first += 64) {
        PacketCounters one;
        std::fill(visits.begin(), visits.end(), 0u);
        one.ray_node_visits = visits.data();
        RayPacket p;
        for (int i = 0; i < 64; ++i) p.push(rays[first + i]);
        HitPacket h;
        h.reset(64);
        bvh.intersect(p, h, &one);
        EXPECT_EQ(one.packets, 1u);
        EXPECT_EQ(one.rays, 64u);
        uint64_t sum = 0;
        for (uint32_t v : visits) {
            EXPECT_GE(v, 1u);                 // every ray is active at the root
            EXPECT_LE(v, one.node_visits);    // and at most at every visit
            sum += v;
        }
        EXPECT_GE(sum, one.node_visits);
        visit_sum += sum;
        pc += one;
        // Counting does not change the answers.
        HitPacket plain;
        plain.reset(64);
        bvh.intersect(p, plain);
        for (int i = 0; i < 64; ++i) EXPECT_EQ(plain.prim[i], h.prim[i]);
    }
    EXPECT_EQ(pc.rays, rays.size());
    EXPECT_LE(pc.box_lanes_active, pc.box_lanes);
    EXPECT_LE(pc.triangle_lanes_active, pc.triangle_lanes);
    EXPECT_GT(pc.box_utilisation(), 0.5);  // a full coherent packet keeps its lanes busy
    EXPECT_GT(pc.triangle_tests, 0u);
    EXPECT_GE(visit_sum, pc.node_visits);

    TraversalCounters single;
    for (const Ray& r : rays) {
        Hit hit;
        bvh.intersect(r, hit, &single);
    }
    const double packet_box = double(pc.box_tests) / double(pc.rays);
    const double single_box = double(single.box_tests) / double(single.rays);
    std::printf("coherent 8x8 packets: %.2f box tests per ray, single rays: %.2f; triangle tests %.2f vs %.2f\n",
                packet_box, single_box, double(pc.triangle_tests) / double(pc.rays),
                double(single.triangle_tests) / double(single.rays));
    EXPECT_LT(packet_box, 0.8 * single_box)
        << "coherent 8x8 packets: " << packet_box << " box tests per ray, single rays: " << single_box;
}

TEST(PacketTraversal, GeneratedCornellBoxCameraAndBounceRays) {
    const int w = 128, h = 96;
    Scene scene;
    ASSERT_TRUE(test::load_fixture("cornell_box.glb", scene, float(w) / float(h)));
    scene.finalize();
    Bvh bvh;
    bvh.build(scene);
    const Camera& cam = scene.camera;
    // Primary rays in 8x8 pixel packets (packet-major order).
    std::vector<Ray> primary;
    for (int by = 0; by < h; by += 8)
        for (int bx = 0; bx < w; bx += 8)
            for (int y = by; y < by + 8; ++y)
                for (int x = bx; x < bx + 8; ++x) {
                    Ray r;
                    r.o = cam.position;
                    r.d = cam.forward + cam.right * ((2.0f * (x + 0.5f) / w - 1.0f) * cam.half_width) +
                          cam.up * ((1.0f - 2.0f * (y + 0.5f) / h) * cam.half_height);
                    primary.push_back(r);
                }
    CheckStats s;
    check_all(bvh, primary, 64, s);
    ASSERT_FALSE(HasFatalFailure());
    EXPECT_GT(s.hits, s.rays / 20);

    // Bounce rays from the hits: one shared direction per 4x4 group (CPT)
    // and independent ones (SPT), with tmax both infinite and finite (AO).
    std::mt19937 rng(37);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    std::vector<Ray> cpt, spt;
    Vec3f shared = random_unit(rng);
    for (size_t i = 0; i < primary.size(); ++i) {
        if (i % 16 == 0) shared = random_unit(rng);
        Hit hit;
        if (!bvh.intersect(primary[i], hit)) continue;
        const Vec3f* v = &scene.vertices[3 * size_t(hit.prim)];
        const Vec3f p = v[0] * (1.0f - hit.u - hit.v) + v[1] * hit.u + v[2] * hit.v;
        Vec3f n = normalize(cross(v[1] - v[0], v[2] - v[0]));
        if (dot(n, primary[i].d) > 0.0f) n = -n;
        Ray r;
        r.o = p + n * 1e-4f;
        r.d = dot(shared, n) < 0.0f ? -shared : shared;
        r.tmax = (i % 2) ? kInf : 0.05f;
        cpt.push_back(r);
        r.d = random_unit(rng);
        if (dot(r.d, n) < 0.0f) r.d = -r.d;
        spt.push_back(r);
    }
    check_all(bvh, cpt, 16, s);
    check_all(bvh, spt, 16, s);
    check_all(bvh, spt, 256, s);
    ASSERT_FALSE(HasFatalFailure());
}

TEST(PacketTraversal, EveryBuildWidthAndAfterRefit) {
    // Packets walk the 8-wide layout, which every build keeps (and refit
    // refreshes): same answers whatever width single rays use, with or
    // without spatial splits, and after the triangles moved.
    auto soup = random_soup(1500, 41, 8.0f, 1.0f);
    std::mt19937 rng(43);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    std::vector<Ray> rays;
    for (int i = 0; i < 1024; ++i) {
        Ray r;
        r.o = random_unit(rng) * 20.0f;
        r.d = Vec3f(u(rng), u(rng), u(rng)) * 6.0f - r.o;
        rays.push_back(r);
    }
    for (int width : {2, 4, 8})
        for (float budget : {0.0f, 0.3f}) {
            BvhBuildOptions opt;
            opt.width = width;
            opt.spatial_split_budget = budget;
            Bvh bvh;
            bvh.build(soup, opt);
            CheckStats s;
            check_all(bvh, rays, 64, s);
            ASSERT_FALSE(HasFatalFailure()) << "width " << width << " budget " << budget;
            EXPECT_GT(s.hits, s.rays / 4);
            // Move every triangle and refit.
            std::vector<Vec3f> moved = soup;
            for (size_t i = 0; i < moved.size(); ++i) moved[i] = moved[i] + Vec3f(0.5f, -0.25f, 0.125f * float(i % 3));
            bvh.refit(moved);
            CheckStats m;
            check_all(bvh, rays, 64, m);
            ASSERT_FALSE(HasFatalFailure()) << "refit, width " << width;
        }
}
