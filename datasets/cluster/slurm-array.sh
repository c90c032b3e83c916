#!/bin/bash
# The wild benchmark over N tasks as a Slurm job array: task K renders
# shard K/N of each wild spec and runs its detector(s) on it. Submit from
# the repository root (see README.md):
#   jobid=$(sbatch --parsable datasets/cluster/slurm-array.sh)
#   sbatch --dependency=afterok:$jobid datasets/cluster/slurm-evaluate.sh
#SBATCH --job-name=coppertag-wild
#SBATCH --array=0-99
#SBATCH --cpus-per-task=1
#SBATCH --mem=2G
#SBATCH --time=02:00:00
#SBATCH --output=build/cluster/logs/%A_%a.out
set -euo pipefail

K=${SLURM_ARRAY_TASK_ID:?run me with sbatch --array}
N=${SLURM_ARRAY_TASK_COUNT:?run me with sbatch --array}
WORK=${WORK:-build/cluster}
BIN=${BIN:-target/release/coppertag}
mkdir -p "$WORK/datasets" "$WORK/runs"

for spec in datasets/wild/*.toml; do
  name=$(basename "$spec" .toml)
  marker=${name%%-*}
  case $marker in
    coppertag|apriltag3|aruco3|stag|fractal) detectors=$marker ;;
    *) detectors="coppertag apriltag3 aruco3 stag fractal" ;;   # tag-free sets: every system
  esac
  ds="$WORK/datasets/$name-$K"
  "$BIN" synth "$spec" --shard "$K/$N" --force --quiet -o "$ds"
  for d in $detectors; do
    "$BIN" run --dataset "$ds" --detector "$d" --shard "$K/$N" --quiet \
      -o "$WORK/runs/$name@$d-$K.mcap"
  done
done
