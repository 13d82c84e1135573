#!/usr/bin/env bash
# Cycles render of an exported GLB through one of its cameras against the native splatting
# render of the same camera: PSNR (scene::metrics, via the image_psnr example).
#
# Usage: scripts/blender-render-compare.sh [CAMERA_NAME] [OUT_DIR]
#   CAMERA_NAME  a camera of the street fixture (default: elevated); time t = 0
#   OUT_DIR      keep the images and files here (default: a temporary directory)
# Environment: SAMPLES (Cycles samples, default 64), RES (default 320x240),
#   EXPORT_ARGS (extra `splatbridge convert` arguments for every export).
#
# For each export variant — `coplanar` (the default export) and `no-coplanar`
# (`--no-coplanar-offset`, the export before the coplanar separation) — it renders:
#   parity   Cycles with scripts/blender-parity-settings.py: Standard view transform, black
#            world (the native background), 1024 transparent bounces. The setting to judge
#            the export by: everything else is what the file carries.
#   factory  Cycles with Blender 3.4's factory defaults as ../shared/tools/blender-check.py
#            leaves them (Filmic, a grey world, 8 transparent bounces): what a user sees
#            before touching the render settings. None of these can be set from a glTF file.
#   trace    `splatbridge trace` (display compositing), the in-repo reference for the file.
# Prints one JSON line per render and a summary table.
# Exit status: 0 done, 1 a step failed, 3 Blender is not installed.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(dirname "$here")
check_py=${BLENDER_CHECK_PY:-$repo/../shared/tools/blender-check.py}
settings_py=$here/blender-parity-settings.py
command -v blender >/dev/null || { echo "blender-render-compare: blender not found" >&2; exit 3; }
[[ -f $check_py ]] || { echo "blender-render-compare: $check_py not found" >&2; exit 3; }
cam=${1:-elevated}
samples=${SAMPLES:-64}
res=${RES:-320x240}
w=${res%x*}; h=${res#*x}
if [[ -n ${2:-} ]]; then out=$2; mkdir -p "$out"; else out=$(mktemp -d); trap 'rm -rf "$out"' EXIT; fi

(cd "$repo" && cargo build -q --bin splatbridge && cargo build -q -p splatbridge-convert --example image_psnr) >&2
sb=$repo/target/debug/splatbridge
psnr=$repo/target/debug/examples/image_psnr

"$sb" fixture street -o "$out/street" >/dev/null 2>&1
manifest=$out/street/scene.json
# The camera's index in the fixture, and a copy of the fixture holding only that camera, so
# the export's first (and only) camera is the one Blender renders through.
idx=$(python3 - "$out/street/cameras.json" "$cam" <<'PY'
import json, sys
cams = json.load(open(sys.argv[1]))
names = [c.get("img_name") or c.get("name") for c in cams]
if sys.argv[2] not in names:
    sys.exit(f"no camera {sys.argv[2]!r} in the street fixture (have {names})")
print(names.index(sys.argv[2]))
PY
)
cp -r "$out/street" "$out/one-camera"
python3 - "$out/one-camera/cameras.json" "$idx" <<'PY'
import json, sys
cams = json.load(open(sys.argv[1]))
json.dump([cams[int(sys.argv[2])]], open(sys.argv[1], "w"))
PY

"$sb" render "$manifest" --camera "scene:$idx" --width "$w" --height "$h" -o "$out/native.png" >/dev/null 2>&1

rows=()
for variant in coplanar no-coplanar; do
  args=(${EXPORT_ARGS:-})
  [[ $variant == no-coplanar ]] && args+=(--no-coplanar-offset)
  glb=$out/street-$variant.glb
  "$sb" convert "$out/one-camera/scene.json" "${args[@]}" -o "$glb" >/dev/null 2>&1
  for mode in parity factory; do
    img=$out/$variant-$mode.png
    pre=()
    [[ $mode == parity ]] && pre=(--python "$settings_py")
    line=$(blender -b --factory-startup "${pre[@]}" --python "$check_py" -- "$glb" \
             --render "$img" --res "$res" --samples "$samples" 2>/dev/null | grep '^BLENDER_CHECK ' | head -1 || true)
    if [[ ! -f $img ]]; then echo "FAIL: no Cycles image for $variant/$mode: ${line:-no BLENDER_CHECK line}" >&2; exit 1; fi
    r=$("$psnr" "$img" "$out/native.png")
    echo "{\"variant\":\"$variant\",\"render\":\"cycles-$mode\",\"camera\":\"$cam\",\"samples\":$samples,\"result\":$r}"
    rows+=("$variant cycles-$mode $r")
  done
  img=$out/$variant-trace.png
  "$sb" trace "$glb" --camera scene:0 --width "$w" --height "$h" -o "$img" >/dev/null 2>&1
  r=$("$psnr" "$img" "$out/native.png")
  echo "{\"variant\":\"$variant\",\"render\":\"trace\",\"camera\":\"$cam\",\"result\":$r}"
  rows+=("$variant trace $r")
done

printf '%s\n' "${rows[@]}" | python3 -c '
import json, sys
print("%-12s %-16s %8s %8s %8s" % ("export", "render", "PSNR dB", "mean", "native"))
for l in sys.stdin:
    v, r, j = l.split(" ", 2)
    d = json.loads(j)
    print("%-12s %-16s %8.2f %8.3f %8.3f" % (v, r, d["psnr_db"], d["mean_a"], d["mean_b"]))
'
