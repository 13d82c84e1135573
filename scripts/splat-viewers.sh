#!/usr/bin/env bash
# three.js's own Gaussian splats and Spark against native splatting, at their defaults and at
# each setting that brings them to 3DGS numerics: PSNR on the cameras of an orbit rig.
#
# Usage: scripts/splat-viewers.sh SCENE [WxH] [OUT_DIR] [CAMERAS]
#   SCENE any splat file splatbridge reads; default size 320x240, OUT_DIR
#   /tmp/splat-viewers/NAME, CAMERAS the indices of `orbit:8` to measure (default 0; e.g.
#   0,1,2,3,4,5,6,7: each render starts a browser, a few seconds on SwiftShader).
# Needs scripts/setup.sh's chromium and npm packages (exit 3 without them). The exports are
# `splatbridge convert SCENE --splats --camera orbit:8` (KHR_gaussian_splatting GLB, which also
# gives the .spz its cameras) and `convert SCENE -o .spz`; native renders `render --camera
# orbit:8:I`; the viewers render through scripts/splat-render.mjs (`--set KEY=VALUE`); and
# examples/image_psnr measures. Prints a markdown row per variant: mean PSNR over CAMERAS.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(dirname "$here")
scene=${1:?usage: splat-viewers.sh SCENE [WxH] [OUT_DIR] [CAMERAS]}
size=${2:-320x240}
name=$(basename "${scene%%.*}")
out=${3:-/tmp/splat-viewers/$name}
cams=${4:-0}
[[ $size =~ ^[0-9]+x[0-9]+$ ]] || { echo "error: size: expected WxH" >&2; exit 2; }
[[ $cams =~ ^[0-7](,[0-7])*$ ]] || { echo "error: CAMERAS: expected indices 0-7, comma-separated" >&2; exit 2; }
w=${size%x*} h=${size#*x}
mkdir -p "$out"
(cd "$repo" && cargo build --release --bin splatbridge --example image_psnr >&2)
sb=$repo/target/release/splatbridge
psnr=$repo/target/release/examples/image_psnr
"$sb" convert "$scene" --splats --camera orbit:8 -o "$out/splats.glb" >/dev/null
"$sb" convert "$scene" -o "$out/splats.spz" >/dev/null
IFS=, read -r -a idx <<<"$cams"
for i in "${idx[@]}"; do
  [[ -f $out/ref_$i.png ]] || "$sb" render "$scene" --camera "orbit:8:$i" --width "$w" --height "$h" -o "$out/ref_$i.png" >/dev/null 2>&1
done

a=0.00392156862745098 # 1/255
# label | client | file | settings
variants=(
  "three.js defaults (sRGB output)|three-splats|glb|"
  "three.js defaults (sRGB output)|three-splats|spz|"
  "three.js, linear output|three-splats|glb|--set output=linear"
  "three.js, linear output|three-splats|spz|--set output=linear"
  "three.js, linear output, WebGL 2 fallback|three-splats|glb|--set output=linear --set backend=webgl"
  "Spark defaults|spark|spz|"
  "Spark, blurAmount=0 preBlurAmount=0.3|spark|spz|--set blurAmount=0 --set preBlurAmount=0.3"
  "Spark, maxStdDev=3|spark|spz|--set maxStdDev=3"
  "Spark, minAlpha=1/255|spark|spz|--set minAlpha=$a"
  "Spark, sortRadial=false|spark|spz|--set sortRadial=false"
  "Spark, the three 3DGS settings (blur, σ cut, α threshold)|spark|spz|--set blurAmount=0 --set preBlurAmount=0.3 --set maxStdDev=3 --set minAlpha=$a"
  "Spark, all four (spark-native)|spark-native|spz|"
)
echo "| variant | file | PSNR (cameras $cams) | seconds per render |"
echo "|---|---|---|---|"
k=0
for v in "${variants[@]}"; do
  IFS='|' read -r label client kind settings <<<"$v"
  pairs=()
  t0=$(date +%s.%N)
  for i in "${idx[@]}"; do
    set +e
    # shellcheck disable=SC2086
    node "$here/splat-render.mjs" "$client" "$out/splats.$kind" "$out/v${k}_$i.png" --camera "$i" \
      --size "$size" --cameras "$out/splats.glb" $settings >"$out/v${k}_$i.log" 2>&1
    rc=$?
    set -e
    [[ $rc -eq 3 ]] && { cat "$out/v${k}_$i.log" >&2; exit 3; }
    [[ $rc -ne 0 ]] && { cat "$out/v${k}_$i.log" >&2; exit 1; }
    pairs+=("$out/ref_$i.png" "$out/v${k}_$i.png")
  done
  t=$(python3 -c "import time; print(f'{(time.time() - $t0) / ${#idx[@]}:.1f}')")
  mean=$("$psnr" "${pairs[@]}" | tail -1 | awk '{print $2}')
  echo "| $label | .$kind | $mean | $t |"
  k=$((k + 1))
done
