#!/usr/bin/env bash
# Installs dependencies, builds, and runs the main job: occgeod on 127.0.0.1:7700 with a
# simulated Bearcat wandering the open-field world in real time. Ctrl-C stops both.
set -euo pipefail
cd "$(dirname "$0")/.."
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

"$BUILD_DIR/clients/sim/occgeo-sim" --server "$LISTEN" --robot bearcat --id bearcat-1 \
  --world clients/sim/worlds/open_field.yaml --start 0,0,0 &
sim=$!

cat <<MSG

occgeod is serving on $LISTEN; a simulated Bearcat (bearcat-1) wanders the open field.
Watch it live in a browser: http://127.0.0.1:7701/   (Prometheus metrics: http://127.0.0.1:7701/metrics)
Try, in another terminal:
  $BUILD_DIR/clients/occgeo status
  $BUILD_DIR/clients/occgeo query collision --robot bearcat-1 --x 0 --y 0 --theta 0
  $BUILD_DIR/clients/occgeo query clearance --robot bearcat-1 --x 0 --y 0
  $BUILD_DIR/clients/occgeo map export --world default --out /tmp/occgeo-map   # PGM + YAML
Ctrl-C stops the robot and the server (the map is saved in $DATA_DIR/).

MSG
wait "$sim" || true
