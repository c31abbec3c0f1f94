// Render modes (render_modes.h): every traversal and packet assembly gives
// the same image as single rays; the integrators are the continuation rules
// they claim to be (checked against path tracing with the matching Blender
// bounce limits); ambient occlusion and the heatmap passes hold their ranges;
// per-bounce statistics add up.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "render/renderer.h"
#include "test_render_helpers.h"

using namespace coherent;
using namespace coherent::test;

namespace {

RenderSettings modes_settings(Integrator integrator, Traversal traversal, SamplerType sampler) {
    RenderSettings rs;
    rs.width = 40;  // not a multiple of the packet or tile size: partial packets
    rs.height = 36;
    rs.spp = 2;
    rs.seed = 7;
    rs.threads = 2;
    rs.integrator = integrator;
    rs.traversal = traversal;
    rs.sampler = sampler;
    rs.ao_samples = 4;
    return rs;
}

std::vector<float> render(const Scene& scene, const RenderSettings& rs, RenderStats* stats = nullptr,
                          std::vector<float>* visits = nullptr, std::vector<float>* simd = nullptr) {
    Renderer r(scene, rs);
    EXPECT_TRUE(r.render());
    if (stats) *stats = r.stats();
    if (visits) *visits = r.film().resolve(PassType::NodeVisits);
    if (simd) *simd = r.film().resolve(PassType::SimdUtilisation);
    return r.film().resolve(PassType::Combined);
}

// Exact equality, with the first differing value in the message.
void expect_same_image(const std::vector<float>& a, const std::vector<float>& b, const std::string& what) {
    ASSERT_EQ(a.size(), b.size()) << what;
    size_t diffs = 0, first = 0;
    for (size_t i = 0; i < a.size(); ++i)
        if (!(a[i] == b[i]) && !(std::isnan(a[i]) && std::isnan(b[i]))) {
            if (diffs++ == 0) first = i;
        }
    EXPECT_EQ(diffs, 0u) << what << ": first difference at float " << first << ": " << a[first] << " vs "
                         << b[first];
}

double mean(const std::vector<float>& rgba) {
    double m = 0.0;
    for (size_t i = 0; i < rgba.size(); i += 4) m += (rgba[i] + rgba[i + 1] + rgba[i + 2]) / 3.0;
    return m / double(rgba.size() / 4);
}

const Integrator kIntegrators[] = {Integrator::PathTrace, Integrator::Distribution, Integrator::Whitted,
                                   Integrator::RayCast, Integrator::AmbientOcclusion};
const SamplerType kSamplers[] = {SamplerType::Spt, SamplerType::Cpt, SamplerType::Icpt};

}  // namespace

TEST(RenderModes, PacketsGiveTheSingleRayImageForEveryIntegratorSamplerAndAssembly) {
    const Scene scene = lobes_scene(true);
    for (Integrator integrator : kIntegrators)
        for (SamplerType sampler : kSamplers) {
            const std::string what =
                std::string(integrator_name(integrator)) + "/" + std::string(sampler_type_name(sampler));
            for (int packet : {2, 4, 16}) {
                // The packet size also sets CPT's and ICPT's sequence regions.
                RenderSettings rs1 = modes_settings(integrator, Traversal::Single, sampler);
                rs1.packet_width = rs1.packet_height = packet;
                const auto single = render(scene, rs1);
                for (PacketAssembly assembly : {PacketAssembly::RayType, PacketAssembly::Runs}) {
                    RenderSettings rs = modes_settings(integrator, Traversal::Packet, sampler);
                    rs.assembly = assembly;
                    rs.packet_width = rs.packet_height = packet;
                    expect_same_image(single, render(scene, rs),
                                      what + " packet " + std::to_string(packet) + " " +
                                          std::string(assembly_name(assembly)));
                }
            }
        }
}

