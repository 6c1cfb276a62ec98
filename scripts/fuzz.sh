#!/usr/bin/env bash
# The sanitizer build (build-fuzz/: clang, ASan + UBSan, libFuzzer's
# coverage): builds the libFuzzer targets (fuzz/) and runs each over its
# committed corpus (fuzz/corpus/<name>/); with --core-tests, first builds
# the tests of the libraries where undefined behaviour would hurt most (the
# learning core, the store, engine replicas on PostgreSQL, the RDT decoder
# and the F/T counter check, frame decoding, the haptic pipeline) in the
# same build, in the same ninja run, and runs them with halt_on_error.
#   scripts/fuzz.sh                 # 10 s per target (CI runs 5)
#   scripts/fuzz.sh --seconds=600   # longer
#   scripts/fuzz.sh --runs=10000000 # a fixed number of executions per target
#   scripts/fuzz.sh --core-tests --seconds=5   # what scripts/test.sh runs
#   scripts/fuzz.sh --core-tests --seconds=0   # the core tests only
# Any crash, leak or sanitizer report fails the run; the reproducer is left
# in build-fuzz/artifacts/. New inputs that reach new code go to
# build-fuzz/corpus/<name>/ (not the committed corpus).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=10
runs=""
core_tests=0
for arg in "$@"; do
  case "$arg" in
    --seconds=*) seconds="${arg#--seconds=}" ;;
    --runs=*) runs="${arg#--runs=}" ;;
    --core-tests) core_tests=1 ;;
    *) echo "unknown argument $arg" >&2; exit 2 ;;
  esac
done
JOBS="${JOBS:-${BITEWISE_JOBS:-$(nproc)}}"
FUZZERS=(rdt_fuzzer frame_fuzzer trace_fuzzer request_fuzzer)
# Test executables (build-relative paths) of the core sanitizer check.
CORE_TESTS=(tests/bandit/bandit_core_test tests/bandit/bandit_split_run_test
  tests/bandit/store/bandit_store_test
  tests/bandit/bandit_replica_test tests/robot/robot_rdt_protocol_test
  tests/robot/robot_counter_clock_test tests/perception/perception_frame_test
  tests/haptic/haptic_core_test)

# -O1 with line tables only: sanitizer reports keep file and line, and the
# build takes about two thirds of -O2 -g's time.
if [ ! -f build-fuzz/build.ninja ]; then
  CC=clang CXX=clang++ cmake -S . -B build-fuzz -G Ninja \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -gline-tables-only -DNDEBUG" \
    -DBITEWISE_FUZZ=ON -DBITEWISE_NATIVE=OFF >/dev/null
fi
targets=("${FUZZERS[@]}")
if ((core_tests)); then
  for t in "${CORE_TESTS[@]}"; do targets+=("$(basename "$t")"); done
  printf '\n==> Building the fuzz targets and the core tests (clang, ASan + UBSan, build-fuzz/)\n'
else
  printf '\n==> Building the fuzz targets (clang, ASan + UBSan, build-fuzz/)\n'
fi
cmake --build build-fuzz -j "$JOBS" --target "${targets[@]}"

if ((core_tests)); then
  printf '\n==> Sanitizer check (ASan + UBSan) of the core libraries\n'
  for t in "${CORE_TESTS[@]}"; do
    echo "--- $t"
    ASAN_OPTIONS="detect_leaks=1:halt_on_error=1:abort_on_error=1" \
    UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1" \
      "build-fuzz/$t" --gtest_brief=1
  done
fi
if [ "$seconds" = "0" ] && [ -z "$runs" ]; then exit 0; fi

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
