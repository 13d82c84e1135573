#!/usr/bin/env bash
# Check our splat decoders against @playcanvas/splat-transform, and time both side by side.
# Usage: scripts/formats-compare.sh [PLY...] [--repeats N]
#   PLYs default to every .ply in ../shared/data/real. For each PLY and each format splat-transform
#   writes (.spz, .compressed.ply, .sog), splat-transform encodes the PLY; then both tools decode
#   that file to a float 3DGS PLY and `examples/splat_diff.rs` compares the two decodings
#   attribute by attribute within the format's quantisation step. The shared `plant.splat` and
#   `fourth_st.spz` (files made by other encoders) are compared the same way.
# Timing (median of N process runs, default 3, cold process each time, same work on both
# sides, outputs in /dev/shm): decoding = `FILE → float PLY`; SPZ encoding = `PLY → .spz`. Peak memory of our
# decoder: `splatbridge bench ply` (VmHWM above the start, relative to the decoded cloud), and
# the whole `convert` process's maximum RSS from GNU time (binary and libraries included).
# splat-transform is installed from scripts/package.json into $SPLAT_TRANSFORM_DIR
# (default ~/.cache/splat-transform), reinstalled when the version there differs.
# Exit status: 0 when every comparison is within its step and every speed target is met,
# 1 otherwise, 3 when a tool or the data is missing.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(dirname "$here")
real=$repo/../shared/data/real
reps=3
plys=()
while [[ $# -gt 0 ]]; do
  case $1 in
    --repeats) reps=$2; shift 2 ;;
    *) plys+=("$1"); shift ;;
  esac