// Single rays and packets under CPT draw each random set once per packet
// of pixels that share it (SharedSets), walking tiles block by block. Tiles
// that cut blocks, packets that are not the tile's divisors, and runs of
// several samples per pixel must still give every path its own numbers: the
// stream driver, which shares nothing, renders the oracle.
TEST(RenderModes, CptSharingNumbersPerPacketGivesTheUnsharedImage) {
    const Scene scene = lobes_scene(true);
    for (int packet : {3, 4})
        for (int tile : {7, 16}) {
            RenderSettings rs = modes_settings(Integrator::PathTrace, Traversal::Stream, SamplerType::Cpt);
            rs.spp = 6;
            rs.max_bounces = 3;
            rs.tile_size = tile;
            rs.packet_width = rs.packet_height = packet;
            rs.report_interval = 60.0;  // batches of passes: pixel runs of several samples
            const auto unshared = render(scene, rs);
            for (Traversal t : {Traversal::Single, Traversal::Packet}) {
                rs.traversal = t;
                expect_same_image(unshared, render(scene, rs),
                                  std::string(traversal_name(t)) + " packet " + std::to_string(packet) + " tile " +
                                      std::to_string(tile));
            }
        }
}

TEST(RenderModes, StreamsAndWavefrontGiveTheSingleRayImage) {
    const Scene scene = lobes_scene(true);
    for (Integrator integrator : kIntegrators)
        for (SamplerType sampler : {SamplerType::Spt, SamplerType::Cpt}) {
            const std::string what =
                std::string(integrator_name(integrator)) + "/" + std::string(sampler_type_name(sampler));
            const auto single = render(scene, modes_settings(integrator, Traversal::Single, sampler));
            expect_same_image(single, render(scene, modes_settings(integrator, Traversal::Stream, sampler)),
                              what + " stream");
            for (ReorderMode reorder : {ReorderMode::None, ReorderMode::Static1D, ReorderMode::Static3D,
                                        ReorderMode::Hash32, ReorderMode::Hash192, ReorderMode::Csd32})
                for (int wave : {97, 1 << 16}) {  // several waves per pass, and one
                    RenderSettings rs = modes_settings(integrator, Traversal::Wavefront, sampler);
                    rs.reorder = reorder;
                    rs.wave_size = wave;
                    expect_same_image(single, render(scene, rs),
                                      what + " wavefront " + std::string(reorder_name(reorder)) + " wave " +
                                          std::to_string(wave));
                }
        }
    // Every tree width traces the same hits.
    for (int width : {2, 4}) {
        RenderSettings rs = modes_settings(Integrator::PathTrace, Traversal::Single, SamplerType::Spt);
        const auto eight = render(scene, rs);
        rs.bvh_width = width;
        expect_same_image(eight, render(scene, rs), "bvh width " + std::to_string(width));
    }
}

TEST(RenderModes, AutoTraversalTrialsBothAndKeepsTheImage) {
    // Auto with CPT traces pass 0 with single rays and pass 1 with packets,
    // then keeps the faster: whichever it keeps, the image is the
    // single-ray image, and the traversal it reports is one of the two.
    const Scene scene = lobes_scene(true);
    RenderSettings rs = modes_settings(Integrator::PathTrace, Traversal::Single, SamplerType::Cpt);
    rs.spp = 6;
    const auto single = render(scene, rs);
    rs.traversal = Traversal::Auto;
    Renderer r(scene, rs);
    EXPECT_EQ(r.settings().traversal, Traversal::Packet);  // resolved for CPT
    ASSERT_TRUE(r.render());
    expect_same_image(single, r.film().resolve(PassType::Combined), "auto");
    EXPECT_TRUE(r.settings().traversal == Traversal::Packet || r.settings().traversal == Traversal::Single);
    // Auto with SPT is single rays.
    rs.sampler = SamplerType::Spt;
    EXPECT_EQ(Renderer(scene, rs).settings().traversal, Traversal::Single);
}

