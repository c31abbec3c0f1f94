// Memory accounting and the check before a render's large allocations.
#include "memory_budget.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>

#include "../denoise/denoiser.h"
#include "../film/film.h"
#include "../scene/scene.h"
#include "settings.h"

namespace coherent {

namespace {

template <class T>
uint64_t vector_bytes(const std::vector<T>& v) {
    return uint64_t(v.capacity()) * sizeof(T);
}

// A "Key:   1234 kB" line of /proc/meminfo or /proc/self/status, in bytes; 0 if absent.
uint64_t proc_kib_field(const char* path, const std::string& key) {
    std::ifstream in(path);
    std::string line;
    while (std::getline(in, line)) {
        if (line.compare(0, key.size(), key) != 0 || line.size() <= key.size() || line[key.size()] != ':') continue;
        std::istringstream fields(line.substr(key.size() + 1));
        uint64_t kib = 0;
        fields >> kib;
        return kib * 1024;
    }
    return 0;
}

// A cgroup file holding one number ("max" or unreadable: none).
bool read_cgroup_number(const std::string& path, uint64_t& value) {
    std::ifstream in(path);
    std::string text;
    if (!(in >> text) || text == "max") return false;
    char* end = nullptr;
    value = std::strtoull(text.c_str(), &end, 10);
    return end && *end == '\0';
}

// Room left under the memory.max of this process's cgroup (v2) and its
// ancestors, e.g. a Slurm job's --mem with task/cgroup; UINT64_MAX if none.
uint64_t cgroup_room() {
    std::ifstream in("/proc/self/cgroup");
    std::string line, path;
    while (std::getline(in, line))
        if (line.rfind("0::", 0) == 0) path = line.substr(3);
    uint64_t room = std::numeric_limits<uint64_t>::max();
    if (path.empty()) return room;
    for (;;) {
        const std::string dir = "/sys/fs/cgroup" + (path == "/" ? std::string() : path);
        uint64_t max = 0, current = 0;
        if (read_cgroup_number(dir + "/memory.max", max) && read_cgroup_number(dir + "/memory.current", current))
            room = std::min(room, max > current ? max - current : 0);
        if (path == "/" || path.empty()) break;
        const size_t slash = path.find_last_of('/');
        path = slash == 0 ? "/" : path.substr(0, slash);
    }
    return room;
}

}  // namespace

uint64_t parse_byte_size(const std::string& text) {
    const std::invalid_argument bad("'" + text + "' is not a memory size (e.g. 512M, 2G, 1000000)");
    char* end = nullptr;
    const double number = std::strtod(text.c_str(), &end);
    if (end == text.c_str()) throw bad;
    std::string unit(end);
    unit.erase(std::remove(unit.begin(), unit.end(), ' '), unit.end());
    for (const std::string suffix : {"iB", "B"})
        if (unit.size() >= suffix.size() && unit.compare(unit.size() - suffix.size(), suffix.size(), suffix) == 0) {
            unit.resize(unit.size() - suffix.size());
            break;
        }
    double scale = 1.0;
    if (!unit.empty()) {
        const size_t power = std::string("KMGT").find(char(std::toupper(static_cast<unsigned char>(unit[0]))));
        if (unit.size() != 1 || power == std::string::npos) throw bad;
        scale = std::pow(1024.0, double(power + 1));
    }
    const double bytes = number * scale;
    if (!std::isfinite(bytes) || bytes < 1.0 || bytes >= 1.8e19) throw bad;
    return uint64_t(bytes);
}

std::string format_bytes(uint64_t bytes) {
    const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
    double value = double(bytes);
    int unit = 0;
    while (value >= 1024.0 && unit < 4) {
        value /= 1024.0;
        ++unit;
    }
    char text[32];
    if (unit == 0) std::snprintf(text, sizeof text, "%llu B", static_cast<unsigned long long>(bytes));
    else std::snprintf(text, sizeof text, "%.1f %s", value, units[unit]);
    return text;
}

MemoryLimit memory_limit() {
    if (const char* env = std::getenv("COHERENT_MEMORY_LIMIT"); env && *env) {
        try {
            return {parse_byte_size(env), true, "the memory limit COHERENT_MEMORY_LIMIT=" + std::string(env)};
        } catch (const std::invalid_argument& e) {
            throw std::invalid_argument(std::string("COHERENT_MEMORY_LIMIT: ") + e.what());
        }
    }
    MemoryLimit limit;
    limit.bytes = proc_kib_field("/proc/meminfo", "MemAvailable");
    limit.source = "the available memory (MemAvailable in /proc/meminfo)";
    const uint64_t room = cgroup_room();
    if (room < limit.bytes || (limit.bytes == 0 && room != std::numeric_limits<uint64_t>::max())) {
        limit.bytes = room;
        limit.source = "the room left under this process's cgroup memory.max";
    }
    return limit;
}

uint64_t instance_record_bytes(const Scene& s) {
    return vector_bytes(s.instances) + vector_bytes(s.instance_materials) + vector_bytes(s.instance_close);
}

uint64_t scene_bytes(const Scene& s) {
    uint64_t bytes = vector_bytes(s.vertices) + vector_bytes(s.normals) + vector_bytes(s.has_normals) +
                     vector_bytes(s.material_of) + vector_bytes(s.object_of) + vector_bytes(s.motion_vertices) +
                     vector_bytes(s.motion_normals) + vector_bytes(s.materials) + vector_bytes(s.lights) +
                     vector_bytes(s.emissive_triangles) + vector_bytes(s.geometric_normals) +
                     vector_bytes(s.moving_triangles) + vector_bytes(s.moving_flag) + vector_bytes(s.object_names);
    for (const std::string& name : s.object_names) bytes += name.capacity();
    // Shared geometry: each prototype once, each instance one record.
    bytes += vector_bytes(s.prototypes) + instance_record_bytes(s);
    for (const Prototype& p : s.prototypes)
        bytes += vector_bytes(p.vertices) + vector_bytes(p.normals) + vector_bytes(p.has_normals) +
                 vector_bytes(p.slot_of);
    return bytes;
}

// Triangles the render builds BVHs over: the world-space ones plus each
// prototype once (instances add a top-level node each, not triangles).
static size_t unique_triangle_count(const Scene& s) {
    size_t n = s.triangle_count();
    for (const Prototype& p : s.prototypes) n += p.triangle_count();
    return n + s.instances.size();
}

uint64_t film_bytes(const RenderSettings& settings) {
    const uint64_t pixels = uint64_t(settings.border_width()) * uint64_t(settings.border_height());
    return pixels * Film::bytes_per_pixel(settings.heatmaps, settings.denoising_features(), settings.denoise,
                                          PassMask(settings.passes), settings.cryptomatte, settings.cryptomatte_levels);
}

uint64_t bvh_build_bytes_estimate(size_t triangles) {
    // Builds over random soups peak at 214-232 bytes per triangle (72-84 of
    // them kept in the finished BVH), the repository's scenes keep 78-86
    // (docs: README "Memory"); 400 leaves room for allocator slack and
    // more threads' build buffers.
    constexpr uint64_t kBytesPerTriangle = 400;
    constexpr uint64_t kFixed = 64 * 1024;  // the tree's root and small-scene rounding
    return kFixed + uint64_t(triangles) * kBytesPerTriangle;
}

MemoryEstimate estimate_render_memory(const Scene& scene, const RenderSettings& settings, bool builds_bvh) {
    MemoryEstimate e;
    e.triangles = unique_triangle_count(scene);
    e.scene = scene_bytes(scene);
    e.bvh = builds_bvh ? bvh_build_bytes_estimate(e.triangles) : 0;
    e.film = film_bytes(settings);
    if (settings.denoise) {
        DenoiseOptions options;
        options.threads = settings.threads;
        e.denoiser = denoise_working_bytes(settings.border_width(), settings.border_height(), options);
    }
    return e;
}

void check_memory(const MemoryEstimate& e, const MemoryLimit& limit) {
    if (limit.bytes == 0) return;
    const uint64_t needed = limit.whole_render ? e.total() : e.to_allocate();
    if (needed <= limit.bytes) return;
    std::string parts = "BVH " + format_bytes(e.bvh) + " for " + std::to_string(e.triangles) + " triangles, film " +
                        format_bytes(e.film);
    if (e.denoiser) parts += ", denoiser " + format_bytes(e.denoiser);
    parts += limit.whole_render ? ", scene " + format_bytes(e.scene) : "; the scene already holds " + format_bytes(e.scene);
    const std::string remedy = limit.whole_render ? "raise the limit or reduce" : "reduce";
    throw OutOfMemoryBudget("not enough memory for this render: it needs about " + format_bytes(needed) + " (" +
                            parts + "), more than " + limit.source + ", " + format_bytes(limit.bytes) + "; " +
                            remedy + " the triangle count (instances instead of copies, lower subdivision) or the "
                            "image size" + (e.denoiser ? std::string(", or render without denoising") : std::string()));
}

uint64_t peak_rss_bytes() { return proc_kib_field("/proc/self/status", "VmHWM"); }

}  // namespace coherent
