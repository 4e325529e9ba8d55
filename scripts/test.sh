#!/usr/bin/env bash
# Runs every test: lint, the ROS-free core, the CLI, and the planner node in real processes.
# Installs what it needs into .venv first. Extra arguments go to pytest.
set -euo pipefail
repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=venv.sh
source "$repo_root/scripts/venv.sh"
cd "$repo_root"
python -m pytest -p no:cacheprovider "$@"
