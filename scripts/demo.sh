#!/usr/bin/env bash
# make demo: the whole loop in about a minute and a half.
#   1. the live system (sensor publisher + logger, alert and fusion nodes) recorded for 30 s
#   2. bagkit stats summary of the recording
#   3. its sensor topics replayed at --rate 2 through the nodes (use_sim_time), outputs recorded
#   4. bagkit compare of the replayed outputs against the live ones, with a verdict
# Every process stays on this machine, on a domain of its own, and is stopped by its pid.
set -euo pipefail
cd "$(dirname "$0")/.."
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-77}"
BIN=.venv/bin
OUT=demo_out
LIVE_SECONDS=30
SENSORS=/imu/data,/gps/fix,/temperature,/barometer/pressure
OUTPUTS=(/alerts /logger/summary /fusion/odometry /fusion/baro_altitude)
NODES=data_logger,alert_system,sensor_fusion

# Job control: each background process gets a process group of its own (so a terminal's Ctrl-C
# reaches only this script, which stops them in order) and does not ignore SIGINT.
set -m
pids=()
start() {  # start "$@" in the background, remember its pid
  "$@" &
  pids+=($!)
}
stop() {  # SIGINT the given pids, SIGKILL whatever is still there after 15 s
  for pid in "$@"; do kill -INT "$pid" 2>/dev/null || true; done
  for pid in "$@"; do
    for _ in $(seq 150); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -KILL -- "-$pid" 2>/dev/null || true
    wait "$pid" 2>/dev/null || true
  done
}
cleanup() { stop "${pids[@]}"; }
trap cleanup EXIT
trap 'exit 130' INT TERM
step() { printf '\n\033[1m== %s\033[0m\n' "$*"; }

rm -rf "$OUT" && mkdir -p "$OUT/logs"

step "1. live system, recorded for ${LIVE_SECONDS} s (ROS_DOMAIN_ID=$ROS_DOMAIN_ID)"
start env COLUMNS=120 "$BIN/bagkit" record -o "$OUT/live" --all >"$OUT/logs/record-live.log" 2>&1
recorder=${pids[-1]}
sleep 1  # the recorder is in the graph before the first sensor message
start "$BIN/fusion" launch >"$OUT/logs/live-system.log" 2>&1
system=${pids[-1]}
sleep "$LIVE_SECONDS"
# A service call, recorded with the topics (-a: topics and services): the logger's summary.
summary=$("$BIN/fusion" summary 2>&1 || true)
sleep 0.5  # the call's introspection events reach the recorder
stop "$recorder" "$system"
sed -n '3,$p' "$OUT/logs/record-live.log"  # the recorder's report: messages and losses per topic
echo
echo "alerts raised and cleared by the alert system (faults scheduled in fusion/config/params.yaml):"
grep '^\[alert_system\]' "$OUT/logs/live-system.log" || echo "(none)"
echo
echo "the data logger's answer to fusion summary (service /logger/get_summary):"
echo "$summary"
echo
echo "the data logger's last summary:"
awk '/^\[data_logger\].*summary at/ { last = "" } /^\[data_logger\]/ { last = last $0 "\n" }
     END { printf "%s", last }' "$OUT/logs/live-system.log"

step "2. bagkit stats summary $OUT/live"
"$BIN/bagkit" stats summary "$OUT/live" --topics /temperature --topics /barometer/pressure \
  --topics /fusion/baro_altitude --fields temperature --fields fluid_pressure \
  --fields 'pose.pose.position.z' --fields 'pose.covariance[14]'

step "3. sensor topics replayed at --rate 2 through the logger, alert and fusion nodes"
start "$BIN/fusion" launch --use-sim-time --only "$NODES" >"$OUT/logs/replay-nodes.log" 2>&1
nodes=${pids[-1]}
start "$BIN/bagkit" record --use-sim-time -o "$OUT/replayed" "${OUTPUTS[@]}" \
  >"$OUT/logs/record-replayed.log" 2>&1
recorder=${pids[-1]}
# Until every node subscribes to its inputs and /clock and the recorder to every output.
"$BIN/python" - <<'EOF'
from bagkit.ros.graph_wait import wait_for_subscriptions

inputs = {"/imu/data": 3, "/gps/fix": 3, "/temperature": 2, "/barometer/pressure": 3, "/clock": 3}
outputs = dict.fromkeys(["/alerts", "/logger/summary", "/fusion/odometry", "/fusion/baro_altitude"], 1)
wait_for_subscriptions({**inputs, **outputs}, timeout=60, alive=lambda: True)
EOF
"$BIN/bagkit" replay --clock --rate 2 --topics "$SENSORS" "$OUT/live"
sleep 2  # the last outputs are still in flight on a loaded machine
stop "$recorder" "$nodes"

step "4. bagkit compare: replayed outputs against the live ones"
# What the comparison leaves out, and why:
# - /logger/summary: the live logger's timer ran on the wall clock from the nodes' start, the
#   replayed one on bag time; the lockstep golden tests compare summaries.
# - the first 8 s: the live nodes started before the recorder caught up, so their filter had
#   seen samples the bag does not hold; the replayed filter converges to the same state.
# - odometry x/y: ENU coordinates from the first GPS fix each fusion node saw, which for the
#   live node came before the recording started (a constant offset).
# Tolerances: the live ones of the golden fixtures (cross-topic reordering on DDS).
echo "(after 8 s of filter warm-up; odometry x/y and /logger/summary left out: see scripts/demo.sh)"
set +e
"$BIN/bagkit" compare "$OUT/live" "$OUT/replayed" --spec fixtures/faults/spec.yaml --live \
  --topics /alerts,/fusion/odometry,/fusion/baro_altitude --skip 8 \
  --ignore-fields /fusion/odometry:pose.pose.position.x \
  --ignore-fields /fusion/odometry:pose.pose.position.y --report "$OUT/compare.json"
verdict=$?
set -e
if [ "$verdict" -eq 0 ]; then
  printf '\n\033[1;32mVERDICT: the replay through the nodes reproduces the live outputs.\033[0m\n'
else
  printf '\n\033[1;31mVERDICT: replayed outputs differ from the live ones (see %s).\033[0m\n' \
    "$OUT/compare.json"
fi
exit "$verdict"
