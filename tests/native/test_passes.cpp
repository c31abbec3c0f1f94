// Cycles' render passes (film/passes.h): the light passes add up to
// Combined, enabling passes never changes Combined, and the data passes
// hold what they say on scenes where the answer is known exactly.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "test_render_helpers.h"

namespace coherent::test {
namespace {

PassMask all_passes() { return (PassMask(1) << kRenderPassCount) - 1; }

RenderSettings small_settings(int size, int spp) {
    RenderSettings rs;
    rs.width = rs.height = size;
    rs.spp = spp;
    rs.threads = 2;
    return rs;
}

constexpr Traversal kTraversals[] = {Traversal::Single, Traversal::Packet, Traversal::Stream, Traversal::Wavefront};

// The light passes of lobes_scene, 48 x 48 at 4 spp, with traversal t.
RenderSettings light_pass_settings(Traversal t) {
    RenderSettings rs = small_settings(48, 4);
    rs.traversal = t;
    rs.passes = kLightPassMask;
    return rs;
}

// (Dir + Ind) x Col per lobe, plus Emit and Env, per pixel and channel.
std::vector<float> light_pass_sum(const Film& film) {
    const size_t n = size_t(film.width()) * size_t(film.height());
    std::vector<float> sum(3 * n, 0.0f);
    const RenderPass lobes[3] = {RenderPass::DiffuseDirect, RenderPass::GlossyDirect, RenderPass::TransmissionDirect};
    for (RenderPass first : lobes) {
        const auto dir = film.resolve(pass_type(first));
        const auto ind = film.resolve(pass_type(RenderPass(int(first) + 1)));
        const auto col = film.resolve(pass_type(RenderPass(int(first) + 2)));
        for (size_t k = 0; k < 3 * n; ++k) sum[k] += (dir[k] + ind[k]) * col[k];
    }
    for (RenderPass p : {RenderPass::Emission, RenderPass::Environment}) {
        const auto v = film.resolve(pass_type(p));
        for (size_t k = 0; k < 3 * n; ++k) sum[k] += v[k];
    }
    return sum;
}

// Diffuse, mirror and rough metal, glass, an area light and the world seen
// at the image's edges: every light pass is non-zero somewhere.
TEST(Passes, LightPassesAddUpToCombinedForEveryTraversal) {
    const Scene scene = lobes_scene(false, 9.0f);
    for (Traversal t : kTraversals) {
        Renderer r(scene, light_pass_settings(t));
        r.render();
        const auto combined = r.film().resolve(PassType::Combined);
        const auto sum = light_pass_sum(r.film());
        double worst = 0.0;
        std::vector<double> pass_total(kRenderPassCount, 0.0);
        for (size_t i = 0; i < sum.size() / 3; ++i)
            for (int c = 0; c < 3; ++c) {
                const double want = combined[4 * i + c], got = sum[3 * i + c];
                worst = std::max(worst, std::abs(want - got) / std::max(1.0, std::abs(want)));
            }
        EXPECT_LT(worst, 2e-5) << "traversal " << int(t);
        for (int p = 0; p <= int(RenderPass::Environment); ++p) {
            // Smooth glass refracts twice before light can leave it: no TransDir.
            if (RenderPass(p) == RenderPass::TransmissionDirect) continue;
            double total = 0.0;
            for (float v : r.film().resolve(pass_type(RenderPass(p)))) total += v;
            EXPECT_GT(total, 0.0) << render_pass_info(RenderPass(p)).name << " is empty";
        }
    }
}

// The direct light the denoiser may filter apart (Film::add_direct_light,
// PathOutput::direct) is Cycles' Dir of every lobe plus Emit and Env, which
// the light passes compute on their own, for every traversal.
TEST(Passes, DenoisingDirectLightIsDirPlusEmitPlusEnv) {
    const Scene scene = lobes_scene(false, 9.0f);
    for (Traversal t : kTraversals) {
        RenderSettings rs = light_pass_settings(t);
        rs.denoising_data = true;
        Renderer r(scene, rs);
        r.render();
        const Film& film = r.film();
        const size_t n = size_t(film.width()) * size_t(film.height());
        std::vector<float> want(3 * n, 0.0f);
        for (RenderPass p : {RenderPass::DiffuseDirect, RenderPass::GlossyDirect, RenderPass::TransmissionDirect}) {
            const auto dir = film.resolve(pass_type(p));
            const auto col = film.resolve(pass_type(RenderPass(int(p) + 2)));
            for (size_t k = 0; k < 3 * n; ++k) want[k] += dir[k] * col[k];
        }
        for (RenderPass p : {RenderPass::Emission, RenderPass::Environment}) {
            const auto v = film.resolve(pass_type(p));
            for (size_t k = 0; k < 3 * n; ++k) want[k] += v[k];
        }
        const Film::Sums s = film.sums();
        ASSERT_NE(s.direct, nullptr);
        double worst = 0.0, total = 0.0, combined = 0.0;
        for (size_t i = 0; i < n; ++i)
            for (int c = 0; c < 3; ++c) {
                const double got = s.count[i] ? s.direct[3 * i + size_t(c)] / double(s.count[i]) : 0.0;
                worst = std::max(worst, std::abs(got - want[3 * i + size_t(c)]) / std::max(1.0, std::abs(got)));
                total += got;
                combined += s.count[i] ? s.rgba[4 * i + size_t(c)] / double(s.count[i]) : 0.0;
            }
        EXPECT_LT(worst, 2e-5) << "traversal " << int(t);
        // Not vacuous: direct light is most, not all, of this scene's light.
        EXPECT_GT(total, 0.3 * combined) << "traversal " << int(t);
        EXPECT_LT(total, 0.99 * combined) << "traversal " << int(t);
    }
}

// Passes copy contributions; they never change what Combined adds up.
TEST(Passes, EnablingPassesLeavesCombinedBitIdentical) {
    const Scene scene = lobes_scene(false, 9.0f);
    for (Traversal t : {Traversal::Single, Traversal::Packet, Traversal::Wavefront}) {
        RenderSettings rs = small_settings(32, 3);
        rs.traversal = t;
        const auto plain = render_combined(scene, rs);
        rs.passes = all_passes();
        const auto with_passes = render_combined(scene, rs);
        ASSERT_EQ(plain.size(), with_passes.size());
        for (size_t k = 0; k < plain.size(); ++k) ASSERT_EQ(plain[k], with_passes[k]) << "traversal " << int(t);
    }
}

// Two quads seen straight down by an orthographic camera: every data pass
// has one exact value per quad.
TEST(Passes, DataPassesOnKnownGeometry) {
    Scene s;
    const uint32_t a = s.add_material(diffuse_material(Vec3f(0.5f), "a"));
    const uint32_t b = s.add_material(principled(0.8f, 1.0f, 0.2f, 0.5f, 0.0f));
    add_quad(s, {-1, 0, 0}, {1, 0, 0}, {0, 1, 0}, 2.0f, 4.0f, a, "left");   // z = 0
    add_quad(s, {1, 0, -2}, {1, 0, 0}, {0, 1, 0}, 2.0f, 4.0f, b, "right");  // z = -2
    s.camera = ortho_camera_looking_down(10.0f, 2.0f);
    s.world_color = Vec3f(0.3f);
    s.data_passes.object_pass_index = {3.0f, 7.0f};  // object_names order: left, right
    s.data_passes.material_pass_index = {0.0f, 5.0f, 9.0f};
    s.data_passes.mist_start = 8.0f;
    s.data_passes.mist_depth = 8.0f;
    s.data_passes.mist_falloff = 2.0f;
    s.data_passes.ao_distance = 1.0f;
    s.finalize();
    ASSERT_EQ(s.object_names.size(), 2u);
    RenderSettings rs = small_settings(16, 4);
    rs.passes = all_passes();
    Renderer r(s, rs);
    r.render();
    const Film& f = r.film();
    const auto mist = f.resolve(pass_type(RenderPass::Mist)), pos = f.resolve(pass_type(RenderPass::Position));
    const auto ob = f.resolve(pass_type(RenderPass::IndexOB)), ma = f.resolve(pass_type(RenderPass::IndexMA)), ao = f.resolve(pass_type(RenderPass::AO));
    const auto dcol = f.resolve(pass_type(RenderPass::DiffuseColor)), gcol = f.resolve(pass_type(RenderPass::GlossyColor));
    for (int y = 2; y < 14; ++y)
        for (const int x : {3, 12}) {
            const size_t i = size_t(y) * 16 + size_t(x);
            const bool left = x < 8;
            // Distance 10 (left) or 12 (right): mist ((d - 8) / 8)^2.
            EXPECT_NEAR(mist[i], left ? 0.0625f : 0.25f, 1e-5f);
            EXPECT_NEAR(pos[3 * i + 2], left ? 0.0f : -2.0f, 1e-5f);
            EXPECT_EQ(ob[i], left ? 3.0f : 7.0f);
            EXPECT_EQ(ma[i], left ? 5.0f : 9.0f);
            // Nothing above either quad within the AO distance.
            EXPECT_EQ(ao[3 * i], 1.0f);
            EXPECT_NEAR(dcol[3 * i], left ? 0.5f : 0.0f, 1e-6f);
            EXPECT_GT(gcol[3 * i], left ? -1.0f : 0.5f);
        }
}

// Mist is 1 and the indices 0 where the camera sees only the world; AO is
// 0 there (no AO ray is cast), Env holds the world.
TEST(Passes, WorldPixels) {
    Scene s;
    s.add_material(diffuse_material(Vec3f(0.5f)));
    add_quad(s, {100, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1.0f, 1.0f, 0, "away");
    s.camera = ortho_camera_looking_down(10.0f, 2.0f);
    s.world_color = Vec3f(0.25f, 0.5f, 1.0f);
    s.finalize();
    RenderSettings rs = small_settings(8, 2);
    rs.passes = all_passes();
    Renderer r(s, rs);
    r.render();
    const Film& f = r.film();
    const auto mist = f.resolve(pass_type(RenderPass::Mist)), ob = f.resolve(pass_type(RenderPass::IndexOB));
    const auto env = f.resolve(pass_type(RenderPass::Environment)), ao = f.resolve(pass_type(RenderPass::AO));
    for (size_t i = 0; i < 64; ++i) {
        EXPECT_EQ(mist[i], 1.0f);
        EXPECT_EQ(ob[i], 0.0f);
        EXPECT_EQ(ao[3 * i], 0.0f);
        EXPECT_FLOAT_EQ(env[3 * i + 2], 1.0f);
    }
}

// A 4 x 4 quad filling an orthographic view, its active render UV map ("")
// the affine (x + 2, y + 2) / 4: the UV pass is each pixel's position in the
// image to within the half pixel a sample may land off its centre, with A = 1.
// A scene whose programs ask for no "" map has no UVs for the pass: zeros.
TEST(Passes, UvPassReadsTheActiveRenderMap) {
    for (const bool requested : {true, false}) {
        Scene s;
        s.shading.uv_names = requested ? std::vector<std::string>{"other", ""} : std::vector<std::string>{"other"};
        const float pos[] = {-2, -2, 0, 2, -2, 0, 2, 2, 0, -2, 2, 0};
        const uint32_t idx[] = {0, 1, 2, 0, 2, 3};
        const float uv[] = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1};  // per corner of both triangles
        const float swapped[] = {0, 0, 0, 1, 1, 1, 0, 0, 1, 1, 1, 0};
        MeshInput m;
        m.positions = pos;
        m.vertex_count = 4;
        m.indices = idx;
        m.triangle_count = 2;
        m.material_slots = {s.add_material(diffuse_material(Vec3f(0.5f), "a"))};
        m.shading.uvs = requested ? std::vector<const float*>{swapped, uv} : std::vector<const float*>{swapped};
        s.add_mesh(m);
        s.camera = ortho_camera_looking_down(5.0f, 2.0f);
        s.finalize();
        RenderSettings rs = small_settings(8, 4);
        rs.passes = pass_bit(RenderPass::UV);
        Renderer r(s, rs);
        r.render();
        const auto uva = r.film().resolve(pass_type(RenderPass::UV));
        for (int y = 0; y < 8; ++y)
            for (int x = 0; x < 8; ++x) {
                const float* p = &uva[3 * size_t(y * 8 + x)];
                if (!requested) {
                    EXPECT_EQ(p[0] + p[1] + p[2], 0.0f);
                    continue;
                }
                EXPECT_NEAR(p[0], (float(x) + 0.5f) / 8.0f, 0.5f / 8.0f + 1e-5f) << x << "," << y;
                EXPECT_NEAR(p[1], 1.0f - (float(y) + 0.5f) / 8.0f, 0.5f / 8.0f + 1e-5f) << x << "," << y;
                EXPECT_EQ(p[2], 1.0f);
            }
    }
}

TEST(Passes, NamesParseAndUnknownNamesAreNamed) {
    EXPECT_EQ(pass_mask_from_names({"DiffDir", "mist"}), pass_bit(RenderPass::DiffuseDirect) | pass_bit(RenderPass::Mist));
    try {
        pass_mask_from_names({"diffuse"});
        FAIL() << "no error";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("'diffuse'"), std::string::npos);
    }
}

// MurmurHash3_x86_32 reference values (seed 0), and Cycles' float conversion.
TEST(Cryptomatte, HashAndIdAreCycles) {
    EXPECT_EQ(murmur_hash3(""), 0u);
    EXPECT_EQ(murmur_hash3("hello"), 0x248bfa47u);
    EXPECT_EQ(murmur_hash3("The quick brown fox jumps over the lazy dog"), 0x2e4ff723u);
    // Exponent clamped into [1, 254]: never 0, denormal, inf or NaN.
    for (uint32_t h : {0u, 0x7f800000u, 0xffffffffu, 0x00000001u}) {
        const float f = hash_to_float(h);
        EXPECT_TRUE(std::isnormal(f)) << h;
    }
    EXPECT_EQ(cryptomatte_manifest({"a", "b\"a"}), std::string("{\"a\":\"") + [] {
        char hex[9];
        std::snprintf(hex, sizeof hex, "%08x", murmur_hash3("a"));
        return std::string(hex);
    }() + "\",\"b\\\"a\":\"" + [] {
        char hex[9];
        std::snprintf(hex, sizeof hex, "%08x", murmur_hash3("b\"a"));
        return std::string(hex);
    }() + "\"}");
}

// Two quads meet in the middle of the image's middle column: rank 0 holds
// the id covering most of a pixel, coverages add up to 1 where no world is seen.
TEST(Cryptomatte, RankedCoverage) {
    Scene s;
    s.add_material(diffuse_material(Vec3f(0.5f), "matA"));
    const uint32_t b = s.add_material(diffuse_material(Vec3f(0.5f), "matB"));
    add_quad(s, {-1.0f, 0, 0}, {1, 0, 0}, {0, 1, 0}, 2.0f, 4.0f, 0, "left");
    add_quad(s, {1.0f, 0, 0}, {1, 0, 0}, {0, 1, 0}, 2.0f, 4.0f, b, "right");
    s.camera = ortho_camera_looking_down(10.0f, 2.0f * 7.0f / 8.0f);  // pixel 3 of 7 straddles x = 0
    s.finalize();
    RenderSettings rs = small_settings(7, 64);
    rs.cryptomatte = 0b111;
    rs.cryptomatte_levels = 4;
    Renderer r(s, rs);
    r.render();
    ASSERT_EQ(r.film().cryptomatte_layers(), 2);
    std::vector<float> l0(7 * 7 * 4), l1(7 * 7 * 4);
    r.film().resolve_cryptomatte(CryptoType::Object, 0, l0.data());
    r.film().resolve_cryptomatte(CryptoType::Object, 1, l1.data());
    const float left = cryptomatte_id("left"), right = cryptomatte_id("right");
    for (int y = 0; y < 7; ++y) {
        const float* p = &l0[size_t(y * 7) * 4];
        EXPECT_EQ(p[0], left);
        EXPECT_EQ(p[1], 1.0f);
        EXPECT_EQ(p[3], 0.0f);
        const float* m = &l0[size_t(y * 7 + 3) * 4];  // the straddling pixel: both ids
        EXPECT_TRUE((m[0] == left && m[2] == right) || (m[0] == right && m[2] == left));
        EXPECT_GE(m[1], m[3]);
        EXPECT_NEAR(m[1] + m[3], 1.0f, 1e-6f);
        EXPECT_EQ(l1[size_t(y * 7 + 3) * 4 + 1], 0.0f);
    }
    std::vector<float> mat(7 * 7 * 4);
    r.film().resolve_cryptomatte(CryptoType::Material, 0, mat.data());
    EXPECT_EQ(mat[size_t(6) * 4], cryptomatte_id("matB"));
}

}  // namespace
}  // namespace coherent::test
