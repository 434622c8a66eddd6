#!/usr/bin/env bash
# make demo: run the live fusion system for about 20 s and show its summaries and alerts.
set -euo pipefail
cd "$(dirname "$0")/.."
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-77}"
timeout --signal=INT 20 .venv/bin/fusion launch || [ $? -eq 124 ]