done
if [[ ${#plys[@]} -eq 0 ]]; then
  [[ -d $real ]] || { echo "formats-compare: $real not found" >&2; exit 3; }
  plys=("$real"/*.ply)
fi
command -v npm >/dev/null || { echo "formats-compare: npm not found" >&2; exit 3; }
st_dir=${SPLAT_TRANSFORM_DIR:-$HOME/.cache/splat-transform}
st=$st_dir/node_modules/.bin/splat-transform
want=$(python3 -c "import json,sys; print(json.load(open('$here/package.json'))['dependencies']['@playcanvas/splat-transform'])")
have=$(python3 -c "import json; print(json.load(open('$st_dir/node_modules/@playcanvas/splat-transform/package.json'))['version'])" 2>/dev/null || echo none)
if [[ ! -x $st || $have != "$want" ]]; then
  mkdir -p "$st_dir"
  cp "$here/package.json" "$st_dir/package.json"
  (cd "$st_dir" && npm install --silent --no-audit --no-fund >/dev/null)
fi
(cd "$repo" && cargo build --release --bin splatbridge --example splat_diff >&2)
sb=$repo/target/release/splatbridge
diff=$repo/target/release/examples/splat_diff
# Outputs go to memory (/dev/shm when it is there) for both tools: the decode figures time
# decoding and writing the PLY, not the disk. splatbridge makes every output durable
# (`fdatasync` before the rename), splat-transform does not, and on a shared disk syncing
# 32 MB took longer than decoding it.
shm=/dev/shm; [[ -d $shm && -w $shm ]] || shm=${TMPDIR:-/tmp}
out=$(mktemp -d -p "$shm")
trap 'rm -rf "$out"' EXIT
fail=0

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

# our load's peak over the decoded cloud (`bench ply`): what the load allocates (the counting
# allocator; the target) and the resident set above the process's start (with fixed runtime
# costs: code pages, stacks, malloc arenas), as "HEAP RSS"
peak() {
  "$sb" bench ply "$1" --repeat 1 --json | python3 -c "import json,sys; v=json.load(sys.stdin); print(f\"{v['heap_peak_over_cloud']:.2f} {v['peak_over_cloud']:.2f}\")"
}

# a whole process's maximum resident set (GNU time), e.g. "45.1 MB"
maxrss() {
  if [[ -x /usr/bin/time ]]; then
    /usr/bin/time -f '%M' "$@" 2>&1 >/dev/null | tail -1 | python3 -c "import sys; print(f'{int(sys.stdin.read()) / 1000:.1f} MB')"
  else
    echo "n/a"
  fi
}

# decode FILE with both tools, compare, time; $1 format name for splat_diff, $2 file
check() {
  local fmt=$1 file=$2 base
  base=$out/$(basename "$file")
  "$st" -q -w "$file" "$base.st.ply"
  "$sb" convert "$file" --splats -o "$base.sb.ply" >/dev/null 2>&1
  # splat-transform skips SPZ's RUB <-> RDF conversion (nianticlabs/spz's README; fourth_st.spz
  # vs fourth_st.ply): its SPZ decodings are ours turned half a turn about x, undone here.
  local flip=(); [[ $fmt == spz ]] && flip=(--flip-yz)
  if ! "$diff" "$fmt" "$base.sb.ply" "$base.st.ply" "${flip[@]}"; then fail=1; fi
  local t_sb t_st ratio
  t_sb=$(timeit "$sb" convert "$file" --splats -o "$base.sb.ply")
  t_st=$(timeit "$st" -q -w "$file" "$base.st.ply")
  ratio=$(python3 -c "print(f'{$t_st / $t_sb:.1f}')")
  local mem heap rss
  mem=$(peak "$file"); heap=${mem% *}
  rss=$(maxrss "$sb" convert "$file" --splats -o "$base.sb.ply")
  printf '  decode %-16s splatbridge %7.3f s  splat-transform %7.3f s  %5s×  peak heap / RSS %s× cloud  (max RSS %s)\n' \
    "$fmt" "$t_sb" "$t_st" "$ratio" "${mem/ / \/ }" "$rss"
  python3 -c "import sys; sys.exit(0 if $t_st / $t_sb >= 5 and $heap <= 1.5 else 1)" || { echo "  ^ below target (5× faster, ≤ 1.5× memory)"; fail=1; }
}

# decode FILE with both tools and time them, without comparing the decodings: for the inputs
# splat-transform reads as plain PLY columns (it keeps `filter_3D` and `red green blue` as
# extra columns instead of applying them, so the two outputs differ by design) and for
# `.ksplat` (decoding checked against splat-transform's in tests/, fixtures/formats/*.ksplat*).
# $1 label, $2 file
timed() {
  local label=$1 file=$2 base
  base=$out/$(basename "$file")
  "$st" -q -w "$file" "$base.st.ply" || { echo "  splat-transform cannot read $label"; fail=1; return; }
  "$sb" convert "$file" --splats -o "$base.sb.ply" >/dev/null 2>&1 || { echo "  splatbridge cannot read $label"; fail=1; return; }
  local t_sb t_st ratio mem heap rss
  t_sb=$(timeit "$sb" convert "$file" --splats -o "$base.sb.ply")
  t_st=$(timeit "$st" -q -w "$file" "$base.st.ply")
  ratio=$(python3 -c "print(f'{$t_st / $t_sb:.1f}')")
  mem=$(peak "$file"); heap=${mem% *}
  rss=$(maxrss "$sb" convert "$file" --splats -o "$base.sb.ply")
  printf '  decode %-16s splatbridge %7.3f s  splat-transform %7.3f s  %5s×  peak heap / RSS %s× cloud  (max RSS %s)\n' \
    "$label" "$t_sb" "$t_st" "$ratio" "${mem/ / \/ }" "$rss"
  # A .ksplat is read whole (sections addressed by offset): its memory target is 2× the cloud.
  local cap=1.5; [[ $label == ksplat* ]] && cap=2.0
  python3 -c "import sys; sys.exit(0 if $t_st / $t_sb >= 5 and $heap <= $cap else 1)" || { echo "  ^ below target (5× faster, ≤ $cap× memory)"; fail=1; }
}

for ply in "${plys[@]}"; do
  name=$(basename "$ply" .ply)
  echo "== $name ($(stat -c %s "$ply") bytes)"
  for ext in spz compressed.ply sog; do
    "$st" -q -w "$ply" "$out/$name.$ext" || { echo "  splat-transform cannot write $ext"; fail=1; continue; }
    fmt=$ext; [[ $ext == compressed.ply ]] && fmt=compressed-ply
    check "$fmt" "$out/$name.$ext"
  done
  # The newer readers splat-transform also reads: .ksplat at every compression level (written
  # by our writer), and the PLY layouts beside 3DGS's (scripts/ply-variants.py): 2DGS
  # (`scale_0 scale_1`, which splat-transform reads as 2DGS), Mip-Splatting (`filter_3D`) and
  # `red green blue` colours.
  for level in 0 1 2; do
    "$sb" convert "$ply" --ksplat-level "$level" -o "$out/$name.l$level.ksplat" >/dev/null
    timed "ksplat level $level" "$out/$name.l$level.ksplat"
  done
  python3 "$here/ply-variants.py" "$ply" "$out" >/dev/null
  for v in 2dgs mip rgb; do
    timed "$v PLY" "$out/$name.$v.ply"
  done
  t_sb=$(timeit "$sb" convert "$ply" -o "$out/$name.sb.spz")
  t_st=$(timeit "$st" -q -w "$ply" "$out/$name.st.spz")
  printf '  encode spz              splatbridge %7.3f s  splat-transform %7.3f s  %5s×  (%s / %s bytes)\n' \
    "$t_sb" "$t_st" "$(python3 -c "print(f'{$t_st / $t_sb:.1f}')")" \
    "$(stat -c %s "$out/$name.sb.spz")" "$(stat -c %s "$out/$name.st.spz")"
  python3 -c "import sys; sys.exit(0 if $t_st >= $t_sb else 1)" || { echo "  ^ SPZ encoding slower than splat-transform"; fail=1; }
  # splat-transform must read what we write.
  "$st" -q -w "$out/$name.sb.spz" "$out/$name.sb.spz.st.ply" && "$sb" convert "$out/$name.sb.spz" --splats -o "$out/$name.sb.spz.sb.ply" >/dev/null 2>&1 \
    && { "$diff" spz "$out/$name.sb.spz.sb.ply" "$out/$name.sb.spz.st.ply" --flip-yz >/dev/null && echo "  our .spz reads back in splat-transform: ok" || { echo "  our .spz decodes differently in splat-transform"; fail=1; }; }
done
for f in "$real/plant.splat:splat" "$real/fourth_st.spz:spz"; do
  file=${f%:*}; fmt=${f##*:}
  [[ -f $file ]] || continue
  echo "== $(basename "$file") (other encoders)"
  check "$fmt" "$file"
done

# ---- SOG unbundled (meta.json + WebP) and glTF KHR_gaussian_splatting
# splat-transform's SOG encoder runs its k-means on the GPU unless told `-g cpu`.
# KHR: splat-transform writes KHR_gaussian_splatting GLB but reads no glTF, so the plain GLB is
# checked by reading it back against the PLY it came from (float32 attributes: the `splat`
# steps, which are float-exact for positions and scales); splat-transform writes no
# SPZ-compressed glTF, so KHR-SPZ encoding (`examples/khr_encode.rs`) is timed against its
# `.spz` writer (the same SPZ v3 work plus a GLB container), target: at least as fast.
(cd "$repo" && cargo build --release --example khr_encode >&2)
khr=$repo/target/release/examples/khr_encode
for ply in "${plys[@]}"; do
  name=$(basename "$ply" .ply)
  echo "== $name: SOG unbundled, KHR glTF"
  mkdir -p "$out/$name.unbundled"
  if "$st" -q -g cpu -w "$ply" "$out/$name.unbundled/meta.json"; then
    check sog "$out/$name.unbundled/meta.json"
  else
    echo "  splat-transform cannot write meta.json"; fail=1
  fi
  if "$st" -q -w "$ply" "$out/$name.st.glb"; then
    "$sb" convert "$out/$name.st.glb" --splats -o "$out/$name.st.glb.sb.ply" >/dev/null 2>&1 \
      && "$diff" splat "$ply" "$out/$name.st.glb.sb.ply" >/dev/null \
      && echo "  splat-transform's GLB reads back as the PLY: ok" \
      || { echo "  splat-transform's GLB does not read back as the PLY"; fail=1; }
  fi
  t_sb=$(timeit "$khr" "$ply" "$out/$name.khr-spz.glb" spz)
  t_st=$(timeit "$st" -q -w "$ply" --spz-version 3 "$out/$name.st3.spz")
  printf '  encode KHR-SPZ glb      splatbridge %7.3f s  splat-transform .spz %7.3f s  %5s×  (%s / %s bytes)\n' \
    "$t_sb" "$t_st" "$(python3 -c "print(f'{$t_st / $t_sb:.1f}')")" \
    "$(stat -c %s "$out/$name.khr-spz.glb")" "$(stat -c %s "$out/$name.st3.spz")"
  python3 -c "import sys; sys.exit(0 if $t_st >= $t_sb else 1)" || { echo "  ^ KHR-SPZ encoding slower than splat-transform's SPZ"; fail=1; }
  # KHR-SPZ decoding: splat-transform reads no glTF, so it is timed decoding the same SPZ v3
  # payload as a .spz file (the GLB adds only a small JSON chunk).
  t_sb=$(timeit "$sb" convert "$out/$name.khr-spz.glb" --splats -o "$out/$name.khr-spz.sb.ply")
  t_st=$(timeit "$st" -q -w "$out/$name.st3.spz" "$out/$name.st3.st.ply")
  printf '  decode KHR-SPZ glb      splatbridge %7.3f s  splat-transform .spz %7.3f s  %5s×  peak heap / RSS %s× cloud  (max RSS %s)\n' \
    "$t_sb" "$t_st" "$(python3 -c "print(f'{$t_st / $t_sb:.1f}')")" "$(peak "$out/$name.khr-spz.glb" | sed 's| | / |')" \
    "$(maxrss "$sb" convert "$out/$name.khr-spz.glb" --splats -o "$out/$name.khr-spz.sb.ply")"
  python3 -c "import sys; sys.exit(0 if $t_st / $t_sb >= 5 else 1)" || { echo "  ^ KHR-SPZ decoding below 5× splat-transform's SPZ"; fail=1; }
  if [[ -f $out/$name.st.glb ]]; then
    mem=$(peak "$out/$name.st.glb")
    printf '  load float KHR glb      peak heap / RSS %s× cloud  (max RSS %s converting to PLY)\n' "${mem/ / \/ }" \
      "$(maxrss "$sb" convert "$out/$name.st.glb" --splats -o "$out/$name.st.glb.sb.ply")"
    python3 -c "import sys; sys.exit(0 if ${mem% *} <= 1.5 else 1)" || { echo "  ^ float GLB above 1.5× memory"; fail=1; }
  fi
done
exit $fail