TEST(RenderModes, IntegratorsAreThePathTracerWithTheirBounceRules) {
    // Ray casting is direct light at the first hit: path tracing with Max
    // Bounces 0. Distribution ray tracing drops diffuse interreflection:
    // path tracing with Diffuse Bounces 0. Same numbers, so same image
    // (without depth of field, which ray casting ignores by design).
    const Scene scene = lobes_scene(false);
    for (Traversal traversal : {Traversal::Single, Traversal::Packet}) {
        RenderSettings pt0 = modes_settings(Integrator::PathTrace, traversal, SamplerType::Spt);
        pt0.max_bounces = 0;
        expect_same_image(render(scene, modes_settings(Integrator::RayCast, traversal, SamplerType::Spt)),
                          render(scene, pt0), "rcs vs pt with max bounces 0");
        RenderSettings pt_nodiffuse = modes_settings(Integrator::PathTrace, traversal, SamplerType::Spt);
        pt_nodiffuse.diffuse_bounces = 0;
        expect_same_image(render(scene, modes_settings(Integrator::Distribution, traversal, SamplerType::Spt)),
                          render(scene, pt_nodiffuse), "drt vs pt with diffuse bounces 0");
    }
    // Each integrator keeps a subset of the path tracer's (non-negative)
    // contributions, so image means are ordered pt >= drt >= wrt >= rcs; the
    // scene's diffuse interreflection, rough metal and mirror make every gap
    // far larger than the noise at this sample count.
    const Scene flat = lobes_scene(false);
    double m[4];
    int i = 0;
    for (Integrator integrator : {Integrator::PathTrace, Integrator::Distribution, Integrator::Whitted,
                                  Integrator::RayCast}) {
        RenderSettings rs = modes_settings(integrator, Traversal::Single, SamplerType::Spt);
        rs.spp = 64;
        m[i++] = mean(render(flat, rs));
    }
    EXPECT_GT(m[0], m[1] * 1.05) << "pt " << m[0] << " drt " << m[1];
    EXPECT_GT(m[1], m[2]) << "drt " << m[1] << " wrt " << m[2];
    EXPECT_GT(m[2], m[3] * 1.01) << "wrt " << m[2] << " rcs " << m[3];
}

TEST(RenderModes, WhittedAndRayCastingNeverSampleTheLens) {
    // A pinhole integrator ignores the aperture: the image with depth of
    // field equals the one without, bit for bit.
    for (Integrator integrator : {Integrator::Whitted, Integrator::RayCast}) {
        const auto with_lens = render(lobes_scene(true), modes_settings(integrator, Traversal::Single, SamplerType::Spt));
        const auto pinhole = render(lobes_scene(false), modes_settings(integrator, Traversal::Single, SamplerType::Spt));
        expect_same_image(with_lens, pinhole, std::string(integrator_name(integrator)));
    }
    // Path tracing does follow the lens.
    const auto a = render(lobes_scene(true), modes_settings(Integrator::PathTrace, Traversal::Single, SamplerType::Spt));
    const auto b = render(lobes_scene(false), modes_settings(Integrator::PathTrace, Traversal::Single, SamplerType::Spt));
    EXPECT_NE(a, b);
}

TEST(RenderModes, AmbientOcclusionIsAFractionOneOnOpenGroundZeroInsideAClosedBox) {
    const Scene scene = lobes_scene(false);
    RenderSettings rs = modes_settings(Integrator::AmbientOcclusion, Traversal::Packet, SamplerType::Cpt);
    rs.ao_samples = 16;
    rs.ao_distance = 0.5f;
    RenderStats stats;
    const auto img = render(scene, rs, &stats);
    int ones = 0, partial = 0;
    for (size_t i = 0; i < img.size(); i += 4) {
        ASSERT_GE(img[i], 0.0f);
        ASSERT_LE(img[i], 1.0f);
        EXPECT_EQ(img[i], img[i + 1]);
        ones += img[i] == 1.0f;
        partial += img[i] > 0.0f && img[i] < 1.0f;
    }
    EXPECT_GT(ones, int(img.size() / 4) / 4);  // open floor and background
    EXPECT_GT(partial, 20);                     // contact shadows under the spheres
    // 16 occlusion rays per camera ray that hit, no other shadow rays.
    EXPECT_GT(stats.rays[size_t(RayType::Shadow)], 0u);
    EXPECT_LE(stats.rays[size_t(RayType::Shadow)], 16 * stats.rays[size_t(RayType::Camera)]);

    // Inside a closed box every AO ray is blocked (the box is smaller than
    // the AO distance).
    Scene box;
    const uint32_t white = box.add_material(diffuse_material(Vec3f(0.5f)));
    add_quad(box, {0, 0, -1}, {1, 0, 0}, {0, 1, 0}, 2, 2, white, "bottom");
    add_quad(box, {0, 0, 1}, {0, 1, 0}, {1, 0, 0}, 2, 2, white, "top");
    add_quad(box, {-1, 0, 0}, {0, 1, 0}, {0, 0, 1}, 2, 2, white, "left");
    add_quad(box, {1, 0, 0}, {0, 0, 1}, {0, 1, 0}, 2, 2, white, "right");
    add_quad(box, {0, -1, 0}, {0, 0, 1}, {1, 0, 0}, 2, 2, white, "front");
    add_quad(box, {0, 1, 0}, {1, 0, 0}, {0, 0, 1}, 2, 2, white, "back");
    Camera c;
    c.position = {0.0f, 0.0f, 0.0f};
    c.forward = {0.0f, 1.0f, 0.0f};
    c.right = {1.0f, 0.0f, 0.0f};
    c.up = {0.0f, 0.0f, 1.0f};
    c.half_width = c.half_height = 0.8f;
    box.camera = c;
    box.finalize();
    RenderSettings rb = modes_settings(Integrator::AmbientOcclusion, Traversal::Packet, SamplerType::Spt);
    rb.ao_distance = 10.0f;
    const auto inside = render(box, rb);
    for (size_t i = 0; i < inside.size(); i += 4) EXPECT_EQ(inside[i], 0.0f) << "pixel " << i / 4;
}

