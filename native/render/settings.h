// Everything a render needs besides the scene. Shared by CLI and Blender.
#pragma once

#include <cstdint>

#include "../sample/sampler_type.h"
#include "render_modes.h"

namespace coherent {

struct RenderSettings {
    int width = 512, height = 512;      // full frame size in pixels (after resolution %)
    // Render border in pixels, [x0, x1) x [y0, y1), y = 0 at the TOP row.
    // The film covers only the border region; defaults to the whole frame.
    int border_x0 = 0, border_y0 = 0, border_x1 = -1, border_y1 = -1;

    int spp = 16;
    // Stopping rules besides spp; whichever comes first ends the render.
    // target_error: stop once Film::relative_rmse_estimate() (the even/odd
    // half-buffer estimate of the image's relative RMSE) is <= this, checked
    // after every batch of passes (report_interval; always an even number of
    // passes from 2 on). 0 = off.
    double target_error = 0.0;
    // time_limit: seconds of wall-clock time; checked between batches of
    // passes, which are cut short to end by it, so a render overruns it by
    // about one pass. 0 = off.
    double time_limit = 0.0;
    uint64_t seed = 0;
    int threads = 0;                    // 0 = all cores
    // Seconds a batch of passes aims to take between progress reports (the
    // error estimate, stopping rules and the callback run between batches;
    // inside one, threads move from tile to tile without waiting for each
    // other). Batches grow to at most half the passes done so far and end at
    // even pass counts. 0, or progressive_display (the viewport shows every
    // pass): one pass per report.
    double report_interval = 0.25;

    // Adaptive sampling (off by default). After every batch of passes
    // (report_interval) from adaptive_min_samples on, a pixel stops receiving samples once the
    // relative error it would have at its own count, judged from the pixels
    // just around it (Renderer::update_convergence: their half-buffer errors
    // scaled to its count, over their mean radiance floored at
    // kAdaptiveLuminanceFloor), is <= adaptive_threshold. The pixel's own
    // samples, and those of pixels that share its random numbers (a CPT
    // packet), are left out of the decision: a stop that reads them selects
    // lucky runs, biasing both the image and its error estimate. Converged
    // pixels keep their samples (the film normalises each pixel by its own
    // count) and never resume. Batches end at even pass counts, which keeps
    // the even and odd halves balanced, and grow by at most a quarter of the
    // passes done, so decisions come at least that often. Unbiasedness and the calibration of the
    // error estimate are measured in tests/native/test_adaptive.cpp.
    bool adaptive = false;
    double adaptive_threshold = 0.01;
    int adaptive_min_samples = 16;      // rounded up to an even number, at least 2
    // Radiance below which the relative error is taken relative to this
    // floor instead: near-black pixels must reach a small absolute error
    // rather than an ever smaller relative one.
    static constexpr double kAdaptiveLuminanceFloor = 0.01;

    // Blender's Light Paths > Max Bounces.
    int max_bounces = 12;
    int diffuse_bounces = 4;
    int glossy_bounces = 4;
    int transmission_bounces = 12;
    int transparent_max_bounces = 8;   // Transparent BSDF pass-throughs, camera and shadow rays alike (Cycles)
    // Russian roulette may end a path once it has bounced this often. 2 rather
    // than 3: at 4 bounces, 3 left almost every path at full length. 2 took
    // Sponza from 0.97 to 1.17x Cycles' efficiency with no loss beyond noise
    // on 8 other scenes; 1 gave Sponza 1.40 but cost the repository's Cornell
    // box 8 % (docs/results/efficiency_speed.md section 7).
    int rr_min_bounces = 2;
    // Blender's Light Paths > Clamping (0 = off). Each light contribution is
    // scaled so its largest component is at most the limit; "direct" means
    // it left the camera's first hit (or was seen directly), as in Cycles.
    // Biased, off by default; Blender's own defaults are 0 and 10.
    float clamp_direct = 0.0f;
    float clamp_indirect = 0.0f;
    // Next-event estimation picks emitters uniformly instead of by estimated
    // power (light_sampling.h); the selection before importance, for comparisons.
    bool uniform_light_selection = false;

    // Which random numbers paths consume (native/sample): SPT, CPT, ICPT, or
    // Auto, resolved by resolve_sampler_type() (sample/sampler_type.h): ICPT
    // when intermediate results are displayed (progressive_display, set by
    // the viewport), CPT for final renders, the most efficient there, SPT
    // when denoising (the filter wants independent pixel noise).
    // Spt by default: independent pixel errors, as before.
    SamplerType sampler = SamplerType::Spt;
    // Packet size in pixels; ICPT partitions square blocks of side
    // min(packet_width, packet_height) (at most 16).
    int packet_width = 4, packet_height = 4;
    // CPT/ICPT sequences shared per packet (paper Fig. 3) or over the whole
    // image (paper eq. 3); see SequenceScope in sample/sampler_type.h.
    SequenceScope sequence_scope = SequenceScope::Packet;
    // The numbers behind every sampler: padded Owen-scrambled Sobol
    // (sample/owen_sobol.h; 1.4-2.9x the efficiency of white noise for SPT
    // and CPT at 16-256 spp, docs/results/sobol_sampling.md), or white noise.
    SampleSequence pattern = SampleSequence::OwenSobol;
    // Auto: the render estimates its error (even and odd Sobol samples from
    // paired scrambles) only where something decides with the estimate;
    // elsewhere its samples come from one scramble, which leaves less noise
    // but no estimate (the halves' difference would overstate the error up
    // to 6x). Front ends ask for Exact when they show the Error pass or
    // record the estimate (sample/sampler_type.h).
    ErrorEstimate error_estimate = ErrorEstimate::Auto;
    bool progressive_display = false;   // a front end shows passes as they finish

