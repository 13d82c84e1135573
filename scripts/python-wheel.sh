#!/usr/bin/env bash
# Build the splatbridge Python wheel (python/, PyO3 + maturin, abi3) into target/wheels and
# print its path. The Python environment is target/py-venv (made here when missing, with
# maturin, numpy and pytest from PyPI).
#
# Usage: scripts/python-wheel.sh
# SPLATBRIDGE_WHEEL_ARGS: more `maturin build` options (default `--release`); the test
# command passes `--profile dev --features embree --auditwheel skip --strip`: the libraries
# `cargo test` has already built are reused (the test profile shares the dev profile's
# artifacts), so the wheel adds only PyO3 and the bindings crate. Not `--profile test`:
# `cargo rustc --profile test` builds a test harness, not a loadable extension module.
set -euo pipefail
cd "$(dirname "$0")/.."
read -r -a extra <<< "${SPLATBRIDGE_WHEEL_ARGS:---release}"
venv=${SPLATBRIDGE_PY_VENV:-target/py-venv}
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
if ! "$venv/bin/python" -c "import maturin, numpy, pytest" 2>/dev/null; then
  "$venv/bin/pip" install -q "maturin>=1.9,<2" numpy pytest
fi
rm -rf target/wheels/splatbridge-*.whl
"$venv/bin/maturin" build -q --manifest-path python/Cargo.toml "${extra[@]}" \
  --interpreter "$venv/bin/python" --out target/wheels >&2
ls target/wheels/splatbridge-*.whl
