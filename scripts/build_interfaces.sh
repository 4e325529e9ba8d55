#!/usr/bin/env bash
# Builds the project's interface packages with plain cmake and installs them into the venv, where
# rclpy from PyPI finds them:
#   interfaces/nav2_msgs  Nav2 Jazzy's two planner actions
#   interfaces/px4_msgs   the PX4 v1.16 messages of the setpoint follower and the simulated vehicle
# Usage: scripts/build_interfaces.sh [VENV]        (default: $UAV_PLANNER_VENV or .venv)
# scripts/venv.sh calls it after installing the pinned requirements. Each package builds once: a
# stamp per package in the venv records its interface files, this script and the pins the build
# uses, and an unchanged stamp with the package in place skips it at once. Needs cmake, a C and a
# C++ compiler and the Python headers. Exit status 0 when every package is importable from the
# venv afterwards; a package that fails to build is named and the others still build.
# A ROS 2 Jazzy install brings the real nav2_msgs (package.xml) and a PX4 workspace its
# px4_msgs instead; this is for the venv.
set -uo pipefail

repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="${1:-${UAV_PLANNER_VENV:-$repo_root/.venv}}"
python="$venv/bin/python"

# package name -> the Python import that proves it is installed.
packages=(nav2_msgs px4_msgs)
declare -A import_check=(
  [nav2_msgs]='from nav2_msgs.action import ComputePathThroughPoses, ComputePathToPose'
  [px4_msgs]='from px4_msgs.msg import OffboardControlMode, TrajectorySetpoint, VehicleCommand, VehicleCommandAck, VehicleLocalPosition, VehicleOdometry, VehicleStatus'
)
# The generated Python module whose __init__.py shows a finished install.
declare -A python_module=([nav2_msgs]=action [px4_msgs]=msg)

fail() {
  echo "build_interfaces: $*" >&2
  exit 1
}

[ -x "$python" ] || fail "no Python in $venv (source scripts/venv.sh first)"
for tool in cmake cc c++; do
  command -v "$tool" >/dev/null 2>&1 || fail "$tool not found: install cmake, gcc and g++"
done

# What a package's build depends on: its interface files, the shared cmake code of interfaces/,
# this script, and the pins of the ROS
# wheels (generators, message packages), catkin-pkg and numpy (whose headers the Python bindings
# use). Other pins do not trigger a rebuild.
fingerprint() {
  local package_dir="$1"
  {
    (cd "$package_dir" && find . -type f -print0 | LC_ALL=C sort -z | xargs -0 sha256sum)
    (cd "$repo_root/interfaces/cmake" && find . -type f -print0 | LC_ALL=C sort -z | xargs -0 sha256sum)
    sha256sum < "${BASH_SOURCE[0]}"
    grep -E '^(ros-|catkin-pkg|numpy)' "$repo_root/requirements.txt"
    cat "$venv/pyvenv.cfg"
  } | sha256sum | cut -d' ' -f1
}

is_current() {
  local package="$1" wanted="$2"
  [ "$(cat "$venv/.$package.sha256" 2>/dev/null)" = "$wanted" ] \
    && [ -f "$venv/share/$package/package.xml" ] \
    && compgen -G "$venv/lib/python*/site-packages/$package/${python_module[$package]}/__init__.py" \
      >/dev/null
}

# Builds one package into the venv. The old install stays in place while cmake builds, so
# processes using it meanwhile keep working; only the install step replaces it.
build_package() {
  local package="$1"
  local package_dir="$repo_root/interfaces/$package"
  local build_dir="$venv/build/$package"
  local manifest="$venv/share/$package/install_manifest.txt"
  [ -f "$package_dir/package.xml" ] || { echo "build_interfaces: missing $package_dir/package.xml" >&2; return 1; }

  local wanted
  wanted="$(fingerprint "$package_dir")"
  is_current "$package" "$wanted" && return 0

  # Two shells sourcing venv.sh at once must not build into the same prefix together.
  if command -v flock >/dev/null 2>&1; then
    exec 9>"$venv/.$package.lock"
    flock 9
    if is_current "$package" "$wanted"; then
      exec 9>&-
      return 0
    fi
  fi

  echo "Building $package into $venv ..."
  local log status
  log="$(mktemp -t uav_planner_interfaces.XXXXXX)"
  (
    # The generators find the message packages and the type supports through the ament index
    # of the venv, and must run with the venv's Python.
    export PATH="$venv/bin:$PATH"
    export AMENT_PREFIX_PATH="$venv"
    export CMAKE_PREFIX_PATH="$venv"
    set -e
    rm -rf "$build_dir"
    cmake -S "$package_dir" -B "$build_dir" \
      -DCMAKE_BUILD_TYPE=Release \
      -DCMAKE_INSTALL_PREFIX="$venv" \
      -DCMAKE_PREFIX_PATH="$venv" \
      -DCMAKE_INSTALL_RPATH="$venv/lib" \
      -DPython3_EXECUTABLE="$python" \
      -DPython3_FIND_VIRTUALENV=ONLY \
      -DBUILD_TESTING=OFF
    cmake --build "$build_dir" --parallel 2
    # Files of an earlier build that this one may no longer install (a renamed type).
    if [ -f "$manifest" ]; then
      while IFS= read -r file; do
        case "$file" in "$venv"/*) rm -f -- "$file" ;; esac
      done < "$manifest"
    fi
    cmake --install "$build_dir"
    cp "$build_dir/install_manifest.txt" "$manifest"
    rm -rf "$build_dir"
    rmdir "$venv/build" 2>/dev/null || true
    "$python" -c "${import_check[$package]}"
  ) >"$log" 2>&1
  status=$?
  if [ "$status" -ne 0 ]; then
    tail -n 40 "$log" >&2
    echo "build_interfaces: building $package failed (full log: $log)" >&2
    exec 9>&- 2>/dev/null || true
    return 1
  fi
  rm -f "$log"
  echo "$wanted" > "$venv/.$package.sha256"
  exec 9>&- 2>/dev/null || true
  echo "$package installed into $venv"
}

failed=()
for package in "${packages[@]}"; do
  build_package "$package" || failed+=("$package")
done
[ "${#failed[@]}" -eq 0 ] || fail "not built: ${failed[*]}"
