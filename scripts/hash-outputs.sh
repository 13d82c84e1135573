#!/usr/bin/env bash
# Render a fixed set of reference outputs with the release CLI and print their SHA-256, one
# line per file (path relative to the output directory), so a refactor can be checked to keep
# every image, export and LiDAR scan bit-identical:
#
#   scripts/hash-outputs.sh > before.txt   # on the old code
#   scripts/hash-outputs.sh > after.txt    # on the new code
#   diff before.txt after.txt
#
# Covers native render, GES hybrid, mesh trace of the GLB and OBJ exports of every profile,
# Gaussian trace, each declared effect (weather, motion blur, shadows, LiDAR) on the street
# manifest, and a `compare` run's images; on the street fixture and, when present,
# ../shared/data/real/fourth_st.ply (override with FOURTH_ST=PATH). Sizes are small so the
# whole run takes a minute or two. Set BIN to use another binary, KEEP=DIR to keep the outputs.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${BIN:-target/release/splatbridge}
FOURTH_ST=${FOURTH_ST:-../shared/data/real/fourth_st.ply}
if [ ! -x "$BIN" ]; then
  echo "hash-outputs.sh: $BIN not found; run cargo build --release --bin splatbridge" >&2
  exit 2
fi
if [ -n "${KEEP:-}" ]; then
  out=$KEEP
  mkdir -p "$out"
else
  out=$(mktemp -d)
  trap 'rm -rf "$out"' EXIT
fi
run() { "$BIN" "$@" > /dev/null; }
size=(--width 96 --height 64)

# Scenes: the plain street and one manifest per declared effect.
run fixture street --count 4000 -o "$out/street"
for e in rain motion_blur shadows lidar; do
  run fixture street --count 4000 --effects "$e" -o "$out/street_$e"
done
street="$out/street/scene.json"

scenes=("street:$street")
if [ -f "$FOURTH_ST" ]; then
  scenes+=("fourth:$FOURTH_ST")
else
  echo "hash-outputs.sh: $FOURTH_ST missing; real-scene outputs skipped" >&2
fi

for entry in "${scenes[@]}"; do
  tag=${entry%%:*}
  src=${entry#*:}
  d="$out/$tag"
  mkdir -p "$d"
  run render "$src" --camera orbit:8:1 "${size[@]}" --time 1.0 -o "$d/native.png"
  run render "$src" --camera orbit:8:5 "${size[@]}" --extent alpha --sh-degree 1 -o "$d/native_knobs.exr"
  run hybrid "$src" --camera orbit:8:1 "${size[@]}" --time 1.0 -o "$d/hybrid.png"
  run hybrid "$src" --camera orbit:8:3 "${size[@]}" --supersample 4 --blur -o "$d/hybrid_ss.png"
  run trace "$src" --mode gaussian --camera orbit:8:1 "${size[@]}" --time 1.0 -o "$d/gaussian.png"
  for p in meshsplats rings texture; do
    run convert "$src" --profile "$p" -o "$d/$p.glb"
    run trace "$d/$p.glb" --camera orbit:8:1 "${size[@]}" --time 1.0 -o "$d/trace_$p.png"
    run trace "$d/$p.glb" --camera orbit:8:1 "${size[@]}" --time 1.0 --compositing viewer -o "$d/trace_${p}_viewer.png"
  done
  run convert "$src" -o "$d/meshsplats.obj"
  run trace "$d/meshsplats.obj" --camera orbit:8:1 "${size[@]}" -o "$d/trace_obj.png"
  run trace "$src" --camera orbit:8:2 "${size[@]}" --time 1.0 -o "$d/trace_in_memory.png"
done

# Effects on the street manifest: every renderer that simulates each one.
for e in rain motion_blur shadows lidar; do
  m="$out/street_$e/scene.json"
  d="$out/effects_$e"
  mkdir -p "$d"
  run render "$m" --camera scene:0 "${size[@]}" --time 1.0 -o "$d/native.png"
  run hybrid "$m" --camera scene:0 "${size[@]}" --time 1.0 -o "$d/hybrid.png"
  run trace "$m" --mode gaussian --camera scene:0 "${size[@]}" --time 1.0 --lidar-out "$d/lidar_g" -o "$d/gaussian.png"
  run trace "$m" --camera scene:0 "${size[@]}" --time 1.0 --lidar-out "$d/lidar_m" -o "$d/mesh.png"
  run convert "$m" -o "$d/export.glb"
  run trace "$d/export.glb" --effects-from "$m" --camera scene:0 "${size[@]}" --time 1.0 --lidar-out "$d/lidar_x" -o "$d/exported.png"
done
run trace "$out/street_lidar/scene.json" --mode gaussian --camera scene:0 "${size[@]}" --lidar-all-frames --lidar-out "$out/effects_lidar/all_g" -o "$out/effects_lidar/all_g.png"
run render "$out/street_motion_blur/scene.json" --camera scene:0 "${size[@]}" --frames -o "$out/effects_motion_blur/frames.png"

# A compare run (images and heat-maps; the reports carry timings and are not hashed).
run compare "$street" --cameras orbit:2,scene --times 0,2 --width 64 --height 48 -o "$out/compare"

cd "$out"
find . -type f \( -name '*.png' -o -name '*.exr' -o -name '*.glb' -o -name '*.obj' -o -name '*.mtl' -o -name '*.ply' -o -name '*.json' \) \
  ! -path './compare/report.json' -print0 | sort -z | xargs -0 sha256sum
