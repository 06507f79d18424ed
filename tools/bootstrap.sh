#!/usr/bin/env bash
# Set up (or bring up to date) everything the project needs, on a machine that has only
# Python 3.11, a C compiler and CMake: the venv with pinned wheels (real rclpy on Fast DDS),
# the fix for the wheels' CMake include paths, the colcon build of the workspace, and the
# `auv` command. Each step is skipped when its inputs have not changed since it last ran.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
VENV="$ROOT/.venv"
PY=${AUV_PYTHON:-$(command -v python3.11 || command -v python3)}
log() { printf 'setup: %s\n' "$*" >&2; }

if ! "$PY" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))'; then
  echo "error: Python 3.11 is required (found $("$PY" --version 2>&1) at $PY)" >&2
  exit 1
fi

# 1. venv and pinned wheels
if [ ! -x "$VENV/bin/python" ]; then
  log "creating venv $VENV"
  "$PY" -m venv "$VENV"
fi
if ! cmp -s "$ROOT/requirements.lock" "$VENV/.requirements.done"; then
  log "installing pinned wheels (requirements.lock)"
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check -r "$ROOT/requirements.lock"
  # The wheels' exported CMake files name include paths of the machine that built them.
  "$VENV/bin/python" - "$VENV" <<'PY'
import pathlib, sys, sysconfig
import numpy
venv = pathlib.Path(sys.argv[1])
fixes = {
    '/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include': numpy.get_include(),
    '/opt/python/cp311-cp311/include/python3.11': sysconfig.get_paths()['include'],
}
for path in venv.glob('share/*/cmake/*.cmake'):
    text = path.read_text()
    new = text
    for old, repl in fixes.items():
        new = new.replace(old, repl)
    if new != text:
        path.write_text(new)
PY
  cp "$ROOT/requirements.lock" "$VENV/.requirements.done"
fi

# 2. colcon build of the workspace (messages and the ament_python packages)
stamp=$(cd "$ROOT" && find src -type f \( -path 'src/auv_msgs/*' -o -name package.xml \
          -o -name setup.py -o -name setup.cfg -o -path '*/resource/*' \
          -o -path 'src/auv_contract/config/*' \) -print0 \
        | sort -z | xargs -0 sha1sum | sha1sum | cut -d' ' -f1)
if [ ! -f "$ROOT/install/.build-stamp" ] || [ "$(cat "$ROOT/install/.build-stamp")" != "$stamp" ]; then
  log "colcon build (messages and packages)"
  mkdir -p "$ROOT/log"
  (cd "$ROOT" && AMENT_PREFIX_PATH="$VENV" CMAKE_PREFIX_PATH="$VENV" PATH="$VENV/bin:$PATH" \
    "$VENV/bin/colcon" --log-base "$ROOT/log" build --base-paths src \
      --build-base "$ROOT/build" --install-base "$ROOT/install" \
      --cmake-args -DPython3_EXECUTABLE="$VENV/bin/python" -DBUILD_TESTING=OFF \
      > "$ROOT/log/colcon-build.txt" 2>&1 || { mkdir -p "$ROOT/log"; tail -n 30 "$ROOT/log/colcon-build.txt" >&2; \
        echo "error: colcon build failed (full log: log/colcon-build.txt)" >&2; exit 1; })
  echo "$stamp" > "$ROOT/install/.build-stamp"
fi

# 3. The source packages on the venv's path (edits take effect at once), and the `auv` command.
site=$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
# the ament_python packages: every src/<pkg> with a setup.py
PKGS=$(cd "$ROOT/src" && for f in */setup.py; do printf '%s ' "${f%/setup.py}"; done)
prefix=""
for pkg in auv_msgs $PKGS; do prefix="$prefix$ROOT/install/$pkg:"; done
{
  for pkg in $PKGS; do echo "$ROOT/src/$pkg"; done
  echo "$ROOT/install/auv_msgs/lib/python3.11/site-packages"
  # after the sources: the installed packages' metadata, for the ros2-run executables in
  # install/<pkg>/lib/<pkg>/ (their modules resolve to the sources above)
  for pkg in $PKGS; do
    echo "$ROOT/install/$pkg/lib/python3.11/site-packages"
  done
} > "$site/auv_workspace.pth"
cat > "$VENV/bin/auv-env" <<SH
# Environment of the workspace: source it, or prefix a command with it (auv-env CMD...).
export AMENT_PREFIX_PATH="$prefix$VENV\${AMENT_PREFIX_PATH:+:\$AMENT_PREFIX_PATH}"
export LD_LIBRARY_PATH="$ROOT/install/auv_msgs/lib\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}"
export PATH="$VENV/bin:\$PATH"
export AUV_ROOT="$ROOT"
export MPLBACKEND=Agg
# The toolkit's Fast DDS profile (auv_contract.dds) for every process started from here (a
# script, ros2 topic echo), unless the user names one: found within ~0.5 s by a graph
# started after it, not only at Fast DDS's 3 s announcements.
if [ -z "\${FASTDDS_DEFAULT_PROFILES_FILE:-}\${FASTRTPS_DEFAULT_PROFILES_FILE:-}" ]; then
  export FASTDDS_DEFAULT_PROFILES_FILE="$ROOT/install/auv_contract/share/auv_contract/config/dds/fastdds.xml"
fi
SH
cat > "$VENV/bin/auv" <<SH
#!/usr/bin/env bash
# The project's umbrella command (see README.md).
. "$VENV/bin/auv-env"
exec "$VENV/bin/python" -m auv_bringup.cli "\$@"
SH
chmod +x "$VENV/bin/auv"
