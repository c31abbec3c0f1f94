# Renders one .blend several times in one Blender process (one start-up for
# all of them), for test_denoising.py and bench/denoise.py:
#   blender -b SCENE.blend --addons coherent --python denoise_renders.py -- OUT_DIR PERCENT SPEC...
# where each SPEC is "name:samples:seed:denoise[:strength[:sampler[:distribute]]]" (denoise 0 or 1,
# sampler as the CLI names it: spt, cpt, icpt; empty or absent: the scene's; distribute 0 or 1,
# Distribute Samples, default on); writes
# OUT_DIR/name.exr (multilayer: Combined, and with denoise Noisy Image and
# the Denoising Albedo/Normal passes). Exits non-zero on any failure.
import sys
import traceback

import bpy


def main(argv):
    out_dir, percent, specs = argv[0], int(argv[1]), argv[2:]
    scene = bpy.context.scene
    scene.render.engine = "COHERENT"
    scene.render.resolution_percentage = percent
    scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
    # Denoising renders with paired scrambles (Error Estimate: Exact); the
    # plain renders must too, to be the denoised ones' inputs seed for seed.
    scene.coherent.error_estimate = "EXACT"
    for spec in specs:
        name, samples, seed, denoise, *options = spec.split(":")
        if options:
            scene.coherent.denoising_strength = float(options[0])
        if len(options) > 1 and options[1]:
            scene.coherent.sampler = options[1].upper()
        scene.coherent.use_distribute_samples = len(options) < 3 or options[2] == "1"
        scene.coherent.samples = int(samples)
        scene.coherent.seed = int(seed)
        scene.coherent.use_denoising = denoise == "1"
        scene.coherent.use_pass_denoising_data = denoise == "1"
        scene.render.filepath = f"{out_dir}/{name}.exr"
        bpy.ops.render.render(write_still=True)


try:
    main(sys.argv[sys.argv.index("--") + 1:])
except Exception:  # noqa: BLE001 - any failure must fail the Blender process
    traceback.print_exc()
    sys.exit(1)
