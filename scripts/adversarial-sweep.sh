#!/usr/bin/env bash
# Adversarial sweep of the release binary: every file of the malformed corpora
# (fixtures/malformed_corpus/files, fixtures/malformed, fixtures/formats/malformed) and up to
# PER_CORPUS files of each raw fuzz corpus (fuzz/corpus/TARGET, given the target's extension)
# through every command that reads a scene file (info, render, convert, trace, hybrid), each
# under a 4 GiB address-space limit and a 20 s timeout. Prints one summary line and writes
# every run that panicked (exit 101), timed out or ended with another status than 0 or 2 to
# the log.
#
#   scripts/adversarial-sweep.sh [BINARY] [PER_CORPUS] [LOG]
set -uo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
bin="${1:-$root/target/release/splatbridge}"
per="${2:-200}"
log="${3:-$root/target/adversarial-sweep.log}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
: >"$log"

inputs=()
for f in "$root"/fixtures/malformed_corpus/files/* "$root"/fixtures/malformed/* \
  "$root"/fixtures/formats/malformed/*; do
  [ -f "$f" ] && inputs+=("$f")
  # Unbundled SOG cases are folders holding a meta.json.
  [ -f "$f/meta.json" ] && inputs+=("$f/meta.json")
done
declare -A ext=([ply]=ply [manifest]=json [cameras]=json [gltf]=glb [obj]=obj [splat]=splat
  [spz]=spz [compressed_ply]=compressed.ply [sog]=sog [gltf_splats]=glb)
for t in "${!ext[@]}"; do
  d="$root/fuzz/corpus/$t"
  [ -d "$d" ] || continue
  mkdir -p "$work/corpus/$t"
  n=0
  for f in "$d"/*; do
    [ -f "$f" ] || continue
    # At most a few MB: the goal's bound on input size.
    [ "$(stat -c %s "$f")" -le 4194304 ] || continue
    cp "$f" "$work/corpus/$t/$(basename "$f").${ext[$t]}"
    n=$((n + 1))
    [ "$n" -ge "$per" ] && break
  done
  for f in "$work/corpus/$t"/*; do [ -f "$f" ] && inputs+=("$f"); done
done

runs=0 ok=0 rejected=0 panics=0 timeouts=0 other=0
for f in "${inputs[@]}"; do
  out="$work/out"
  for cmd in info render convert trace hybrid; do
    rm -rf "$out" && mkdir -p "$out"
    case "$cmd" in
      info) args=(info "$f") ;;
      render) args=(render "$f" --width 16 --height 12 -o "$out/r.png") ;;
      convert) args=(convert "$f" -o "$out/c.glb") ;;
      trace) args=(trace "$f" --width 16 --height 12 -o "$out/t.png") ;;
      hybrid) args=(hybrid "$f" --width 16 --height 12 -o "$out/h.png") ;;
    esac
    (ulimit -v 4194304 && exec timeout 20 "$bin" "${args[@]}") >/dev/null 2>"$work/err"
    code=$?
    runs=$((runs + 1))
    case "$code" in
      0) ok=$((ok + 1)) ;;
      2) rejected=$((rejected + 1)) ;;
      101) panics=$((panics + 1)); echo "PANIC $cmd $f: $(head -c 300 "$work/err")" >>"$log" ;;
      124) timeouts=$((timeouts + 1)); echo "TIMEOUT $cmd $f" >>"$log" ;;
      *) other=$((other + 1)); echo "EXIT $code $cmd $f: $(head -c 300 "$work/err")" >>"$log" ;;
    esac
  done
done
echo "inputs=${#inputs[@]} runs=$runs ok=$ok rejected(2)=$rejected panics(101)=$panics timeouts=$timeouts other=$other" | tee -a "$log"
