#!/usr/bin/env bash
# Sets up the workspace: .venv with the pinned ROS 2 Jazzy wheels and Python packages, msgs_defs
# and tf2_msgs (no wheel on PyPI) built with cmake and installed into the venv, the project's
# packages installed editable.
# Idempotent: each step keeps a stamp (a hash of its inputs) and is skipped when nothing changed.
# A failing step stops the script with its name and leaves no stamp, so the next run redoes it.
set -euo pipefail

ROOT=$(cd "$(dirname "$0")/.." && pwd)
VENV="$ROOT/.venv"
PY="$VENV/bin/python"
BUILD="$ROOT/build"
STAMPS="$VENV/.activetrack-stamps"
STEP="start"

fail() {
    echo "setup: FAILED in step '$STEP' (see the output above); rerun 'make setup' after fixing it" >&2
}
trap fail ERR

step() { STEP="$1"; echo "setup: [$STEP] $2"; }
hash_of() { cat "$@" | sha256sum | cut -c1-16; }
stamp_ok() { [ -f "$STAMPS/$1" ] && [ "$(cat "$STAMPS/$1")" = "$2" ]; }
stamp_write() { mkdir -p "$STAMPS"; echo "$2" > "$STAMPS/$1"; }

# --- 1. system tools (cmake, ninja, a C compiler: Debian packages) -------------------------
step system-tools "checking cmake, ninja and a C/C++ compiler"
missing=()
command -v cmake >/dev/null || missing+=(cmake)
command -v ninja >/dev/null || missing+=(ninja-build)
command -v g++ >/dev/null || missing+=(g++)
if [ ${#missing[@]} -gt 0 ]; then
    echo "setup: installing ${missing[*]} with apt-get"
    SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq "${missing[@]}"
fi

# --- 2. the virtual environment -------------------------------------------------------------
step venv "python 3.11 virtual environment in .venv"
BASE_PY=${PYTHON:-$(command -v python3.11 || command -v python3)}
"$BASE_PY" -c 'import sys; assert sys.version_info[:2] == (3, 11), sys.version' \
    || { echo "setup: the ros-jazzy-* wheels are built for CPython 3.11; set PYTHON=/path/to/python3.11" >&2; false; }
if [ ! -x "$PY" ] || ! "$PY" -c 'import sys' 2>/dev/null; then
    rm -rf "$VENV"
    "$BASE_PY" -m venv "$VENV"
fi

# --- 3. pinned Python packages ---------------------------------------------------------------
step python-packages "pinned wheels from requirements.txt / constraints.txt"
h=$(hash_of "$ROOT/requirements.txt" "$ROOT/constraints.txt" "$ROOT/tools/fix_ros_wheel_paths.py")
if ! stamp_ok python-packages "$h"; then
    rm -f "$STAMPS/python-packages" "$STAMPS/msgs_defs" "$STAMPS/tf2_msgs"
    # The ROS wheels' bootstrap re-execs python once; never inherit it from another venv.
    env -u _ROS_WHEELS_BOOTSTRAP_COMPLETE "$PY" -m pip install -qq --disable-pip-version-check \
        -r "$ROOT/requirements.txt" -c "$ROOT/constraints.txt"
    "$PY" "$ROOT/tools/fix_ros_wheel_paths.py" "$VENV"
    stamp_write python-packages "$h"
else
    echo "setup: [$STEP] unchanged, skipped"
fi

# --- 4./5. interface packages (rosidl, cmake) installed into the venv prefix -------------------
# build_interfaces NAME SOURCE_DIR CHECK: rebuilt when its inputs changed or CHECK fails.
build_interfaces() {
    local name="$1" src="$2" check="$3"
    step "$name" "building the $name interface package with cmake"
    h=$(hash_of "$STAMPS/python-packages" "$src/CMakeLists.txt" "$src/package.xml" "$src"/msg/*.msg)
    if stamp_ok "$name" "$h" && "$PY" -c "import $name.msg" 2>/dev/null; then
        echo "setup: [$STEP] unchanged, skipped"
        return
    fi
    rm -f "$STAMPS/$name"
    rm -rf "${BUILD:?}/$name"; mkdir -p "$BUILD"
    env -u _ROS_WHEELS_BOOTSTRAP_COMPLETE AMENT_PREFIX_PATH="$VENV" \
        cmake -S "$src" -B "$BUILD/$name" -G Ninja \
        -DCMAKE_PREFIX_PATH="$VENV" -DCMAKE_INSTALL_PREFIX="$VENV" \
        -DPython3_EXECUTABLE="$PY" -DBUILD_TESTING=OFF > "$BUILD/$name.configure.log" 2>&1 \
        || { tail -n 40 "$BUILD/$name.configure.log"; false; }
    cmake --build "$BUILD/$name" --target install > "$BUILD/$name.build.log" 2>&1 \
        || { tail -n 40 "$BUILD/$name.build.log"; false; }
    env -u _ROS_WHEELS_BOOTSTRAP_COMPLETE "$PY" -c "$check"
    stamp_write "$name" "$h"
}
build_interfaces msgs_defs "$ROOT/src/msgs_defs" 'from msgs_defs.msg import Scan, TrackArray'
# tf2_msgs has no ros-jazzy-tf2-msgs wheel on PyPI: TFMessage and TF2Error, wire-identical to
# ROS 2 Jazzy's (for /tf), built like msgs_defs from interfaces/tf2_msgs.
build_interfaces tf2_msgs "$ROOT/interfaces/tf2_msgs" 'from tf2_msgs.msg import TFMessage, TF2Error'

# --- 6. the project's Python packages, editable ---------------------------------------------
step editable-packages "installing the project's packages in editable mode"
PKGS=(activetrack activetrack_experiments activetrack_ros sim_node tracker_node planner_node activetrack_bringup)
meta=()
for p in "${PKGS[@]}"; do
    for f in pyproject.toml setup.py setup.cfg package.xml; do
        [ -f "$ROOT/src/$p/$f" ] && meta+=("$ROOT/src/$p/$f")
    done
done
h=$(hash_of "$STAMPS/python-packages" "${meta[@]}")
if ! stamp_ok editable-packages "$h"; then
    rm -f "$STAMPS/editable-packages"
    args=()
    for p in "${PKGS[@]}"; do args+=(-e "$ROOT/src/$p"); done
    env -u _ROS_WHEELS_BOOTSTRAP_COMPLETE "$PY" -m pip install -qq --disable-pip-version-check \
        --no-deps --no-build-isolation "${args[@]}"
    stamp_write editable-packages "$h"
else
    echo "setup: [$STEP] unchanged, skipped"
fi

# --- 7. compiled kernels: numba's disk cache, next to their sources ------------------------------
# Every kernel compiles with cache=True; doing it here keeps the compilation (15-30 s on a busy
# 2-core machine) out of the first campaign. numba keys its cache on each source's mtime and
# size, so the stamp hashes those as well as the contents.
step kernels "compiling the numba kernels (activetrack.kernels.KERNEL_MODULES) into their disk cache"
A="$ROOT/src/activetrack/activetrack"
KSRC=("$A"/kernels/*.py "$A/models/_fisher_kernels.py" "$A/bounds/_kernels.py" "$A/planning/_kernels.py")
h=$( { cat "$STAMPS/python-packages" "${KSRC[@]}"; stat -c '%n %Y %s' "${KSRC[@]}"; } | sha256sum | cut -c1-16)
if stamp_ok kernels "$h" && compgen -G "$A/kernels/__pycache__/*.nbi" >/dev/null \
    && compgen -G "$A/planning/__pycache__/_kernels*.nbi" >/dev/null; then
    echo "setup: [$STEP] unchanged, skipped"
else
    rm -f "$STAMPS/kernels"
    # numba keys a kernel's cache on its own file only: one that inlines another file's
    # function (the PF's sampling inlines kernels/pcg64.py's draws) would keep the old code.
    # Any change to a kernel source recompiles them all.
    for d in "$A"/kernels "$A"/models "$A"/bounds "$A"/planning; do
        rm -f "$d"/__pycache__/*.nbi "$d"/__pycache__/*.nbc
    done
    env -u _ROS_WHEELS_BOOTSTRAP_COMPLETE "$PY" -m activetrack.kernels
    stamp_write kernels "$h"
fi

STEP="check"
# Also fills the bag-schema cache (.venv/share/activetrack), so the first recording is fast.
env -u _ROS_WHEELS_BOOTSTRAP_COMPLETE "$PY" -c 'import rclpy, activetrack, msgs_defs.msg, tf2_msgs.msg
from activetrack_bringup.bag import graph_schemas; graph_schemas(write_cache=True)'
echo "setup: done ($VENV)"
