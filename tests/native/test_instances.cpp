// Instancing (scene/instance.h, accel/instance_bvh.h): a procedural rock
// placed 50 times with random rotations, non-uniform and mirroring scales,
// against the very same triangles flattened into world space (add_mesh),
// and against a double-precision brute force through the transforms.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "accel/bvh.h"
#include "accel/instance_bvh.h"
#include "accel/motion_bvh.h"
#include "accel/ray_stream.h"
#include "core/random.h"
#include "render/instance_shading.h"
#include "render/ray_offset.h"
#include "render/renderer.h"
#include "test_render_helpers.h"

using namespace coherent;
using namespace coherent::test;

namespace {

// A lumpy sphere with smooth normals; odd rings use material slot 1.
struct Rock {
    std::vector<float> pos, nrm;
    std::vector<uint32_t> idx, slot;
};

Rock make_rock(Pcg32& rng, int rings = 10, int segments = 20) {
    Rock r;
    for (int i = 0; i <= rings; ++i)
        for (int k = 0; k < segments; ++k) {
            const float theta = kPi * float(i) / float(rings), phi = 2.0f * kPi * float(k) / float(segments);
            const float radius = (i == 0 || i == rings) ? 1.0f : 0.8f + 0.4f * rng.next_float();
            r.pos.insert(r.pos.end(), {radius * std::sin(theta) * std::cos(phi), radius * std::sin(theta) * std::sin(phi),
                                       radius * std::cos(theta)});
        }
    auto vid = [&](int i, int k) { return uint32_t(i * segments + (k % segments)); };
    auto push = [&](uint32_t a, uint32_t b, uint32_t c, uint32_t s) {
        for (uint32_t v : {a, b, c}) {
            r.idx.push_back(v);
            const Vec3f n = normalize(Vec3f(r.pos[3 * v], r.pos[3 * v + 1], r.pos[3 * v + 2]));
            r.nrm.insert(r.nrm.end(), {n.x, n.y, n.z});
        }
        r.slot.push_back(s);
    };
    for (int i = 0; i < rings; ++i)
        for (int k = 0; k < segments; ++k) {
            if (i != 0) push(vid(i, k), vid(i + 1, k), vid(i, k + 1), uint32_t(i & 1));
            if (i != rings - 1) push(vid(i, k + 1), vid(i + 1, k), vid(i + 1, k + 1), uint32_t(i & 1));
        }
    return r;
}

MeshInput rock_input(const Rock& r) {
    MeshInput m;
    m.name = "rock";
    m.positions = r.pos.data();
    m.vertex_count = r.pos.size() / 3;
    m.indices = r.idx.data();
    m.triangle_count = r.idx.size() / 3;
    m.normals = r.nrm.data();
    m.material_ids = r.slot.data();
    return m;
}

// Rotation about a random axis, per-axis scales in [0.4, 1.6] (every third
// mirrored), a translation over [-6, 6]^2 x [0, 3]; the last one nearly
// singular (a 1e-4 thin pancake).
std::vector<Transform> random_transforms(Pcg32& rng, int n) {
    std::vector<Transform> out;
    for (int i = 0; i < n; ++i) {
        const Vec3f axis = normalize(Vec3f(rng.next_float() - 0.5f, rng.next_float() - 0.5f, rng.next_float() - 0.5f));
        const float angle = 2.0f * kPi * rng.next_float(), c = std::cos(angle), s = std::sin(angle);
        const float R[3][3] = {
            {c + axis.x * axis.x * (1 - c), axis.x * axis.y * (1 - c) - axis.z * s, axis.x * axis.z * (1 - c) + axis.y * s},
            {axis.y * axis.x * (1 - c) + axis.z * s, c + axis.y * axis.y * (1 - c), axis.y * axis.z * (1 - c) - axis.x * s},
            {axis.z * axis.x * (1 - c) - axis.y * s, axis.z * axis.y * (1 - c) + axis.x * s, c + axis.z * axis.z * (1 - c)}};
        Vec3f scale{0.4f + 1.2f * rng.next_float(), 0.4f + 1.2f * rng.next_float(), 0.4f + 1.2f * rng.next_float()};
        if (i % 3 == 0) scale.x = -scale.x;
        if (i == n - 1) scale.z = 1e-4f;
        const Vec3f t{12.0f * rng.next_float() - 6.0f, 12.0f * rng.next_float() - 6.0f, 3.0f * rng.next_float()};
        Transform x;
        for (int r = 0; r < 3; ++r) {
            for (int k = 0; k < 3; ++k) x.m[r][k] = R[r][k] * scale[k];
            x.m[r][3] = t[r];
        }
        out.push_back(x);
    }
    return out;
}

// The same rocks, instanced (one prototype) and flattened (add_mesh each).
struct RockField {
    Scene instanced, flattened;
    std::vector<Transform> xf;
    size_t tris_per_rock = 0;
};

// With `moving`, each rock grows by 10 % and slides by (0.7, 0.3, 0) over the shutter.
void build_field(RockField& f, uint32_t seed, int count, const std::vector<uint32_t>& slots, bool moving = false) {
    Pcg32 rng(seed);
    const Rock rock = make_rock(rng);
    f.xf = random_transforms(rng, count);
    std::vector<Transform> close = f.xf;
    for (Transform& x : close)
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c) x.m[r][c] *= 1.1f;
            x.m[r][3] += r == 0 ? 0.7f : (r == 1 ? 0.3f : 0.0f);
        }
    for (Scene* s : {&f.instanced, &f.flattened})
        for (size_t m = 1; m < 4; ++m) s->add_material(diffuse_material(Vec3f(0.2f * float(m), 0.5f, 0.7f)));
    MeshInput in = rock_input(rock);
    const uint32_t proto = f.instanced.add_prototype(in);
    ASSERT_NE(proto, Scene::kNoPrototype);
    f.tris_per_rock = f.instanced.prototypes[proto].triangle_count();
    ASSERT_EQ(f.instanced.add_instances(proto, f.xf.data(), f.xf.size(), slots, "rocks", moving ? close.data() : nullptr),
              f.xf.size());
    in.material_slots = slots;
    for (size_t i = 0; i < f.xf.size(); ++i) {
        in.object_to_world = f.xf[i];
        in.moves = moving;
        in.object_to_world_close = close[i];
        ASSERT_EQ(f.flattened.add_mesh(in), f.tris_per_rock);
    }
}

