#!/usr/bin/env bash
# Package the Blender extension (blender/splatbridge_import, Blender 4.2+) with the
# splatbridge wheel bundled into target/blender/splatbridge-VERSION.zip, installable with
# Edit > Preferences > Get Extensions > Install from Disk or
# `blender --command extension install-file -r user_default FILE.zip`.
# The same files under a folder `splatbridge_import/` make the legacy add-on for Blender
# 3.4–4.1, target/blender/splatbridge-VERSION-legacy.zip (Edit > Preferences > Add-ons >
# Install, or `bpy.ops.preferences.addon_install`); it unpacks the bundled wheel itself on
# first use. Both paths are printed, the extension's first.
#
# Usage: scripts/blender-extension.sh [WHEEL]   (default: build one, scripts/python-wheel.sh)
set -euo pipefail
cd "$(dirname "$0")/.."
wheel=${1:-}
if [ -z "$wheel" ]; then
  wheel=$(scripts/python-wheel.sh)
fi
[ -f "$wheel" ] || { echo "error: $wheel: no such wheel" >&2; exit 2; }
version=$(sed -n 's/^version = "\(.*\)"/\1/p' blender/splatbridge_import/blender_manifest.toml)
stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT
dir="$stage/splatbridge_import"
mkdir -p "$dir/wheels"
cp blender/splatbridge_import/*.py "$dir/"
cp "$wheel" "$dir/wheels/"
sed "s|\./wheels/WHEEL|./wheels/$(basename "$wheel")|" \
  blender/splatbridge_import/blender_manifest.toml > "$dir/blender_manifest.toml"
mkdir -p target/blender
out="$PWD/target/blender/splatbridge-$version.zip"
rm -f "$out"
(cd "$dir" && python3 -m zipfile -c "$out" blender_manifest.toml ./*.py wheels)
legacy="$PWD/target/blender/splatbridge-$version-legacy.zip"
rm -f "$legacy"
(cd "$stage" && python3 -m zipfile -c "$legacy" splatbridge_import)
echo "$out"
echo "$legacy"
