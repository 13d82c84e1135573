#!/usr/bin/env bash
# Blender EEVEE and Cycles renders of a GLB export against native splatting, next to our
# tracer on the same file: PSNR (scene::metrics, via the image_stats example) and wall time.
#
# Usage: scripts/blender-render-compare.sh [SCENE] [--camera N] [--size WxH] [--samples N]
#                                          [--time T] [--engines eevee,cycles] [--out DIR]
#                                          [-- CONVERT_ARGS...]
#   SCENE     a manifest whose cameras the export embeds (default: the street fixture)
#   --camera  the scene's N-th camera (= the export's N-th glTF camera; default 0)
#   --size    image size (default 160x120)
#   --samples Blender samples (default 64)
#   --out     keep the files and images here (default: a temporary folder)
#   after --, extra `splatbridge convert` arguments for the export (e.g. --profile rings)
# The export is rendered by scripts/blender-render.sh (set up by blender-splat-setup.py).
# Prints one JSON line per image and a table. Exit status: 0 done, 1 a step failed,
# 3 Blender (or Xvfb for EEVEE) is not available.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(dirname "$here")
scene= camera=0 size=160x120 samples=64 time=0 engines=eevee,cycles out=
while (( $# )); do
  case $1 in
    --camera) camera=$2; shift 2 ;;
    --size) size=$2; shift 2 ;;
    --samples) samples=$2; shift 2 ;;
    --time) time=$2; shift 2 ;;
    --engines) engines=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --) shift; break ;;
    -*) echo "error: unknown option $1" >&2; exit 2 ;;
    *) scene=$1; shift ;;
  esac
done
convert_args=("$@")
w=${size%x*}; h=${size#*x}
if [[ -n $out ]]; then mkdir -p "$out"; else out=$(mktemp -d); trap 'rm -rf "$out"' EXIT; fi
command -v blender >/dev/null || { echo "blender-render-compare: blender not found" >&2; exit 3; }

(cd "$repo" && cargo build -q --release --bin splatbridge && cargo build -q --release -p splatbridge-convert --example image_stats) >&2
sb=$repo/target/release/splatbridge
psnr=$repo/target/release/examples/image_stats

if [[ -z $scene ]]; then
  "$sb" fixture street -o "$out/street" >/dev/null
  scene=$out/street/scene.json
fi
glb=$out/export.glb
"$sb" convert "$scene" "${convert_args[@]}" -o "$glb" >/dev/null
"$sb" render "$scene" --camera "scene:$camera" --width "$w" --height "$h" --time "$time" -o "$out/native.png" >/dev/null

now() { date +%s%N; }
since_ms() { echo $(( ($(now) - $1) / 1000000 )); }
rows=()
measure() {  # NAME IMAGE MILLISECONDS
  local r
  r=$("$psnr" "$2" "$out/native.png")
  echo "{\"render\":\"$1\",\"camera\":$camera,\"size\":\"$size\",\"samples\":$samples,\"milliseconds\":$3,\"result\":$r}"
  rows+=("$1 $3 $r")
}
t0=$(now)
"$sb" trace "$glb" --camera "scene:$camera" --width "$w" --height "$h" --time "$time" -o "$out/trace.png" >/dev/null
measure trace "$out/trace.png" "$(since_ms "$t0")"
for engine in ${engines//,/ }; do
  t0=$(now)
  status=0
  "$here/blender-render.sh" "$glb" "$out/$engine.png" --engine "$engine" --camera "$camera" \
    --size "$size" --samples "$samples" --time "$time" >/dev/null || status=$?
  (( status == 0 )) || exit "$status"
  measure "$engine" "$out/$engine.png" "$(since_ms "$t0")"
done

printf '%s\n' "${rows[@]}" | python3 -c '
import json, sys
print("%-8s %8s %8s %8s %8s" % ("render", "PSNR dB", "seconds", "mean", "native"))
for l in sys.stdin:
    r, s, j = l.split(" ", 2)
    d = json.loads(j)
    print("%-8s %8.2f %8.1f %8.3f %8.3f" % (r, d["psnr_db"], float(s) / 1e3, d["mean_a"], d["mean_b"]))
'
