#!/usr/bin/env bash
# A cpmx sweep as a Slurm array job: every task runs one deterministic slice of the matrix
# into its own folder; a final step merges them. The merged summary is byte-identical to the
# summary of one `cpmx run` of the whole matrix.
#
#   sbatch --array=1-8 examples/slurm/array-job.sh experiments/quickstart.yaml
#   # after all tasks have finished:
#   cpmx report out/sweep/shard-* --format markdown
#   cpmx report out/sweep/shard-* --out out/sweep/merged     # summary files and plots
#
# The data path reaches the tasks as CPMX_DATA (sbatch exports the environment); logs go to the
# submit directory (Slurm does not create folders for them). Submit from the repository root
# (the spec and out/ are relative to the submit directory, where Slurm starts the tasks); `cpmx`
# must be on the tasks' PATH (the README's `cargo install` puts it in ~/.cargo/bin).
#
#SBATCH --job-name=cpmx-sweep
#SBATCH --cpus-per-task=2
#SBATCH --time=01:00:00
#SBATCH --output=slurm-sweep-%A_%a.log
set -euo pipefail
command -v cpmx >/dev/null || {
  echo "cpmx is not on this task's PATH: install it with \`cargo install --path . --locked\` (README)" >&2
  exit 2
}

spec=${1:?usage: sbatch --array=1-N array-job.sh SPEC}
shards=${SLURM_ARRAY_TASK_COUNT:?run this with sbatch --array}
shard=${SLURM_ARRAY_TASK_ID:?run this with sbatch --array}

# --resume makes a requeued or preempted task skip the runs it already finished.
cpmx run "$spec" \
  --shard "${shard}/${shards}" \
  --jobs "${SLURM_CPUS_PER_TASK:-1}" \
  --out "out/sweep/shard-${shard}" \
  --resume
