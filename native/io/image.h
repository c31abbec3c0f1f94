// Writing rendered passes to image files (OpenImageIO).
//
// The format follows the file extension, case-insensitively:
//  - .exr: 32-bit float, channels R G B A (Combined, linear, alpha
//    associated as in Blender/Cycles), Z (Depth, 1e10 where nothing was hit,
//    as Cycles writes) and N.X N.Y N.Z (Normal), ZIP compressed.
//  - .png: Combined only, 8-bit RGBA with straight alpha: colour is
//    un-premultiplied, encoded with the sRGB transfer function and clamped,
//    as Blender's "Standard" view transform saves a PNG.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace coherent {

class Film;

enum class ImageFormat { Unknown, Exr, Png };

// Format implied by `path`'s extension; Unknown for anything else.
ImageFormat image_format_for(const std::string& path);

// Borrowed pass buffers, top row first, interleaved.
struct ImagePasses {
    int width = 0, height = 0;
    const float* combined = nullptr;  // width*height*4, required
    const float* depth = nullptr;     // width*height, optional (EXR only)
    const float* normal = nullptr;    // width*height*3, optional (EXR only)
    // More layers (EXR only), channels named "<name>.<channel id>" (the
    // OpenEXR layer convention: "DiffDir.R", "Mist.Z").
    struct Layer {
        std::string name;
        std::string channel_ids;  // one character per channel: "RGB", "XYZ", "Z"
        const float* pixels;      // width*height*channels
    };
    std::vector<Layer> layers;
};

// Writes the passes; false with a one-line `error` naming the file if the
// extension is unknown, a buffer is missing or the file cannot be written.
bool write_image(const std::string& path, const ImagePasses& passes, std::string& error);

// Resolves Combined, Depth and Normal from the film and writes them, and
// to an EXR also every render pass the film accumulated (film/passes.h) as
// a layer of Cycles' name.
bool write_film(const std::string& path, const Film& film, std::string& error);

// Diagnostic images (heatmaps): one float channel named `channel` to an
// EXR (linear, ZIP), and 8-bit sRGB-encoded RGB (already display values) to
// a PNG. Same error reporting as write_image.
bool write_value_exr(const std::string& path, int width, int height, const float* values, const char* channel,
                     std::string& error);
bool write_rgb8_png(const std::string& path, int width, int height, const uint8_t* rgb, std::string& error);

// sRGB opto-electronic transfer function (IEC 61966-2-1) on [0,1].
float linear_to_srgb(float linear);

}  // namespace coherent
