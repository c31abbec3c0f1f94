// Image writing: files are read back with OpenImageIO and compared with
// values computed independently (sRGB formula, straight alpha).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include <OpenImageIO/imageio.h>

#include "io/image.h"
#include "test_gltf_util.h"

using namespace coherent;

namespace {

struct Image {
    OIIO::ImageSpec spec;
    std::vector<float> pixels;
};

Image read_back(const std::string& path) {
    Image img;
    auto in = OIIO::ImageInput::open(path);
    if (!in) return img;
    img.spec = in->spec();
    img.pixels.resize(size_t(img.spec.width) * img.spec.height * img.spec.nchannels);
    in->read_image(0, 0, 0, -1, OIIO::TypeDesc::FLOAT, img.pixels.data());
    in->close();
    return img;
}

int channel(const OIIO::ImageSpec& spec, const std::string& name) {
    for (int c = 0; c < spec.nchannels; ++c)
        if (spec.channelnames[size_t(c)] == name) return c;
    return -1;
}

// Independent sRGB encode in double precision.
double srgb(double x) { return x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1.0 / 2.4) - 0.055; }

}  // namespace

TEST(ImageIo, FormatFromExtension) {
    EXPECT_EQ(image_format_for("a/b.exr"), ImageFormat::Exr);
    EXPECT_EQ(image_format_for("B.EXR"), ImageFormat::Exr);
    EXPECT_EQ(image_format_for("x.png"), ImageFormat::Png);
    EXPECT_EQ(image_format_for("x.jpg"), ImageFormat::Unknown);
    EXPECT_EQ(image_format_for("png"), ImageFormat::Unknown);
    EXPECT_EQ(image_format_for("dir.exr/file"), ImageFormat::Unknown);
}

TEST(ImageIo, SrgbTransferFunction) {
    for (double x : {0.0, 0.001, 0.0031308, 0.01, 0.18, 0.5, 0.9, 1.0})
        EXPECT_NEAR(linear_to_srgb(float(x)), srgb(x), 1e-6) << x;
    EXPECT_EQ(linear_to_srgb(-1.0f), 0.0f);
    EXPECT_EQ(linear_to_srgb(7.0f), 1.0f);
    EXPECT_EQ(linear_to_srgb(NAN), 0.0f);
}

TEST(ImageIo, ExrRoundTripsAllPasses) {
    const int w = 3, h = 2;
    std::vector<float> rgba(w * h * 4), depth(w * h), normal(w * h * 3);
    for (size_t i = 0; i < rgba.size(); ++i) rgba[i] = 0.1f * float(i) + 0.01f;
    for (size_t i = 0; i < depth.size(); ++i) depth[i] = i == 0 ? 1e10f : 2.5f * float(i);
    for (size_t i = 0; i < normal.size(); ++i) normal[i] = -0.5f + 0.05f * float(i);
    test::TempDir dir;
    const std::string path = (dir.path / "out.exr").string();
    std::string error;
    ASSERT_TRUE(write_image(path, {w, h, rgba.data(), depth.data(), normal.data()}, error)) << error;

    const Image img = read_back(path);
    ASSERT_EQ(img.spec.width, w);
    ASSERT_EQ(img.spec.height, h);
    ASSERT_EQ(img.spec.nchannels, 8);
    const int R = channel(img.spec, "R"), A = channel(img.spec, "A"), Z = channel(img.spec, "Z");
    const int NX = channel(img.spec, "N.X"), NZ = channel(img.spec, "N.Z");
    ASSERT_GE(R, 0);
    ASSERT_GE(A, 0);
    ASSERT_GE(Z, 0);
    ASSERT_GE(NX, 0);
    ASSERT_GE(NZ, 0);
    for (int i = 0; i < w * h; ++i) {
        const float* px = &img.pixels[size_t(i) * 8];
        EXPECT_EQ(px[R], rgba[size_t(i) * 4]);  // float channels are exact
        EXPECT_EQ(px[A], rgba[size_t(i) * 4 + 3]);
        EXPECT_EQ(px[Z], depth[size_t(i)]);
        EXPECT_EQ(px[NX], normal[size_t(i) * 3]);
        EXPECT_EQ(px[NZ], normal[size_t(i) * 3 + 2]);
    }
}

TEST(ImageIo, PngIsStraightAlphaSrgb8Bit) {
    // Pixels: linear 0.5 opaque; 0.5 at alpha 0.5 premultiplied (0.25); over-
    // range and negative values; fully transparent.
    const std::vector<float> rgba = {0.5f, 0.5f, 0.5f, 1.0f, 0.25f, 0.25f, 0.25f, 0.5f,
                                     4.0f, -1.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.0f, 0.0f};
    test::TempDir dir;
    const std::string path = (dir.path / "out.png").string();
    std::string error;
    ASSERT_TRUE(write_image(path, {2, 2, rgba.data(), nullptr, nullptr}, error)) << error;

    auto in = OIIO::ImageInput::open(path);
    ASSERT_TRUE(in);
    ASSERT_EQ(in->spec().nchannels, 4);
    ASSERT_EQ(in->spec().format, OIIO::TypeDesc::UINT8);
    OIIO::ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);  // read the stored bytes as they are
    in->close();
    in = OIIO::ImageInput::open(path, &config);
    ASSERT_TRUE(in);
    std::vector<uint8_t> px(16);
    ASSERT_TRUE(in->read_image(0, 0, 0, -1, OIIO::TypeDesc::UINT8, px.data()));
    const int half = int(std::lround(srgb(0.5) * 255.0));  // 188
    EXPECT_EQ(px[0], half);
    EXPECT_EQ(px[3], 255);
    EXPECT_EQ(px[4], half);  // un-premultiplied
    EXPECT_EQ(px[7], 128);
    EXPECT_EQ(px[8], 255);   // clamped
    EXPECT_EQ(px[9], 0);
    EXPECT_EQ(px[15], 0);
}

TEST(ImageIo, ErrorsAreOneLineAndNameTheFile) {
    const std::vector<float> rgba(4, 0.5f);
    test::TempDir dir;
    for (const std::string& path : {(dir.path / "x.tga").string(), (dir.path / "no/such/dir/x.png").string(),
                                   (dir.path / "no/such/dir/x.exr").string()}) {
        std::string error;
        EXPECT_FALSE(write_image(path, {1, 1, rgba.data(), nullptr, nullptr}, error));
        EXPECT_NE(error.find(path), std::string::npos) << error;
        EXPECT_EQ(error.find('\n'), std::string::npos) << error;
    }
    std::string error;
    EXPECT_FALSE(write_image((dir.path / "x.png").string(), {0, 0, nullptr, nullptr, nullptr}, error));
}
