# Run by test_cycles_agreement.py in a subprocess Blender:
#
#   blender -b cornell_box.blend --addons coherent --python render_for_agreement.py -- \
#       ENGINE SAMPLES PERCENT MAX_BOUNCES OUT_DIR SEED [SEED ...]
#
# Renders the loaded scene once per seed with ENGINE (CYCLES or COHERENT) to
# OUT_DIR/<engine>_<seed>.exr (32-bit float, linear). Both engines get the
# same light path limits and a 1-pixel box filter; Cycles additionally has
# everything turned off that would bias or smooth its estimate (adaptive
# sampling, denoising, clamping, light threshold, glossy blur), so both are
# plain unbiased path tracers of the same scene.

import os
import sys

import bpy

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "blend_scenes"))
from cycles_reference import configure_cycles_reference  # noqa: E402

args = sys.argv[sys.argv.index("--") + 1:]
engine, samples, percent, max_bounces, out_dir = args[0], int(args[1]), int(args[2]), int(args[3]), args[4]
seeds = [int(s) for s in args[5:]]

scene = bpy.context.scene
render = scene.render
render.engine = engine
render.resolution_percentage = percent
render.film_transparent = False
render.use_border = False
render.image_settings.file_format = "OPEN_EXR"
render.image_settings.color_depth = "32"
render.image_settings.exr_codec = "ZIP"

bounces = dict(max_bounces=max_bounces, diffuse_bounces=min(4, max_bounces),
               glossy_bounces=min(4, max_bounces), transmission_bounces=max_bounces)

c = configure_cycles_reference(scene, samples)
for key, value in bounces.items():
    setattr(c, key, value)

if engine == "COHERENT":
    s = scene.coherent
    s.samples = samples
    s.use_animated_seed = False
    for key, value in bounces.items():
        setattr(s, key, value)

for seed in seeds:
    c.seed = seed
    if engine == "COHERENT":
        scene.coherent.seed = seed
    render.filepath = f"{out_dir}/{engine.lower()}_{seed}.exr"
    result = bpy.ops.render.render(write_still=True)
    print(f"AGREEMENT_RENDER {engine} seed={seed} -> {render.filepath} {sorted(result)}")
    sys.stdout.flush()
