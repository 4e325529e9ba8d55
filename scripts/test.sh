#!/usr/bin/env bash
# Runs every test: lint, the ROS-free core, the CLI, and the planner node in real processes.
# Installs what it needs into .venv first. Extra arguments go to pytest.
set -euo pipefail
repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=venv.sh
source "$repo_root/scripts/venv.sh"
cd "$repo_root"
# Headless Chromium opens the interactive HTML view in a test (Debian's package; no download).
if ! command -v chromium >/dev/null 2>&1; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "Installing chromium (Debian package) for the HTML view test ..."
    { apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y chromium; } \
      >/tmp/uav_planner_apt.log 2>&1 || tail -n 20 /tmp/uav_planner_apt.log >&2
  else
    echo "warning: chromium not found; install it (apt-get install chromium) for the HTML test" >&2
  fi
fi
python -m pytest -p no:cacheprovider "$@"
