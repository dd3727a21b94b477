#!/bin/sh
# wfiscene-submit.sh - submit a survey: the job array of wfiscene-array.sh
# (one task per task line) and, after it, wfiscene-merge.sh.
#
#   wfiscene-submit.sh TASKS SCRATCH OUTDIR [sbatch options for the array]
#
# e.g. wfiscene-submit.sh tasks.txt /scratch/$USER/parts out --partition=long
# Prints the two job ids.  The merge job runs only if every task succeeded
# (afterok); see README for what to do when one fails.
set -eu

usage="usage: wfiscene-submit.sh TASKS SCRATCH OUTDIR [sbatch options]"
tasks=${1:?$usage}
scratch=${2:?$usage}
outdir=${3:?$usage}
shift 3
here=$(cd "$(dirname "$0")" && pwd)

n=$(grep -cEv '^[[:space:]]*(#|$)' "$tasks") || :
if [ "${n:-0}" -eq 0 ]; then
	echo "wfiscene-submit: $tasks: no task lines" >&2
	exit 1
fi
# --parsable prints "jobid" or "jobid;cluster".
array=$(sbatch --parsable --array="1-$n" "$@" "$here/wfiscene-array.sh" "$tasks" "$scratch")
array=${array%%;*}
merge=$(sbatch --parsable --dependency="afterok:$array" "$here/wfiscene-merge.sh" \
	"$tasks" "$scratch" "$outdir")
merge=${merge%%;*}
echo "array job $array ($n tasks), merge job $merge"
