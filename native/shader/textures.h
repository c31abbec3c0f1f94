// Image textures of a scene. Images that exist only inside the host
// application (packed, generated or painted in Blender) come as whole pixel buffers (bytes stay
// bytes, floats floats; memory_images.h) and are filtered straight from that
// buffer as Cycles' CPU kernel does (image_filter.h): for pixels already in
// RAM a cache adds only work (bilinear over a 2048x2048 byte image: 60 ns per
// lookup instead of 230 in a small region, 240 instead of 490 at random, where
// the texel's cache miss is most of both). Such an image added under a key is
// retained after the store goes, so the next render of the same unchanged
// image reuses it (add_retained).
//
// Image files are decoded by OpenImageIO into such buffers too, as long as
// the store's buffers stay within its memory limit (Cycles holds every image
// whole), and retained under the file's size, inode and times, so an
// unchanged file is decoded once per process. A file beyond the limit is
// looked up through OpenImageIO's TextureSystem, whose ImageCache tiles and
// caches it under the same limit (its tiles, too, outlive the store while the
// file is unchanged). bench/textured_twin.py --files, whose normal map went
// through the cache until the twentieth session: the textured render 0.45 s
// -> 0.33 s, as with the images packed (docs/results/textured_twin.md).
//
// An image that cannot be read (missing file, zero size, unreadable) keeps
// its index but looks up Cycles' "missing texture" magenta; the reason is in
// warnings(), so a bad file never stops a render.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "../core/vec.h"

namespace coherent {

struct TextureLookup {
    enum class Interp : uint8_t { Linear, Closest, Cubic };
    enum class Extension : uint8_t { Repeat, Extend, Clip };
    Interp interp = Interp::Linear;
    Extension extension = Extension::Repeat;
};

struct PixelBuffer;  // memory_images.h
struct ImagePixels;  // image_filter.h

// What an image file's header says, read without decoding its pixels: the
// channel count, and whether its values are wider than 8 bits (Blender then
// holds the image as float: 16-bit PNG and TIFF, EXR, HDR).
struct ImageFileFormat {
    int channels = 0;
    bool wide = false;
};
// False (and `format` untouched) when OpenImageIO cannot open the file.
bool read_image_file_format(const std::string& path, ImageFileFormat& format);

// Cycles' colour of a missing image.
constexpr float kMissingTexture[4] = {1.0f, 0.0f, 1.0f, 1.0f};

class TextureStore {
public:
    // `decode_files` false: every file goes through the TextureSystem (the
    // reference decoded files are tested against).
    explicit TextureStore(size_t cache_megabytes = 1024, bool decode_files = true);
    ~TextureStore();
    TextureStore(const TextureStore&) = delete;
    TextureStore& operator=(const TextureStore&) = delete;

    // Registers an image file; returns its index. `label` names it in warnings.
    // Decoded whole (as RGBA, alpha as stored) while within the memory limit.
    // `associate`: a straight byte colour file whose texels Cycles associates
    // on load (c * a / 255, truncated); decoded whatever the limit.
    uint32_t add_file(const std::string& path, const std::string& label, bool associate = false);
    // Registers pixels (height rows of width x channels floats, first row at
    // the TOP, as image files store them); copied. Returns its index.
    // A non-empty `key` ("identity\nversion", see memory_images.h) retains the copy.
    uint32_t add_pixels(const std::string& label, int width, int height, int channels, const float* pixels,
                        const std::string& key = "");
    // An encoded image held in memory (a PNG's or JPEG's bytes, as a .glb
    // embeds them; `name`'s extension picks the format), decoded as add_file
    // decodes a file: RGBA, alpha as stored. Undecodable bytes render magenta.
    uint32_t add_encoded(const std::string& label, const std::string& name, const uint8_t* bytes, size_t size);
    // The same for byte pixels, read as value / 255. `associate`: RGBA texels
    // whose colour Cycles associates with their alpha on load (c * a / 255,
    // truncated), as add_file's.
    uint32_t add_bytes(const std::string& label, int width, int height, int channels, const uint8_t* pixels,
                       const std::string& key = "", bool associate = false);
    // Adds the in-memory image retained under `key` by an earlier add; false
    // (nothing added) when none is held.
    bool add_retained(const std::string& label, const std::string& key, uint32_t& index);

    size_t size() const { return images_.size(); }
    // RGBA at texture coordinates (u, v), v = 0 at the bottom row as in
    // Blender's UV space. Thread-safe. Missing images give kMissingTexture.
    void lookup(uint32_t image, float u, float v, TextureLookup how, float rgba[4]) const {
        lookup_by(image, u, v, how, rgba, true);
    }
    // Starts loading the texels lookup(image, u, v, how) reads, when the
    // image is in memory (files: nothing; OIIO finds its tiles itself).
    void prefetch(uint32_t image, float u, float v, TextureLookup how) const;
    // The pixels lookup() filters directly (image_filter.h) when `image` is
    // in memory and present; null for files read through the TextureSystem
    // and for missing images.
    const ImagePixels* memory_pixels(uint32_t image) const;
    // The same through OIIO's TextureSystem also for in-memory images: the
    // reference the direct filter is tested against.
    void lookup_through_oiio(uint32_t image, float u, float v, TextureLookup how, float rgba[4]) const {
        lookup_by(image, u, v, how, rgba, false);
    }

    // Bytes held by the cache now (tiles of every image read so far).
    size_t memory_bytes() const;
    // Bytes of the in-memory pixel buffers this store uses.
    size_t buffer_bytes() const;
    // How many images add_retained found held (handed over by an earlier store).
    size_t reused() const { return reused_; }
    std::vector<std::string> warnings() const;

private:
    struct Image;
    std::vector<std::unique_ptr<Image>> images_;
    struct Oiio;
    std::unique_ptr<Oiio> oiio_;
    mutable std::mutex warn_mutex_;
    mutable std::vector<std::string> warnings_;
    size_t reused_ = 0;
    size_t cache_bytes_limit_ = 0;  // for this store's buffers, and OIIO's tiles
    bool decode_files_ = true;
    bool add_decoded_file(const std::string& path, const std::string& label, bool associate, uint32_t& index);
    void lookup_by(uint32_t image, float u, float v, TextureLookup how, float rgba[4], bool direct) const;
    void check_image(Image& image);
    uint32_t add_buffer(const std::string& label, std::shared_ptr<PixelBuffer> buffer, const std::string& key);
    uint32_t add_memory_image(const std::string& label, const std::string& name, std::vector<std::string> dropped);
    void forget(const std::vector<std::string>& names);
};

}  // namespace coherent
