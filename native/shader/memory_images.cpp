// MemoryImages and the OIIO reader of in-memory images. See memory_images.h.
#include "memory_images.h"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cstring>

namespace coherent {

namespace {

std::string identity_of(const std::string& key) { return key.substr(0, key.find('\n')); }

// Tiles as large as the image where that wastes little: OIIO's per-thread
// micro-cache remembers the last two tiles, so with one tile per image most
// lookups skip its shared tile table (random lookups over a 2048x2048 image
// took half the time of 64x64 tiles, and the textured benchmark ~7 % less
// CPU). A side is a power of two (small images: one tile), at most 4096,
// padding the image by at most 1/8 (else smaller, down to OIIO's usual 64);
// a tile holds at most 16 MB, so one image never outgrows the cache limit.
constexpr int kMinTile = 64, kMaxTile = 4096;
constexpr size_t kMaxTileBytes = size_t(16) << 20;

int tile_side(int extent) {
    if (extent <= kMinTile) {
        int side = 8;
        while (side < extent) side *= 2;
        return side;
    }
    for (int side = kMaxTile; side > kMinTile; side /= 2)
        if (size_t((extent + side - 1) / side) * size_t(side) * 8 <= size_t(extent) * 9) return side;
    return kMinTile;
}

void choose_tiles(const PixelBuffer& buffer, OIIO::ImageSpec& spec) {
    spec.tile_width = tile_side(buffer.width);
    spec.tile_height = tile_side(buffer.height);
    spec.tile_depth = 1;
    const size_t texel = size_t(buffer.channels) * buffer.value_bytes();
    while (size_t(spec.tile_width) * size_t(spec.tile_height) * texel > kMaxTileBytes &&
           std::max(spec.tile_width, spec.tile_height) > kMinTile) {
        if (spec.tile_width >= spec.tile_height) spec.tile_width /= 2;
        else spec.tile_height /= 2;
    }
}

class MemoryImageInput final : public OIIO::ImageInput {
public:
    const char* format_name() const override { return "coherent_pixels"; }
    bool open(const std::string& name, OIIO::ImageSpec& newspec) override {
        buffer_ = MemoryImages::instance().find(name);
        if (!buffer_) return false;
        const OIIO::TypeDesc type = buffer_->is_float ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8;
        m_spec = OIIO::ImageSpec(buffer_->width, buffer_->height, buffer_->channels, type);
        choose_tiles(*buffer_, m_spec);
        newspec = m_spec;
        return true;
    }
    bool close() override {
        buffer_.reset();
        return true;
    }
    bool read_native_scanline(int, int, int, int, void*) override { return false; }  // tiled only
    // Copies the tile at (x, y); texels past the image's edge are zero.
    bool read_native_tile(int subimage, int miplevel, int x, int y, int /*z*/, void* data) override {
        if (!buffer_ || subimage != 0 || miplevel != 0 || x < 0 || y < 0 || x >= buffer_->width ||
            y >= buffer_->height)
            return false;
        const size_t texel = size_t(buffer_->channels) * buffer_->value_bytes();
        const size_t tile_row = size_t(m_spec.tile_width) * texel;
        const size_t copied = size_t(std::min(m_spec.tile_width, buffer_->width - x)) * texel;
        auto* out = static_cast<uint8_t*>(data);
        for (int row = 0; row < m_spec.tile_height; ++row, out += tile_row) {
            if (y + row >= buffer_->height) {
                std::memset(out, 0, tile_row);
                continue;
            }
            std::memcpy(out, buffer_->bytes.data() + size_t(y + row) * buffer_->row_bytes() + size_t(x) * texel,
                        copied);
            std::memset(out + copied, 0, tile_row - copied);
        }
        return true;
    }

private:
    std::shared_ptr<const PixelBuffer> buffer_;  // kept while open, even if the registry drops it
};

OIIO::ImageInput* create_memory_input() { return new MemoryImageInput; }

}  // namespace

void declare_memory_image_format() {
    static std::once_flag once;
    std::call_once(once, [] {
        static const char* extensions[] = {kMemoryImageExtension, nullptr};
        OIIO::declare_imageio_format("coherent_pixels", create_memory_input, extensions, nullptr, nullptr, "1");
    });
}

MemoryImages& MemoryImages::instance() {
    static auto* images = new MemoryImages;  // outlives static destruction, like the texture system
    return *images;
}

MemoryImages::Added MemoryImages::add(std::shared_ptr<const PixelBuffer> buffer, const std::string& key) {
    std::lock_guard<std::mutex> lock(mutex_);
    Added added;
    if (!key.empty()) {
        auto held = by_key_.find(key);
        if (held != by_key_.end()) {  // added meanwhile by another store: share it
            Entry& e = entries_[held->second];
            ++e.users;
            e.last_use = ++clock_;
            added.name = held->second;
            return added;
        }
        newest_key_[identity_of(key)] = key;
        std::vector<std::string> superseded;
        for (const auto& [name, e] : entries_)
            if (e.users == 0 && !e.key.empty() && identity_of(e.key) == identity_of(key)) superseded.push_back(name);
        for (const std::string& name : superseded) drop(name, added.dropped);
    }
    added.name = "coherent-" + std::to_string(serial_++) + "." + kMemoryImageExtension;
    entries_[added.name] = Entry{std::move(buffer), key, 1, ++clock_};
    if (!key.empty()) by_key_[key] = added.name;
    enforce_limit(added.dropped);
    return added;
}

std::string MemoryImages::reuse(const std::string& key) {
    std::lock_guard<std::mutex> lock(mutex_);
    auto held = by_key_.find(key);
    if (held == by_key_.end()) return {};
    Entry& e = entries_[held->second];
    ++e.users;
    e.last_use = ++clock_;
    return held->second;
}

std::vector<std::string> MemoryImages::release(const std::string& name) {
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<std::string> dropped;
    auto it = entries_.find(name);
    if (it == entries_.end() || --it->second.users > 0) return dropped;
    const std::string& key = it->second.key;
    if (key.empty() || newest_key_[identity_of(key)] != key) drop(name, dropped);
    else enforce_limit(dropped);
    return dropped;
}

std::shared_ptr<const PixelBuffer> MemoryImages::find(const std::string& name) const {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = entries_.find(name);
    return it == entries_.end() ? nullptr : it->second.buffer;
}

void MemoryImages::set_retention_limit(size_t bytes) {
    std::lock_guard<std::mutex> lock(mutex_);
    limit_ = bytes;
}

size_t MemoryImages::retained_count() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return by_key_.size();
}

size_t MemoryImages::retained_bytes() const {
    std::lock_guard<std::mutex> lock(mutex_);
    size_t bytes = 0;
    for (const auto& [name, e] : entries_)
        if (!e.key.empty()) bytes += e.buffer->bytes.size();
    return bytes;
}

void MemoryImages::drop(const std::string& name, std::vector<std::string>& dropped) {
    auto it = entries_.find(name);
    if (it == entries_.end()) return;
    if (!it->second.key.empty()) by_key_.erase(it->second.key);
    entries_.erase(it);
    dropped.push_back(name);
}

void MemoryImages::enforce_limit(std::vector<std::string>& dropped) {
    for (;;) {
        size_t unused = 0;
        const std::string* oldest = nullptr;
        uint64_t oldest_use = UINT64_MAX;
        for (const auto& [name, e] : entries_) {
            if (e.users > 0 || e.key.empty()) continue;
            unused += e.buffer->bytes.size();
            if (e.last_use < oldest_use) {
                oldest_use = e.last_use;
                oldest = &name;
            }
        }
        if (unused <= limit_ || !oldest) return;
        drop(std::string(*oldest), dropped);
    }
}

}  // namespace coherent
