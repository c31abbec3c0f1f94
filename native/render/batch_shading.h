// Shading the hits of a packet, or of a stretch of a wavefront or stream
// queue, together: the hits whose materials run a shader program are grouped
// by material and each group's program runs as SoA batches
// (shader/eval_batch.h), so that shading stays as coherent as the traversal
// that found the hits; shade_hit() then takes each hit's surface point and
// material from here (PreShaded) instead of evaluating it alone. The result
// is bit for bit what shade_hit() computes by itself.
//
// Scenes without program materials, the AO integrator and
// RenderSettings::shader_batch = false skip all of it: their hits cost what
// they cost before.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include "../shader/eval_batch.h"
#include "path_state.h"

namespace coherent {

// Queue entries prepared at once: bounds the prepared data (a few hundred
// bytes a hit) for waves of a million paths.
constexpr size_t kShadeChunk = 4096;

class HitShading {
public:
    // Whether preparing can pay: batches are asked for, the integrator shades
    // materials and some material of the scene runs a program.
    bool wanted(const PathContext& ctx) {
        if (ctx.scene != scanned_) {
            scanned_ = ctx.scene;
            programs_ = std::any_of(ctx.scene->materials.begin(), ctx.scene->materials.end(),
                                    [](const Material& m) { return m.program != nullptr; });
        }
        return programs_ && ctx.settings->shader_batch && ctx.settings->integrator != Integrator::AmbientOcclusion;
    }

    // Prepares entries i < count (at most kShadeChunk): hit(i) is entry i's
    // surface hit (null: it missed), state(i) its path, about to be shaded.
    template <class HitOf, class StateOf>
    void prepare(const PathContext& ctx, size_t count, HitOf hit, StateOf state) {
        slot_.assign(count, -1);
        pre_.clear();
        keys_.clear();
        if (!wanted(ctx)) return;
        collect(ctx, count, hit, state);
        evaluate(ctx, hit, state);
    }

    // What shade_hit() takes for entry i (null: it shades the hit alone).
    const shading::PreShaded* at(size_t i) const { return slot_[i] < 0 ? nullptr : &pre_[size_t(slot_[i])]; }

    size_t bytes() const {
        return (slot_.capacity() + starts_.capacity()) * sizeof(int32_t) +
               pre_.capacity() * sizeof(shading::PreShaded) +
               (keys_.capacity() + sorted_.capacity()) * sizeof(uint64_t) +
               geometry_.capacity() * sizeof(ShadingGeometry) + paths_.capacity() * sizeof(LightPathInfo) +
               materials_.capacity() * sizeof(Material) + normals_.capacity() * sizeof(Vec3f);
    }

private:
    // The surface points of the entries on program materials and of those on
    // instances (whose material needs the point); keys_ sorts the program
    // ones by material, then entry.
    template <class HitOf, class StateOf>
    void collect(const PathContext& ctx, size_t count, HitOf hit, StateOf state) {
        const Scene& scene = *ctx.scene;
        for (size_t i = 0; i < count; ++i) {
            const Hit* h = hit(i);
            if (!h) continue;
            if (h->instance == kInvalidPrim && !scene.materials[scene.material_of[h->prim]].program) continue;
            shading::PreShaded p;
            p.sp = shading::surface_point(scene, state(i), *h);
            slot_[i] = int32_t(pre_.size());
            if (scene.materials[p.sp.material].program) keys_.push_back(uint64_t(p.sp.material) << 32 | i);
            pre_.push_back(p);
        }
        sort_by_material(scene.materials.size());
    }

    // keys_ ascending. They were pushed in entry order, so a stable counting
    // sort by material gives what std::sort would: a scene has a few
    // materials and a chunk thousands of keys, where comparisons cost more.
    void sort_by_material(size_t materials) {
        if (keys_.size() < 64) {
            std::sort(keys_.begin(), keys_.end());
            return;
        }
        starts_.assign(materials + 1, 0);
        for (const uint64_t key : keys_) ++starts_[size_t(key >> 32) + 1];
        for (size_t m = 0; m < materials; ++m) starts_[m + 1] += starts_[m];
        sorted_.resize(keys_.size());
        for (const uint64_t key : keys_) sorted_[starts_[size_t(key >> 32)]++] = key;
        keys_.swap(sorted_);
    }

    // Runs each material's program over its entries, in one batch.
    template <class HitOf, class StateOf>
    void evaluate(const PathContext& ctx, HitOf hit, StateOf state) {
        const size_t n = keys_.size();
        // Grown, never shrunk: entries [0, n) are all written below, and
        // resizing down and up again would construct every Material anew.
        if (geometry_.size() < n) {
            geometry_.resize(n);
            paths_.resize(n);
            materials_.resize(n);
            normals_.resize(n);
        }
        for (size_t j = 0; j < n; ++j) {
            const size_t i = size_t(keys_[j] & 0xFFFFFFFFu);
            const shading::PreShaded& p = pre_[size_t(slot_[i])];
            const ShaderProgram& prog = *ctx.scene->materials[p.sp.material].program;
            shading::fill_shading_geometry(ctx, state(i), *hit(i), p.sp, prog, geometry_[j]);
            if (prog.uses_light_path) {
                paths_[j] = shading::hit_light_path(state(i), *hit(i));
                geometry_[j].path = &paths_[j];
            }
        }
        for (size_t first = 0; first < n;) {
            const uint32_t material = uint32_t(keys_[first] >> 32);
            size_t end = first + 1;
            while (end < n && uint32_t(keys_[end] >> 32) == material) ++end;
            evaluate_material_batch(*ctx.scene, ctx.scene->materials[material], &geometry_[first], end - first,
                                    &materials_[first], &normals_[first]);
            first = end;
        }
        for (size_t j = 0; j < n; ++j) {
            shading::PreShaded& p = pre_[size_t(slot_[size_t(keys_[j] & 0xFFFFFFFFu)])];
            p.material = &materials_[j];
            p.n = normals_[j];
        }
    }

    const Scene* scanned_ = nullptr;
    bool programs_ = false;
    std::vector<int32_t> slot_;  // entry -> pre_ index, -1: not prepared
    std::vector<shading::PreShaded> pre_;
    std::vector<uint64_t> keys_;  // material << 32 | entry, of the program entries
    std::vector<uint64_t> sorted_;  // sort_by_material's output, swapped with keys_
    std::vector<uint32_t> starts_;  // sort_by_material: each material's next key slot
    std::vector<ShadingGeometry> geometry_;  // in keys_ order, as the batches
    std::vector<LightPathInfo> paths_;
    std::vector<Material> materials_;
    std::vector<Vec3f> normals_;
};

}  // namespace coherent