Ray random_ray(Pcg32& rng) {
    Ray r;
    r.o = {20.0f * rng.next_float() - 10.0f, 20.0f * rng.next_float() - 10.0f, 10.0f * rng.next_float() - 3.0f};
    const Vec3f target{14.0f * rng.next_float() - 7.0f, 14.0f * rng.next_float() - 7.0f, 4.0f * rng.next_float() - 0.5f};
    r.d = (target - r.o) * (0.5f + rng.next_float());  // not unit: t must survive the transform unscaled
    r.tmin = 0.0f;
    r.tmax = rng.next_float() < 0.2f ? 0.8f : kInf;
    return r;
}

bool same_hit(const Hit& a, const Hit& b) {
    return a.prim == b.prim && a.instance == b.instance && (!a.valid() || (a.t == b.t && a.u == b.u && a.v == b.v));
}

// Closest hit in double precision over every instanced triangle carried to
// the world (Moller-Trumbore): an oracle sharing no code with the kernels.
struct OracleHit {
    double t = INFINITY;
    uint32_t instance = kInvalidPrim, prim = kInvalidPrim;
};

OracleHit brute_force(const Scene& s, const Ray& r) {
    OracleHit best;
    for (uint32_t i = 0; i < s.instances.size(); ++i) {
        const Instance& inst = s.instances[i];
        const Prototype& p = s.prototypes[inst.prototype];
        for (uint32_t t = 0; t < p.triangle_count(); ++t) {
            double v[3][3];
            for (int k = 0; k < 3; ++k)
                for (int a = 0; a < 3; ++a) {
                    const float* m = inst.object_to_world.m[a];
                    const Vec3f& o = p.vertices[3 * t + k];
                    v[k][a] = double(m[0]) * o.x + double(m[1]) * o.y + double(m[2]) * o.z + double(m[3]);
                }
            const double e1[3] = {v[1][0] - v[0][0], v[1][1] - v[0][1], v[1][2] - v[0][2]};
            const double e2[3] = {v[2][0] - v[0][0], v[2][1] - v[0][1], v[2][2] - v[0][2]};
            const double d[3] = {r.d.x, r.d.y, r.d.z};
            const double pv[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2], d[0] * e2[1] - d[1] * e2[0]};
            const double det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
            if (det == 0.0) continue;
            const double tv[3] = {r.o.x - v[0][0], r.o.y - v[0][1], r.o.z - v[0][2]};
            const double u = (tv[0] * pv[0] + tv[1] * pv[1] + tv[2] * pv[2]) / det;
            const double qv[3] = {tv[1] * e1[2] - tv[2] * e1[1], tv[2] * e1[0] - tv[0] * e1[2], tv[0] * e1[1] - tv[1] * e1[0]};
            const double w = (d[0] * qv[0] + d[1] * qv[1] + d[2] * qv[2]) / det;
            const double tt = (e2[0] * qv[0] + e2[1] * qv[1] + e2[2] * qv[2]) / det;
            if (u < 0 || w < 0 || u + w > 1 || !(tt > r.tmin) || tt > r.tmax || tt >= best.t) continue;
            best = {tt, i, t};
        }
    }
    return best;
}

}  // namespace

