#!/usr/bin/env bash
# Measure what each export lever buys in stock three.js: PSNR against native splatting over
# the 8 cameras of an orbit rig, next to our tracer's PSNR on the same file and the file size.
#
# Usage: scripts/viewer-levers.sh SCENE.ply [OUT_DIR] [WxH]
#   (default OUT_DIR /tmp/viewer-levers/NAME, size 320x240)
# Needs scripts/setup.sh's chromium and npm packages (exit 3 without them). Each variant is
# `splatbridge convert SCENE --camera orbit:8 …`; three.js renders the file's cameras
# (scripts/client-render.sh), the tracer renders the same file through the same embedded
# cameras (`trace --camera scene:I`), and examples/image_psnr measures both against
# `render --camera orbit:8:I`. Prints one markdown row per variant.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(dirname "$here")
scene=${1:?usage: viewer-levers.sh SCENE.ply [OUT_DIR] [WxH]}
name=$(basename "${scene%.*}")
out=${2:-/tmp/viewer-levers/$name}
size=${3:-320x240}
w=${size%x*} h=${size#*x}
mkdir -p "$out"
(cd "$repo" && cargo build --release --bin splatbridge --example image_psnr >&2)
sb=$repo/target/release/splatbridge
psnr=$repo/target/release/examples/image_psnr
cams=0,1,2,3,4,5,6,7

for i in 0 1 2 3 4 5 6 7; do
  [[ -f $out/ref_$i.png ]] || "$sb" render "$scene" --camera "orbit:8:$i" --width "$w" --height "$h" -o "$out/ref_$i.png" >/dev/null 2>&1
done
pairs() { for i in 0 1 2 3 4 5 6 7; do printf '%s %s ' "$out/ref_$i.png" "$1_$i.png"; done; }

# variant name | convert flags | trace it too
variants=(
  "today (input order, doubleSided, NORMAL)|--layout input|trace"
  "no NORMAL|--layout input --normals false|"
  "chunks 4096, input order|--layout input --chunk-size 4096|"
  "one node, ordered along its normal|--layout input --chunk-order normal|"
  "both windings, one node, input order|--layout input --windings both|"
  "both windings, one node, ordered|--layout input --windings both --chunk-order normal|"
  "chunks 4096 + ordered + both windings|--layout input --chunk-size 4096 --chunk-order normal --windings both|"
  "chunks 1024 + ordered + both windings|--layout input --chunk-size 1024 --chunk-order normal --windings both|"
  "chunks 256 + ordered + both windings|--layout input --chunk-size 256 --chunk-order normal --windings both|"
  "default: --layout viewer (chunks 256, ordered, both windings, no NORMAL)||trace"
  "--view-order orbit:8:0 (camera 0 only)|--layout input --view-order orbit:8:0|"
)
echo "| variant | three.js PSNR (8 cameras) | camera 0 | tracer PSNR | bytes |"
echo "|---|---|---|---|---|"
k=0
for v in "${variants[@]}"; do
  IFS='|' read -r label flags trace <<<"$v"
  f=$out/v$k.glb
  # shellcheck disable=SC2086
  "$sb" convert "$scene" -o "$f" --camera orbit:8 $flags >/dev/null 2>&1
  "$here/client-render.sh" three "$f" "$out/three${k}_{camera}.png" --camera "$cams" --size "$size" >/dev/null
  # shellcheck disable=SC2046
  res=$("$psnr" $(pairs "$out/three$k"))
  mean=$(tail -1 <<<"$res" | awk '{print $2}')
  c0=$(head -1 <<<"$res" | awk '{print $2}')
  tr=-
  if [[ -n $trace ]]; then
    for i in 0 1 2 3 4 5 6 7; do
      "$sb" trace "$f" --camera "scene:$i" --width "$w" --height "$h" -o "$out/trace${k}_$i.png" >/dev/null 2>&1
    done
    # shellcheck disable=SC2046
    tr=$("$psnr" $(pairs "$out/trace$k") | tail -1 | awk '{print $2}')
  fi
  echo "| $label | $mean | $c0 | $tr | $(stat -c %s "$f") |"
  k=$((k + 1))
done
