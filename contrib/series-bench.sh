#!/bin/sh
# The cost of a series of exposures of one field drawn in one run (the
# catalog read once per pass) against the same exposures as separate runs.
#
#   sh contrib/series-bench.sh [STARS [EXPOSURES]]      (default 1000000 10)
#
# STARS stars (contrib/starfield, with proper motions and parallaxes added)
# fill SCA 1 of a bulge pointing; EXPOSURES dated exposures 15 minutes apart
# are drawn (F146, no noise) three ways, one after the other in this run so
# that the machine's load falls alike on all: one run with --memory for all
# of them (one pass), one run with --memory for a quarter (four passes), and
# one run per exposure.  Prints seconds (wall and CPU) and peak memory of
# each, and the ratios.  Images go to a temporary directory, deleted.
# With SERIES_MEMORY=MB the series is drawn once, in passes of what that
# holds (a long series on a machine that cannot hold it all), against the
# separate runs.
set -e
B=${WFS_BUILD:-build}
n=${1:-1000000}
k=${2:-10}
tmp=$(mktemp -d "${TMPDIR:-/tmp}/series-bench.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
"$B/contrib/starfield" -n "$n" -r 268.5 -d -28.9 -w 0.12 -m 18 -M 27 -s 7 |
	awk -F, 'NR == 1 { print $0 ",pmra,pmdec,parallax"; next }
		 { printf "%s,%.2f,%.2f,0.12\n", $0, (NR % 13) - 6, (NR % 7) - 3 }' > "$tmp/field.csv"
# every 15 minutes, as the Galactic Bulge Time Domain Survey revisits
awk -v k="$k" 'BEGIN { for (i = 0; i < k; i++)
	printf "268.5 -28.9 0 e%d - %.6f\n", i, 61460 + i / 96 }' > "$tmp/series.txt"
WFS="$B/wfiscene --filter F146 --sca 1 --ra 268.5 --dec -28.9 -q"
export WFS tmp
# measure NAME SCRIPT: wall, user+sys seconds and peak RSS (MB) of sh -c SCRIPT
measure() {
	name=$1
	shift
	/usr/bin/time -f "%e %U %S %M" -o "$tmp/t" sh -c "$1"
	read -r wall user sys rss < "$tmp/t"
	echo "$name $wall $(echo "$user + $sys" | bc) $((rss / 1024))" >> "$tmp/results"
	rm -f "$tmp"/*.fits
}
each=$(( (4088 * 4088 * 8 + 56 * 1048576) / 1048576 + 1 ))
if [ -n "${SERIES_MEMORY:-}" ]; then
	measure "memory-$SERIES_MEMORY" "\$WFS --memory $SERIES_MEMORY -v \
		--pointings \$tmp/series.txt -o \$tmp/s_%s.fits \$tmp/field.csv 2>&1 |
		grep passes || true"
else
	measure one-pass "\$WFS --memory $((each * k + 100)) --pointings \$tmp/series.txt \
		-o \$tmp/s_%s.fits \$tmp/field.csv"
	measure four-passes "\$WFS --memory $((each * ((k + 3) / 4))) \
		--pointings \$tmp/series.txt -o \$tmp/s_%s.fits \$tmp/field.csv"
fi
# the separate runs each delete their image, as the series keeps its own
measure separate 'while read -r ra dec pa name seed date; do
	$WFS --date "$date" -o "$tmp/r_$name.fits" "$tmp/field.csv" || exit 1
	rm -f "$tmp/r_$name.fits"
done < "$tmp/series.txt"'
echo "$n stars on SCA 1, $k exposures:"
awk 'BEGIN { print "  how           wall s   CPU s   peak MB" }
     { printf "  %-12s %8.1f %7.1f %9d\n", $1, $2, $3, $4; w[NR] = $2; c[NR] = $3 }
     END { printf "  separate / first: %.2f wall, %.2f CPU", w[NR] / w[1], c[NR] / c[1]
	   if (NR == 3) printf "; four passes / one pass: %.2f wall", w[2] / w[1]
	   printf "\n" }' "$tmp/results"
