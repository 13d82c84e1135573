#!/usr/bin/env bash
# Obtain Embree 4 for the `embree` feature of splatbridge-raytrace.
#
# Debian 12 ships only Embree 3, so the library comes from the PyPI wheel `embreex`, which
# carries `libembree4-<hash>.so.4` and its TBB in `embreex.libs/` (with RPATH $ORIGIN). The
# script unpacks the wheel into .tools/embree/, adds a `libembree4.so` symlink for the linker,
# and prints the environment raytrace/build.rs reads (SPLATBRIDGE_EMBREE_DIR; its default is
# this folder) and the LD_LIBRARY_PATH the CLI binary needs (the raytrace test binaries carry an
# rpath). bindgen in embree4-sys needs libclang-dev.
#
# Usage: scripts/get-embree.sh [DEST]   (default DEST: <repo>/.tools/embree)
set -euo pipefail

VERSION=4.4.0
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
dest="${1:-$repo/.tools/embree}"
lib="$dest/lib"

if [ -e "$lib/libembree4.so" ] && [ -e "$dest/.version-$VERSION" ]; then
    echo "Embree $VERSION already in $lib"
else
    py="$(command -v python3 || command -v python || true)"
    if [ -z "$py" ]; then
        echo "error: get-embree.sh: python3 with pip is needed to download the embreex wheel" >&2
        exit 2
    fi
    tmp="$(mktemp -d)"
    trap 'rm -rf "$tmp"' EXIT
    "$py" -m pip download --quiet --no-deps --only-binary=:all: --dest "$tmp" "embreex==$VERSION"
    wheel="$(ls "$tmp"/embreex-*.whl | head -n1)"
    (cd "$tmp" && "$py" -m zipfile -e "$wheel" unpacked)
    libs="$tmp/unpacked/embreex.libs"
    if [ ! -d "$libs" ]; then
        echo "error: get-embree.sh: $wheel has no embreex.libs folder" >&2
        exit 2
    fi
    rm -rf "$lib"
    mkdir -p "$lib"
    cp -a "$libs"/. "$lib"/
    so="$(ls "$lib"/libembree4*.so.4 2>/dev/null | head -n1 || true)"
    if [ -z "$so" ]; then
        echo "error: get-embree.sh: no libembree4*.so.4 in $wheel" >&2
        exit 2
    fi
    ln -sf "$(basename "$so")" "$lib/libembree4.so"
    touch "$dest/.version-$VERSION"
    echo "Embree $VERSION unpacked to $lib"
fi
if ! command -v llvm-config >/dev/null 2>&1 && ! ls /usr/lib/llvm-*/lib/libclang*.so* >/dev/null 2>&1; then
    echo "warning: libclang not found; bindgen (embree4-sys) needs it: apt-get install libclang-dev" >&2
fi
echo "export SPLATBRIDGE_EMBREE_DIR=$lib"
echo "# the raytrace tests embed an rpath; the CLI built with --features embree also needs:"
echo "export LD_LIBRARY_PATH=$lib\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}"
echo "# then: cargo test -p splatbridge-raytrace --features embree"
