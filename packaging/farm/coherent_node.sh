# Sourced by the Slurm job scripts (frames.sbatch, tile.sbatch): what every
# node does before it renders. Needs COHERENT_ADDON_ZIP (the zip that
# packaging/build_zip.py writes, on storage every node sees).
#
# The add-on is installed once per node and zip: extracted into
#   ${COHERENT_NODE_DIR:-${TMPDIR:-/tmp}/coherent-farm-$USER}/<zip sha256>/scripts/addons/coherent
# and that folder becomes Blender's user scripts folder (BLENDER_USER_SCRIPTS),
# which is where Preferences > Install would have put it. Array tasks that
# land on the same node at once take a lock, so exactly one extracts; a new
# zip (another hash) gets its own folder, so a running job never sees its
# add-on replaced.

coherent_fail() {
  echo "coherent farm: $*" >&2
  exit 1
}

coherent_install_addon() {
  local zip=${COHERENT_ADDON_ZIP:-}
  [[ -n "$zip" ]] || coherent_fail "COHERENT_ADDON_ZIP is not set (the add-on zip from packaging/build_zip.py)"
  [[ -f "$zip" ]] || coherent_fail "the add-on zip $zip does not exist on $(hostname)"
  local root=${COHERENT_NODE_DIR:-${TMPDIR:-/tmp}/coherent-farm-$(id -un)}
  local hash
  hash=$(sha256sum "$zip" | cut -c1-16)
  local scripts="$root/$hash/scripts"
  mkdir -p "$root/$hash" || coherent_fail "cannot create $root/$hash on $(hostname)"
  (
    flock 9
    if [[ ! -f "$scripts/addons/coherent/__init__.py" ]]; then
      local tmp
      tmp=$(mktemp -d "$root/$hash/.install.XXXXXX")
      python3 -m zipfile -e "$zip" "$tmp/addons" || exit 1
      [[ -f "$tmp/addons/coherent/__init__.py" ]] || { echo "no coherent/ package in $zip" >&2; exit 1; }
      mv "$tmp" "$scripts"
      echo "coherent farm: installed $(basename "$zip") into $scripts on $(hostname)"
    fi
  ) 9>"$root/$hash/.lock" || coherent_fail "installing $zip into $scripts failed on $(hostname)"
  export BLENDER_USER_SCRIPTS="$scripts"
}

# The Blender command every task runs: factory settings (a worker's own
# preferences never change a frame), the add-on enabled from the node's
# install, the COHERENT engine, and farm_setup.py, which fails the task
# unless COHERENT really is the engine (Blender would otherwise fall back to
# another engine and still write frames). Threads: the CPUs Slurm gave the
# task (0 = all of the node).
coherent_blender() {
  local blend=$1
  shift
  "${COHERENT_BLENDER:-blender}" -b --factory-startup --addons coherent "$blend" -E COHERENT \
    -t "${SLURM_CPUS_PER_TASK:-0}" --python-exit-code 1 "$@"
}
