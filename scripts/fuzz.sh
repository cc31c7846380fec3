#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, ASan + UBSan) and runs each for a while, two at a time.
#
#   scripts/fuzz.sh [--seconds S | --runs N] [--ci] [--jobs J] [--targets "a b"] [--build-dir DIR] [--no-build] [--nice]
#
#   --seconds S   run each target for S seconds (default 60)
#   --runs N      run each target for N executions instead
#   --ci          the bounded run CI uses: 30 s per target for the targets that do not need the server library
#                 (framing messages log_parser mcap map_file), so the clang build stays small; the server and config
#                 targets still replay their corpus in the ordinary build
#   --jobs J      targets run at once (default 2)
#   --targets     a subset of: framing messages server log_parser mcap config map_file
#   --build-dir   where to build (default build-fuzz/ in the repository); it also keeps the grown corpora
#                 (corpus/<target>/) and any crashing inputs (artifacts/)
#   --no-build    use the binaries already in the build directory
#   --nice        run the fuzzers at the lowest CPU priority
#
# Prints, per target, the executions, libFuzzer's final coverage (cov: edges, ft: features), the corpus
# size and whether it crashed, then the total. Exits 1 on any crash, sanitizer report or timeout, and 77
# (CTest's "skipped") when clang++ is not installed.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build_dir="$repo/build-fuzz"
seconds=60
runs=""
jobs=2
build=1
ci=0
nice_cmd=()
targets=(framing messages server log_parser mcap config map_file)
targets_given=0

while [[ $# -gt 0 ]]; do
  case "$1" in
    --seconds) seconds="$2"; runs=""; shift 2 ;;
    --runs) runs="$2"; shift 2 ;;
    --ci) ci=1; seconds=30; runs=""; shift ;;
    --jobs) jobs="$2"; shift 2 ;;
    --targets) read -r -a targets <<<"$2"; targets_given=1; shift 2 ;;
    --build-dir) build_dir="$(mkdir -p "$2" && cd "$2" && pwd)"; shift 2 ;;
    --no-build) build=0; shift ;;
    --nice) nice_cmd=(nice -n 19); shift ;;
    -h|--help) sed -n '2,20p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "fuzz.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done

if [[ $ci -eq 1 && $targets_given -eq 0 ]]; then targets=(framing messages log_parser mcap map_file); fi

if ! command -v clang++ >/dev/null 2>&1; then
  echo "fuzz.sh: skipped: clang++ is not installed (libFuzzer needs clang; see scripts/setup.sh)"
  exit 77
fi

started=$(date +%s)
mkdir -p "$build_dir"
if [[ $build -eq 1 ]]; then
  generator=()
  command -v ninja >/dev/null 2>&1 && generator=(-G Ninja)
  launcher=()
  command -v ccache >/dev/null 2>&1 && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
  # -O1 with assertions on: the usual trade-off for fuzzing (fast enough, and asserts are more oracles).
  CC=clang CXX=clang++ cmake -S "$repo" -B "$build_dir" "${generator[@]}" "${launcher[@]}" \
    -DOCCGEO_FUZZ=ON -DOCCGEO_WERROR=OFF -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" >"$build_dir/fuzz-configure.log" 2>&1 ||
    { cat "$build_dir/fuzz-configure.log"; exit 1; }
  build_targets=()
  for target in "${targets[@]}"; do build_targets+=("fuzz_$target"); done
  echo "fuzz.sh: building ${build_targets[*]} with clang in $build_dir"
  cmake --build "$build_dir" --target "${build_targets[@]}" --parallel "$jobs" >"$build_dir/fuzz-build.log" 2>&1 ||
    { tail -50 "$build_dir/fuzz-build.log"; exit 1; }
fi
built=$(date +%s)

mkdir -p "$build_dir/artifacts" "$build_dir/logs"
run_target() {
  local target="$1"
  local corpus="$build_dir/corpus/$target"
  local rc=0
  rm -f "$build_dir/logs/$target.log" "$build_dir/logs/$target.rc"
  mkdir -p "$corpus"
  local limit=(-max_total_time="$seconds")
  [[ -n "$runs" ]] && limit=(-runs="$runs")
  # New inputs go to the build directory's corpus; the committed seeds are read only.
  "${nice_cmd[@]}" "$build_dir/tests/fuzz/fuzz_$target" "${limit[@]}" -timeout=25 -rss_limit_mb=2048 \
    -print_final_stats=1 -artifact_prefix="$build_dir/artifacts/$target-" \
    "$corpus" "$repo/tests/fuzz/corpus/$target" >"$build_dir/logs/$target.log" 2>&1 || rc=$?
  echo "$rc" >"$build_dir/logs/$target.rc"
}

echo "fuzz.sh: running ${targets[*]} (${runs:+$runs runs}${runs:-$seconds s} each, $jobs at a time)"
for target in "${targets[@]}"; do
  while [[ $(jobs -rp | wc -l) -ge $jobs ]]; do wait -n || true; done
  run_target "$target" &
done
wait || true
finished=$(date +%s)

failed=0
total=0
printf '%-12s %12s %10s %8s %8s %8s  %s\n' target executions exec/s cov ft corpus result
for target in "${targets[@]}"; do
  log="$build_dir/logs/$target.log"
  rc=$(cat "$build_dir/logs/$target.rc" 2>/dev/null || echo 1)
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | awk '{print $2}' | tail -1)
  if [[ -z "$execs" ]]; then execs=$(grep -o '^#[0-9]*' "$log" | tr -d '#' | tail -1); fi
  execs=${execs:-0}
  rate=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | awk '{print $2}' | tail -1)
  cov=$(grep -o 'cov: [0-9]*' "$log" | awk '{print $2}' | tail -1)
  ft=$(grep -o 'ft: [0-9]*' "$log" | awk '{print $2}' | tail -1)
  corp=$(grep -o 'corp: [0-9]*' "$log" | awk '{print $2}' | tail -1)
  result=ok
  if [[ "$rc" != 0 ]] || grep -qE 'ERROR: (AddressSanitizer|LeakSanitizer|libFuzzer)|runtime error:|SUMMARY: |fuzz property broken' "$log"; then
    result="CRASH (see $log; input in $build_dir/artifacts/)"
    failed=1
  fi
  total=$((total + execs))
  printf '%-12s %12s %10s %8s %8s %8s  %s\n' "$target" "$execs" "${rate:-?}" "${cov:-?}" "${ft:-?}" "${corp:-?}" "$result"
done
printf '%-12s %12s\n' total "$total"
echo "fuzz.sh: build $((built - started)) s, fuzzing $((finished - built)) s (wall)"
if [[ $failed -ne 0 ]]; then
  echo "fuzz.sh: FAILED: a target crashed or a sanitizer reported; reproduce with <binary> <input>" >&2
  exit 1
fi
echo "fuzz.sh: no crashes, no sanitizer reports"
