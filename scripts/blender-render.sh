#!/usr/bin/env bash
# Render a GLB/glTF export in Blender through one of its glTF cameras, set up by
# scripts/blender-splat-setup.py (order-independent transparency, display-space colour, Raw
# view, black world, the camera's OpenCV intrinsics): an sRGB PNG comparable with
# `splatbridge render` of the same camera.
#
# Usage: scripts/blender-render.sh FILE OUT.png --engine eevee|cycles [--camera N]
#                                  [--size WxH] [--samples N] [--time SECONDS]
#   --camera N   the file's N-th glTF camera (default 0)
#   --size WxH   image size; the camera's intrinsics are scaled as `render --width/--height`
#                scale them (default: the camera's own size)
#   --samples N  render samples (default 64)
#   --time T     the animation at T seconds (default 0)
# EEVEE needs an OpenGL context: without a display it runs under `xvfb-run` (software GL, slow:
# keep scenes and sizes small).
# Exit status: 0 done, 1 failed, 2 bad arguments, 3 Blender (or Xvfb for EEVEE) not available.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
usage() { echo "usage: $0 FILE OUT.png --engine eevee|cycles [--camera N] [--size WxH] [--samples N] [--time SECONDS]" >&2; exit 2; }
(( $# >= 2 )) || usage
file=$1 out=$2; shift 2
engine= camera=0 size= samples=64 time=0
while (( $# )); do
  (( $# >= 2 )) || { echo "error: $1 needs a value" >&2; exit 2; }
  case $1 in
    --engine) engine=$2 ;;
    --camera) camera=$2 ;;
    --size) size=$2 ;;
    --samples) samples=$2 ;;
    --time) time=$2 ;;
    *) echo "error: unknown option $1" >&2; usage ;;
  esac
  shift 2
done
case $engine in eevee|cycles) ;; *) echo "error: --engine: expected eevee or cycles" >&2; exit 2 ;; esac
[[ $camera =~ ^[0-9]+$ ]] || { echo "error: --camera: expected a camera index, got '$camera'" >&2; exit 2; }
[[ $samples =~ ^[1-9][0-9]*$ ]] || { echo "error: --samples: expected a positive integer, got '$samples'" >&2; exit 2; }
[[ -z $size || $size =~ ^[1-9][0-9]*x[1-9][0-9]*$ ]] || { echo "error: --size: expected WxH, got '$size'" >&2; exit 2; }
[[ $time =~ ^[0-9]+([.][0-9]+)?$ ]] || { echo "error: --time: expected seconds, got '$time'" >&2; exit 2; }
[[ -f $file ]] || { echo "error: $file: not a regular file" >&2; exit 2; }

command -v blender >/dev/null || { echo "blender-render: blender not found" >&2; exit 3; }
run=()
if [[ $engine == eevee && -z ${DISPLAY:-} ]]; then
  command -v xvfb-run >/dev/null || { echo "blender-render: EEVEE needs a display and xvfb-run is not installed" >&2; exit 3; }
  run=(xvfb-run -a -s "-screen 0 1280x1024x24")
fi

# Render next to the output and rename on success, so a failed render leaves no partial PNG.
outdir=$(dirname "$out")
mkdir -p "$outdir"
tmp=$(mktemp "$outdir/.blender-render-XXXXXX.png")
trap 'rm -f "$tmp"' EXIT
args=("$file" --render "$tmp" --engine "$engine" --camera "$camera" --samples "$samples" --time "$time")
[[ -n $size ]] && args+=(--size "$size")
log=$(mktemp)
trap 'rm -f "$tmp" "$log"' EXIT
status=0
"${run[@]}" blender -b --factory-startup --python-exit-code 1 \
  --python "$here/blender-splat-setup.py" -- "${args[@]}" >"$log" 2>&1 || status=$?
line=$(grep '^SPLAT_SETUP ' "$log" | tail -1 || true)
if (( status != 0 )) || [[ -z $line || ! -s $tmp ]]; then
  echo "blender-render: $engine render of $file failed (exit $status):" >&2
  grep -E '^error:|Error|Traceback' "$log" | head -20 >&2 || tail -20 "$log" >&2
  exit 1
fi
mv -f "$tmp" "$out"
line=${line#SPLAT_SETUP }
echo "${line//"$tmp"/"$out"}"
