#!/usr/bin/env bash
# Installs the Debian bookworm packages bitewise needs (only those missing)
# and builds into build/. Safe to run again: it only does what is left to do.
#
#   scripts/setup.sh          everything: services, clients, console, tests,
#                             benchmarks, experiments (scripts/test.sh)
#   scripts/setup.sh --meal   only what a simulated meal needs: the four
#                             services, the orchestrator and the health probe
#                             (scripts/meal.sh); a later full setup reuses
#                             the same build/ and its compiled objects
set -euo pipefail
cd "$(dirname "$0")/.."

mode="all"
case "${1:-}" in
  "") ;;
  --meal) mode="meal" ;;
  *)
    echo "usage: scripts/setup.sh [--meal]" >&2
    exit 2
    ;;
esac

# What the meal's targets need to configure and build.
MEAL_PACKAGES=(
  build-essential cmake ninja-build ccache pkg-config git
  libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler
  libabsl-dev libeigen3-dev libopencv-dev libonnx-dev
  libsqlite3-dev libpq-dev prometheus-cpp-dev
)
MEAL_TARGETS=(bitewise-bandit bitewise-perception bitewise-haptic bitewise-robot
  bitewise-orchestrator bitewise-health)
# Everything else: tests, benchmarks, fuzzing, the console, the plots.
PACKAGES=(
  openssl clang-format gnuplot-nox
  libgtest-dev libgmock-dev libbenchmark-dev sqlite3
  libpq-dev postgresql-15  # the PostgreSQL store; its tests start a server
  prometheus-cpp-dev
  clang libclang-rt-14-dev  # the libFuzzer targets (scripts/fuzz.sh)
  # bitewise-console: its HTTP(S) server, and Chromium for its browser test
  libcpp-httplib-dev libssl-dev zlib1g-dev libbrotli-dev chromium
)
# SPANet's PyTorch definition, export tool and their tests (scripts/spanet):
# CPU PyTorch, without its recommended C++ headers.
PYTHON_PACKAGES=(python3-torch python3-onnx python3-pil python3-numpy)

step() { printf '\n==> %s\n' "$*"; }

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
updated=0
install_missing() {  # install_missing [apt options] -- packages...
  local options=() missing=()
  while [ "$1" != "--" ]; do options+=("$1"); shift; done
  shift
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" ||
      missing+=("$p")
  done
  if ((${#missing[@]})); then
    step "Installing ${#missing[@]} missing Debian packages: ${missing[*]}"
    if ((!updated)); then $SUDO apt-get update -q; updated=1; fi
    $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -q \
      "${options[@]}" "${missing[@]}"
  fi
}
JOBS="${BITEWISE_JOBS:-$(nproc)}"
if [ "$mode" = "meal" ]; then
  install_missing --no-install-recommends -- "${MEAL_PACKAGES[@]}"
  if [ ! -f build/build.ninja ]; then
    step "Configuring the meal's targets (CMake, Ninja, Release)"
    cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DBITEWISE_WERROR=ON \
      -DBITEWISE_MEAL_ONLY=ON
  fi
  step "Building the meal's ${#MEAL_TARGETS[@]} programs with $JOBS jobs"
  cmake --build build -j "$JOBS" --target "${MEAL_TARGETS[@]}"
  exit 0
fi

install_missing -- "${MEAL_PACKAGES[@]}" "${PACKAGES[@]}"
# The console's web app is bundled with npm at build time. A machine with
# Node.js from elsewhere keeps it; otherwise Debian's.
if ! command -v npm >/dev/null || ! command -v node >/dev/null; then
  install_missing -- nodejs npm
fi
install_missing --no-install-recommends -- "${PYTHON_PACKAGES[@]}"

if [ ! -f build/build.ninja ]; then
  step "Configuring (CMake, Ninja, Release)"
  cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DBITEWISE_WERROR=ON \
    -DBITEWISE_MEAL_ONLY=OFF
elif grep -q '^BITEWISE_MEAL_ONLY:BOOL=ON' build/CMakeCache.txt; then
  step "Configuring the rest of the tree (tests, benchmarks, console)"
  cmake -S . -B build -DBITEWISE_MEAL_ONLY=OFF
fi
step "Building with $JOBS jobs (first build takes a few minutes; ccache makes later ones fast)"
cmake --build build -j "$JOBS"
