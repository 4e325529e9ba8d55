#!/usr/bin/env bash
# The main job: starts planner_node with config/planner.yaml, publishes a scene's obstacles and
# goal over ROS 2, prints the plan received and writes a 3D plot. Installs what it needs into
# .venv first. Extra arguments go to uav-demo (try --help).
set -euo pipefail
repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=venv.sh
source "$repo_root/scripts/venv.sh"
cd "$repo_root"
# uav-demo picks a ROS domain that nothing else on this machine uses (--join-domain to share
# $ROS_DOMAIN_ID), so it never talks to another ROS graph.
exec uav-demo "$@"
