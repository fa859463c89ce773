#!/usr/bin/env bash
# The README's Slurm recipe on a running Slurm (e.g. one node: Debian's slurmctld, slurmd and
# munge): a 4-task job array of parts, a merge job with --dependency=afterok, and the merged
# image compared byte for byte with the whole render. Usage: slurm-one-node-test.sh PATHTRACER
set -euo pipefail
bin=$(realpath "${1:?usage: $0 PATHTRACER}")
dir=$(mktemp -d "$HOME/pt-slurm-XXXXXX")   # on a filesystem the node sees
cd "$dir"
mkdir parts logs
"$bin" gen cornell -o scene.dae > /dev/null
cat > render.sbatch <<SBATCH
#!/bin/bash
#SBATCH --array=0-3
#SBATCH --cpus-per-task=1
#SBATCH --output=logs/%A_%a.out
"$bin" -t "\$SLURM_CPUS_PER_TASK" -s 8 -m 3 -r 64 48 \\
    --part "\$SLURM_ARRAY_TASK_ID/4" -f "parts/p\$SLURM_ARRAY_TASK_ID.ptpart" scene.dae
SBATCH
job=$(sbatch --parsable render.sbatch)
merge=$(sbatch --parsable --dependency=afterok:"$job" --output=logs/merge.out \
  --wrap "\"$bin\" merge parts/p*.ptpart -f scene.png")
for _ in $(seq 1 300); do
  squeue -h -j "$job,$merge" 2> /dev/null | grep -q . || break
  sleep 1
done
"$bin" -s 8 -m 3 -r 64 48 --quiet -f whole.png scene.dae > /dev/null
cmp whole.png scene.png
echo "slurm: job array $job and merge $merge give the whole render's bytes ($dir)"
