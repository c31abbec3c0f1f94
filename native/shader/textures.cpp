// TextureStore: OpenImageIO's TextureSystem behind a small interface. See textures.h.
#include "textures.h"

#include "image_filter.h"
#include "memory_images.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagecache.h>
#include <OpenImageIO/imageio.h>
#include <OpenImageIO/texture.h>

#include <sys/stat.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>
#include <optional>

namespace coherent {

namespace {

// Sets NaN and infinite values to 0 (what Cycles' image loader does); returns how many.
size_t zero_non_finite(float* values, size_t n) {
    size_t count = 0;
    for (size_t i = 0; i < n; ++i)
        if (!std::isfinite(values[i])) {
            values[i] = 0.0f;
            ++count;
        }
    return count;
}

std::shared_ptr<PixelBuffer> new_buffer(int width, int height, int channels, bool is_float) {
    auto buffer = std::make_shared<PixelBuffer>();
    buffer->width = width;
    buffer->height = height;
    buffer->channels = channels;
    buffer->is_float = is_float;
    buffer->bytes.resize(size_t(height) * buffer->row_bytes());
    return buffer;
}

// Cycles' association of straight byte texels on load (BlenderImageLoader,
// OIIOImageLoader): c = c * a / 255 in integers, truncated.
void associate_bytes(uint8_t* rgba, size_t texels) {
    for (size_t i = 0; i < texels; ++i, rgba += 4)
        for (int c = 0; c < 3; ++c) rgba[c] = uint8_t((unsigned(rgba[c]) * rgba[3]) / 255u);
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
    bool in_memory = false;  // path names a MemoryImages buffer this store holds one use of
    std::shared_ptr<const PixelBuffer> buffer;  // an in-memory image's pixels, filtered directly
    ImagePixels pixels;                         // a view of `buffer`; data null for files
};

// One texture system for the process, never destroyed: destroying one inside
// Blender (at Python shutdown) corrupts the heap that OpenColorIO's exit-time
// destructors then free (a crash on quit), and one cache under one memory
// limit is what OIIO is designed for. Scenes keep their images apart by file
// name (each in-memory image gets its own) and forget them when they go.
OIIO::TextureSystem* process_texture_system() {
    static OIIO::TextureSystem* ts = [] {
        declare_memory_image_format();
        OIIO::TextureSystem* t = OIIO::TextureSystem::create(false);
        t->attribute("autotile", 64);
        t->attribute("automip", 1);
        t->attribute("accept_untiled", 1);
        t->attribute("accept_unmipped", 1);
        // Files' alpha as stored (straight in a PNG), as Blender and Cycles read
        // it: the shader associates it where the image's alpha mode says so.
        t->attribute("unassociatedalpha", 1);
        return t;
    }();
    return ts;
}

// What tells a file's contents apart between renders without reading it:
// its size, inode and modification and change times (ns). The add-on keys
// the image files it hands over as pixels by size and modification time too.
struct FileStamp {
    off_t size = 0;
    ino_t inode = 0;
    int64_t modified_ns = 0, changed_ns = 0;
    bool operator==(const FileStamp& o) const {
        return size == o.size && inode == o.inode && modified_ns == o.modified_ns && changed_ns == o.changed_ns;
    }
};

std::optional<FileStamp> stamp_of(const std::string& path) {
    struct stat st;
    if (::stat(path.c_str(), &st) != 0) return std::nullopt;
    const auto ns = [](const timespec& t) { return int64_t(t.tv_sec) * 1000000000 + int64_t(t.tv_nsec); };
    return FileStamp{st.st_size, st.st_ino, ns(st.st_mtim), ns(st.st_ctim)};
}

// The image files whose tiles the process's texture system holds, as they
// were when it read them. A render keeps the tiles of a file that is
// unchanged since (an F12 re-render decoded every texture file again) and
// has OIIO forget those of a file that changed or went.
class HeldFiles {
public:
    static HeldFiles& instance() {
        static HeldFiles* held = new HeldFiles;  // never destroyed, as the texture system
        return *held;
    }
    void refresh(OIIO::TextureSystem& ts, const std::string& path) {
        const std::optional<FileStamp> now = stamp_of(path);
        std::lock_guard<std::mutex> lock(mutex_);
        const auto it = stamps_.find(path);
        if (now && it != stamps_.end() && it->second == *now) return;
        ts.invalidate(OIIO::ustring(path), true);
        if (now) stamps_[path] = *now;
        else if (it != stamps_.end()) stamps_.erase(it);
    }

private:
    std::mutex mutex_;
    std::map<std::string, FileStamp> stamps_;
};

struct TextureStore::Oiio {
    OIIO::TextureSystem* ts = nullptr;
};

TextureStore::TextureStore(size_t cache_megabytes, bool decode_files)
    : oiio_(std::make_unique<Oiio>()), cache_bytes_limit_(cache_megabytes << 20), decode_files_(decode_files) {
    oiio_->ts = process_texture_system();
    oiio_->ts->attribute("max_memory_MB", float(cache_megabytes));
    // Pixel buffers kept for later renders count against the same limit.
    MemoryImages::instance().set_retention_limit(cache_megabytes << 20);
}

// In-memory images are released, and those the registry drops are
// forgotten. Files stay cached: the next store that adds one checks it
// (HeldFiles), and OIIO's memory limit bounds what stays.
TextureStore::~TextureStore() {
    for (const auto& image : images_)
        if (image->in_memory) forget(MemoryImages::instance().release(image->path));
}

void TextureStore::forget(const std::vector<std::string>& names) {
    for (const std::string& name : names) oiio_->ts->invalidate(OIIO::ustring(name), true);
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

uint32_t TextureStore::add_file(const std::string& path, const std::string& label, bool associate) {
    uint32_t index = 0;
    if ((decode_files_ || associate) && add_decoded_file(path, label, associate, index)) return index;
    HeldFiles::instance().refresh(*oiio_->ts, path);
    auto image = std::make_unique<Image>();
    image->path = path;
    image->label = label;
    check_image(*image);
    images_.push_back(std::move(image));
    return uint32_t(images_.size() - 1);
}

uint32_t TextureStore::add_memory_image(const std::string& label, const std::string& name,
                                        std::vector<std::string> dropped) {
    forget(dropped);
    const auto buffer = MemoryImages::instance().find(name);
    if (buffer && buffer->zeroed > 0) {
        std::lock_guard<std::mutex> lock(warn_mutex_);
        warnings_.push_back(label + ": image has " + std::to_string(buffer->zeroed) +
                            " NaN or infinite pixel values; using 0 for them, as Cycles does");
    }
    auto image = std::make_unique<Image>();
    image->label = label;
    image->in_memory = true;
    image->path = name;
    check_image(*image);
    if (buffer && !image->missing) {
        image->pixels = ImagePixels{buffer->bytes.data(), buffer->width, buffer->height, buffer->channels,
                                    buffer->is_float};
        image->buffer = buffer;
    }
    images_.push_back(std::move(image));
    return uint32_t(images_.size() - 1);
}

uint32_t TextureStore::add_buffer(const std::string& label, std::shared_ptr<PixelBuffer> buffer,
                                  const std::string& key) {
    MemoryImages::Added added = MemoryImages::instance().add(std::move(buffer), key);
    return add_memory_image(label, added.name, std::move(added.dropped));
}

uint32_t TextureStore::add_pixels(const std::string& label, int width, int height, int channels,
                                  const float* pixels, const std::string& key) {
    if (width <= 0 || height <= 0 || channels <= 0 || !pixels) return add_bytes(label, 0, 0, 0, nullptr);
    auto buffer = new_buffer(width, height, channels, true);
    float* values = reinterpret_cast<float*>(buffer->bytes.data());
    const size_t n = size_t(width) * size_t(height) * size_t(channels);
    std::memcpy(values, pixels, n * sizeof(float));
    buffer->zeroed = zero_non_finite(values, n);
    return add_buffer(label, std::move(buffer), key);
}

uint32_t TextureStore::add_bytes(const std::string& label, int width, int height, int channels,
                                 const uint8_t* pixels, const std::string& key, bool associate) {
    if (width <= 0 || height <= 0 || channels <= 0 || !pixels) {
        {
            std::lock_guard<std::mutex> lock(warn_mutex_);
            warnings_.push_back(label + ": image has no pixels; rendered magenta");
        }
        auto image = std::make_unique<Image>();
        image->label = label;
        images_.push_back(std::move(image));
        return uint32_t(images_.size() - 1);
    }
    auto buffer = new_buffer(width, height, channels, false);
    std::memcpy(buffer->bytes.data(), pixels, buffer->bytes.size());
    if (associate && channels == 4) associate_bytes(buffer->bytes.data(), size_t(width) * size_t(height));
    return add_buffer(label, std::move(buffer), key);
}

namespace {

// The texel values of a decoded file: bytes for 8-bit files, float for wider
// ones, as the TextureSystem reads them (and Blender holds them).
bool is_wide(const OIIO::ImageSpec& spec) { return spec.format.size() > 1; }

// Expands n-channel texels to RGBA as lookup_by reads the TextureSystem's:
// grey to (g, g, g), alpha 1 where the file has none, channels past 4 dropped.
template <class T>
void expand_to_rgba(const T* in, int channels, size_t texels, T opaque, T* out) {
    for (size_t i = 0; i < texels; ++i, in += channels, out += 4) {
        if (channels <= 2) out[0] = out[1] = out[2] = in[0];
        else out[0] = in[0], out[1] = in[1], out[2] = in[2];
        out[3] = channels == 2 ? in[1] : (channels >= 4 ? in[3] : opaque);
    }
}

// An image's first subimage at full resolution as RGBA texels, read from the
// file `name` or, with `proxy`, from the bytes it holds (`name`'s extension
// then picks the format); null when it cannot be read or would take more
// than `max_bytes` (for a file the caller then falls back to the
// TextureSystem, which reports why). Alpha is read as stored (straight in a
// PNG), as the TextureSystem's "unassociatedalpha" reads it; `associate`: a
// byte image's colour is then associated with its alpha.
std::shared_ptr<PixelBuffer> decode_image(const std::string& name, OIIO::Filesystem::IOProxy* proxy, size_t max_bytes,
                                          bool associate) {
    OIIO::ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);
    // With a configuration OpenImageIO 2.4 reads the proxy from it, not from open()'s argument.
    if (proxy) config.attribute("oiio:ioproxy", OIIO::TypeDesc::PTR, &proxy);
    auto in = OIIO::ImageInput::open(name, &config, proxy);
    if (!in) {
        (void)OIIO::geterror();
        return nullptr;
    }
    const OIIO::ImageSpec spec = in->spec();
    const bool wide = is_wide(spec);
    const size_t texels = size_t(std::max(spec.width, 0)) * size_t(std::max(spec.height, 0));
    if (texels == 0 || spec.nchannels <= 0 || spec.depth > 1 || texels * 4 * (wide ? 4 : 1) > max_bytes) return nullptr;
    const int channels = spec.nchannels;
    auto buffer = new_buffer(spec.width, spec.height, 4, wide);
    const OIIO::TypeDesc type = wide ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8;
    std::vector<uint8_t> raw;
    uint8_t* target = buffer->bytes.data();
    if (channels != 4) {
        raw.resize(texels * size_t(channels) * type.size());
        target = raw.data();
    }
    if (!in->read_image(0, 0, 0, channels, type, target)) {
        (void)in->geterror();
        return nullptr;
    }
    if (channels != 4) {
        if (wide)
            expand_to_rgba(reinterpret_cast<const float*>(raw.data()), channels, texels, 1.0f,
                           reinterpret_cast<float*>(buffer->bytes.data()));
        else
            expand_to_rgba(raw.data(), channels, texels, uint8_t(255), buffer->bytes.data());
    }
    if (wide) buffer->zeroed = zero_non_finite(reinterpret_cast<float*>(buffer->bytes.data()), texels * 4);
    else if (associate && (channels == 2 || channels >= 4)) associate_bytes(buffer->bytes.data(), texels);
    return buffer;
}

}  // namespace

bool TextureStore::add_decoded_file(const std::string& path, const std::string& label, bool associate,
                                    uint32_t& index) {
    const std::optional<FileStamp> stamp = stamp_of(path);
    if (!stamp) return false;
    const std::string key = std::string(associate ? "associated " : "file ") + path + "\n" +
                            std::to_string(stamp->size) + " " + std::to_string(stamp->inode) + " " +
                            std::to_string(stamp->modified_ns) + " " + std::to_string(stamp->changed_ns);
    if (add_retained(label, key, index)) return true;
    // Association needs the whole image whatever the limit (as Blender's
    // pixels of it, which the add-on would hand over instead, would be).
    const size_t used = buffer_bytes();
    if (used >= cache_bytes_limit_ && !associate) return false;
    const size_t room = associate ? SIZE_MAX : cache_bytes_limit_ - used;
    std::shared_ptr<PixelBuffer> buffer = decode_image(path, nullptr, room, associate);
    if (!buffer) return false;
    index = add_buffer(label, std::move(buffer), key);
    return true;
}

uint32_t TextureStore::add_encoded(const std::string& label, const std::string& name, const uint8_t* bytes,
                                   size_t size) {
    OIIO::Filesystem::IOMemReader reader(bytes, size);
    std::shared_ptr<PixelBuffer> buffer = bytes && size ? decode_image(name, &reader, SIZE_MAX, false) : nullptr;
    if (!buffer) return add_bytes(label, 0, 0, 0, nullptr);
    return add_buffer(label, std::move(buffer), "");
}

bool TextureStore::add_retained(const std::string& label, const std::string& key, uint32_t& index) {
    const std::string name = MemoryImages::instance().reuse(key);
    if (name.empty()) return false;
    index = add_memory_image(label, name, {});
    ++reused_;
    return true;
}

namespace {

OIIO::TextureOpt oiio_options(TextureLookup how) {
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
    return opt;
}

}  // namespace

void TextureStore::lookup_by(uint32_t index, float u, float v, TextureLookup how, float rgba[4], bool direct) const {
    const Image* image = index < images_.size() ? images_[index].get() : nullptr;
    if (!image || image->missing) {
        std::memcpy(rgba, kMissingTexture, sizeof(kMissingTexture));
        return;
    }
    const int channels = std::min(image->channels, 4);
    float texel[4] = {0.0f, 0.0f, 0.0f, 1.0f};
    if (direct && image->pixels.data) {
        filter_image(image->pixels, u, v, how, texel);
    } else if (how.extension == TextureLookup::Extension::Clip && (u < 0.0f || u > 1.0f || v < 0.0f || v > 1.0f)) {
        // Nothing outside a clipped image (Cycles' closest; its linear and
        // cubic fade out over the texels past the edge, as the direct filter).
        rgba[0] = rgba[1] = rgba[2] = rgba[3] = 0.0f;
        return;
    } else {
        OIIO::TextureOpt opt = oiio_options(how);
        // Image rows run top to bottom; Blender's v runs bottom to top.
        oiio_->ts->texture(image->handle, oiio_->ts->get_perthread_info(), opt, u, 1.0f - v, 0.0f, 0.0f, 0.0f, 0.0f,
                           channels, texel);
    }
    // Files are not scanned when added (OIIO reads them lazily), and a filter
    // of huge values can overflow: a NaN or infinite texel must still not
    // reach shading (Cycles zeroes them on load).
    for (float& c : texel)
        if (!std::isfinite(c)) c = 0.0f;
    // Without alpha, texel[3] is 1 (OIIO), or as Cycles the filtered alpha of
    // 1 (direct: below 1 where a clipped image fades out).
    if (channels <= 2) {  // grey (+ alpha), as Blender reads it
        rgba[3] = channels == 2 ? texel[1] : texel[3];
        rgba[0] = rgba[1] = rgba[2] = texel[0];
        return;
    }
    std::memcpy(rgba, texel, sizeof(texel));
}

void TextureStore::prefetch(uint32_t index, float u, float v, TextureLookup how) const {
    if (const ImagePixels* pixels = memory_pixels(index)) prefetch_image(*pixels, u, v, how);
}

const ImagePixels* TextureStore::memory_pixels(uint32_t index) const {
    const Image* image = index < images_.size() ? images_[index].get() : nullptr;
    return image && !image->missing && image->pixels.data ? &image->pixels : nullptr;
}

bool read_image_file_format(const std::string& path, ImageFileFormat& format) {
    auto in = OIIO::ImageInput::open(path);
    if (!in) {
        (void)OIIO::geterror();  // clear OIIO's per-thread message; the caller decides what to say
        return false;
    }
    const OIIO::ImageSpec& spec = in->spec();
    format.channels = spec.nchannels;
    format.wide = spec.format.size() > 1;
    in->close();
    return true;
}

size_t TextureStore::memory_bytes() const {
    long long bytes = 0;
    oiio_->ts->imagecache()->getattribute("stat:cache_memory_used", OIIO::TypeDesc::INT64, &bytes);
    return bytes > 0 ? size_t(bytes) : 0;
}

size_t TextureStore::buffer_bytes() const {
    size_t bytes = 0;
    for (const auto& image : images_)
        if (image->in_memory)
            if (auto buffer = MemoryImages::instance().find(image->path)) bytes += buffer->bytes.size();
    return bytes;
}

std::vector<std::string> TextureStore::warnings() const {
    std::lock_guard<std::mutex> lock(warn_mutex_);
    return warnings_;
}

}  // namespace coherent
