#!/bin/sh
# make bench: wfiscene's benchmark suite.  Generates its scenes on the fly,
# prints markdown tables on stdout (paste them into BENCHMARKS.md), keeps its
# scratch files in build/bench/.  Never part of make check.
#
#   BENCH_QUICK=1 make bench     smaller catalogs, for a quick look
set -e
B=${WFS_BUILD:-build}
W=$B/bench
mkdir -p "$W"
WFS="$B/wfiscene"
GEN="$B/contrib/starfield"
export WFISCENE_PLUGIN_PATH="$B/plugins"
quick=${BENCH_QUICK:-0}
big=1000000
huge=10000000
[ "$quick" = 1 ] && big=200000 && huge=1000000

# seconds and peak KiB of a shell command, as "SECONDS KIB"
measure() {
	/usr/bin/time -f '%e %M' -o "$W/time" sh -c "$1" > /dev/null 2> "$W/err" ||
		{ cat "$W/err" >&2; exit 1; }
	cat "$W/time"
}

echo "# wfiscene benchmarks, $(date -u +%Y-%m-%d), $(nproc) cores, $(uname -m)"
echo
echo "Commands are shown with each table; catalogs come from build/contrib/starfield."

# Warm the PSF cache so that PSF building is not timed here.
: > "$W/empty.csv"
"$WFS" --filter F129 --sca 1-18 --compress gzip -o "$W/warm.fits" "$W/empty.csv"

echo
echo "## Faint stars (AB 20-27), end to end"
echo
echo "\`zstd -dc stars.csv.zst | wfiscene --filter F129 --sca S --flux-unit abmag -o out.fits\`"
echo
echo "| stars | SCAs | wall s | empty scene s | stars/s (all) | stars/s (less empty scene) | peak MiB |"
echo "|---|---|---|---|---|---|---|"
for n in 100000 $big; do
	"$GEN" -n $n -x -s 1 | zstd -q -c > "$W/one.csv.zst"
	"$GEN" -n $n -r 10 -d 20 -w 0.8 -s 2 | zstd -q -c > "$W/all.csv.zst"
	for scas in 1 1-18; do
		if [ $scas = 1 ]; then cat=one; opt=""; else
			cat=all; opt="--ra 10 --dec 20 --pointing-ref boresight"; fi
		set -- $(measure "'$WFS' --filter F129 --sca $scas $opt -o '$W/e.fits' '$W/empty.csv'")
		e=$1
		set -- $(measure "zstd -dc '$W/$cat.csv.zst' | '$WFS' --filter F129 --sca $scas $opt --flux-unit abmag -o '$W/o.fits' -")
		awk -v n=$n -v s=$scas -v t=$1 -v e=$e -v m=$2 'BEGIN {
			printf "| %d | %s | %.2f | %.2f | %.0f | %.0f | %.0f |\n", n, s, t, e, n / t,
				(t > e ? n / (t - e) : 0), m / 1024 }'
	done
done

echo
echo "## Catalog parse rate, zstd CSV on stdin"
echo
echo "Rows far from the pointing are read, parsed, projected and culled, so this"
echo "is the reading side alone: \`zstd -dc far.csv.zst | wfiscene --filter F129 --ra 180 -o out.fits -\`"
echo
echo "| rows | MB (CSV) | wall s | rows/s | MB/s | peak MiB |"
echo "|---|---|---|---|---|---|"
"$GEN" -n $big -r 10 -d 20 -s 3 | zstd -q -c > "$W/far.csv.zst"
mb=$(zstd -dc "$W/far.csv.zst" | wc -c)
set -- $(measure "zstd -dc '$W/far.csv.zst' | '$WFS' --filter F129 --ra 180 --dec -20 --flux-unit abmag -o '$W/o.fits' -")
awk -v n=$big -v b=$mb -v t=$1 -v m=$2 'BEGIN {
	printf "| %d | %.1f | %.2f | %.0f | %.1f | %.0f |\n", n, b / 1e6, t, n / t, b / 1e6 / t, m / 1024 }'

echo
echo "## Peak memory against catalog length"
echo
echo "Faint stars on SCA 1, generated on the fly and piped in (nothing stored):"
echo "\`starfield -n N -x | wfiscene --filter F129 --flux-unit abmag -o out.fits\`"
echo
echo "| rows | wall s | peak MiB |"
echo "|---|---|---|"
for n in 100000 $big $huge; do
	set -- $(measure "'$GEN' -n $n -x -s 4 | '$WFS' --filter F129 --flux-unit abmag -o '$W/o.fits' -")
	awk -v n=$n -v t=$1 -v m=$2 'BEGIN { printf "| %d | %.1f | %.0f |\n", n, t, m / 1024 }'
done
rm -f "$W"/*.fits
