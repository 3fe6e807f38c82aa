#!/usr/bin/env bash
# Fuzzes mcslam's parsers with libFuzzer (clang, AddressSanitizer + UBSan): the sequence lists,
# the settings files, TUM trajectories, detections files, vocabulary files, map session files,
# MCAP files and CDR messages (ROS 2 recordings).
# Each fuzzer starts from its seed corpus in fuzz/corpus/<name>/ (kept in the repository) and runs
# for SECONDS (default 60); new inputs go to build-fuzz/corpus/<name>/, crashes to
# build-fuzz/artifacts/. Exit 1 on a crash.
# SECONDS 0 replays the seed corpora once (every input, including the ones that once crashed or
# hung): the quick regression check CI runs.
# A fuzzer also stops after MCSLAM_FUZZ_RUNS inputs (default 200000), whichever comes first, so
# that its share of CI is bounded by work as well as by time (each prints how many it ran).
# Usage: scripts/fuzz.sh [SECONDS] [NAME...]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"
shift || true
names=("$@")
[ ${#names[@]} -gt 0 ] || names=(sequence_lists settings trajectory detections vocabulary session mcap cdr)
bash scripts/install-deps.sh > /dev/null
cmake --preset fuzz > /dev/null
cmake --build --preset fuzz -j "$(nproc)"
mkdir -p build-fuzz/artifacts
# One fuzzer per core at a time: each is single-threaded, and CI's budget counts wall time.
fuzz_one() {
  local name="$1" work="build-fuzz/corpus/$1" mode dirs
  mkdir -p "$work"
  if [ "$seconds" = 0 ]; then
    echo "fuzz: $name, replaying fuzz/corpus/$name"
    mode=(-runs=0)
    dirs=("fuzz/corpus/$name")
  else
    echo "fuzz: $name for $seconds s"
    mode=(-max_total_time="$seconds" -runs="${MCSLAM_FUZZ_RUNS:-200000}")
    dirs=("$work" "fuzz/corpus/$name")
  fi
  if ! ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
      "build-fuzz/fuzz/fuzz_$name" "${dirs[@]}" "${mode[@]}" \
      -rss_limit_mb=2048 -timeout=10 -max_len=4096 \
      -artifact_prefix="build-fuzz/artifacts/$name-" -print_final_stats=1 \
      > "build-fuzz/$name.log" 2>&1; then
    echo "fuzz: $name FAILED (see build-fuzz/$name.log and build-fuzz/artifacts/)"
    tail -30 "build-fuzz/$name.log"
    return 1
  fi
  grep -E "^stat::number_of_executed_units|^stat::peak_rss_mb" "build-fuzz/$name.log" | sed "s/^/fuzz: $name /" || true
}
status=0
jobs=$(nproc)
running=()
for name in "${names[@]}"; do
  if [ ${#running[@]} -ge "$jobs" ]; then
    wait "${running[0]}" || status=1
    running=("${running[@]:1}")
  fi
  fuzz_one "$name" &
  running+=($!)
done
for pid in "${running[@]}"; do wait "$pid" || status=1; done
exit $status
