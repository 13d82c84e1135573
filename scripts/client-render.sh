#!/usr/bin/env bash
# Render a glTF/GLB in a viewer people use, through the file's N-th glTF camera (the order
# `splatbridge convert` writes them), black background, no tone mapping, as a display-referred
# sRGB PNG comparable with `splatbridge render`.
#
# Usage: scripts/client-render.sh CLIENT FILE OUT.png [--camera N] [--size WxH] [--cameras CAMS.glb] [--time T]
#   (three and babylon also take --camera N,N,… with `{camera}` in OUT.png: one load, many views;
#   three takes --time T or T,T,… with `{time}` in OUT.png: the animations played by an
#   AnimationMixer set to each time)
#   CLIENT: three | babylon  (headless chromium, scripts/web-render.mjs)
#           three-splats | three-splats-linear | spark | spark-native
#                            (Gaussian splat renderers in headless chromium, scripts/splat-render.mjs;
#                            a FILE without cameras, `.spz`, takes them from --cameras CAMS.glb)
#           eevee | cycles   (Blender, scripts/blender-render.sh)
# Exit status: 0 written, 1 failed, 2 bad arguments, 3 the client is not available (the
# reason is printed: run scripts/setup.sh).
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
usage() { echo "usage: client-render.sh three|babylon|three-splats|three-splats-linear|spark|spark-native|eevee|cycles FILE OUT.png [--camera N] [--size WxH] [--cameras CAMS.glb] [--time T]" >&2; exit 2; }
[[ $# -ge 3 ]] || usage
client=$1 file=$2 out=$3
shift 3
camera=0 size= cameras= time=
while [[ $# -gt 0 ]]; do
  case $1 in
    --camera) [[ $# -ge 2 && $2 =~ ^[0-9]+(,[0-9]+)*$ ]] || usage; camera=$2; shift 2 ;;
    --size) [[ $# -ge 2 && $2 =~ ^[0-9]+x[0-9]+$ ]] || usage; size=$2; shift 2 ;;
    --cameras) [[ $# -ge 2 ]] || usage; cameras=$2; shift 2 ;;
    --time) [[ $# -ge 2 && $2 =~ ^[0-9]+([.][0-9]+)?(,[0-9]+([.][0-9]+)?)*$ ]] || usage; time=$2; shift 2 ;;
    *) usage ;;
  esac
done
[[ -f $file ]] || { echo "error: $file: not a regular file" >&2; exit 2; }
case $client in
  three|babylon)
    command -v node >/dev/null 2>&1 || { echo "client-render: node not found (run scripts/setup.sh)" >&2; exit 3; }
    [[ -z $time || $client == three ]] || { echo "error: --time: only three (and eevee, cycles) play animations here" >&2; exit 2; }
    exec node "$here/web-render.mjs" "$client" "$file" "$out" --camera "$camera" ${size:+--size "$size"} ${time:+--time "$time"}
    ;;
  three-splats|three-splats-linear|spark|spark-native)
    [[ $camera =~ ^[0-9]+$ && -z $time ]] || usage
    command -v node >/dev/null 2>&1 || { echo "client-render: node not found (run scripts/setup.sh)" >&2; exit 3; }
    exec node "$here/splat-render.mjs" "$client" "$file" "$out" --camera "$camera" ${size:+--size "$size"} ${cameras:+--cameras "$cameras"}
    ;;
  eevee|cycles)
    [[ -x $here/blender-render.sh ]] || { echo "client-render: scripts/blender-render.sh not found" >&2; exit 3; }
    [[ $time != *,* ]] || usage
    exec "$here/blender-render.sh" "$file" "$out" --engine "$client" --camera "$camera" ${size:+--size "$size"} ${time:+--time "$time"}
    ;;
  *) usage ;;
esac