TEST(Instances, PrototypeIsStoredOnceAndInstancesAreValidated) {
    RockField f;
    build_field(f, 1, 50, {1, 2});
    const Scene& s = f.instanced;
    EXPECT_EQ(s.prototypes.size(), 1u);
    EXPECT_EQ(s.instances.size(), 50u);
    EXPECT_EQ(s.triangle_count(), 0u);  // nothing flattened
    EXPECT_EQ(s.instanced_triangle_count(), 50 * f.tris_per_rock);
    EXPECT_EQ(f.flattened.triangle_count(), 50 * f.tris_per_rock);
    // The instanced scene's bounds hold the flattened triangles.
    const BBox b = s.bounds(), fb = f.flattened.bounds();
    for (int a = 0; a < 3; ++a) {
        EXPECT_LE(b.lo[a], fb.lo[a]);
        EXPECT_GE(b.hi[a], fb.hi[a]);
    }
    // A singular transform is skipped and reported; an emissive material
    // flattens its instances (next-event estimation samples them).
    Scene t = s;
    Transform flat;
    flat.m[2][2] = 0.0f;
    EXPECT_EQ(t.add_instances(0, &flat, 1, {1}, "flat"), 0u);
    EXPECT_NE(t.dropped.summary().find("non-invertible"), std::string::npos) << t.dropped.summary();
    const uint32_t light = t.add_material(emission_material(Vec3f(1.0f)));
    EXPECT_EQ(t.add_instances(0, f.xf.data(), 2, {light}, "glow"), 2u);
    EXPECT_EQ(t.instances.size(), 50u);
    EXPECT_EQ(t.triangle_count(), 2 * f.tris_per_rock);
    EXPECT_THROW(t.add_instances(7, f.xf.data(), 1, {}, "x"), std::invalid_argument);
    t.finalize();
    EXPECT_TRUE(t.features.emissive_meshes);
}

