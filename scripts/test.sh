#!/usr/bin/env bash
# The project's test command: set up what the tests need (scripts/setup.sh), check formatting
# and lints, then run every test of the workspace with both BVH backends (obvhs and Embree 4).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
features=""
if [ -e .tools/embree/lib/libembree4.so ]; then
  features="--features embree"
fi
cargo fmt --all -- --check
cargo clippy --workspace --all-targets $features -- -D warnings
cargo test --workspace $features
