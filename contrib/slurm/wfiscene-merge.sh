#!/bin/sh
#SBATCH --job-name=wfiscene-merge
#SBATCH --cpus-per-task=1
#SBATCH --mem=1G
#SBATCH --time=01:00:00
#SBATCH --output=wfiscene-merge-%j.log
#
# wfiscene-merge.sh - the step after wfiscene-array.sh: join the parts of
# each exposure into OUTDIR/NAME.fits with `wfiscene merge`.
#
#   sbatch --dependency=afterok:$jobid wfiscene-merge.sh tasks.txt SCRATCH OUTDIR
#
# TASKS and SCRATCH are those the array job was given.  Each exposure's
# parts are the files its task lines name (SCRATCH/NAME/sca-SCAS.fits, or
# sca-SCAS.rows-A-B.fits for a line with --rows A-B); a
# missing part is an error, and so is an SCA in two parts or parts whose
# settings differ (`wfiscene merge` checks).  The parts are removed once
# their exposure is merged, unless KEEP_PARTS=1.
#
# Run as an array itself (sbatch --array=1-E, E exposures, in the order of
# their first task line), task k merges only the k-th exposure; otherwise
# one job merges them all.  Environment: WFISCENE (default wfiscene).
set -eu

usage="usage: wfiscene-merge.sh TASKS SCRATCH OUTDIR"
tasks=${1:?$usage}
scratch=${2:?$usage}
outdir=${3:?$usage}
wfiscene=${WFISCENE:-wfiscene}
only=${SLURM_ARRAY_TASK_ID:-}

# "NAME PART" for every task line, in the order of the file, named as
# wfiscene-array.sh names them (with the line's --rows, if any).
parts=$(awk '
	/^[[:space:]]*(#|$)/ { next }
	{
		s = $6; gsub(",", "+", s); r = ""
		for (i = 8; i <= NF; i++)
			if ($i == "--rows" && i < NF) r = ".rows-" $(i + 1)
			else if ($i ~ /^--rows=/) r = ".rows-" substr($i, 8)
		print $1, $1 "/sca-" s r ".fits"
	}' "$tasks")
# The exposures, each once, in the order of their first line.
names=$(printf '%s\n' "$parts" | awk 'NF && !seen[$1]++ { print $1 }')
if [ -z "$names" ]; then
	echo "wfiscene-merge: $tasks: no tasks" >&2
	exit 1
fi
if [ -n "$only" ]; then
	names=$(printf '%s\n' "$names" | sed -n "${only}p")
	if [ -z "$names" ]; then
		echo "wfiscene-merge: $tasks: no exposure $only" >&2
		exit 1
	fi
fi

mkdir -p "$outdir"
set -f
for name in $names; do
	files=
	for p in $(printf '%s\n' "$parts" | awk -v n="$name" '$1 == n { print $2 }'); do
		if [ ! -f "$scratch/$p" ]; then
			echo "wfiscene-merge: $name: part $scratch/$p is missing (did its task fail?)" >&2
			exit 1
		fi
		files="$files $scratch/$p"
	done
	echo "wfiscene-merge: $name:$files -> $outdir/$name.fits" >&2
	# shellcheck disable=SC2086
	"$wfiscene" merge -o "$outdir/$name.fits" $files
	if [ "${KEEP_PARTS:-0}" != 1 ]; then
		# shellcheck disable=SC2086
		rm -f $files
		rmdir "$scratch/$name" 2>/dev/null || :
	fi
done
