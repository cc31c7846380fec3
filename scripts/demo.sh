#!/usr/bin/env bash
# Installs dependencies, builds, and runs the main job: occgeod on 127.0.0.1:7700 with a
# simulated robot driving the open-field world in real time until Ctrl-C stops both.
#   scripts/demo.sh [--robot bearcat|scout|activitybot|ugv]   (default bearcat)
# bearcat and ugv are steered by the server's Bearcat behaviour (with its map-based escape, so
# they never park in a corner), scout by seed 001's wander on its sonar ring; the activitybot
# follows a looped script (sweeping its servo, a quarter turn between sweeps).
set -euo pipefail
cd "$(dirname "$0")/.."
ROBOT=bearcat
while [ $# -gt 0 ]; do
  case "$1" in
    --robot) ROBOT=${2:-}; shift 2 ;;
    --robot=*) ROBOT=${1#--robot=}; shift ;;
    -h|--help) sed -n '2,7p' "$0"; exit 0 ;;
    *) echo "demo.sh: unknown argument '$1' (try --robot bearcat|scout|activitybot|ugv)" >&2; exit 2 ;;
  esac
done
case "$ROBOT" in
  bearcat) WHAT="a simulated Bearcat wanders the open field (Bearcat behaviour, map-based escape)"; EXTRA=() ;;
  ugv) WHAT="a simulated tracked UGV drives the open field (Bearcat behaviour, map-based escape)"; EXTRA=() ;;
  scout) WHAT="a simulated Nomad Scout wanders the open field on its sonar ring (seed 001)"; EXTRA=() ;;
  activitybot) WHAT="a simulated ActivityBot sweeps its LIDAR-Lite and turns a quarter between sweeps"
    EXTRA=(--drive "0,0,7.2;0,0.8,2") ;;
  *) echo "demo.sh: --robot must be bearcat, scout, activitybot or ugv, not '$ROBOT'" >&2; exit 2 ;;
esac
bash scripts/setup.sh
bash scripts/build.sh
BUILD_DIR=${BUILD_DIR:-build}
DATA_DIR=${DATA_DIR:-occgeo-data}
LISTEN=${LISTEN:-127.0.0.1:7700}

"$BUILD_DIR/service/occgeod" --listen "$LISTEN" --data-dir "$DATA_DIR" --log-level warn &
server=$!
sim=""
cleanup() {
  [ -n "$sim" ] && kill -INT "$sim" 2>/dev/null && wait "$sim" 2>/dev/null || true
  kill -TERM "$server" 2>/dev/null && wait "$server" 2>/dev/null || true
}
trap cleanup EXIT INT TERM
for _ in $(seq 50); do
  "$BUILD_DIR/clients/occgeo" status --server "$LISTEN" >/dev/null 2>&1 && break
  sleep 0.1
done

"$BUILD_DIR/clients/sim/occgeo-sim" --server "$LISTEN" --robot "$ROBOT" --id "$ROBOT-1" \
  --world clients/sim/worlds/open_field.yaml --start 0,0,0 ${EXTRA[@]+"${EXTRA[@]}"} &
sim=$!

cat <<MSG

occgeod is serving on $LISTEN; $WHAT ($ROBOT-1).
Watch it live in a browser: http://127.0.0.1:7701/   (Prometheus metrics: http://127.0.0.1:7701/metrics)
Try, in another terminal:
  $BUILD_DIR/clients/occgeo status
  $BUILD_DIR/clients/occgeo query collision --robot $ROBOT-1 --x 0 --y 0 --theta 0
  $BUILD_DIR/clients/occgeo query clearance --robot $ROBOT-1 --x 0 --y 0
  $BUILD_DIR/clients/occgeo map export --world default --out /tmp/occgeo-map   # PGM + YAML
Ctrl-C stops the robot and the server (the map is saved in $DATA_DIR/).

MSG
wait "$sim" || true
