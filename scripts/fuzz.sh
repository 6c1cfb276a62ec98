#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/) with clang, ASan and UBSan into
# build-fuzz/ and runs each over its committed corpus (fuzz/corpus/<name>/).
#   scripts/fuzz.sh                 # 10 s per target (CI runs 5)
#   scripts/fuzz.sh --seconds=600   # longer
#   scripts/fuzz.sh --runs=10000000 # a fixed number of executions per target
# Any crash, leak or sanitizer report fails the run; the reproducer is left
# in build-fuzz/artifacts/. New inputs that reach new code go to
# build-fuzz/corpus/<name>/ (not the committed corpus).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=10
runs=""
for arg in "$@"; do
  case "$arg" in
    --seconds=*) seconds="${arg#--seconds=}" ;;
    --runs=*) runs="${arg#--runs=}" ;;
    *) echo "unknown argument $arg" >&2; exit 2 ;;
  esac
done
JOBS="${JOBS:-$(nproc)}"
FUZZERS=(rdt_fuzzer frame_fuzzer trace_fuzzer request_fuzzer)

if [ ! -f build-fuzz/CMakeCache.txt ]; then
  CC=clang CXX=clang++ cmake -S . -B build-fuzz -G Ninja \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo -DBITEWISE_FUZZ=ON \
    -DBITEWISE_NATIVE=OFF >/dev/null
fi
printf '\n==> Building the fuzz targets (clang, ASan + UBSan, build-fuzz/)\n'
cmake --build build-fuzz -j "$JOBS" --target "${FUZZERS[@]}"

mkdir -p build-fuzz/artifacts
for f in "${FUZZERS[@]}"; do
  mkdir -p "build-fuzz/corpus/$f"
  limit=(-max_total_time="$seconds")
  [ -n "$runs" ] && limit=(-runs="$runs")
  printf '\n==> %s (%s)\n' "$f" "${limit[*]}"
  status=0
  ASAN_OPTIONS="detect_leaks=1:abort_on_error=1" \
  UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1" \
    "build-fuzz/fuzz/$f" "${limit[@]}" -rss_limit_mb=4096 -timeout=10 \
      -artifact_prefix="build-fuzz/artifacts/$f-" -print_final_stats=1 \
      "build-fuzz/corpus/$f" "fuzz/corpus/$f" >"build-fuzz/$f.log" 2>&1 ||
    status=$?
  grep -E "stat::number_of_executed_units|stat::peak_rss_mb|Done [0-9]+ runs" \
    "build-fuzz/$f.log" || true
  if [ "$status" -ne 0 ]; then
    tail -60 "build-fuzz/$f.log"
    echo "$f failed (exit $status); reproducer in build-fuzz/artifacts/" >&2
    exit 1
  fi
done
printf '\nAll fuzz targets ran clean.\n'
