#!/bin/sh
# The cost of drawing bright stars out to the noise (psf-extent=noise, the
# default) against STIPS's boxes (psf-extent=stips), in one run so that the
# ratios see the same machine load: per magnitude, the radius drawn and
# the CPU time per star; then a bulge-like field of 10^6 stars.
#
#   contrib/bench/bright.sh [BUILD [OTHER_WFISCENE]]
#
# OTHER_WFISCENE, when given, is another build's binary (e.g. the previous
# release's) timed on the bulge field alongside.  F158, SCA 1, 139.8 s,
# noise-free (sigma: the filter's average sky and 12 e- read noise), one
# thread; CPU time is user + system of the whole run, the best of 3.
set -e
B=${1:-build}
OTHER=${2:-}
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
cpu() { # command...: the best of 3 runs' user + system seconds
	best=
	for k in 1 2 3; do
		/usr/bin/time -f "%U %S" -o "$W/t" "$@" > /dev/null 2>&1
		t=$(awk '{ print $1 + $2 }' "$W/t")
		best=$(awk -v a="$best" -v b="$t" 'BEGIN { print (a == "" || b < a) ? b : a }')
	done
	echo "$best"
}
PY=/usr/bin/python3
set -- "$B/wfiscene" --filter F158 --flux-unit abmag --exptime 139.8 --threads 1
echo "| AB mag | stars | radius drawn, px (one star) | CPU s, noise | CPU s, stips | × stips | ms/star over an empty run |"
echo "|---|---|---|---|---|---|---|"
e=$(cpu "$@" -o "$W/e.fits" /dev/null)
for m in 0 2 6 10 14 18 22 26; do
	case $m in 0|2) n=1 ;; 6) n=10 ;; 10) n=100 ;; 14) n=1000 ;; *) n=10000 ;; esac
	"$B/contrib/starfield" -n $n -x -m $m -M $m -s 5 > "$W/m.csv"
	printf "id,x,y,flux\n1,2044.3,2044.6,$m\n" > "$W/one.csv"
	r=$("$@" -o "$W/m.fits" "$W/one.csv" && $PY -c "
import numpy as np
from astropy.io import fits
a = fits.getdata('$W/m.fits', 1)
y, x = np.nonzero(a)
print(int(np.hypot(x - 2043.3, y - 2043.6).max()))" 2>/dev/null || echo -)
	a=$(cpu "$@" -o "$W/m.fits" "$W/m.csv")
	b=$(cpu "$@" --set psf-extent=stips -o "$W/m.fits" "$W/m.csv")
	awk -v m=$m -v n=$n -v a=$a -v b=$b -v e=$e -v px="$r" 'BEGIN {
		printf "| %d | %d | %s | %.2f | %.2f | %.2f | %.3g |\n",
			m, n, px, a, b, a / b, 1e3 * (a - e) / n }'
done
"$B/contrib/starfield" -n 1000000 -x -m 14 -M 28 -s 3 > "$W/bulge.csv"
a=$(cpu "$@" -o "$W/b.fits" "$W/bulge.csv")
b=$(cpu "$@" --set psf-extent=stips -o "$W/b.fits" "$W/bulge.csv")
echo
echo "Bulge-like field, 10^6 stars, dN/dm ~ 10^(0.3 m), 14-28 mag: noise $a s, stips $b s, ratio $(awk "BEGIN { printf \"%.2f\", $a / $b }")"
if [ -n "$OTHER" ]; then
	c=$(cpu "$OTHER" --filter F158 --flux-unit abmag --exptime 139.8 --threads 1 -o "$W/b.fits" "$W/bulge.csv")
	echo "  and $OTHER: $c s, ratio $(awk "BEGIN { printf \"%.2f\", $a / $c }")"
fi
