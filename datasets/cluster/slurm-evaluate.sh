#!/bin/bash
# Merge every shard's run and write the report; submit with
# --dependency=afterok:<array job id> (see README.md).
#SBATCH --job-name=coppertag-wild-eval
#SBATCH --cpus-per-task=1
#SBATCH --mem=8G
#SBATCH --time=01:00:00
#SBATCH --output=build/cluster/logs/%j-evaluate.out
set -euo pipefail

WORK=${WORK:-build/cluster}
BIN=${BIN:-target/release/coppertag}
"$BIN" eval --wild "$WORK"/runs/*.mcap -o "$WORK/results"
"$BIN" report --summary "$WORK/results/summary.json" -o "$WORK/reports"
