// What a render holds in memory, how much the machine has, and the check that
// a render fits before its large allocations (the BVH build and the film):
// a scene too large for the machine fails with an error naming the sizes
// instead of std::bad_alloc halfway through a build (or the kernel's OOM
// killer taking the whole of Blender).
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace coherent {

struct Scene;
struct RenderSettings;

// A render that would not fit, thrown before allocating. The Python module
// turns it into MemoryError; the CLI prints it and exits non-zero.
class OutOfMemoryBudget : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// What a render may use. Either a budget for the whole render (scene, BVH
// and film together) from COHERENT_MEMORY_LIMIT, or, without one, the
// memory the machine can still give (MemAvailable, lowered to the room left
// in this process's cgroup, e.g. a Slurm job's --mem), which the scene
// already held does not need any more.
struct MemoryLimit {
    uint64_t bytes = 0;          // 0: nothing known, no check
    bool whole_render = false;   // true: a budget for scene + BVH + film; false: room for what is yet to allocate
    std::string source;          // where it came from, for the error message
};
MemoryLimit memory_limit();

// "512M", "2G", "1.5GiB", "1000000" (bytes; K, M, G, T are powers of 1024,
// with or without "iB"/"B"). Throws std::invalid_argument naming the text.
uint64_t parse_byte_size(const std::string& text);
// "1.5 GiB", "12.0 MiB", "900 B".
std::string format_bytes(uint64_t bytes);

// The scene's arrays (geometry, per-triangle data, materials, lights), as allocated.
uint64_t scene_bytes(const Scene& scene);
// The instances' records: transforms, material slots, shutter-close transforms.
uint64_t instance_record_bytes(const Scene& scene);
// The film's per-pixel buffers as `settings` enable them (Film::bytes_per_pixel):
// heatmaps, denoising features and the denoised image, passes, Cryptomatte.
uint64_t film_bytes(const RenderSettings& settings);
// The most a BVH build over `triangles` holds at once: the finished BVH
// (nodes, leaf order, 8- and 4-wide layouts, triangle packs, with the
// spatial-split duplicates) plus the build's temporaries (boxes, centroids,
// binary build nodes). An upper bound measured on the repository's scenes
// (tests/native/test_memory_budget.cpp checks it against real builds).
uint64_t bvh_build_bytes_estimate(size_t triangles);

// The estimate the check compares with the limit.
struct MemoryEstimate {
    uint64_t scene = 0;  // already allocated
    uint64_t bvh = 0;    // still to allocate (0 when a built BVH is reused)
    uint64_t film = 0;   // still to allocate
    uint64_t denoiser = 0;  // the denoiser's working memory at the end (0 without denoising)
    size_t triangles = 0;
    uint64_t to_allocate() const { return bvh + film + denoiser; }
    uint64_t total() const { return scene + bvh + film + denoiser; }
};
// A render of `scene` with `settings` (border, buffers, denoising): the scene
// as it is, the BVH build's peak unless a built BVH is reused, the film, and
// the denoiser's working memory.
MemoryEstimate estimate_render_memory(const Scene& scene, const RenderSettings& settings, bool builds_bvh);
// Throws OutOfMemoryBudget when the estimate does not fit the limit.
void check_memory(const MemoryEstimate& estimate, const MemoryLimit& limit);

// The process's resident-memory high-water mark (VmHWM: the largest RSS
// since it started, the host application's own memory included); 0 where
// the system does not say.
uint64_t peak_rss_bytes();

}  // namespace coherent
