#!/usr/bin/env bash
# Run every fuzz target for SECONDS each (default 600), one after the other, in one process
# (no -jobs: its log would go to a shared fuzz-N.log), so the run uses one core and several
# copies of this script can run side by side. Needs the nightly toolchain and cargo-fuzz
# (`cargo install cargo-fuzz`). Targets are whatever `cargo fuzz list` reports, so a new target
# needs no change here; `scripts/fuzz.sh 60 gltf obj` runs only the named ones.
#
# By default cargo-fuzz builds with debug assertions (overflow checks); `FUZZ_OPT=1` fuzzes the
# optimised build without them instead (the release binary's arithmetic, and the build that
# `cargo +nightly fuzz build -O` already made, so no second build of the dependencies).
#
# Findings land in fuzz/artifacts/TARGET/; copy each crash into fuzz/regressions/TARGET/ (the
# stable test `tests/fuzz_regressions.rs` replays that folder) and fix it. A summary line per
# target goes to fuzz/fuzz.log.
set -euo pipefail
cd "$(dirname "$0")/../fuzz"
secs="${1:-600}"
shift || true
if [ "$#" -gt 0 ]; then
  targets=("$@")
else
  mapfile -t targets < <(cargo +nightly fuzz list)
fi
# Each input gets 10 s and 2 GiB: the project's goal is no hang and no multi-gigabyte allocation
# from a small input.
for t in "${targets[@]}"; do
  mkdir -p "corpus/$t" "artifacts/$t"
  # Seed the corpus with the committed regressions and malformed cases of the same format.
  if [ -d "regressions/$t" ]; then cp -n regressions/"$t"/* "corpus/$t/" 2>/dev/null || true; fi
  start=$(date -u +%FT%TZ)
  status=0
  opt=()
  if [ "${FUZZ_OPT:-0}" = 1 ]; then opt=(-O); fi
  cargo +nightly fuzz run "${opt[@]}" "$t" "corpus/$t" -- \
    -max_total_time="$secs" -timeout=10 -rss_limit_mb=2048 \
    -malloc_limit_mb=2048 -max_len=65536 -print_final_stats=1 \
    -artifact_prefix="artifacts/$t/" >"artifacts/$t/last-run.log" 2>&1 || status=$?
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "artifacts/$t/last-run.log" | grep -o '[0-9]*$' || echo "?")
  found=$(find "artifacts/$t" -maxdepth 1 -type f \( -name 'crash-*' -o -name 'oom-*' -o -name 'timeout-*' -o -name 'leak-*' \) | wc -l)
  echo "$start $t ${secs}s execs=$execs exit=$status findings=$found" | tee -a fuzz.log
done
