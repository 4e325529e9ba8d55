#!/usr/bin/env bash
# Builds the project's interface packages (interfaces/nav2_msgs: Nav2's two planner actions) with
# plain cmake and installs them into the venv, where rclpy from PyPI finds them:
#   scripts/build_interfaces.sh [VENV]        (default: $UAV_PLANNER_VENV or .venv)
# scripts/venv.sh calls it after installing the pinned requirements. It builds once: a stamp in
# the venv records the interface files, this script and the pins the build uses, and an unchanged
# stamp with the package in place returns at once. Needs cmake, a C and a C++ compiler and the
# Python headers. Exit status 0 when nav2_msgs is importable from the venv afterwards.
# A ROS 2 Jazzy install brings the real nav2_msgs instead (package.xml); this is for the venv.
set -uo pipefail

repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="${1:-${UAV_PLANNER_VENV:-$repo_root/.venv}}"
package_dir="$repo_root/interfaces/nav2_msgs"
python="$venv/bin/python"
stamp="$venv/.nav2_msgs.sha256"
build_dir="$venv/build/nav2_msgs"
manifest="$venv/share/nav2_msgs/install_manifest.txt"

fail() {
  echo "build_interfaces: $*" >&2
  exit 1
}

[ -x "$python" ] || fail "no Python in $venv (source scripts/venv.sh first)"
[ -f "$package_dir/package.xml" ] || fail "missing $package_dir/package.xml"

# What the build depends on: the interface package, this script, and the pins of the ROS wheels
# (generators, message packages), catkin-pkg and numpy (whose headers the Python bindings use).
# Other pins do not trigger a rebuild.
fingerprint() {
  {
    (cd "$package_dir" && find . -type f -print0 | LC_ALL=C sort -z | xargs -0 sha256sum)
    sha256sum < "${BASH_SOURCE[0]}"
    grep -E '^(ros-|catkin-pkg|numpy)' "$repo_root/requirements.txt"
    cat "$venv/pyvenv.cfg"
  } | sha256sum | cut -d' ' -f1
}

is_current() {
  [ "$(cat "$stamp" 2>/dev/null)" = "$1" ] \
    && [ -f "$venv/share/nav2_msgs/package.xml" ] \
    && compgen -G "$venv/lib/python*/site-packages/nav2_msgs/action/__init__.py" >/dev/null
}

wanted="$(fingerprint)"
is_current "$wanted" && exit 0

# Two shells sourcing venv.sh at once must not build into the same prefix together.
if command -v flock >/dev/null 2>&1; then
  exec 9>"$venv/.nav2_msgs.lock"
  flock 9
  is_current "$wanted" && exit 0
fi

for tool in cmake cc c++; do
  command -v "$tool" >/dev/null 2>&1 || fail "$tool not found: install cmake, gcc and g++"
done

echo "Building nav2_msgs (the planner actions) into $venv ..."
log="$(mktemp -t uav_planner_interfaces.XXXXXX)"
(
  # The generators find the message packages and the type supports through the ament index of
  # the venv, and must run with the venv's Python.
  export PATH="$venv/bin:$PATH"
  export AMENT_PREFIX_PATH="$venv"
  export CMAKE_PREFIX_PATH="$venv"
  set -e
  # Files of an earlier build that this one may no longer install (a renamed type).
  if [ -f "$manifest" ]; then
    while IFS= read -r file; do
      case "$file" in "$venv"/*) rm -f -- "$file" ;; esac
    done < "$manifest"
  fi
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
  cmake --install "$build_dir"
  cp "$build_dir/install_manifest.txt" "$manifest"
  rm -rf "$build_dir"
  rmdir "$venv/build" 2>/dev/null || true
  "$python" -c 'from nav2_msgs.action import ComputePathThroughPoses, ComputePathToPose'
) >"$log" 2>&1
status=$?
if [ "$status" -ne 0 ]; then
  tail -n 40 "$log" >&2
  fail "building nav2_msgs failed (full log: $log)"
fi
rm -f "$log"
echo "$wanted" > "$stamp"
echo "nav2_msgs installed into $venv"
