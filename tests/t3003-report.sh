#!/bin/sh
# --report writes a JSON account of the run; a progress line appears on
# stderr only when it is a terminal.
. "$(dirname "$0")/lib.sh"
require_python

cat > stars.csv <<EOT
id,x,y,flux
1,100.3,200.7,1000
2,2045,2045,50000
3,-3,500,200
4,-500,500,5
EOT
test_expect_success '--report is valid JSON with counts, timings and flux' '
	"$WFS" --filter F129 --psf "$PSF" --report r.json -o r.fits stars.csv &&
	"$PY" -c "
import json
r = json.load(open(\"r.json\"))
assert r[\"rows\"][\"read\"] == 4, r[\"rows\"]
assert r[\"rows\"][\"placements\"] == 3 and r[\"rows\"][\"off_detector\"] == 1, r[\"rows\"]
assert r[\"rows\"][\"by_model\"] == {\"point\": 3}, r[\"rows\"]
f = r[\"flux\"][0]
assert f[\"sca\"] == 1 and f[\"requested\"] == 51200
assert 0.95 * 51000 < f[\"placed\"] < f[\"requested\"], f
assert 0 < r[\"error_budget\"][\"largest_truncation_loss\"] < 0.05
assert all(v >= 0 for v in r[\"seconds\"].values())
assert r[\"psf_grids\"][\"built\"] + r[\"psf_grids\"][\"loaded\"] >= 1 or r[\"settings\"][\"psf\"] != \"builtin\"
"
'
test_expect_success 'a --psf name with a quote and a backslash stays valid JSON' '
	"$WFS" psf --filter F129 --sca 1 -o "q\"b\\x.fits" &&
	"$WFS" --filter F129 --psf "q\"b\\x.fits" --report q.json -o q.fits stars.csv &&
	"$PY" -c "
import json
r = json.load(open(\"q.json\"))
assert r[\"settings\"][\"psf\"] == \"q\\\"b\\\\x.fits\", r[\"settings\"][\"psf\"]"
'
test_expect_success 'the report shows what a scene left out: models, FFT plans, tiles, noise' '
	printf "x,y,flux\n100,100,50\n" > pt.csv &&
	"$WFS" --filter F129 --psf "$PSF" --set psf-diffuse=none --report w1.json -o w1.fits pt.csv &&
	printf "x,y,flux,type,n,re,phi,ratio\n300,300,50,sersic,1.5,3,20,0.6\n" > gal.csv &&
	"$WFS" --filter F129 --psf "$PSF" --noise poisson,readnoise --exptime 100 --seed 3 \
		--report w2.json -o w2.fits gal.csv &&
	"$PY" -c "
import json
w = json.load(open(\"w1.json\"))[\"work\"]
assert w == {\"models\": [\"point\"], \"fft_plans\": 0, \"tiles_drawn\": 1,
             \"tiles\": 256, \"noise_stages\": []}, w
r = json.load(open(\"w1.json\"))
assert [b[\"class\"] for b in r[\"psf_grids\"][\"boxes\"]] in ([0], []), r[\"psf_grids\"]
w = json.load(open(\"w2.json\"))[\"work\"]
assert w[\"models\"] == [\"sersic-quick\"] and w[\"fft_plans\"] >= 1, w
assert w[\"noise_stages\"] == [\"poisson\", \"readnoise\"] and w[\"tiles_drawn\"] >= 1, w
"
'
test_expect_success 'no progress line when stderr is not a terminal' '
	"$BUILD/contrib/starfield" -n 30000 -x > many.csv &&
	"$WFS" --filter F129 --psf "$PSF" --flux-unit abmag --chunk 500 -o m.fits many.csv 2> err &&
	! test -s err
'
if command -v script > /dev/null; then
	# The line appears at most four times a second, so a run shorter than
	# that may never print one: the catalog arrives through a pipe that
	# stalls half a second halfway, so the chunks after the stall always
	# find the line due, however fast the machine.  script(1) reads its
	# own stdin, so it is given none.
	test_expect_success 'a progress line when stderr is a terminal, none with -q' '
		slow="{ head -n 15000 many.csv; sleep 0.5; tail -n +15001 many.csv; }" &&
		script -qec "$slow | \"$WFS\" --filter F129 --psf \"$PSF\" --flux-unit abmag --chunk 500 -o m2.fits -" /dev/null < /dev/null > tty.out &&
		test_grep "rows/s" tty.out &&
		script -qec "$slow | \"$WFS\" -q --filter F129 --psf \"$PSF\" --flux-unit abmag --chunk 500 -o m3.fits -" /dev/null < /dev/null > tty2.out &&
		! test_grep "rows/s" tty2.out 2>/dev/null &&
		cmp m2.fits m3.fits
	'
else
	test_skip 'progress on a terminal' 'script(1) is absent (Debian package bsdutils)'
fi
test_done
