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
# The Python package (python/): a wheel built with the dev profile and the features
# `cargo test` just built (cargo test's libraries are reused: only PyO3 and the bindings crate
# compile), installed into target/py-venv; its pytest suite compares it with the CLI `cargo
# test` built. The Blender extension's tests run in the same environment with the `bpy` wheel
# from PyPI (Cycles and EEVEE, see blender/tests), and the legacy add-on in Debian's Blender. Skip the
# whole Python part with SPLATBRIDGE_PYTHON_TESTS=0.
if [ "${SPLATBRIDGE_PYTHON_TESTS:-1}" = 1 ]; then
  SPLATBRIDGE_WHEEL_ARGS="--profile dev $features --auditwheel skip --strip" scripts/python-wheel.sh >/dev/null
  venv=target/py-venv
  "$venv/bin/pip" install -q --force-reinstall --no-deps target/wheels/splatbridge-*.whl
  "$venv/bin/python" -c "import bpy" 2>/dev/null || "$venv/bin/pip" install -q "bpy>=4.5,<4.6"
  export SPLATBRIDGE_CLI="$PWD/target/debug/splatbridge"
  pytest=("$venv/bin/python" -m pytest -q -rs)
  if [ -z "${DISPLAY:-}" ] && command -v xvfb-run >/dev/null; then
    pytest=(xvfb-run -a -s "-screen 0 1280x1024x24" "${pytest[@]}")
  fi
  # Two runs: each suite has its own conftest module (one pytest session would import only
  # the first `conftest`).
  "${pytest[@]}" python/tests
  "${pytest[@]}" blender/tests
fi
