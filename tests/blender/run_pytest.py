# Runs the Blender-side test suite inside Blender's own Python.
#
#   blender -b --factory-startup --python-exit-code 1 \
#       --python tests/blender/run_pytest.py -- -q tests/blender
#
# Everything after "--" is passed to pytest.main(). Blender 3.4 on Debian runs
# the system Python 3.11, so Debian's python3-pytest (in
# /usr/lib/python3/dist-packages) is importable. The repository's addon/
# directory is put first on sys.path so that `import coherent` finds the
# working tree's add-on (and its freshly built _coherent module), never an
# installed copy.
#
# Blender exits with pytest's return code. Return code 5 ("no tests were
# collected") is turned into a failure: a suite that silently finds nothing
# must not pass.

import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
ADDON_DIR = os.path.join(REPO, "addon")

if ADDON_DIR not in sys.path:
    sys.path.insert(0, ADDON_DIR)
DEBIAN_DIST_PACKAGES = "/usr/lib/python3/dist-packages"
if os.path.isdir(DEBIAN_DIST_PACKAGES) and DEBIAN_DIST_PACKAGES not in sys.path:
    sys.path.append(DEBIAN_DIST_PACKAGES)

import pytest  # noqa: E402  (needs the path set up above)

PYTEST_NO_TESTS_COLLECTED = 5


def main():
    args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [HERE]
    if not args or all(a.startswith("-") for a in args):
        args = [*args, HERE]
    # No .pytest_cache inside the source tree.
    args = ["-p", "no:cacheprovider", *args]
    rc = int(pytest.main(args))
    if rc == PYTEST_NO_TESTS_COLLECTED:
        print("run_pytest: no tests were collected; treating that as a failure", file=sys.stderr)
        rc = 1
    sys.stdout.flush()
    sys.stderr.flush()
    sys.exit(rc)


main()
