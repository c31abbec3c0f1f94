// Which sampler draws a render's random numbers, and the rule that resolves
// SamplerType::Auto. Kept apart from the samplers so RenderSettings can name
// the choice without pulling in any sampler code.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

namespace coherent {

// Sadeghi et al. 2009, "Coherent Path Tracing":
//   Spt:  standard path tracing, an independent sequence per pixel and sample.
//   Cpt:  coherent path tracing, one sequence per sample shared by the pixels
//         of a packet (or of the whole image, see SequenceScope).
//   Icpt: interleaved CPT, packet blocks split into Latin-square subsets,
//         one shared sequence per subset, the split re-randomised per block
//         and sample.
//   Auto: resolved by resolve_sampler_type() below.
enum class SamplerType : uint8_t { Spt, Cpt, Icpt, Auto };

// What a sampler's sequences are made of (sampler.h, SampleStream): padded
// Owen-scrambled Sobol points (error falls faster than 1/sqrt(spp) on smooth
// integrands, docs/results/sobol_sampling.md) or white noise from a
// counter-based hash. A render picks one with RenderSettings::pattern
// (Sobol by default).
//
// OwenSobol draws the even and the odd samples from two independently
// scrambled sequences, so that the film's even/odd half-images have
// independent errors (an unbiased error estimate). OwenSobolOneScramble
// draws every sample from one sequence: its points stay stratified across
// the halves, so the image's error is lower (0.73x the variance on the
// sphere scene at 64 spp, 0.78x on the sun-lit bunny's direct light at 256,
// docs/results/efficiency_speed.md section 6) but the halves' difference overstates it (6x on a smooth scene
// at 64 spp), so such a render reports no estimate. Renders pick it through
// RenderSettings::error_estimate, never through `pattern`.
enum class SampleSequence : uint8_t { OwenSobol, WhiteNoise, OwenSobolOneScramble };

// Whether a render estimates its error (ErrorEstimate::Exact: samples from
// paired scrambles) or, where nothing decides by the estimate, leaves it out
// in exchange for less noise (Auto; RenderSettings::exact_error_estimate()).
enum class ErrorEstimate : uint8_t { Auto, Exact };

// Auto chooses by error per second (issue 10, item 5), measured through
// Blender on the repository's and the public scenes (6 scenes, 128x128,
// 2 threads, 16/64/256 spp, white noise and Sobol; docs/results/
// efficiency_vs_cycles.md, "Auto sampler"). Efficiency, 1 / (MSE x s),
// relative to the best of SPT/CPT/ICPT on each scene, geometric mean over
// scenes: CPT 0.88-0.97 at every spp and pattern, ICPT 0.32-0.77, SPT
// 0.64-0.90; CPT over ICPT 1.14-1.36x with white noise and 2.5-3.1x with
// Sobol. CPT's error at equal spp is 0.88-1.18x SPT's (the glass scene's
// fireflies aside) and its packets trace faster; ICPT's subsets, re-drawn per sample, lose Sobol's
// gain (0.14-0.26 of SPT's efficiency on the sun-lit Sponza and bunny).
// The former rule, ICPT below 256 spp, paid that. Hence:
//   progressive display (viewport, or any front end showing passes) -> ICPT:
//       there intermediate passes are looked at, and CPT's noise is
//       structured (blocky, neighbour correlation ~0.7) until it is small;
//       the paper (section 4) picks ICPT "when intermediate results are
//       displayed".
//   final render, any spp                                            -> CPT
//   denoising (either)                                               -> SPT:
//       the filter expects noise independent from pixel to pixel; CPT's
//       4x4 blocks share theirs, and denoised 16 spp came out 1.5-2.4x
//       worse in RMSE than from SPT's noise on the repo's Blender scenes
//       (docs/results/denoise.md), while noisy 256 spp differs within 10 %.
// Never returns Auto.
constexpr SamplerType resolve_sampler_type(SamplerType requested, bool progressive_display, bool denoise = false) {
    if (requested != SamplerType::Auto) return requested;
    if (denoise) return SamplerType::Spt;
    return progressive_display ? SamplerType::Icpt : SamplerType::Cpt;
}

// Over which pixels CPT and ICPT share their sequences. The paper is not
// uniform on this: equation (3) and the abstract share u_k between "all the
// pixels in each sample" (Image), while the introduction ("the same sequence
// of random numbers for all rays in a packet"), section 2.3 ("four different
// random sequences per 8x8 block") and Fig. 3 ("both cases need 4 sequences
// of random numbers for an 8x8 block" for CPT and ICPT) describe sequences
// local to a packet (Packet):
//   Packet: CPT draws one sequence per packet (packet_width x packet_height
//           pixels); ICPT n sequences per group of 2x2 blocks (the paper's
//           8x8 pixels for n = 4), each subset j of the group's blocks
//           forming one coherent packet of 4n rays.
//   Image:  CPT one sequence per sample for the whole image, ICPT n.
// Coherence inside a packet is the same, and so is the RMSE. Image makes
// CPT's error pattern identical everywhere (long streaks, errors correlated
// across packet edges) and repeats ICPT's fireflies in every block (dotted
// rows); Packet confines both to a packet or region
// (docs/results/sampler_rmse.md), so it is the default.
enum class SequenceScope : uint8_t { Packet, Image };

constexpr std::string_view sequence_scope_name(SequenceScope s) { return s == SequenceScope::Image ? "image" : "packet"; }

inline std::optional<SequenceScope> parse_sequence_scope(std::string_view name) {
    for (SequenceScope s : {SequenceScope::Packet, SequenceScope::Image})
        if (name == sequence_scope_name(s)) return s;
    return std::nullopt;
}

constexpr std::string_view sampler_type_name(SamplerType t) {
    switch (t) {
        case SamplerType::Spt: return "spt";
        case SamplerType::Cpt: return "cpt";
        case SamplerType::Icpt: return "icpt";
        case SamplerType::Auto: return "auto";
    }
    return "auto";
}

// Case-sensitive lower-case names as printed by sampler_type_name().
inline std::optional<SamplerType> parse_sampler_type(std::string_view name) {
    for (SamplerType t : {SamplerType::Spt, SamplerType::Cpt, SamplerType::Icpt, SamplerType::Auto})
        if (name == sampler_type_name(t)) return t;
    return std::nullopt;
}

}  // namespace coherent
