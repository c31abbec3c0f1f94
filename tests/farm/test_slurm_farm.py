"""Farm rendering through a real scheduler: a one-node Slurm cluster on
localhost (slurm_cluster.py) runs packaging/farm's jobs exactly as a farm
would, through submit.py:

- frames: a 4-frame range in 2 array tasks of 2 frames;
- still: frame 1 split into a 3x2 grid of border tiles (an image size that
  does not divide evenly), then the dependent stitch job.

The oracle is a single-process render of frame 1 with the add-on taken
straight from the source tree (not the zip): the stitched still and frame 1
of the frame range must equal it pixel for pixel in every channel (the
renderer keys every random number by full-frame pixel and sample, so a tile
holds exactly its part of the whole frame).
"""

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

sys.path.append("/usr/lib/python3/dist-packages")  # Debian's OpenImageIO
import OpenImageIO as oiio  # noqa: E402

from slurm_cluster import LocalSlurmCluster  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
FARM = REPO / "packaging" / "farm"
WIDTH, HEIGHT, FRAMES = 50, 30, 4
JOB_TIMEOUT = 120.0

# The shot: the repository's Cornell box, small and with few samples, saved
# with multilayer float EXR output (the frames job writes what the file says).
MAKE_SHOT = f"""
import bpy
s = bpy.context.scene
s.render.engine = "COHERENT"
s.render.resolution_x, s.render.resolution_y, s.render.resolution_percentage = {WIDTH}, {HEIGHT}, 100
s.render.use_border = False
s.coherent.samples = 4
s.frame_start, s.frame_end = 1, {FRAMES}
s.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
s.render.image_settings.color_depth = "32"
s.render.image_settings.exr_codec = "ZIP"
s.render.use_compositing = False
s.render.use_sequencer = False
s.view_layers[0].use_pass_z = True
bpy.ops.wm.save_as_mainfile(filepath=r"{{path}}")
"""


def run(cmd, **kwargs):
    done = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=120, **kwargs)
    assert done.returncode == 0, f"{' '.join(map(str, cmd))} exited {done.returncode}:\n{done.stdout}\n{done.stderr}"
    return done.stdout


def source_tree_scripts(tmp_path):
    """A Blender user scripts folder whose add-on is addon/coherent itself."""
    scripts = tmp_path / "source_scripts"
    (scripts / "addons").mkdir(parents=True)
    (scripts / "addons" / "coherent").symlink_to(REPO / "addon" / "coherent")
    return scripts


def pixels(path):
    buf = oiio.ImageBuf(str(path))
    assert not buf.has_error, f"{path}: {buf.geterror()}"
    return list(buf.spec().channelnames), buf.get_pixels(oiio.FLOAT)


@pytest.fixture
def cluster():
    # Not under pytest's tmp_path: munged needs every folder above its socket
    # searchable by all, and pytest's are private (0700).
    root = tempfile.mkdtemp(prefix="coherent-slurm-")
    c = LocalSlurmCluster(root)
    try:
        c.start()
        yield c
    finally:
        c.stop()
        shutil.rmtree(root, ignore_errors=True)


@pytest.fixture
def shot(tmp_path):
    """(blend file, the add-on zip, the single-process render of frame 1)."""
    blender_env = dict(os.environ, BLENDER_USER_SCRIPTS=str(source_tree_scripts(tmp_path)))
    blend = tmp_path / "shot.blend"
    run(["blender", "-b", "--factory-startup", "--addons", "coherent", REPO / "blend_scenes" / "cornell_box.blend",
         "--python-exit-code", "1", "--python-expr", MAKE_SHOT.format(path=blend)], env=blender_env)
    run(["blender", "-b", "--factory-startup", "--addons", "coherent", blend, "-E", "COHERENT",
         "--python-exit-code", "1", "--python", FARM / "farm_setup.py", "-o", tmp_path / "reference_####",
         "-f", "1", "--", "--raw-exr"], env=blender_env)
    zip_path = run([sys.executable, REPO / "packaging" / "build_zip.py", "--out-dir", tmp_path / "dist"])
    return blend, Path(zip_path.strip().splitlines()[-1]), tmp_path / "reference_0001.exr"


def submit(cluster, tmp_path, *args):
    env = dict(cluster.env, COHERENT_NODE_DIR=str(tmp_path / "nodes"))
    out = run([sys.executable, FARM / "submit.py", *args, "--log-dir", tmp_path / "logs"], env=env)
    return out.split()


def assert_all_completed(cluster, tmp_path, states):
    logs = "\n".join(f"--- {p.name}:\n{p.read_text(errors='replace')[-3000:]}"
                     for p in sorted((tmp_path / "logs").glob("*.log")))
    failed = {job: s for job, s in states.items() if s != ("COMPLETED", "0:0")}
    assert not failed, f"jobs did not complete: {failed}\n{logs}\n{cluster.logs_text()}"


def test_slurm_renders_a_frame_range_and_a_stitched_still(cluster, shot, tmp_path):
    blend, zip_path, reference = shot
    frames = submit(cluster, tmp_path, "frames", blend, "--addon-zip", zip_path, "--start", 1, "--end", FRAMES,
                    "--chunk", 2, "--output", tmp_path / "frames" / "shot_####")
    still = tmp_path / "still.exr"
    tiles, stitch = submit(cluster, tmp_path, "still", blend, "--addon-zip", zip_path, "--frame", 1,
                           "--grid", "3x2", "--output", still)
    states = cluster.wait_for_jobs(frames + [tiles, stitch], JOB_TIMEOUT)
    assert len(states) == 2 + 6 + 1, states  # 2 frame chunks, 6 tiles, the stitch
    assert_all_completed(cluster, tmp_path, states)

    # Every task rendered with the add-on installed from the zip on the node.
    task_logs = sorted((tmp_path / "logs").glob("coherent-[ft]*.log"))  # frames and tiles, not the stitch
    assert len(task_logs) == 2 + 6, [p.name for p in task_logs]
    for log in task_logs:
        assert f"coherent farm: add-on {tmp_path / 'nodes'}" in log.read_text(), log.read_text()

    ref_channels, ref = pixels(reference)
    assert ref.shape == (HEIGHT, WIDTH, len(ref_channels)) and "ViewLayer.Depth.Z" in ref_channels
    assert float(ref[..., :3].mean()) > 0.01  # the Cornell box, not a black frame

    channels, stitched = pixels(still)
    assert channels == ref_channels
    np.testing.assert_array_equal(stitched, ref)

    for frame in range(1, FRAMES + 1):
        path = tmp_path / "frames" / f"shot_{frame:04d}.exr"
        assert path.is_file(), f"frame {frame} is missing: {sorted(p.name for p in path.parent.glob('*'))}"
        frame_channels, image = pixels(path)
        assert frame_channels == ref_channels and image.shape == ref.shape
        if frame == 1:
            np.testing.assert_array_equal(image, ref)
