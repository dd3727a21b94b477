#!/bin/sh
# Load tests for `make validate` (too slow for make check):
#
#  1. 10^8 catalog rows on standard input, generated on the fly by
#     build/contrib/starfield and piped (never stored: about 4 GB of CSV),
#     over a 20-degree square about the pointing, so nearly every row is
#     culled far from SCA01: it measures reading, parsing, projecting and
#     culling at scale.  Memory must be flat: the peak RSS of the 10^8-row
#     run within 10% (plus 8 MB) of a 10^6-row run.  Image tiles are
#     allocated when a source first touches them (512 KiB each, 128 MiB for
#     all 256 tiles of an SCA), so a longer random catalog touches more of
#     them, and each tile's pages only when written; both runs therefore
#     first read a catalog of stars 44 pixels apart in y down the middle
#     of every column of tiles, which writes every page of every tile, so
#     that what is compared is the memory of reading.
#  2. 10^6 point sources on one 256 x 256 tile of SCA01 (uniform in pixels
#     [1, 256]), faint (24-27 mag), so every one is drawn with the 44-pixel
#     box: the worst case for one worker.  The placed count must be 10^6.
#
#   sh tests/validate/load.sh [ROWS]      (ROWS default 100000000)
#
# Prints one line per run: wall seconds, CPU seconds, peak RSS (MB).
# Exit status 0 when the checks hold.
set -e
TOP=$(cd "$(dirname "$0")/../.." && pwd)
BUILD=${WFS_BUILD:-build}
case $BUILD in /*) ;; *) BUILD=$TOP/$BUILD ;; esac
WFS=$BUILD/wfiscene
SF=$BUILD/contrib/starfield
ROWS=${1:-100000000}
T=$(mktemp -d "${TMPDIR:-/tmp}/wfs-load.XXXXXX")
trap 'rm -rf "$T"' EXIT
[ -x /usr/bin/time ] || { echo "load.sh: /usr/bin/time is needed" >&2; exit 1; }

# measure NAME CMD...: run CMD (a wfiscene pipeline stage) under time(1)
measure() {
	name=$1; shift
	/usr/bin/time -f "%e %U %S %M" -o "$T/$name.time" "$@"
	read -r wall user sys rss < "$T/$name.time"
	awk -v n="$name" -v w="$wall" -v u="$user" -v s="$sys" -v r="$rss" 'BEGIN {
		printf "%-28s wall %7.1f s  cpu %7.1f s  peak RSS %6.0f MB\n", n, w, u + s, r / 1024 }'
}
rss() { awk '{ print $4 }' "$T/$1.time"; }
report_rows() { grep -o '"read": [0-9]*, "culled_far": [0-9]*, "off_detector": [0-9]*, "placements": [0-9]*' "$1"; }

awk 'BEGIN { print "x,y,mag"; for (i = 0; i < 16; i++) for (j = 0; j < 94; j++)
	printf "%d,%d,25\n", 128 + 256 * i, 22 + 44 * j }' > "$T/tiles.csv"
$SF -n 1000000 -w 20 -s 7 | measure "stdin 10^6 rows" "$WFS" --filter F129 --sca 1 \
	--report "$T/r6.json" -o "$T/a.fits" "$T/tiles.csv" -
$SF -n "$ROWS" -w 20 -s 7 | measure "stdin $ROWS rows" "$WFS" --filter F129 --sca 1 \
	--report "$T/r8.json" -o "$T/b.fits" "$T/tiles.csv" -
report_rows "$T/r8.json"
grep -q "\"read\": $((ROWS + 1504))," "$T/r8.json" || { echo "load.sh: not all rows read" >&2; exit 1; }
a=$(rss "stdin 10^6 rows") b=$(rss "stdin $ROWS rows")
if [ "$b" -gt $((a + a / 10 + 8192)) ]; then
	echo "load.sh: memory grows with rows: $a KB for 10^6, $b KB for $ROWS" >&2; exit 1
fi
echo "memory flat: $a KB for 10^6 rows, $b KB for $ROWS rows"

awk 'BEGIN { srand(11); print "x,y,mag";
	for (i = 0; i < 1000000; i++) printf "%.4f,%.4f,%.3f\n", 0.5 + 256 * rand(), 0.5 + 256 * rand(), 24 + 3 * rand() }' \
	> "$T/tile.csv"
measure "10^6 sources on one tile" "$WFS" --filter F129 --sca 1 --report "$T/rt.json" \
	-o "$T/c.fits" "$T/tile.csv"
report_rows "$T/rt.json"
grep -q '"placements": 1000000' "$T/rt.json" || { echo "load.sh: not every source placed" >&2; exit 1; }
