# packaging/build_zip.py produces a zip that Blender installs and renders with.

import subprocess
import zipfile
from pathlib import Path

import numpy as np

import blender_helpers as bh

BUILD_ZIP = bh.REPO_ROOT / "packaging" / "build_zip.py"
SYSTEM_PYTHON = "/usr/bin/python3"


def build_zip(out_dir, addon_dir=None):
    cmd = [SYSTEM_PYTHON, str(BUILD_ZIP), "--out-dir", str(out_dir)]
    if addon_dir is not None:
        cmd += ["--addon-dir", str(addon_dir)]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120)


def test_zip_contents(tmp_path, native_built, coherent_addon):
    proc = build_zip(tmp_path)
    assert proc.returncode == 0, proc.stderr
    zip_path = Path(proc.stdout.strip().splitlines()[-1])
    version = ".".join(map(str, coherent_addon.bl_info["version"]))
    assert zip_path == tmp_path / f"coherent-{version}.zip"
    with zipfile.ZipFile(zip_path) as zf:
        names = set(zf.namelist())
    assert "coherent/__init__.py" in names
    assert f"coherent/{native_built.name}" in names
    expected_py = {f"coherent/{p.relative_to(bh.ADDON_PACKAGE).as_posix()}"
                   for p in bh.ADDON_PACKAGE.rglob("*.py") if "__pycache__" not in p.parts}
    assert expected_py <= names
    assert all(n.startswith("coherent/") for n in names)
    assert not any("__pycache__" in n or n.endswith(".pyc") for n in names)


def test_missing_native_module_is_an_error(tmp_path):
    # An add-on tree with sources but no compiled module.
    fake = tmp_path / "addon" / "coherent"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text('bl_info = {"name": "x", "version": (1, 2, 3)}\n')
    proc = build_zip(tmp_path / "dist", addon_dir=tmp_path / "addon")
    assert proc.returncode != 0
    assert "_coherent" in proc.stderr and "missing" in proc.stderr
    assert not (tmp_path / "dist" / "coherent-1.2.3.zip").exists()


def test_install_zip_and_render(tmp_path, native_built):
    proc = build_zip(tmp_path / "dist")
    assert proc.returncode == 0, proc.stderr
    zip_path = Path(proc.stdout.strip().splitlines()[-1])

    # A fresh, empty user scripts dir: the add-on can only come from the zip.
    user = tmp_path / "user"
    scripts = user / "scripts"
    scripts.mkdir(parents=True)
    (user / "config").mkdir()
    out = tmp_path / "installed.png"
    script = "; ".join([
        "import bpy, sys",
        f"bpy.ops.preferences.addon_install(filepath={str(zip_path)!r})",
        "bpy.ops.preferences.addon_enable(module='coherent')",
        "import coherent",
        "print('INSTALLED_FROM', coherent.__file__)",
        "scene = bpy.context.scene",
        "scene.render.engine = 'COHERENT'",
        "scene.render.resolution_percentage = 6",
        "scene.coherent.samples = 2",
        f"scene.render.filepath = {str(out)!r}",
        "scene.render.image_settings.file_format = 'PNG'",
        "print('RENDER', bpy.ops.render.render(write_still=True))",
    ])
    result = bh.run_blender([bh.BLEND_SCENES / "cornell_box.blend", "--python-expr", script], scripts,
                            addons=False, cwd=tmp_path)
    assert result.returncode == 0, result.describe()
    installed = [l for l in result.stdout.splitlines() if l.startswith("INSTALLED_FROM")]
    assert installed, result.describe()
    installed_path = Path(installed[0].split(" ", 1)[1])
    assert scripts in installed_path.parents, f"add-on imported from {installed_path}, not from the zip install"
    assert (scripts / "addons" / "coherent" / native_built.name).is_file()
    assert "RENDER {'FINISHED'}" in result.stdout, result.describe()
    rgb = np.stack([bh.read_image_channels(out)[c] for c in "RGB"], axis=-1)
    assert rgb.shape == (30, 30, 3)  # 512 * 6 % = 30.72, truncated
    assert np.isfinite(rgb).all() and rgb.mean() > 0.01
