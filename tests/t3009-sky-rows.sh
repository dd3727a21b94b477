#!/bin/sh
# Sky rows over the whole focal plane: the catalog's cells are read, and
# the rows projected to the focal plane and to each SCA's pixels, on
# several threads.  The image, the --placed list and the first error are
# those of one thread going through the rows in order, for any number of
# threads and any chunk size.  The catalog covers the 18 SCAs, their gaps
# and edges, and rows off the focal plane; a second catalog of pixel rows
# is merged with them on each SCA.
. "$(dirname "$0")/lib.sh"
require_python

"$BUILD/contrib/starfield" -n 30000 -r 10 -d 20 -w 1.2 -m 20 -M 27 -s 9 > stars.csv
run() { "$WFS" --filter F158 --sca 1-18 --ra 10 --dec 20 --pointing-ref boresight \
	--flux-unit abmag "$@"; }

test_expect_success 'a sky catalog over the focal plane and beyond, and pixel rows' '
	"$PY" -c "
import random
random.seed(5)
rows = open(\"stars.csv\").read().split()[1:]
with open(\"sky.csv\", \"w\") as f:
    print(\"id,ra,dec,mag\", file=f)
    for r in rows:
        print(r, file=f)
    # far from the pointing: over the whole sky, and near the poles
    for i in range(300):
        print(\"%d,%.6f,%.6f,22\" % (900000 + i, random.uniform(0, 360),
              random.choice([random.uniform(-90, 90), 89.99, -89.99])), file=f)
with open(\"pix.csv\", \"w\") as f:
    print(\"id,x,y,sca,mag\", file=f)
    for i in range(2000):
        print(\"%d,%.3f,%.3f,%d,%.2f\" % (800000 + i, random.uniform(-30, 4120),
              random.uniform(-30, 4120), 1 + i % 18, random.uniform(20, 27)), file=f)
" && test "$(wc -l < sky.csv)" = 30301
'
# (The --placed list goes chunk by chunk, SCA by SCA: its order depends on
# the chunk size, not on the threads.)
test_expect_success 'the image and the placed list do not depend on the threads' '
	run --threads 1 -o t1.fits --placed p1.csv --report r1.json sky.csv pix.csv &&
	run --threads 2 -o t2.fits --placed p2.csv sky.csv pix.csv &&
	cmp t1.fits t2.fits && cmp p1.csv p2.csv &&
	run --threads 1 --chunk 777 -o c1.fits --placed c1.csv sky.csv pix.csv &&
	cmp t1.fits c1.fits &&
	run --threads 3 --chunk 777 -o c3.fits --placed c3.csv sky.csv pix.csv &&
	cmp t1.fits c3.fits && cmp c1.csv c3.csv
'
test_expect_success 'every sky row is culled, placed or off the detectors' '
	"$PY" -c "
import json, csv
r = json.load(open(\"r1.json\"))[\"rows\"]
assert r[\"read\"] == 32300, r
placed = list(csv.reader(open(\"p1.csv\")))[1:]
assert r[\"placements\"] == len(placed), r
scas = set(int(p[1]) for p in placed)
assert scas == set(range(1, 19)), scas
# the rows far from the pointing are never placed
assert not [p for p in placed if 900000 <= int(p[0]) < 900300]
# rows off the focal plane (the catalog is 1.2 degrees wide) are culled
assert r[\"culled_far\"] > 5000, r
sky = [p for p in placed if int(p[0]) < 800000]
assert len(sky) > 0.12 * 30000, len(sky)
# a row is placed at most on the SCAs its light reaches: seldom on two
ids = [p[0] for p in sky]
assert len(ids) - len(set(ids)) < 0.05 * len(ids), (len(ids), len(set(ids)))
"
'
# --chunk's default: 262144 rows for one exposure; in a series (whose
# exposures each hold a chunk's placements) 16384 rows an SCA, from 65536
# to 262144
chunk_is() {
	"$PY" -c "import json, sys; c = json.load(open(sys.argv[1]))[\"settings\"][\"chunk\"]
assert c == int(sys.argv[2]), c" "$1" "$2"
}
test_expect_success 'the default chunk: 262144 rows, in a series 16384 an SCA' '
	printf "id,x,y,sca,mag\n" > none.csv &&
	printf "10 20 0 e1\n10 20 0.5 e2\n" > pt.txt &&
	for c in "1 262144 65536" "1-4 262144 65536" "1-8 262144 131072" \
		 "1-18 262144 262144"; do
		set -- $c &&
		run --sca $1 --report rc.json -o /dev/null none.csv &&
		chunk_is rc.json $2 &&
		run --sca $1 --pointings pt.txt --rows 2040-2047 --report "rc_%s.json" \
			-o "pt_%s.fits" none.csv &&
		chunk_is rc_e1.json $3 || return 1
	done &&
	run --sca 1-18 --chunk 777 --report rc.json -o /dev/null none.csv &&
	chunk_is rc.json 777 && chunk_is r1.json 262144
'
test_expect_success 'rows near SCA edges keep their pixels when read in other chunks' '
	"$PY" -c "
import csv
a = {(p[0], p[1]): p[2:4] for p in list(csv.reader(open(\"p1.csv\")))[1:]}
b = {(p[0], p[1]): p[2:4] for p in list(csv.reader(open(\"c3.csv\")))[1:]}
assert a == b
edge = [k for k, v in a.items() if min(float(v[0]), float(v[1]), 4089 - float(v[0]),
        4089 - float(v[1])) < 3]
assert len(edge) > 10, len(edge)
"
'
# A sky row is culled from an SCA it lies farther from than its reach:
# faint rows take the 88-pixel box's without being planned (reach_faint),
# bright ones their halo's.  Bright stars 5 to 400 pixels outside SCA 1,
# given on the sky and as pixel rows at the same places (the pixel path
# culls by the drawn box): the same light on the SCA.  (With every row's
# reach taken as the box's, 43 of the 60 were culled, a quarter of the
# light lost.)
test_expect_success 'bright sky rows beyond an SCA light it as pixel rows do' '
	printf "id,x,y,sca,mag\n1,2000,2000,1,20\n" > one.csv &&
	run --sca 1 -o wcs.fits one.csv &&
	"$PY" -c "
import random
from astropy.io import fits
from astropy.wcs import WCS
w = WCS([h for h in fits.open(\"wcs.fits\") if h.data is not None][0].header)
random.seed(3)
with open(\"bsky.csv\", \"w\") as s, open(\"bpix.csv\", \"w\") as p:
    print(\"id,ra,dec,mag\", file=s)
    print(\"id,x,y,sca,mag\", file=p)
    for i in range(60):
        d, t = random.uniform(5, 400), random.uniform(-300, 4400)
        x, y = [(-d, t), (4089 + d, t), (t, -d), (t, 4089 + d)][i % 4]
        mag = random.uniform(8, 14)
        ra, dec = w.all_pix2world([[x, y]], 1)[0]
        print(\"%d,%.10f,%.10f,%.3f\" % (i + 1, ra, dec, mag), file=s)
        print(\"%d,%.6f,%.6f,1,%.3f\" % (i + 1, x, y, mag), file=p)
" &&
	run --sca 1 --exptime 1000 --report bs.json -o bs.fits bsky.csv &&
	run --sca 1 --exptime 1000 -o bp.fits bpix.csv &&
	"$PY" -c "
import json
import numpy as np
from astropy.io import fits
r = json.load(open(\"bs.json\"))[\"rows\"]
assert r[\"placements\"] == 60 and r[\"culled_far\"] == 0, r
a, b = (fits.getdata(f).astype(float) for f in (\"bs.fits\", \"bp.fits\"))
assert b.sum() > 1e5, b.sum()
assert abs(a.sum() / b.sum() - 1) < 1e-6, (a.sum(), b.sum())
assert np.abs(a - b).max() < 1e-4 * b.max(), np.abs(a - b).max()
"
'
# Two bad rows in one chunk, in different parts of it: the first in the
# file is the one reported, whichever thread reads it.
test_expect_success 'the first bad row is reported, for any threads' '
	awk "NR == 20001 { \$0 = \"20000,10.01,95,22\" } NR == 17001 { \$0 = \"17000,10.01,20.01,abc\" } 1" \
		sky.csv > bad.csv &&
	for t in 1 3; do
		test_must_fail --status 1 run --threads $t -o bad.fits bad.csv 2> err$t &&
		grep -q "bad.csv:17001: column .mag.: not a number" err$t &&
		cmp err1 err$t && test ! -e bad.fits || return 1
	done
'
test_done