TEST(Instances, EveryKernelAgreesAndMatchesTheFlattenedTriangles) {
    RockField f;
    build_field(f, 2, 50, {1, 2});
    Bvh flat;
    flat.build(f.flattened);
    InstanceBvh inst;
    inst.build(f.instanced);
    Pcg32 rng(7);
    std::vector<Ray> rays(4096);
    for (Ray& r : rays) r = random_ray(rng);

    std::vector<Hit> single(rays.size()), streamed(rays.size());
    std::vector<uint8_t> single_occ(rays.size()), streamed_occ(rays.size(), 0);
    for (size_t i = 0; i < rays.size(); ++i) {
        inst.intersect(rays[i], single[i]);
        single_occ[i] = inst.occluded(rays[i]) ? 1 : 0;
        EXPECT_EQ(single_occ[i], single[i].valid() ? 1 : 0) << i;
    }
    inst.intersect_stream(rays.data(), rays.size(), streamed.data());
    inst.occluded_stream(rays.data(), rays.size(), streamed_occ.data());
    for (size_t i = 0; i < rays.size(); ++i) {
        EXPECT_TRUE(same_hit(single[i], streamed[i])) << "stream, ray " << i;
        EXPECT_EQ(single_occ[i], streamed_occ[i]) << "stream, ray " << i;
    }
    auto packet = std::make_unique<RayPacket>();
    auto hits = std::make_unique<HitPacket>();
    for (size_t b = 0; b < rays.size(); b += 100) {  // sizes not a multiple of 8, every third lane inactive
        packet->clear();
        for (size_t i = b; i < std::min(b + 100, rays.size()); ++i) packet->push(rays[i]);
        for (int l = 0; l < packet->size; l += 3) packet->active[l >> 5] &= ~(1u << (l & 31));
        hits->reset(packet->size);
        inst.intersect(*packet, *hits);
        OcclusionMask occ;
        inst.occluded(*packet, occ);
        for (int l = 0; l < packet->size; ++l) {
            const bool active = packet->is_active(l);
            EXPECT_TRUE(same_hit(hits->hit(l), active ? single[b + l] : Hit{})) << "packet, ray " << b + l;
            EXPECT_EQ(occ.test(l), active && single_occ[b + l]) << "packet, ray " << b + l;
        }
    }

    // Against the flattened triangles: the same triangle at nearly the same
    // t, except for rays grazing an edge (the transform rounds differently).
    size_t hits_found = 0, differ = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
        Hit h;
        const bool found = flat.intersect(rays[i], h);
        hits_found += found;
        if (found != single[i].valid() ||
            (found && (h.prim != single[i].instance * f.tris_per_rock + single[i].prim ||
                       std::fabs(h.t - single[i].t) > 1e-4f * h.t)))
            ++differ;
    }
    EXPECT_GT(hits_found, rays.size() / 4);
    EXPECT_LE(differ, rays.size() / 500) << differ << " of " << rays.size();
}

TEST(Instances, HitsMatchABruteForceThroughTheTransforms) {
    RockField f;
    build_field(f, 3, 12, {1, 2});
    InstanceBvh inst;
    inst.build(f.instanced);
    Pcg32 rng(11);
    size_t hits = 0, differ = 0, thin = 0;
    const uint32_t pancake = uint32_t(f.xf.size() - 1);
    for (int i = 0; i < 1500; ++i) {
        Ray r = random_ray(rng);
        if (i % 2 == 0) {  // aim at the near-singular (1e-4 thin) instance, unscaled radius 0.8 or more
            const Transform& x = f.xf[pancake];
            const Vec3f target = x.point({rng.next_float() - 0.5f, rng.next_float() - 0.5f, 0.0f});
            r.o = target + normalize(Vec3f(rng.next_float() - 0.5f, rng.next_float() - 0.5f, rng.next_float() - 0.5f));
            r.d = target - r.o;
            r.tmax = kInf;
        }
        Hit h;
        inst.intersect(r, h);
        const OracleHit o = brute_force(f.instanced, r);
        hits += h.valid();
        thin += h.valid() && h.instance == pancake;
        const bool agree = h.valid() == (o.instance != kInvalidPrim) &&
                           (!h.valid() || (h.instance == o.instance && h.prim == o.prim &&
                                           std::fabs(double(h.t) - o.t) <= 1e-4 * o.t));
        differ += agree ? 0 : 1;
    }
    EXPECT_GT(hits, 300u);
    EXPECT_GT(thin, 150u);
    EXPECT_LE(differ, 4u) << "of " << hits << " hits";  // edge grazers only
}

