# Helpers shared by the Blender-side tests: repository paths, subprocess
# Blender with an isolated user configuration, and EXR reading.
#
# Image reading uses the OpenImageIO Python module when it is importable
# (Debian: python3-openimageio) and otherwise OpenImageIO's `oiiotool`
# (openimageio-tools), converting one channel at a time to PFM, a format
# simple enough to parse here. Both give linear float data, top row first.

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[2]
ADDON_DIR = REPO_ROOT / "addon"
ADDON_PACKAGE = ADDON_DIR / "coherent"
BLEND_SCENES = REPO_ROOT / "blend_scenes"
SHARED_SCENES = REPO_ROOT.parent / "shared" / "scenes"
ADDON_MODULE = "coherent"
ENGINE_ID = "COHERENT"


def blender_binary():
    try:
        import bpy
        if bpy.app.binary_path:
            return bpy.app.binary_path
    except ImportError:
        pass
    return shutil.which("blender") or "/usr/bin/blender"


def native_module_paths():
    return sorted(ADDON_PACKAGE.glob("_coherent*.so"))


def make_user_scripts(root):
    """Creates a BLENDER_USER_SCRIPTS tree under `root` whose addons/coherent
    is a symlink to the working tree's add-on, and returns it.

    Pointing Blender at this directory (plus BLENDER_USER_CONFIG at an empty
    one) lets `--addons coherent` find the add-on without touching the user's
    real configuration.
    """
    scripts = Path(root) / "scripts"
    addons = scripts / "addons"
    addons.mkdir(parents=True, exist_ok=True)
    link = addons / ADDON_MODULE
    if not link.exists():
        link.symlink_to(ADDON_PACKAGE, target_is_directory=True)
    (Path(root) / "config").mkdir(exist_ok=True)
    return scripts


class BlenderResult:
    """A finished subprocess Blender: return code and captured output."""

    def __init__(self, cmd, proc):
        self.cmd = cmd
        self.returncode = proc.returncode
        self.stdout = proc.stdout
        self.stderr = proc.stderr

    @property
    def output(self):
        return self.stdout + "\n" + self.stderr

    def describe(self, tail=4000):
        return (f"command: {' '.join(map(str, self.cmd))}\nreturn code: {self.returncode}\n"
                f"--- stdout (tail) ---\n{self.stdout[-tail:]}\n--- stderr (tail) ---\n{self.stderr[-tail:]}")


def run_blender(args, user_scripts, timeout=300, addons=True, cwd=None):
    """Runs `blender -b --factory-startup [--addons coherent] *args`.

    The add-on comes from `user_scripts` (see make_user_scripts), the user
    configuration from an empty sibling directory. Python errors in
    --python/--python-expr make Blender exit non-zero (--python-exit-code).
    """
    cmd = [blender_binary(), "-b", "--factory-startup", "--python-exit-code", "1"]
    if addons:
        cmd += ["--addons", ADDON_MODULE]
    cmd += [str(a) for a in args]
    env = dict(os.environ)
    env["BLENDER_USER_SCRIPTS"] = str(user_scripts)
    env["BLENDER_USER_CONFIG"] = str(Path(user_scripts).parent / "config")
    env.pop("PYTHONPATH", None)  # the subprocess must find the add-on through Blender only
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env,
                          cwd=cwd or tempfile.gettempdir())
    return BlenderResult(cmd, proc)


def python_expr(*statements):
    """A --python-expr argument that imports bpy and runs the statements."""
    return "import bpy; scene = bpy.context.scene; " + "; ".join(statements)


# --- image reading -------------------------------------------------------------

def _read_with_oiio_python(path):
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise OSError(f"OpenImageIO cannot open {path}: {oiio.geterror()}")
    try:
        spec = inp.spec()
        pixels = inp.read_image(0, 0, 0, spec.nchannels, "float")
        if pixels is None:
            raise OSError(f"OpenImageIO cannot read {path}: {inp.geterror()}")
        pixels = np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels)
        return {name: pixels[:, :, i].copy() for i, name in enumerate(spec.channelnames)}
    finally:
        inp.close()


def _read_with_oiiotool(path):
    iinfo = subprocess.run(["iinfo", "-v", str(path)], capture_output=True, text=True, check=True).stdout
    header = iinfo.splitlines()[0]  # "name : W x H, C channel, ..."
    width, height = (int(t) for t in header.split(":", 1)[1].split(",")[0].split("x"))
    line = next(l for l in iinfo.splitlines() if "channel list:" in l)
    names = [n.strip().split(" (")[0] for n in line.split("channel list:", 1)[1].split(",")]
    # --dumpdata prints "Pixel (x, y): v0 v1 ..." in row-major order, top row first.
    dump = subprocess.run(["oiiotool", "--dumpdata", str(path)], capture_output=True, text=True,
                          check=True).stdout
    values = [l.split(":", 1)[1] for l in dump.splitlines() if l.lstrip().startswith("Pixel (")]
    data = np.array(" ".join(values).split(), dtype=np.float32).reshape(height, width, len(names))
    return {name: data[:, :, i].copy() for i, name in enumerate(names)}


def read_image_channels(path):
    """Reads every channel of an image (EXR, multilayer EXR, PNG) as float32
    arrays keyed by channel name (e.g. "ViewLayer.Combined.R"), top row first."""
    try:
        import OpenImageIO  # noqa: F401
    except ImportError:
        return _read_with_oiiotool(path)
    return _read_with_oiio_python(path)


def find_channels(channels, pass_name, suffixes):
    """Stacks the channels of one pass of a multilayer EXR, e.g.
    find_channels(ch, "Normal", "XYZ") -> array (h, w, 3). Raises KeyError
    naming what is there when a channel is missing."""
    planes = []
    for s in suffixes:
        hits = [n for n in channels if n.split(".")[-2:] == [pass_name, s]]
        if len(hits) != 1:
            raise KeyError(f"channel {pass_name}.{s} not found exactly once in {sorted(channels)}")
        planes.append(channels[hits[0]])
    return np.stack(planes, axis=-1)
