#!/usr/bin/env bash
# Validate the converter's glTF exports with the Khronos glTF-Validator
# (../shared/tools/gltf-validate.sh, npm `gltf-validator`).
#
# Usage:
#   scripts/validate-exports.sh [--mesh FILE...] [--splats FILE...]
#       Mesh exports must have 0 errors and 0 warnings. KHR_gaussian_splatting exports may
#       only carry MESH_PRIMITIVE_INVALID_ATTRIBUTE (the validator does not know the
#       extension's attributes yet); anything else is a defect.
#   scripts/validate-exports.sh
#       Build the CLI, export the street fixture and ../shared/data/real/fourth_st.ply with
#       every profile (GLB and glTF), with surfels (--surfels, default and rings profile) and
#       as splats, and validate them all.
# Exit status: 0 clean, 1 a file failed, 3 the validator cannot run here (no node/npm).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(dirname "$here")
validate=${GLTF_VALIDATE:-$repo/../shared/tools/gltf-validate.sh}
if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
  echo "validate-exports: node/npm not found; cannot run the glTF validator" >&2; exit 3
fi
if [[ ! -x $validate ]]; then
  echo "validate-exports: $validate not found" >&2; exit 3
fi

mesh=(); splats=(); mode=mesh
for a in "$@"; do
  case $a in
    --mesh) mode=mesh ;;
    --splats) mode=splats ;;
    *) if [[ $mode == mesh ]]; then mesh+=("$a"); else splats+=("$a"); fi ;;
  esac
done

if (( ${#mesh[@]} == 0 && ${#splats[@]} == 0 )); then
  out=$(mktemp -d)
  trap 'rm -rf "$out"' EXIT
  (cd "$repo" && cargo build --release --bin splatbridge >&2)
  sb=$repo/target/release/splatbridge
  inputs=()
  if "$sb" fixture street -o "$out/street" >&2 2>&1; then
    # The manifest is scene.json (cameras.json beside it is not a scene).
    if [[ -f $out/street/scene.json ]]; then inputs+=("$out/street/scene.json"); fi
  else
    echo "validate-exports: no street fixture (fixture command failed); using real data only" >&2
  fi
  real=$repo/../shared/data/real/fourth_st.ply
  [[ -f $real ]] && inputs+=("$real")
  for in in "${inputs[@]}"; do
    [[ -n $in ]] || continue
    name=$(basename "${in%.*}")
    for prof in meshsplats rings texture; do
      "$sb" convert "$in" --profile "$prof" -o "$out/$name-$prof.glb" >&2 && mesh+=("$out/$name-$prof.glb")
      "$sb" convert "$in" --profile "$prof" -o "$out/$name-$prof.gltf" >&2 && mesh+=("$out/$name-$prof.gltf")
    done
    "$sb" convert "$in" --volumetric flat -o "$out/$name-flat.glb" >&2 && mesh+=("$out/$name-flat.glb")
    "$sb" convert "$in" --surfels -o "$out/$name-surfels.glb" >&2 && mesh+=("$out/$name-surfels.glb")
    "$sb" convert "$in" --surfels --profile rings -o "$out/$name-surfels-rings.gltf" >&2 && mesh+=("$out/$name-surfels-rings.gltf")
    "$sb" convert "$in" --splats -o "$out/$name-splats.glb" >&2 && splats+=("$out/$name-splats.glb")
  done
fi

status=0
if (( ${#mesh[@]} > 0 )); then
  "$validate" "${mesh[@]}" || status=1
fi
if (( ${#splats[@]} > 0 )); then
  "$validate" --allow MESH_PRIMITIVE_INVALID_ATTRIBUTE "${splats[@]}" || status=1
fi
exit $status
