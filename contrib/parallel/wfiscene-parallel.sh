#!/bin/sh
# wfiscene-parallel.sh - one exposure as several wfiscene runs, one per group
# of SCAs, run by GNU parallel, then joined by `wfiscene merge`.
#
#   wfiscene-parallel.sh [-j JOBS] [-g GROUPS] [-S HOSTS] -o OUT.fits \
#       wfiscene-options... catalog...
#
#   -j JOBS    runs at once (default 3); each gets --threads cores/JOBS
#   -g GROUPS  the SCA groups, one --sca list each, separated by blanks
#              (default: SCAs 1-18 in JOBS contiguous groups)
#   -S HOSTS   GNU parallel's --sshlogin: spread the runs over machines
#              that share this file system (and have wfiscene at $WFISCENE)
#   -o FILE    the merged exposure ('-' for stdout)
#
# Everything after these options goes to every run unchanged, so all groups
# share one seed and one set of settings, as `wfiscene merge` requires; it
# must not hold --sca or -o.  Catalogs must be files, not stdin: every run
# reads them whole.  The result is byte for byte the file of one wfiscene
# run over all the groups' SCAs (with SOURCE_DATE_EPOCH set; otherwise DATE
# is the first group's).  Environment: WFISCENE (default wfiscene).
set -eu

usage="usage: wfiscene-parallel.sh [-j JOBS] [-g GROUPS] [-S HOSTS] -o OUT.fits wfiscene-options... catalog..."
jobs=3 groups='' hosts='' out=''
while [ $# -gt 0 ]; do
	case $1 in
	-j) jobs=${2:?$usage}; shift 2 ;;
	-g) groups=${2:?$usage}; shift 2 ;;
	-S) hosts=${2:?$usage}; shift 2 ;;
	-o) out=${2:?$usage}; shift 2 ;;
	-h|--help) echo "$usage"; exit 0 ;;
	--) shift; break ;;
	*) break ;;
	esac
done
if [ -z "$out" ] || [ $# -eq 0 ]; then
	echo "$usage" >&2
	exit 1
fi
case $jobs in
'' | *[!0-9]* | 0) echo "wfiscene-parallel: -j: want a positive integer, got '$jobs'" >&2; exit 1 ;;
esac
for a in "$@"; do
	case $a in
	--sca | --sca=* | -o | --output | --output=*)
		echo "wfiscene-parallel: give SCAs with -g and the output with -o, before the wfiscene options" >&2
		exit 1 ;;
	-)
		echo "wfiscene-parallel: catalogs must be files: runs under parallel get no standard input" >&2
		exit 1 ;;
	esac
done
command -v parallel >/dev/null || {
	echo "wfiscene-parallel: GNU parallel is not installed" >&2
	exit 2
}
wfiscene=${WFISCENE:-wfiscene}

if [ -z "$groups" ]; then
	# 18 SCAs in JOBS contiguous groups, the first ones one larger.
	groups=$(awk -v j="$jobs" 'BEGIN {
		if (j > 18) j = 18
		lo = 1
		for (k = 0; k < j; k++) {
			n = int(18 / j) + (k < 18 % j)
			printf "%s%d", k ? " " : "", lo
			if (n > 1) printf "-%d", lo + n - 1
			lo += n
		}
	}')
fi
cores=$(getconf _NPROCESSORS_ONLN 2>/dev/null || echo 1)
threads=$((cores / jobs))
[ "$threads" -ge 1 ] || threads=1

# Parts go next to the output (the same file system, which other hosts of
# -S see too) and are removed however the script ends.
case $out in
-) dir=${TMPDIR:-/tmp} ;;
*/*) dir=${out%/*} ;;
*) dir=. ;;
esac
tmp=$(mktemp -d "$dir/.wfiscene-parallel.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
trap 'exit 4' INT TERM HUP
tmp=$(cd "$tmp" && pwd)

# -q: the wfiscene options reach every run as the words they are here.
# --halt now,fail=1: the first failed run stops the others.  {#} numbers
# the parts in the order of the groups, so the first group's primary
# header (and DATE) is the one merge keeps.
set -f
# shellcheck disable=SC2086
parallel -q -j "$jobs" ${hosts:+-S "$hosts"} --halt now,fail=1 \
	"$wfiscene" --sca {} --threads "$threads" -o "$tmp/part-{#}.fits" "$@" \
	::: $groups
# The parts, in the order of the groups.
# shellcheck disable=SC2086
n=$(printf '%s\n' $groups | grep -c .)
set --
i=1
while [ "$i" -le "$n" ]; do
	set -- "$@" "$tmp/part-$i.fits"
	i=$((i + 1))
done
"$wfiscene" merge -o "$out" "$@"
