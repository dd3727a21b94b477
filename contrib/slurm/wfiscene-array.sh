#!/bin/sh
#SBATCH --job-name=wfiscene
#SBATCH --cpus-per-task=4
#SBATCH --mem=2G
#SBATCH --time=01:00:00
#SBATCH --output=wfiscene-%A_%a.log
#
# wfiscene-array.sh - one task of a Slurm job array: render one exposure, or
# one group of SCAs of an exposure, listed in a task file.
#
#   n=$(grep -cEv '^[[:space:]]*(#|$)' tasks.txt)
#   sbatch --array=1-$n wfiscene-array.sh tasks.txt /scratch/$USER/parts
#
# Array task k runs the k-th task line of TASKS (blank lines and # comments
# do not count) and writes SCRATCH/NAME/sca-SCAS.fits (sca-SCAS.rows-A-B.fits
# when its options hold --rows A-B: a band of rows of those SCAs).  A task
# line is
#
#   NAME  RA  DEC  PA  FILTER  SCAS  CATALOG  [wfiscene options ...]
#
# for example
#
#   exp001  150.10  2.20  0  F158  1-9    cosmos.csv  --seed 101
#   exp001  150.10  2.20  0  F158  10-18  cosmos.csv  --seed 101
#   exp002  150.12  2.21  0  F158  5      dense.csv   --seed 102 --rows 1-2044
#   exp002  150.12  2.21  0  F158  5      dense.csv   --seed 102 --rows 2045-4088
#
# Every line of one exposure must give it the same settings (the same seed
# above all: noise is keyed by seed and pixel, so that is what makes the
# groups fit together); wfiscene-merge.sh then joins them with
# `wfiscene merge`, byte for byte the file one --sca 1-18 run would write.
#
# Environment: WFISCENE (the program, default wfiscene), WFISCENE_OPTS
# (options for every task, before the task line's own, e.g. "--noise all
# --background avg --exptime 139.8"), SOURCE_DATE_EPOCH (pins DATE, so parts
# written at different times still compare byte for byte).  sbatch passes
# the submitting shell's environment on.  With SLURM_ARRAY_TASK_ID set by
# hand the script runs one task without Slurm (for testing).
set -eu

tasks=${1:?usage: wfiscene-array.sh TASKS SCRATCH}
scratch=${2:?usage: wfiscene-array.sh TASKS SCRATCH}
task=${SLURM_ARRAY_TASK_ID:?not an array task: submit with sbatch --array=1-N}
wfiscene=${WFISCENE:-wfiscene}

# The task's line: the k-th line that is neither blank nor a comment.
line=$(awk -v k="$task" '
	/^[[:space:]]*(#|$)/ { next }
	++n == k { print; found = 1; exit }
	END { if (!found) exit 1 }' "$tasks") || {
	echo "wfiscene-array: $tasks: no task $task (array ids count task lines from 1)" >&2
	exit 1
}

# Split the line into words; no file name globbing of its fields.
set -f
# shellcheck disable=SC2086
set -- $line
if [ $# -lt 7 ]; then
	echo "wfiscene-array: $tasks: task $task: want NAME RA DEC PA FILTER SCAS CATALOG, got '$line'" >&2
	exit 1
fi
name=$1 ra=$2 dec=$3 pa=$4 filter=$5 scas=$6 catalog=$7
shift 7
case $name in
*[!A-Za-z0-9._-]* | .* | '')
	echo "wfiscene-array: $tasks: task $task: exposure name '$name' is not [A-Za-z0-9._-]+" >&2
	exit 1 ;;
esac
case $scas in
*[!0-9A-Za-z,-]*)
	echo "wfiscene-array: $tasks: task $task: bad SCA list '$scas'" >&2
	exit 1 ;;
esac

# The part's name comes from its SCA list and --rows; wfiscene-merge.sh
# finds it the same way.  wfiscene writes it under a temporary name and
# renames it when complete, so a task that fails or is requeued never leaves
# half a part.
rows=
next=
for a in "$@"; do
	if [ -n "$next" ]; then rows=$a next=; continue; fi
	case $a in
	--rows) next=1 ;;
	--rows=*) rows=${a#--rows=} ;;
	esac
done
case $rows in
*[!0-9-]*)
	echo "wfiscene-array: $tasks: task $task: bad --rows '$rows'" >&2
	exit 1 ;;
esac
mkdir -p "$scratch/$name"
part=$scratch/$name/sca-$(printf '%s' "$scas" | tr , +)${rows:+.rows-$rows}.fits
threads=${SLURM_CPUS_PER_TASK:-0}

echo "wfiscene-array: task $task: $name $filter SCAs $scas${rows:+ rows $rows} -> $part" >&2
# shellcheck disable=SC2086
exec "$wfiscene" --filter "$filter" --ra "$ra" --dec "$dec" --pa "$pa" \
	--sca "$scas" --threads "$threads" ${WFISCENE_OPTS:-} "$@" \
	-o "$part" "$catalog"
