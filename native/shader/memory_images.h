// Images that exist only in memory (handed over by the host application, or
// decoded from bytes it holds). The texture store filters them straight from
// these buffers (image_filter.h); they are also served to OpenImageIO as the
// "files" of a private image format, which checks them when added and is the
// reference the direct filter is tested against (TextureStore::lookup_through_oiio).
//
// Byte images stay bytes (4 bytes per RGBA pixel; OIIO caches uint8 tiles as
// uint8 and reads them as value / 255, as Blender does), float images stay
// float.
//
// A buffer added under a key is retained: it outlives the TextureStore that
// added it, and OIIO keeps its file name and so its tiles, so a later render
// of the same unchanged image reuses both instead of handing the pixels over
// again. A key is "identity\nversion" (the host's name for the image, and what
// changes when its pixels do). Invariants, kept under one mutex:
//   - an unused buffer whose identity has a newer version is dropped at once;
//   - unused retained buffers take at most the retention limit, the least
//     recently used going first;
//   - an unkeyed buffer is dropped when its one user releases it.
// Dropped names are returned so the caller can have OIIO forget their tiles.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "../core/huge_page_allocator.h"

namespace coherent {

struct PixelBuffer {
    int width = 0, height = 0, channels = 0;
    bool is_float = false;       // float32 values, else uint8 read as value / 255
    std::vector<uint8_t, HugePageAllocator<uint8_t>> bytes;  // rows top to bottom, channels interleaved
    size_t zeroed = 0;           // NaN or infinite values set to 0 (warned about at every use)

    size_t value_bytes() const { return is_float ? sizeof(float) : 1; }
    size_t row_bytes() const { return size_t(width) * size_t(channels) * value_bytes(); }
};

// File extension of the private format (how OIIO picks our reader).
constexpr const char* kMemoryImageExtension = "coherentpixels";

class MemoryImages {
public:
    // The process's registry (OIIO's reader factory is a plain function, so it
    // finds buffers through this one instance).
    static MemoryImages& instance();

    struct Added {
        std::string name;                  // the file name OIIO opens
        std::vector<std::string> dropped;  // names OIIO should forget
    };
    // Registers `buffer` with one user. A non-empty key retains it (see above);
    // if the key is already held, that buffer is used instead of this one.
    Added add(std::shared_ptr<const PixelBuffer> buffer, const std::string& key);
    // The name of the buffer retained under `key`, with one more user; "" if none.
    std::string reuse(const std::string& key);
    // One user of `name` is done with it; returns the names dropped.
    std::vector<std::string> release(const std::string& name);

    std::shared_ptr<const PixelBuffer> find(const std::string& name) const;
    void set_retention_limit(size_t bytes);
    // Retained buffers (in use or not), and their bytes: for tests and stats.
    size_t retained_count() const;
    size_t retained_bytes() const;

private:
    struct Entry {
        std::shared_ptr<const PixelBuffer> buffer;
        std::string key;  // "" = not retained
        int users = 0;
        uint64_t last_use = 0;
    };
    mutable std::mutex mutex_;
    std::map<std::string, Entry> entries_;           // by file name
    std::map<std::string, std::string> by_key_;      // key -> file name
    std::map<std::string, std::string> newest_key_;  // identity -> newest version's key
    size_t limit_ = size_t(1024) << 20;
    uint64_t clock_ = 0;
    uint64_t serial_ = 0;

    void drop(const std::string& name, std::vector<std::string>& dropped);
    void enforce_limit(std::vector<std::string>& dropped);
};

// Registers the private format with OIIO (once per process).
void declare_memory_image_format();

}  // namespace coherent
