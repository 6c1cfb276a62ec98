#!/usr/bin/env bash
# Runs every test: builds (installing missing packages first), checks that
# the tree is clang-formatted (Google style), then runs CTest.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh

printf '\n==> Checking clang-format (Google style) on every C++ file\n'
unformatted=$(git ls-files '*.cc' '*.h' | while read -r f; do
  clang-format --dry-run -Werror "$f" >/dev/null 2>&1 || echo "$f"
done)
if [ -n "$unformatted" ]; then
  echo "Not clang-formatted (run: clang-format -i FILE):"
  echo "$unformatted"
  exit 1
fi

printf '\n==> Running tests\n'
cd build
ctest --output-on-failure -j "${BITEWISE_JOBS:-$(nproc)}" --timeout 300