TEST(Instances, SpawnedRaysNeverHitTheirOwnInstancedSurface) {
    // Far from the origin and with large and tiny scales, a ray leaving an
    // instanced surface point (offset by the error bound that includes both
    // directions of the transform) never meets its own triangle again.
    Pcg32 rng(5);
    const Rock rock = make_rock(rng);
    Scene s;
    const uint32_t proto = s.add_prototype(rock_input(rock));
    std::vector<Transform> xf = random_transforms(rng, 30);
    for (size_t i = 0; i < xf.size(); ++i) {
        const float k = i % 2 ? 3000.0f : 0.01f;
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c) xf[i].m[r][c] *= k;
            xf[i].m[r][3] = xf[i].m[r][3] * 2000.0f + 1e4f;
        }
    }
    s.add_instances(proto, xf.data(), xf.size(), {}, "rocks");
    InstanceBvh inst;
    inst.build(s);
    size_t surfaces = 0, self_hits = 0;
    for (size_t i = 0; i < s.instances.size(); ++i) {
        const Instance& in = s.instances[i];
        for (int n = 0; n < 200; ++n) {
            Ray r;
            const Vec3f c = in.world_bounds.center(), e = in.world_bounds.extent();
            r.o = c + e * 3.0f;
            r.d = c + Vec3f(rng.next_float() - 0.5f, rng.next_float() - 0.5f, rng.next_float() - 0.5f) * e * 0.5f - r.o;
            Hit h;
            if (!inst.intersect(r, h)) continue;
            const InstancedPoint ip = instanced_point(s, h);
            for (float side : {1.0f, -1.0f}) {
                const Vec3f w = normalize(ip.ng * side + Vec3f(rng.next_float() - 0.5f, rng.next_float() - 0.5f,
                                                               rng.next_float() - 0.5f) * 0.9f);
                Ray out;
                out.o = offset_ray_origin(ip.p, ip.p_error, ip.ng, w);
                out.d = w;
                out.tmin = 0.0f;
                Hit again;
                ++surfaces;
                if (inst.intersect(out, again) && again.instance == h.instance && again.prim == h.prim) ++self_hits;
            }
        }
    }
    EXPECT_GT(surfaces, 2000u);
    EXPECT_EQ(self_hits, 0u);
}

namespace {

// Every traversal renders the instanced rocks bit for bit as single rays
// do, and that image matches the flattened rocks' within rounding.
void check_images(RockField& f) {
    for (Scene* s : {&f.instanced, &f.flattened}) {
        add_quad(*s, {0, 0, -0.5f}, {1, 0, 0}, {0, 1, 0}, 20.0f, 20.0f, 3, "floor");
        const uint32_t light = s->add_material(emission_material(Vec3f(6.0f)));
        add_quad(*s, {2, 1, 9}, {0, 1, 0}, {1, 0, 0}, 4.0f, 4.0f, light, "light");
        s->camera = ortho_camera_looking_down(12.0f, 8.0f);
        s->world_color = Vec3f(0.1f);
        s->finalize();
    }
    RenderSettings rs;
    rs.width = 40;
    rs.height = 40;
    rs.spp = 16;
    rs.threads = 2;
    rs.sampler = SamplerType::Cpt;
    const std::vector<float> single = render_combined(f.instanced, rs);
    for (Traversal t : {Traversal::Packet, Traversal::Stream, Traversal::Wavefront}) {
        rs.traversal = t;
        EXPECT_EQ(render_combined(f.instanced, rs), single) << traversal_name(t);
    }
    rs.traversal = Traversal::Single;
    const std::vector<float> flat = render_combined(f.flattened, rs);
    // Same samples, same hits but for rounding: per-pixel differences are
    // rare and the means agree far inside the 16-spp noise.
    double mean_i = 0.0, mean_f = 0.0, abs_diff = 0.0;
    for (size_t i = 0; i < single.size(); i += 4) {
        mean_i += single[i] + single[i + 1] + single[i + 2];
        mean_f += flat[i] + flat[i + 1] + flat[i + 2];
        abs_diff += std::fabs(single[i] - flat[i]);
    }
    ASSERT_GT(mean_f, 0.0);
    EXPECT_NEAR(mean_i / mean_f, 1.0, 0.01);
    EXPECT_LT(abs_diff / mean_f, 0.02);
}

}  // namespace

