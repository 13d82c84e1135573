#!/usr/bin/env bash
# Time `splatbridge convert --splats` against `@playcanvas/splat-transform` (PLY → GLB with
# KHR_gaussian_splatting) on the same file, side by side, and validate both outputs.
# Usage: scripts/splat-transform-compare.sh [PLY] [REPEATS]
#   PLY defaults to ../shared/data/real/fourth_st.ply, REPEATS to 5 (the median is reported).
# Both tools run as processes from a cold start, reading the PLY and writing the GLB, so the
# times include loading. splat-transform is installed from scripts/package.json into
# $SPLAT_TRANSFORM_DIR (default ~/.cache/splat-transform).
# Exit status: 0 when splatbridge is at least 5× faster, 1 otherwise, 3 when a tool is missing.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(dirname "$here")
ply=${1:-$repo/../shared/data/real/fourth_st.ply}
reps=${2:-5}
[[ -f $ply ]] || { echo "splat-transform-compare: $ply not found" >&2; exit 3; }
command -v npm >/dev/null || { echo "splat-transform-compare: npm not found" >&2; exit 3; }
st_dir=${SPLAT_TRANSFORM_DIR:-$HOME/.cache/splat-transform}
st=$st_dir/node_modules/.bin/splat-transform
if [[ ! -x $st ]]; then
  mkdir -p "$st_dir"
  cp "$here/package.json" "$st_dir/package.json"
  (cd "$st_dir" && npm install --silent --no-audit --no-fund >/dev/null)
fi
(cd "$repo" && cargo build --release --bin splatbridge >&2)
sb=$repo/target/release/splatbridge
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

# median wall time in seconds of a command run $reps times
timeit() {
  python3 - "$reps" "$@" <<'PY'
import subprocess, sys, time
reps, cmd = int(sys.argv[1]), sys.argv[2:]
ts = []
for _ in range(reps):
    t = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    ts.append(time.perf_counter() - t)
ts.sort()
print(f"{ts[len(ts) // 2]:.4f}")
PY
}

t_sb=$(timeit "$sb" convert "$ply" --splats -o "$out/splatbridge.glb")
t_st=$(timeit "$st" -q -w "$ply" "$out/splat-transform.glb")
s_sb=$(stat -c %s "$out/splatbridge.glb")
s_st=$(stat -c %s "$out/splat-transform.glb")
ratio=$(python3 -c "print(f'{$t_st / $t_sb:.1f}')")
echo "input: $ply ($(stat -c %s "$ply") bytes), median of $reps runs"
printf '%-18s %10s %12s\n' tool seconds bytes
printf '%-18s %10s %12s\n' splatbridge "$t_sb" "$s_sb"
printf '%-18s %10s %12s\n' splat-transform "$t_st" "$s_st"
echo "splatbridge is ${ratio}× faster"
if [[ -x $repo/../shared/tools/gltf-validate.sh ]] && command -v node >/dev/null; then
  "$repo/../shared/tools/gltf-validate.sh" --allow MESH_PRIMITIVE_INVALID_ATTRIBUTE "$out/splatbridge.glb" "$out/splat-transform.glb" || true
fi
# Cross-read: splatbridge reads splat-transform's GLB back as a scene.
"$sb" convert "$out/splat-transform.glb" --splats -o "$out/reread.glb" >/dev/null 2>&1 && echo "splat-transform's GLB reads back: ok" || echo "splat-transform's GLB does not read back" >&2
python3 -c "import sys; sys.exit(0 if $t_st / $t_sb >= 5 else 1)"
