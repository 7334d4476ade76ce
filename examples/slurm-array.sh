#!/usr/bin/env bash
# Bake a motion library on a Slurm cluster as a job array, one task per shard:
#
#   sbatch --array=0-15 examples/slurm-array.sh /shared/mocap /shared/baked
#
# Each task bakes its share of the inputs (sorted by path; file k goes to task k mod 16: quatcurve
# reads SLURM_ARRAY_TASK_ID, SLURM_ARRAY_TASK_MIN and SLURM_ARRAY_TASK_COUNT) and records it in
# /shared/baked/manifest.<I>-of-16.json. --resume makes a requeued task (node failure,
# preemption) redo only inputs whose outputs are missing or damaged. The outputs of all tasks
# together are byte for byte those of one unsharded run, provided every task uses the same
# device: hence --device cpu here (use --device gpu on a GPU partition, not auto on a mixed one).
#SBATCH --job-name=quatcurve-bake
#SBATCH --cpus-per-task=4
#SBATCH --mem=8G
#SBATCH --time=02:00:00
#SBATCH --requeue
#SBATCH --output=quatcurve-bake-%A_%a.log
set -euo pipefail

input=${1:?usage: sbatch --array=0-N slurm-array.sh INPUT_DIR OUTPUT_DIR}
output=${2:?usage: sbatch --array=0-N slurm-array.sh INPUT_DIR OUTPUT_DIR}

exec "${QUATCURVE:-quatcurve}" bake --input "$input" --output "$output" --rate 30 --device cpu --resume
