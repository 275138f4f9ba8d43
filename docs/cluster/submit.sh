#!/bin/bash
# Plans a verification study and submits it to Slurm: a job array with one task per run
# (run.sbatch) and a merge job (merge.sbatch) that starts when every task has succeeded.
#
# Usage: docs/cluster/submit.sh STUDY-FOLDER [options of verify, e.g. --case zones3d --order 2]
# The folder must be on a file system that every node sees; VERIFY names the binary
# (default: verify on the PATH).
set -euo pipefail
folder=$1
shift
here=$(cd "$(dirname "$0")" && pwd)
export VERIFY=${VERIFY:-verify}
export MANIFEST=$folder/manifest.json
runs=$("$VERIFY" plan "$@" --manifest "$MANIFEST" | awk '/^runs: /{print $2}')
array=$(sbatch --parsable --array=0-$((runs - 1)) --export=ALL "$here/run.sbatch")
array=${array%%;*}
merge=$(sbatch --parsable --dependency=afterok:"$array" --export=ALL "$here/merge.sbatch")
echo "manifest $MANIFEST: $runs runs in job array $array, merge job ${merge%%;*}"