TEST(RenderModes, HeatmapsHoldNodeVisitsAndUtilisation) {
    const Scene scene = lobes_scene(false);
    for (Traversal traversal : {Traversal::Single, Traversal::Packet}) {
        RenderSettings rs = modes_settings(Integrator::PathTrace, traversal, SamplerType::Cpt);
        rs.heatmaps = true;
        RenderStats stats;
        std::vector<float> visits, simd;
        render(scene, rs, &stats, &visits, &simd);
        ASSERT_EQ(visits.size(), size_t(rs.width * rs.height));
        double total = 0.0;
        for (size_t i = 0; i < visits.size(); ++i) {
            EXPECT_TRUE(std::isfinite(visits[i]));
            EXPECT_GE(visits[i], 0.0f);
            EXPECT_GT(simd[i], 0.0f);
            EXPECT_LE(simd[i], 1.0f);
            if (traversal == Traversal::Single) {
                EXPECT_EQ(simd[i], 1.0f);
            }
            total += visits[i];
        }
        // Every camera ray enters the root: at least one visit per sample.
        for (float v : visits) EXPECT_GE(v, 1.0f);
        // Single rays: the pass sums to the render's node visits (per sample
        // mean x spp). A packet's node visit counts once in the statistics
        // but once for every ray active at it in the pass, so the pass is at
        // least the statistics.
        const double node_visits = double(stats.traversal.node_visits);
        if (traversal == Traversal::Single)
            EXPECT_NEAR(total * rs.spp, node_visits, 1e-4 * node_visits);
        else
            EXPECT_GE(total * rs.spp, node_visits * (1.0 - 1e-4));
        if (traversal == Traversal::Packet) {
            // A packet's lanes are not all busy at the edges of objects.
            double m = 0.0;
            for (float u : simd) m += u;
            EXPECT_LT(m / double(simd.size()), 1.0);
        }
    }
    // Off by default: zero passes.
    RenderSettings rs = modes_settings(Integrator::PathTrace, Traversal::Single, SamplerType::Spt);
    std::vector<float> visits, simd;
    render(scene, rs, nullptr, &visits, &simd);
    for (float v : visits) EXPECT_EQ(v, 0.0f);
}

TEST(RenderModes, PerBounceStatisticsAddUpToTheTotals) {
    const Scene scene = lobes_scene(false);
    for (Traversal traversal : {Traversal::Single, Traversal::Packet, Traversal::Stream, Traversal::Wavefront}) {
        RenderStats st;
        render(scene, modes_settings(Integrator::PathTrace, traversal, SamplerType::Cpt), &st);
        BounceStats sum;
        for (const BounceStats& b : st.bounces) sum += b;
        EXPECT_EQ(sum.rays, st.total_rays());
        EXPECT_EQ(sum.rays, st.traversal.rays);
        EXPECT_EQ(sum.box_tests, st.traversal.box_tests);
        EXPECT_EQ(sum.triangle_tests, st.traversal.triangle_tests);
        // Bounce 0 holds the camera rays and their shadow rays.
        EXPECT_GE(st.bounces[0].rays, st.rays[size_t(RayType::Camera)]);
        EXPECT_GT(st.bounces[1].rays, 0u);
        if (traversal == Traversal::Packet) {
            EXPECT_GT(sum.box_lanes, 0u);
            EXPECT_LE(sum.box_lanes_active, sum.box_lanes);
        }
    }
}
