// The render's other two axes besides the sampler (DESIGN.md: Sampler x
// Traversal x Integrator): which light transport is computed and how rays
// are traced, plus the knobs of the packet, stream and wavefront paths. Kept
// apart from their implementations so RenderSettings, the CLI and the
// Python module can name a choice without pulling in any kernel.
//
// Every (integrator, traversal, assembly, reorder) combination computes the
// same estimator: traversal modes give bit-identical hits for the same rays,
// so for a fixed sampler and seed they give the same image.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

#include "../sample/sampler_type.h"

namespace coherent {

// Light transport (Boulos et al. 2007 section 4; Cook 1984; Whitted 1980):
//   PathTrace:      full path tracing with next-event estimation and MIS.
//   Distribution:   distribution ray tracing: direct light (soft shadows from
//                   area lights) at every vertex, paths continue only through
//                   glossy and specular lobes (glossy reflection, refraction);
//                   depth of field when the camera has it. No diffuse
//                   interreflection.
//   Whitted:        direct light at every vertex, paths continue only through
//                   perfectly specular (delta) lobes: mirrors and glass.
//   RayCast:        ray casting with shadows: direct light at the first hit only.
//   AmbientOcclusion: the fraction of ao_samples cosine-distributed rays from
//                   the first hit that escape within ao_distance (white =
//                   unoccluded), as in the reordering paper (004).
enum class Integrator : uint8_t { PathTrace, Distribution, Whitted, RayCast, AmbientOcclusion };

// How rays are traced:
//   Single:    one ray at a time through the BVH of width bvh_width (2/4/8);
//              the reference every other mode must match. ("wide" on the
//              command line is Single: single rays over the wide BVH.)
//   Packet:    SIMD packets of packet_width x packet_height pixels' rays
//              (ray_packet.h), secondary rays assembled by `assembly`.
//   Stream:    breadth-first ray streams (per-node ray queues) over the wide BVH.
//   Wavefront: the staged pipeline (generate, extend, reorder, shade,
//              shadow) over waves of wave_size paths, reordered by `reorder`.
//   Auto:      resolved by resolve_traversal() below.
enum class Traversal : uint8_t { Single, Packet, Stream, Wavefront, Auto };

// Auto: packets where they pay, single rays elsewhere. Measured on whole
// renders (docs/results/coherent_paths.md): with CPT, whose rays share
// their random numbers per packet, packets beat single rays at every bounce
// depth; with SPT and ICPT they do not (SPT's bounces are incoherent; ICPT's
// coherent groups are sparse in the image, so its camera packets are not),
// so those trace single rays. Never returns Auto.
constexpr Traversal resolve_traversal(Traversal requested, SamplerType resolved_sampler) {
    if (requested != Traversal::Auto) return requested;
    return resolved_sampler == SamplerType::Cpt ? Traversal::Packet : Traversal::Single;
}

// Whether a traversal attributes BVH node visits to each path, which the
// "BVH Visits" heatmap shows: streams count their work per node queue, not
// per ray, so with them that heatmap is zero.
constexpr bool traversal_counts_path_visits(Traversal t) { return t != Traversal::Stream; }

// Packet assembly of secondary rays after every bounce (Boulos et al. 2007,
// section 3.2), within each packet of pixels:
//   RayType: one packet per ray type (shadow, diffuse, glossy, reflection,
//            refraction); the paper's choice.
//   Runs:    consecutive rays (in pixel order) of the same type form a packet;
//            a change of type ends the run.
enum class PacketAssembly : uint8_t { RayType, Runs };

// Ray reordering in the wavefront path (Moon et al. / the reordering paper 004):
//   None; Static1D (pixel order along a Morton curve), Static3D (the
//   paper's static 3D work groups of 8 x 16 x 1 over width, height and ray
//   of the pixel; see ray_reorder.h); Hash32 and Hash192 (the paper's HASHKEY32/HASHKEY192 of
//   origin and direction bits, sorted by LSD radix sort); Csd32
//   (compress-sort-decompress of 32-bit keys).
enum class ReorderMode : uint8_t { None, Static1D, Static3D, Hash32, Hash192, Csd32 };

constexpr std::string_view integrator_name(Integrator i) {
    switch (i) {
        case Integrator::PathTrace: return "pt";
        case Integrator::Distribution: return "drt";
        case Integrator::Whitted: return "wrt";
        case Integrator::RayCast: return "rcs";
        case Integrator::AmbientOcclusion: return "ao";
    }
    return "pt";
}
constexpr std::string_view traversal_name(Traversal t) {
    switch (t) {
        case Traversal::Single: return "single";
        case Traversal::Packet: return "packet";
        case Traversal::Stream: return "stream";
        case Traversal::Wavefront: return "wavefront";
        case Traversal::Auto: return "auto";
    }
    return "single";
}
constexpr std::string_view assembly_name(PacketAssembly a) { return a == PacketAssembly::Runs ? "runs" : "types"; }
constexpr std::string_view reorder_name(ReorderMode r) {
    switch (r) {
        case ReorderMode::None: return "none";
        case ReorderMode::Static1D: return "static1d";
        case ReorderMode::Static3D: return "static3d";
        case ReorderMode::Hash32: return "hash32";
        case ReorderMode::Hash192: return "hash192";
        case ReorderMode::Csd32: return "csd32";
    }
    return "none";
}

// Case-sensitive lower-case names as printed by the *_name() functions.
inline std::optional<Integrator> parse_integrator(std::string_view s) {
    for (Integrator i : {Integrator::PathTrace, Integrator::Distribution, Integrator::Whitted, Integrator::RayCast,
                         Integrator::AmbientOcclusion})
        if (s == integrator_name(i)) return i;
    return std::nullopt;
}
inline std::optional<Traversal> parse_traversal(std::string_view s) {
    if (s == "wide") return Traversal::Single;
    for (Traversal t : {Traversal::Single, Traversal::Packet, Traversal::Stream, Traversal::Wavefront, Traversal::Auto})
        if (s == traversal_name(t)) return t;
    return std::nullopt;
}
inline std::optional<PacketAssembly> parse_assembly(std::string_view s) {
    if (s == "types" || s == "type") return PacketAssembly::RayType;
    if (s == "runs") return PacketAssembly::Runs;
    return std::nullopt;
}
inline std::optional<ReorderMode> parse_reorder(std::string_view s) {
    for (ReorderMode r : {ReorderMode::None, ReorderMode::Static1D, ReorderMode::Static3D, ReorderMode::Hash32,
                          ReorderMode::Hash192, ReorderMode::Csd32})
        if (s == reorder_name(r)) return r;
    return std::nullopt;
}

}  // namespace coherent
