#!/usr/bin/env bash
# Soak test: occgeod under 4 robots, 64 query clients and 8 watching observers (occgeo-load) for 10 minutes,
# sampling the server's resident memory over time. Fails on any error, a server crash, or memory that keeps
# growing after warm-up.
#
#   scripts/soak.sh [--build DIR] [--duration S] [--robots N] [--clients M] [--observers K] [--depth D]
#                   [--sample-interval S] [--memory-verdict on|off] [--out DIR]
#
# --memory-verdict off reports memory without judging it (short runs, where the maps are still growing).
#
# Writes DIR/memory.csv (seconds,rss_kib), DIR/load.json (occgeo-load's report) and DIR/occgeod.log; DIR defaults
# to a fresh temporary folder, kept and printed at the end.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="$here/build"
duration=600
robots=4
clients=64
observers=8
depth=1
sample_interval=5
memory_verdict=on
out=""

usage() { sed -n '2,13p' "$0" | sed 's/^# \{0,1\}//'; }
while [[ $# -gt 0 ]]; do
  case "$1" in
    --build) build="$2"; shift 2 ;;
    --duration) duration="$2"; shift 2 ;;
    --robots) robots="$2"; shift 2 ;;
    --clients) clients="$2"; shift 2 ;;
    --observers) observers="$2"; shift 2 ;;
    --depth) depth="$2"; shift 2 ;;
    --sample-interval) sample_interval="$2"; shift 2 ;;
    --memory-verdict) memory_verdict="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "soak.sh: unknown option '$1'" >&2; usage >&2; exit 2 ;;
  esac
done

occgeod="$build/service/occgeod"
load="$build/clients/load/occgeo-load"
for program in "$occgeod" "$load"; do
  [[ -x "$program" ]] || { echo "soak.sh: $program is not built (cmake --build $build --target occgeod occgeo-load)" >&2; exit 2; }
done
[[ -n "$out" ]] || out="$(mktemp -d "${TMPDIR:-/tmp}/occgeo-soak.XXXXXX")"
mkdir -p "$out/data"

server_pid=""
sampler_pid=""
cleanup() {
  [[ -n "$sampler_pid" ]] && kill "$sampler_pid" 2>/dev/null || true
  [[ -n "$server_pid" ]] && kill "$server_pid" 2>/dev/null || true
  wait 2>/dev/null || true
}
trap cleanup EXIT

"$occgeod" --listen 127.0.0.1:0 --data-dir "$out/data" --port-file "$out/port" --log-level warn \
  2> "$out/occgeod.log" &
server_pid=$!
for _ in $(seq 100); do
  [[ -s "$out/port" ]] && break
  kill -0 "$server_pid" 2>/dev/null || { echo "soak.sh: occgeod exited at start:" >&2; cat "$out/occgeod.log" >&2; exit 1; }
  sleep 0.1
done
[[ -s "$out/port" ]] || { echo "soak.sh: occgeod did not start listening" >&2; exit 1; }
port="$(cat "$out/port")"

# Resident memory every sample_interval seconds, while the server lives.
(
  start=$(date +%s)
  echo "seconds,rss_kib"
  while kill -0 "$server_pid" 2>/dev/null; do
    rss=$(awk '/^VmRSS:/ {print $2}' "/proc/$server_pid/status" 2>/dev/null || true)
    [[ -n "$rss" ]] && echo "$(( $(date +%s) - start )),$rss"
    sleep "$sample_interval"
  done
) > "$out/memory.csv" &
sampler_pid=$!

echo "soak: $robots robots, $clients query clients (depth $depth), $observers observers, ${duration} s; output in $out"
load_status=0
"$load" --server "127.0.0.1:$port" --server-pid "$server_pid" --robots "$robots" --clients "$clients" \
  --depth "$depth" --observers "$observers" --duration "$duration" --threads 2 --json --quiet \
  > "$out/load.json" 2> "$out/load.err" || load_status=$?

server_alive=1
kill -0 "$server_pid" 2>/dev/null || server_alive=0
kill "$sampler_pid" 2>/dev/null || true
wait "$sampler_pid" 2>/dev/null || true
sampler_pid=""
kill -TERM "$server_pid" 2>/dev/null || true
wait "$server_pid" 2>/dev/null || true
server_pid=""

# The verdict: errors and crashes from occgeo-load's report; memory flat when the last third of the run's samples
# stays within 10 % (or 16 MiB, whichever is larger) of the middle third's (the first third is warm-up: maps and
# caches filling).
/usr/bin/python3 - "$out" "$load_status" "$server_alive" "$memory_verdict" <<'PY'
import csv, json, sys
out, load_status, server_alive = sys.argv[1], int(sys.argv[2]), sys.argv[3] == "1"
judge_memory = sys.argv[4] != "off"
failures = []
try:
    report = json.load(open(out + "/load.json"))
except (OSError, ValueError) as e:
    report = {}
    failures.append("no occgeo-load report (%s); see %s/load.err" % (e, out))
errors = report.get("errors", -1)
if errors != 0:
    failures.append("%s errors: %s" % (errors, report.get("error_samples", [])))
if not server_alive or not report.get("server_alive", server_alive):
    failures.append("the server died during the run")
if load_status not in (0, 1):
    failures.append("occgeo-load exited with %d" % load_status)
rows = [(int(r["seconds"]), int(r["rss_kib"])) for r in csv.DictReader(open(out + "/memory.csv"))]
print("memory (VmRSS MiB over time): " + " ".join("%ds:%.0f" % (t, kib / 1024) for t, kib in rows[:: max(1, len(rows) // 20)]))
if len(rows) >= 6:
    third = len(rows) // 3
    middle = sum(k for _, k in rows[third:2 * third]) / third
    last = sum(k for _, k in rows[2 * third:]) / len(rows[2 * third:])
    growth = last - middle
    flat = growth <= max(0.10 * middle, 16 * 1024)
    print("memory: middle third %.1f MiB, last third %.1f MiB, growth %+.1f MiB -> %s"
          % (middle / 1024, last / 1024, growth / 1024, "flat" if flat else "GROWING"))
    if not flat and judge_memory:
        failures.append("memory grew by %.1f MiB from the middle to the last third" % (growth / 1024))
else:
    print("memory: only %d samples, too few to judge" % len(rows))
print("load: scans %s (%.0f/s, ingest p50 %.0f us, p99 %.0f us), queries %s (%.0f/s, p50 %.0f us, p99 %.0f us), "
      "observer events %s, dropped %s" % (
          report.get("scans"), report.get("scans_per_s", 0), report.get("ingest_p50_us", 0),
          report.get("ingest_p99_us", 0), report.get("queries"), report.get("queries_per_s", 0),
          report.get("p50_us", 0), report.get("p99_us", 0), report.get("observer_events"),
          report.get("observer_dropped")))
print("errors: %s" % errors)
if failures:
    print("SOAK FAILED: " + "; ".join(failures))
    sys.exit(1)
print("SOAK PASSED")
PY
