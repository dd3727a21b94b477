#!/bin/sh
# make demo-bulge: a season of a small Galactic-bulge field with a
# microlensing event, and its light curve measured back from the images.
#
# make-field.py writes ~4000 stars in a 40" square (bulge proper motions,
# disc parallaxes, a few variables, one microlensing event) and a
# --pointings file of DEMO_EXPOSURES (default 30) dated exposures over a
# spring season.  wfiscene draws rows 1850-2240 of SCA 1 of each in F146
# with the average background and Poisson and read noise, in passes of as
# many exposures as --memory 400 holds; photometry.py measures the event
# star by forced aperture photometry and plots the magnification against
# the event's curve.  Results go to build/demo-bulge/.
set -e
B=${WFS_BUILD:-build}
PY=${PY:-/usr/bin/python3}
here=$(dirname "$0")
out=$B/demo-bulge
mkdir -p "$out"
rows=1850-2240
run() {
	"$B/wfiscene" --filter F146 --sca 1 --ra 268.5 --dec -28.9 --rows "$rows" \
		--exptime 60 "$@"
}

t0=$(date +%s.%N)
"$PY" "$here/make-field.py" "$out" "${DEMO_EXPOSURES:-30}"
run --background avg --noise poisson,readnoise --memory 400 \
	--pointings "$out/season.txt" -o "$out/bulge_%s.fits" \
	--placed "$out/placed_%s.csv" "$out/field.csv"
# the event star alone at its baseline (no date), for the aperture's share
run -o "$out/event_base.fits" --placed "$out/event_base.csv" "$out/event.csv"
t1=$(date +%s.%N)
"$PY" "$here/photometry.py" "$out" "${rows%-*}"
"$B/wfiscene" preview "$out/bulge_e000.fits" -o "$out/bulge_e000.png"
t2=$(date +%s.%N)
cat <<EOT
demo-bulge: simulated in $(echo "$t1 - $t0" | bc) s, measured and plotted in $(echo "$t2 - $t1" | bc) s
demo-bulge: the light curve: $out/lightcurve.png ($out/lightcurve.csv)
EOT
