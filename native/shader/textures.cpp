// TextureStore: OpenImageIO's TextureSystem behind a small interface. See textures.h.
#include "textures.h"

#include <OpenImageIO/imagecache.h>
#include <OpenImageIO/imageio.h>
#include <OpenImageIO/texture.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <map>

namespace coherent {

namespace {

// --- in-memory images: an OIIO image format whose "files" are pixel buffers --

constexpr const char* kMemoryExtension = "coherentpixels";

// Sets NaN and infinite values to 0 (what Cycles' image loader does); returns how many.
size_t zero_non_finite(std::vector<float>& values) {
    size_t count = 0;
    for (float& v : values)
        if (!std::isfinite(v)) {
            v = 0.0f;
            ++count;
        }
    return count;
}

struct PixelBuffer {
    int width = 0, height = 0, channels = 0;
    std::vector<float> pixels;
};

// Buffers by file name. OIIO's format registry takes a plain function
// pointer as the reader factory, so the reader finds its buffer here.
std::mutex& registry_mutex() {
    static std::mutex* m = new std::mutex;  // outlives static destruction, like the texture system
    return *m;
}
std::map<std::string, std::shared_ptr<const PixelBuffer>>& registry() {
    static auto* r = new std::map<std::string, std::shared_ptr<const PixelBuffer>>;
    return *r;
}

class MemoryImageInput final : public OIIO::ImageInput {
public:
    const char* format_name() const override { return "coherent_pixels"; }
    bool open(const std::string& name, OIIO::ImageSpec& newspec) override {
        {
            std::lock_guard<std::mutex> lock(registry_mutex());
            auto it = registry().find(name);
            if (it == registry().end()) return false;
            buffer_ = it->second;
        }
        m_spec = OIIO::ImageSpec(buffer_->width, buffer_->height, buffer_->channels, OIIO::TypeDesc::FLOAT);
        newspec = m_spec;
        return true;
    }
    bool close() override {
        buffer_.reset();
        return true;
    }
    bool read_native_scanline(int subimage, int miplevel, int y, int z, void* data) override {
        if (!buffer_ || subimage != 0 || miplevel != 0 || y < 0 || y >= buffer_->height) return false;
        const size_t row = size_t(buffer_->width) * size_t(buffer_->channels);
        std::memcpy(data, buffer_->pixels.data() + size_t(y) * row, row * sizeof(float));
        return true;
    }

private:
    std::shared_ptr<const PixelBuffer> buffer_;
};

OIIO::ImageInput* create_memory_input() { return new MemoryImageInput; }

void declare_memory_format() {
    static std::once_flag once;
    std::call_once(once, [] {
        static const char* extensions[] = {kMemoryExtension, nullptr};
        OIIO::declare_imageio_format("coherent_pixels", create_memory_input, extensions, nullptr, nullptr, "1");
    });
}

std::string one_line(std::string s) {
    for (char& c : s)
        if (c == '\n') c = ' ';
    while (!s.empty() && s.back() == ' ') s.pop_back();
    return s;
}

}  // namespace

struct TextureStore::Image {
    std::string path;   // what OIIO opens
    std::string label;  // what warnings call it
    OIIO::TextureSystem::TextureHandle* handle = nullptr;
    int channels = 0;
    bool missing = true;
    bool in_memory = false;
};

// One texture system for the process, never destroyed: destroying one inside
// Blender (at Python shutdown) corrupts the heap that OpenColorIO's exit-time
// destructors then free (a crash on quit), and one cache under one memory
// limit is what OIIO is designed for. Scenes keep their images apart by file
// name (in-memory images get unique names) and invalidate them when they go.
OIIO::TextureSystem* process_texture_system() {
    static OIIO::TextureSystem* ts = [] {
        declare_memory_format();
        OIIO::TextureSystem* t = OIIO::TextureSystem::create(false);
        t->attribute("autotile", 64);
        t->attribute("automip", 1);
        t->attribute("accept_untiled", 1);
        t->attribute("accept_unmipped", 1);
        return t;
    }();
    return ts;
}

struct TextureStore::Oiio {
    OIIO::TextureSystem* ts = nullptr;
};

TextureStore::TextureStore(size_t cache_megabytes) : oiio_(std::make_unique<Oiio>()) {
    oiio_->ts = process_texture_system();
    oiio_->ts->attribute("max_memory_MB", float(cache_megabytes));
}

TextureStore::~TextureStore() {
    for (const auto& image : images_) oiio_->ts->invalidate(OIIO::ustring(image->path), true);
    std::lock_guard<std::mutex> lock(registry_mutex());
    for (const auto& image : images_)
        if (image->in_memory) registry().erase(image->path);
}

void TextureStore::check_image(Image& image) {
    OIIO::TextureSystem& ts = *oiio_->ts;
    image.handle = ts.get_texture_handle(OIIO::ustring(image.path));
    const OIIO::ImageSpec* spec = image.handle ? ts.imagespec(image.handle, nullptr) : nullptr;
    std::string reason;
    if (!spec) reason = "cannot be read (" + one_line(ts.geterror()) + ")";
    else if (spec->width <= 0 || spec->height <= 0 || spec->nchannels <= 0) reason = "has no pixels";
    if (!reason.empty()) {
        std::lock_guard<std::mutex> lock(warn_mutex_);
        warnings_.push_back(image.label + ": image " + reason + "; rendered magenta");
        return;
    }
    image.channels = spec->nchannels;
    image.missing = false;
}

uint32_t TextureStore::add_file(const std::string& path, const std::string& label) {
    auto image = std::make_unique<Image>();
    image->path = path;
    image->label = label;
    check_image(*image);
    images_.push_back(std::move(image));
    return uint32_t(images_.size() - 1);
}

uint32_t TextureStore::add_pixels(const std::string& label, int width, int height, int channels,
                                  const float* pixels) {
    static std::atomic<uint64_t> serial{0};
    auto image = std::make_unique<Image>();
    image->label = label;
    image->in_memory = true;
    image->path = "coherent-" + std::to_string(serial++) + "." + kMemoryExtension;
    if (width > 0 && height > 0 && channels > 0 && pixels) {
        auto buffer = std::make_shared<PixelBuffer>();
        buffer->width = width;
        buffer->height = height;
        buffer->channels = channels;
        buffer->pixels.assign(pixels, pixels + size_t(width) * size_t(height) * size_t(channels));
        const size_t bad = zero_non_finite(buffer->pixels);
        if (bad > 0) {
            std::lock_guard<std::mutex> lock(warn_mutex_);
            warnings_.push_back(label + ": image has " + std::to_string(bad) +
                                " NaN or infinite pixel values; using 0 for them, as Cycles does");
        }
        std::lock_guard<std::mutex> lock(registry_mutex());
        registry()[image->path] = std::move(buffer);
    }
    if (width > 0 && height > 0 && channels > 0 && pixels) {
        check_image(*image);
    } else {
        std::lock_guard<std::mutex> lock(warn_mutex_);
        warnings_.push_back(label + ": image has no pixels; rendered magenta");
    }
    images_.push_back(std::move(image));
    return uint32_t(images_.size() - 1);
}

void TextureStore::lookup(uint32_t index, float u, float v, TextureLookup how, float rgba[4]) const {
    const Image* image = index < images_.size() ? images_[index].get() : nullptr;
    if (!image || image->missing) {
        std::memcpy(rgba, kMissingTexture, sizeof(kMissingTexture));
        return;
    }
    OIIO::TextureOpt opt;
    opt.mipmode = OIIO::TextureOpt::MipModeNoMIP;  // Cycles' SVM filters the full-resolution image
    switch (how.interp) {
        case TextureLookup::Interp::Linear: opt.interpmode = OIIO::TextureOpt::InterpBilinear; break;
        case TextureLookup::Interp::Closest: opt.interpmode = OIIO::TextureOpt::InterpClosest; break;
        case TextureLookup::Interp::Cubic: opt.interpmode = OIIO::TextureOpt::InterpBicubic; break;
    }
    switch (how.extension) {
        case TextureLookup::Extension::Repeat: opt.swrap = opt.twrap = OIIO::TextureOpt::WrapPeriodic; break;
        case TextureLookup::Extension::Extend: opt.swrap = opt.twrap = OIIO::TextureOpt::WrapClamp; break;
        case TextureLookup::Extension::Clip: opt.swrap = opt.twrap = OIIO::TextureOpt::WrapBlack; break;
    }
    if (how.extension == TextureLookup::Extension::Clip && (u < 0.0f || u > 1.0f || v < 0.0f || v > 1.0f)) {
        rgba[0] = rgba[1] = rgba[2] = rgba[3] = 0.0f;  // Cycles: nothing outside a clipped image
        return;
    }
    const int channels = std::min(image->channels, 4);
    float texel[4] = {0.0f, 0.0f, 0.0f, 1.0f};
    // Image rows run top to bottom; Blender's v runs bottom to top.
    oiio_->ts->texture(image->handle, oiio_->ts->get_perthread_info(), opt, u, 1.0f - v, 0.0f, 0.0f, 0.0f, 0.0f,
                       channels, texel);
    // Files are not scanned when added (OIIO reads them lazily): a NaN or
    // infinite texel must still not reach shading (Cycles zeroes them on load).
    for (float& c : texel)
        if (!std::isfinite(c)) c = 0.0f;
    if (channels <= 2) {  // grey (+ alpha), as Blender reads it
        rgba[3] = channels == 2 ? texel[1] : 1.0f;
        rgba[0] = rgba[1] = rgba[2] = texel[0];
        return;
    }
    if (channels == 3) texel[3] = 1.0f;
    std::memcpy(rgba, texel, sizeof(texel));
}

size_t TextureStore::memory_bytes() const {
    long long bytes = 0;
    oiio_->ts->imagecache()->getattribute("stat:cache_memory_used", OIIO::TypeDesc::INT64, &bytes);
    return bytes > 0 ? size_t(bytes) : 0;
}

std::vector<std::string> TextureStore::warnings() const {
    std::lock_guard<std::mutex> lock(warn_mutex_);
    return warnings_;
}

}  // namespace coherent
