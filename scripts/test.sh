#!/usr/bin/env bash
# The project's test command: set up what the tests need (scripts/setup.sh), check formatting
# and lints, then run every test of the workspace with both BVH backends (obvhs and Embree 4).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
features=""
if [ -e .tools/embree/lib/libembree4.so ]; then
  features="--features embree"
  # raytrace's own test binaries carry an rpath; the CLI and root tests find Embree here.
  export LD_LIBRARY_PATH="$PWD/.tools/embree/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
else
  echo "test.sh: Embree 4 is not available; testing the obvhs backend only" >&2
fi
cargo fmt --all -- --check
cargo clippy --workspace --all-targets $features -- -D warnings
cargo test --workspace $features
