#!/usr/bin/env bash
# A Slurm job array that runs one `splatbridge compare` shard per array task. Submit with a
# 0-based, contiguous range; the array's size is the shard count:
#
#   SCENE=/shared/scene.ply OUT=/shared/runs/compare sbatch --array=0-15 docs/scale/slurm-compare.sh
#
# then, when every task has succeeded, join the shards (or submit it with
# `sbatch --dependency=afterok:JOBID`):
#
#   splatbridge merge /shared/runs/compare/shard-* -o /shared/runs/compare/merged
#
# Every task reads the same SCENE from shared storage and writes only under its own folder
# OUT/shard-I. A task re-run after a failure (`scontrol requeue JOBID_I`) replaces that folder's
# outputs atomically. Environment: SCENE, OUT (required); CAMERAS (default orbit:64); ARGS
# (more compare options, word-split, the same for every task: e.g. "--width 480 --height
# 360"); SPLATBRIDGE (the binary, default `splatbridge` on PATH).
#SBATCH --job-name=splatbridge-compare
#SBATCH --cpus-per-task=8
#SBATCH --mem=16G
#SBATCH --output=splatbridge-compare-%A_%a.log
set -euo pipefail
: "${SCENE:?set SCENE to the scene file on shared storage}"
: "${OUT:?set OUT to the run folder on shared storage}"
: "${SLURM_ARRAY_TASK_ID:?run as a Slurm job array (sbatch --array=0-N)}"
: "${SLURM_ARRAY_TASK_COUNT:?run as a Slurm job array (sbatch --array=0-N)}"
# A range that does not start at 0 (--array=1-16) still maps onto shards 0..N-1.
index=$((SLURM_ARRAY_TASK_ID - ${SLURM_ARRAY_TASK_MIN:-0}))
# shellcheck disable=SC2086 # ARGS is a list of options, split on purpose.
exec "${SPLATBRIDGE:-splatbridge}" compare "$SCENE" --cameras "${CAMERAS:-orbit:64}" ${ARGS:-} \
  --shard "$index/$SLURM_ARRAY_TASK_COUNT" -o "$OUT/shard-$index"