TEST(Instances, EveryTraversalRendersTheSameImageAndItMatchesTheFlattenedOne) {
    RockField f;
    build_field(f, 4, 50, {1, 2});
    check_images(f);
}

TEST(Instances, MovingInstancesRenderAsMovingFlattenedTriangles) {
    RockField f;
    build_field(f, 6, 50, {1, 2}, true);
    ASSERT_TRUE(f.instanced.has_moving_instances());
    f.instanced.finalize();
    EXPECT_TRUE(f.instanced.features.motion_blur);
    check_images(f);
}

TEST(Instances, MovingInstancesMatchTheMovingFlattenedTrianglesAtRandomTimes) {
    RockField f;
    build_field(f, 8, 20, {1}, true);
    f.flattened.finalize();
    MotionBvh moving;
    moving.build(f.flattened.vertices, f.flattened.motion_vertices, f.flattened.moving_triangles);
    InstanceBvh inst;
    inst.build(f.instanced);
    Pcg32 rng(9);
    size_t hits = 0, differ = 0;
    for (int i = 0; i < 3000; ++i) {
        const Ray r = random_ray(rng);
        const float tau = rng.next_float();
        Hit h, g;
        const bool found = inst.intersect(r, h, nullptr, tau);
        EXPECT_EQ(inst.occluded(r, nullptr, tau), found);
        const bool expect = moving.intersect(r, tau, g);
        hits += found;
        differ += found != expect || (found && (g.prim != h.instance * f.tris_per_rock + h.prim ||
                                                std::fabs(g.t - h.t) > 1e-4f * g.t));
    }
    EXPECT_GT(hits, 500u);
    EXPECT_LE(differ, 6u) << "of " << hits << " hits";
}

// Persistent data: a re-render's instance BVH takes the BVH of every
// prototype whose triangles did not change, wherever it now sits in the
// prototype list, builds the others, and traces exactly like a fresh build.
TEST(Instances, RebuildReusesUnchangedPrototypesAndTracesLikeAFreshBuild) {
    Pcg32 rng(11);
    const Rock kept = make_rock(rng), before = make_rock(rng), after = make_rock(rng);
    auto place = [&](Scene& s, const std::vector<const Rock*>& rocks, uint32_t seed) {
        s.add_material(diffuse_material(Vec3f(0.5f)));
        Pcg32 xf_rng(seed);
        for (const Rock* r : rocks) {
            const uint32_t p = s.add_prototype(rock_input(*r));
            ASSERT_NE(p, Scene::kNoPrototype);
            const std::vector<Transform> xf = random_transforms(xf_rng, 20);
            ASSERT_EQ(s.add_instances(p, xf.data(), xf.size(), {1}, "rocks"), xf.size());
        }
        s.finalize();
    };
    Scene first, second;
    place(first, {&before, &kept}, 1);
    place(second, {&kept, &after}, 2);  // `kept` moved to slot 0 and re-placed; `before` became `after`
    InstanceBvh previous;
    previous.build(first);
    EXPECT_EQ(previous.built_prototypes(), 2u);
    InstanceBvh reused, fresh;
    reused.build_reusing(second, previous, first);
    fresh.build(second);
    EXPECT_EQ(reused.reused_prototypes(), 1u);
    EXPECT_EQ(reused.built_prototypes(), 1u);

    Pcg32 ray_rng(5);
    size_t hits_found = 0;
    for (int i = 0; i < 4096; ++i) {
        const Ray ray = random_ray(ray_rng);
        Hit a, b;
        reused.intersect(ray, a);
        fresh.intersect(ray, b);
        EXPECT_TRUE(same_hit(a, b)) << "ray " << i;
        EXPECT_EQ(reused.occluded(ray), fresh.occluded(ray)) << "ray " << i;
        hits_found += a.valid() ? 1 : 0;
    }
    EXPECT_GT(hits_found, 400u);  // the rays do meet the rocks
}
