#!/bin/sh
# make demo-bulge: SCA 4 of a Galactic-bulge field at the survey's
# 15-minute cadence for a few hours, read up the ramp and fitted (level 2)
# with persistence from one exposure to the next, a short microlensing
# event's light curve measured back, and the afterglow the bright giants
# leave for the next visit.
#
# make-field.py writes ~1.6 million stars (about 1 million on SCA 4, the
# giants that saturate included) and a --pointings file of DEMO_EXPOSURES
# (default 12: three hours) visits 15 minutes apart, each dithered by 1-3",
# plus a baseline visit a day later.  wfiscene draws SCA 4 (the strongest
# persistence the Project measured) of each in F146
# at level 2 (MA table 3, 56.9 s) with the average background, in passes
# of as many exposures as --memory 600 holds, carrying the persistence
# state from each exposure to the next and writing it at the end;
# photometry.py measures the event star by forced aperture photometry;
# afterglow.py maps the afterglow of the final state.  Results go to
# build/demo-bulge/.
set -e
B=${WFS_BUILD:-build}
PY=${PY:-/usr/bin/python3}
here=$(dirname "$0")
out=$B/demo-bulge
mkdir -p "$out"
run() {
	"$B/wfiscene" --filter F146 --sca 4 --ra 268.5 --dec -28.9 "$@"
}

t0=$(date +%s.%N)
"$PY" "$here/make-field.py" "$out" "${DEMO_EXPOSURES:-12}" "${DEMO_STARS:-1600000}"
rm -f "$out/persistence.state"
run --level 2 --ma-table 3 --background avg --memory 600 \
	--pointings "$out/season.txt" --persistence-state "$out/persistence.state" \
	-o "$out/bulge_%s.fits" "$out/field.csv"
# where the event star falls in each exposure (its placement; a 16-row image)
run --rows 1-16 --pointings "$out/season.txt" -o "$out/event_%s.fits" \
	--placed "$out/event_%s.csv" "$out/event.csv"
# the event star alone at its baseline (no date), for the aperture's share
run --exptime 56.924 -o "$out/event_base.fits" --placed "$out/event_base.csv" "$out/event.csv"
t1=$(date +%s.%N)
last=$(awk 'NR > 1 { n = $1 } END { print n }' "$out/season.txt")
"$PY" "$here/afterglow.py" "$out" "$out/persistence.state" 900 4
"$PY" "$here/photometry.py" "$out" 1
"$B/wfiscene" preview --sca 4 "$out/bulge_$last.fits" -o "$out/field.png"
"$B/wfiscene" preview --stretch asinh --min 0 --max 0.1 "$out/afterglow.fits" -o "$out/afterglow.png"
t2=$(date +%s.%N)
cat <<EOT
demo-bulge: simulated in $(echo "$t1 - $t0" | bc) s, measured and plotted in $(echo "$t2 - $t1" | bc) s
demo-bulge: the field: $out/field.png; the afterglow at the next visit: $out/afterglow.png
demo-bulge: the light curve: $out/lightcurve.csv (and lightcurve.png with matplotlib)
EOT
