#!/usr/bin/env bash
# Creates (or refreshes) the project's virtual environment in .venv and installs the pinned
# requirements plus this package in editable mode. Source it: it exports the ROS variables that
# keep DDS traffic on this machine and puts .venv/bin first on PATH. It sets no shell option
# (no set -e), so a shell that sources it keeps its own error handling.
repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="${UAV_PLANNER_VENV:-$repo_root/.venv}"
python_bin="${PYTHON:-python3.11}"

if ! command -v "$python_bin" >/dev/null 2>&1; then
  echo "error: $python_bin not found; ROS 2 Jazzy wheels need Python 3.11 (set PYTHON=...)" >&2
  return 1 2>/dev/null || exit 1
fi

stamp="$venv/.requirements.sha256"
wanted="$(cat "$repo_root/requirements.txt" "$repo_root/setup.py" | sha256sum | cut -d' ' -f1)"
_uav_planner_setup() {
  # Runs under the lock: another shell may have finished the same install meanwhile.
  if [ ! -x "$venv/bin/python" ] || [ "$(cat "$stamp" 2>/dev/null)" != "$wanted" ]; then
    echo "Setting up $venv (pinned versions from requirements.txt) ..."
    local log
    log="$(mktemp -t uav_planner_pip.XXXXXX)"
    if ! { "$python_bin" -m venv "$venv" \
           && "$venv/bin/python" -m pip install --upgrade pip \
           && "$venv/bin/python" -m pip install -r "$repo_root/requirements.txt" \
           && "$venv/bin/python" -m pip install --no-deps --no-build-isolation -e "$repo_root"; \
         } >"$log" 2>&1; then
      tail -n 40 "$log" >&2
      echo "error: installing into $venv failed (full log: $log)" >&2
      return 1
    fi
    rm -f "$log"
    echo "$wanted" > "$stamp"
  fi
  # Nav2's planner actions and PX4's messages (nav2_msgs and px4_msgs are not on PyPI), built
  # from interfaces/ into the venv once: the script keeps a stamp per package and returns at
  # once when nothing changed. Without nav2_msgs the planner node still runs, with its topics
  # and GetPlan; without px4_msgs the setpoint follower has only its MAVLink transport.
  if ! bash "$repo_root/scripts/build_interfaces.sh" "$venv"; then
    echo "warning: interface packages not built (named above); without nav2_msgs planner_node" \
      "starts without its Nav2 action servers, without px4_msgs the follower has no PX4 link" >&2
  fi
}
# One install at a time: shells that source this at once (parallel test runs) wait for the
# first one instead of installing into the same venv together.
if ! ( flock 9 && _uav_planner_setup ) 9>"$venv.lock"; then
  unset -f _uav_planner_setup
  return 1 2>/dev/null || exit 1
fi
unset -f _uav_planner_setup

export PATH="$venv/bin:$PATH"
export VIRTUAL_ENV="$venv"
# DDS stays on this machine; logs go to a temporary folder.
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export ROS_LOG_DIR="${ROS_LOG_DIR:-$(mktemp -d -t uav_planner_roslog.XXXXXX)}"
export RMW_IMPLEMENTATION="${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}"
# Compiled search kernels are cached next to the venv, so later runs start fast.
export NUMBA_CACHE_DIR="${NUMBA_CACHE_DIR:-$venv/numba_cache}"
export MPLBACKEND=Agg
