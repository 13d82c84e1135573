#!/usr/bin/env bash
# Babylon.js's KHR_gaussian_splatting renderer against native splatting, per camera, on the
# 8 cameras of an orbit rig: PSNR of the whole image and of its interior (a border of 1/8 of
# the width left out), which tells errors at the image's edges (Babylon culls a splat whose
# centre is outside 1.2× the clip square) from errors everywhere.
#
# Usage: scripts/babylon-splats.sh SCENE [WxH] [OUT_DIR]
#   SCENE any splat file splatbridge reads; default size 320x240, OUT_DIR /tmp/babylon-splats/NAME
# Needs scripts/setup.sh's chromium and npm packages (exit 3 without them). The export is
# `splatbridge convert SCENE --splats --camera orbit:8` (float KHR_gaussian_splatting GLB);
# Babylon renders the file's cameras (scripts/client-render.sh babylon), native renders
# `render --camera orbit:8:I`, and examples/image_psnr measures. Prints a markdown row per camera.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(dirname "$here")
scene=${1:?usage: babylon-splats.sh SCENE [WxH] [OUT_DIR]}
size=${2:-320x240}
name=$(basename "${scene%%.*}")
out=${3:-/tmp/babylon-splats/$name}
w=${size%x*} h=${size#*x}
border=$((w / 8))
mkdir -p "$out"
(cd "$repo" && cargo build --release --bin splatbridge --example image_psnr >&2)
sb=$repo/target/release/splatbridge
psnr=$repo/target/release/examples/image_psnr
"$sb" convert "$scene" --splats --camera orbit:8 -o "$out/splats.glb" >/dev/null
echo "| camera | Babylon whole | Babylon interior | Babylon seconds |"
echo "|---|---|---|---|"
sum_w=0 sum_i=0
for i in 0 1 2 3 4 5 6 7; do
  "$sb" render "$scene" --camera "orbit:8:$i" --width "$w" --height "$h" -o "$out/ref_$i.png" >/dev/null 2>&1
  t0=$(date +%s.%N)
  set +e
  "$here/client-render.sh" babylon "$out/splats.glb" "$out/babylon_$i.png" --camera "$i" --size "$size" >"$out/babylon_$i.log" 2>&1
  rc=$?
  set -e
  [[ $rc -eq 3 ]] && { cat "$out/babylon_$i.log" >&2; exit 3; }
  [[ $rc -ne 0 ]] && { cat "$out/babylon_$i.log" >&2; exit 1; }
  t=$(python3 -c "import time; print(f'{time.time() - $t0:.1f}')")
  pw=$("$psnr" "$out/ref_$i.png" "$out/babylon_$i.png" | head -1 | cut -d' ' -f2)
  pi=$("$psnr" --border "$border" "$out/ref_$i.png" "$out/babylon_$i.png" | head -1 | cut -d' ' -f2)
  echo "| orbit:8:$i | $pw | $pi | $t |"
  sum_w=$(python3 -c "print($sum_w + $pw)") sum_i=$(python3 -c "print($sum_i + $pi)")
done
echo "| mean | $(python3 -c "print(f'{$sum_w / 8:.2f}')") | $(python3 -c "print(f'{$sum_i / 8:.2f}')") | |"