    // Light transport and tracing (render_modes.h).
    Integrator integrator = Integrator::PathTrace;
    Traversal traversal = Traversal::Auto;  // resolved by the Renderer (render_modes.h)
    PacketAssembly assembly = PacketAssembly::RayType;
    // Packet traversal: an assembled packet is traced as a packet only if
    // its rays point the same way, |mean of unit directions| >= this;
    // otherwise its rays go one at a time (incoherent packets, e.g. SPT
    // bounces, trace at half the single-ray speed: docs/results/
    // packet_traversal.md). 0 = always packets; > 1 = never. Same hits
    // either way. Chosen by measurement (docs/results/coherent_paths.md).
    float packet_min_coherence = 0.9f;
    int bvh_width = 8;                  // 2, 4 or 8 (single-ray and stream traversal)
    ReorderMode reorder = ReorderMode::None;  // wavefront only
    int wave_size = 1 << 16;            // wavefront: paths in flight per wave (bounds memory)
    // Packet, stream and wavefront traversal: shader programs run over the
    // hits of a packet / queue stretch together (render/batch_shading.h).
    bool shader_batch = true;
    // Ambient occlusion: rays per camera sample, and their length
    // (<= 0: a tenth of the scene's bounding-box diagonal).
    int ao_samples = 16;
    float ao_distance = 0.0f;
    // Diagnostic heatmap passes (Film: NodeVisits, SimdUtilisation): BVH node
    // visits per camera sample and the SIMD lane utilisation of the packets
    // that traced the pixel's rays. Off by default: they cost counters.
    bool heatmaps = false;

    // Denoising (denoise/): after the last pass, Combined is replaced by the
    // denoised image (the noisy one stays in the Noisy Image pass).
    // denoise_strength scales the filter's colour tolerance (1 = as tuned).
    // denoising_data fills the feature passes (Denoising Albedo, Depth and
    // Normal) without denoising; either costs three more buffers per half.
    bool denoise = false;
    float denoise_strength = 1.0f;
    bool denoising_data = false;
    // A denoised final render of a fixed sample count takes a quarter of its
    // samples in every pixel (half where the scene can make caustics) and
    // distributes the rest by the error the denoiser is predicted to leave,
    // spp per pixel on average
    // (render/sample_distribution.h). Only where the count is fixed (no
    // error target, time limit or progressive display) and with SPT, whose
    // pixels' random numbers are independent.
    bool distribute_samples = true;
    bool distributes_samples() const {
        return denoise && distribute_samples && !progressive_display && target_error <= 0.0 && time_limit <= 0.0 &&
               resolved_sampler() == SamplerType::Spt && spp >= 4;
    }
    bool denoising_features() const { return denoise || denoising_data; }

    // Cycles' render passes to accumulate (film/passes.h PassMask; 0 = none,
    // which costs nothing). Not a table row: a set of names, given as
    // Renderer(passes=[...]) in Python and --passes in the CLI.
    uint32_t passes = 0;
    // Cryptomatte (film/cryptomatte.h): a bit per CryptoType, and the levels
    // (ranked ids per pixel, Blender's pass_cryptomatte_depth).
    uint32_t cryptomatte = 0;
    int cryptomatte_levels = 6;

    bool transparent_film = false;      // Film > Transparent: world seen directly gives alpha 0
    bool force_all_features = false;    // ignore SceneFeatures specialisation (benchmarks)
    int tile_size = 32;

    int border_width() const { return (border_x1 < 0 ? width : border_x1) - border_x0; }
    // Target error, adaptive sampling and the denoiser (which filters each
    // half with weights from the other) decide with the estimate; the
    // viewport keeps the exact estimate it always showed.
    bool exact_error_estimate() const {
        return error_estimate == ErrorEstimate::Exact || target_error > 0.0 || adaptive || denoise ||
               progressive_display;
    }
    // Whether Stats::error_estimate is filled (white noise halves are
    // independent whatever the setting).
    bool error_estimated() const { return resolved_pattern() != SampleSequence::OwenSobolOneScramble; }
    SampleSequence resolved_pattern() const {
        return pattern == SampleSequence::OwenSobol && !exact_error_estimate() ? SampleSequence::OwenSobolOneScramble
                                                                                 : pattern;
    }
    SamplerType resolved_sampler() const { return resolve_sampler_type(sampler, progressive_display, denoise); }
    Traversal resolved_traversal() const { return resolve_traversal(traversal, resolved_sampler()); }
    int border_height() const { return (border_y1 < 0 ? height : border_y1) - border_y0; }
};

}  // namespace coherent
