#!/usr/bin/env bash
# A cpmx training as a Slurm array job: every task trains one deterministic slice of the
# training runs (`cpmx plan SPEC` lists them: seeds x training-sweep points x fidelities) into
# the one training folder on the shared filesystem. The folder is then the folder one
# unsharded `cpmx train` gives, and the spec's `mlp: {trained}` policies find their actors in it.
#
#   sbatch --array=1-3 examples/slurm/train-array-job.sh experiments/at25-cpmx.yaml out/at25-train
#   (one task per training run: at25-cpmx.yaml trains three seeds; a task past the last run says
#   it has nothing to do)
#   # requeued or preempted tasks continue where they stopped (--resume); add
#   # --open-mode=append to keep the log of the first attempt
#
# The data path reaches the tasks as CPMX_DATA (sbatch exports the environment):
#   CPMX_DATA=path/to/reference sbatch --array=1-3 ...
# Submit from the repository root (the spec and OUT are relative to the submit directory, where
# Slurm starts the tasks); `cpmx` must be on the tasks' PATH (the README's `cargo install` puts
# it in ~/.cargo/bin).
#
#SBATCH --job-name=cpmx-train
#SBATCH --cpus-per-task=2
#SBATCH --time=04:00:00
#SBATCH --output=slurm-train-%A_%a.log
set -euo pipefail
command -v cpmx >/dev/null || {
  echo "cpmx is not on this task's PATH: install it with \`cargo install --path . --locked\` (README)" >&2
  exit 2
}

spec=${1:?usage: sbatch --array=1-N train-array-job.sh SPEC OUT}
out=${2:?usage: sbatch --array=1-N train-array-job.sh SPEC OUT}
shards=${SLURM_ARRAY_TASK_COUNT:?run this with sbatch --array}
shard=${SLURM_ARRAY_TASK_ID:?run this with sbatch --array}

cpmx train "$spec" \
  --shard "${shard}/${shards}" \
  --jobs "${SLURM_CPUS_PER_TASK:-1}" \
  --out "$out" \
  --resume
