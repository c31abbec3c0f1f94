#!/usr/bin/env python3
"""Packages the COHERENT add-on as an installable zip.

    cmake --build build --target _coherent      # writes addon/coherent/_coherent*.so
    python3 packaging/build_zip.py              # -> dist/coherent-<version>.zip

The zip holds one top-level folder, coherent/, with every .py file of the
add-on package and the compiled native module, which is what Blender's
Preferences > Add-ons > Install (bpy.ops.preferences.addon_install) expects.
The version comes from bl_info in addon/coherent/__init__.py, read with ast
so that packaging never imports the add-on (which needs bpy).

Exits with status 1 and a message naming the missing piece when the add-on
or its native module is not there. Prints the path of the zip on success.
"""

import argparse
import ast
import sys
import zipfile
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
PACKAGE_NAME = "coherent"


class PackagingError(Exception):
    pass


def read_bl_info(init_py):
    """Returns the bl_info dict of an add-on's __init__.py without importing it."""
    tree = ast.parse(init_py.read_text(encoding="utf-8"), filename=str(init_py))
    for node in tree.body:
        targets = []
        if isinstance(node, ast.Assign):
            targets = node.targets
        elif isinstance(node, ast.AnnAssign) and node.value is not None:
            targets = [node.target]
        if any(isinstance(t, ast.Name) and t.id == "bl_info" for t in targets):
            try:
                info = ast.literal_eval(node.value)
            except ValueError as exc:
                raise PackagingError(f"{init_py}: bl_info is not a literal dict ({exc})") from exc
            if not isinstance(info, dict):
                raise PackagingError(f"{init_py}: bl_info is not a dict")
            return info
    raise PackagingError(f"{init_py}: no bl_info found")


def version_string(info):
    version = info.get("version")
    if not (isinstance(version, (tuple, list)) and version and all(isinstance(v, int) for v in version)):
        raise PackagingError(f"bl_info['version'] must be a tuple of ints, got {version!r}")
    return ".".join(str(v) for v in version)


def package_files(package_dir):
    """(path, name inside the zip) for every file that goes into the zip."""
    sources = sorted(p for p in package_dir.rglob("*.py") if "__pycache__" not in p.parts)
    natives = sorted(package_dir.glob("_coherent*.so"))
    if not natives:
        raise PackagingError(
            f"the native module is missing: no _coherent*.so in {package_dir}. "
            "Build it first: cmake --build <build dir> --target _coherent")
    files = sources + natives
    return [(p, f"{PACKAGE_NAME}/{p.relative_to(package_dir).as_posix()}") for p in files]


def build_zip(addon_dir, out_dir):
    package_dir = addon_dir / PACKAGE_NAME
    init_py = package_dir / "__init__.py"
    if not init_py.is_file():
        raise PackagingError(f"{init_py} does not exist: not an add-on package")
    version = version_string(read_bl_info(init_py))
    files = package_files(package_dir)

    out_dir.mkdir(parents=True, exist_ok=True)
    zip_path = out_dir / f"{PACKAGE_NAME}-{version}.zip"
    tmp_path = zip_path.with_suffix(".zip.tmp")
    # Written under a temporary name and renamed, so a failed run never leaves
    # a truncated zip that looks valid.
    with zipfile.ZipFile(tmp_path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for path, arcname in files:
            zf.write(path, arcname)
    tmp_path.replace(zip_path)
    return zip_path


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--addon-dir", type=Path, default=REPO_ROOT / "addon",
                        help="directory containing the coherent/ package (default: %(default)s)")
    parser.add_argument("--out-dir", type=Path, default=REPO_ROOT / "dist",
                        help="where the zip is written (default: %(default)s)")
    args = parser.parse_args(argv)
    try:
        zip_path = build_zip(args.addon_dir.resolve(), args.out_dir.resolve())
    except PackagingError as exc:
        print(f"build_zip: error: {exc}", file=sys.stderr)
        return 1
    print(zip_path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
