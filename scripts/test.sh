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
# Two workers run the tests (a test file stays on one worker, with its fixtures); then the tests
# marked serial (test/conftest.py: they measure time or fly a simulator in real time) run alone.
# UAV_TEST_WORKERS=0 runs everything in one process. Exit code 5 (nothing selected, e.g. when the
# arguments name no serial test) counts as success for one phase, not for both.
workers="${UAV_TEST_WORKERS:-2}"
parallel=0
python -m pytest -p no:cacheprovider -n "$workers" --dist loadfile --serial skip "$@" \
  || parallel=$?
serial=0
python -m pytest -p no:cacheprovider --serial only "$@" || serial=$?
if [ "$parallel" = 5 ] && [ "$serial" = 5 ]; then
  exit 5
fi
for code in "$parallel" "$serial"; do
  if [ "$code" != 0 ] && [ "$code" != 5 ]; then
    exit "$code"
  fi
done
