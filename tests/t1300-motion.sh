#!/bin/sh
# Proper motion and parallax: each exposure of a --pointings file places a
# star where it is at its date, seen from Roman near L2, against an
# independent computation with astropy (space motion from the epoch,
# barycentric ephemeris of the Earth and Sun, the observer 0.01 AU beyond
# the Earth); the catalog without a date or motion columns is unmoved.
. "$(dirname "$0")/lib.sh"
require_python

run() { "$WFS" --filter F158 --sca 1 --ra 268 --dec -29 "$@"; }

# 40 stars across SCA 1, some with a per-row epoch, moving up to 300 mas/yr
# with parallaxes up to 60 mas.
test_expect_success 'a catalog of moving stars and two dated exposures' '
	"$PY" -c "
import numpy as np
rng = np.random.default_rng(3)
print(\"id,ra,dec,mag,pmra,pmdec,parallax,epoch\")
for k in range(40):
    ra = 268.0 + rng.uniform(-0.05, 0.05)
    dec = -29.0 + rng.uniform(-0.05, 0.05)
    ep = \"\" if k % 3 else \"%.2f\" % rng.uniform(2010, 2030)
    print(\"%d,%.9f,%.9f,21,%.3f,%.3f,%.3f,%s\" % (k + 1, ra, dec, rng.uniform(-300, 300),
          rng.uniform(-300, 300), rng.uniform(0, 60), ep))
" > stars.csv &&
	printf "name,date,ra,dec,pa\nspring,2027-03-20T06:00,268,-29,0\nautumn,61670.25,268,-29,0\n" > pointings.txt
'
test_expect_success 'each exposure places the stars at its date' '
	run --pointings pointings.txt -o "img_%s.fits" --placed "placed_%s.csv" stars.csv &&
	test "$(wc -l < placed_spring.csv)" -gt 30
'
# astropy: the star at the date (space motion at zero radial velocity), seen
# from Roman; written as a static catalog that wfiscene places with no
# motion, so the comparison is of the motion alone, in pixels.
test_expect_success 'astropy moves the stars independently' '
	for d in "spring 2027-03-20T06:00:00" "autumn 61670.25"; do
		set -- $d
		"$PY" - "$2" > "static_$1.csv" <<-\EOF || return 1
		import sys, numpy as np
		import astropy.units as u
		from astropy.coordinates import SkyCoord, get_body_barycentric, CartesianRepresentation
		from astropy.time import Time
		v = sys.argv[1]
		t = Time(float(v), format="mjd", scale="utc") if ":" not in v else Time(v, scale="utc")
		rows = np.genfromtxt("stars.csv", delimiter=",", names=True, filling_values=np.nan)
		earth = get_body_barycentric("earth", t).xyz.to(u.au).value
		sun = get_body_barycentric("sun", t).xyz.to(u.au).value
		obs = earth + 0.01 * (earth - sun) / np.linalg.norm(earth - sun)
		print("id,ra,dec,mag")
		for r in rows:
		    ep = 2016.0 if np.isnan(r["epoch"]) else r["epoch"]
		    c = SkyCoord(ra=r["ra"] * u.deg, dec=r["dec"] * u.deg,
		                 distance=(1000.0 / r["parallax"]) * u.pc,
		                 pm_ra_cosdec=r["pmra"] * u.mas / u.yr, pm_dec=r["pmdec"] * u.mas / u.yr,
		                 radial_velocity=0 * u.km / u.s,
		                 obstime=Time(ep, format="jyear", scale="tdb"), frame="icrs")
		    m = c.apply_space_motion(new_obstime=t)
		    p = m.cartesian.xyz.to(u.au).value - obs
		    ra = np.degrees(np.arctan2(p[1], p[0])) % 360
		    dec = np.degrees(np.arctan2(p[2], np.hypot(p[0], p[1])))
		    print("%d,%.12f,%.12f,21" % (r["id"], ra, dec))
		EOF
		run -o "ref_$1.fits" --placed "ref_$1.csv" "static_$1.csv" || return 1
	done
'
# placed FILE1 FILE2 LIMIT: the largest distance (pixels) between the same
# ids, asserted below LIMIT and above zero (the stars did move)
compare() {
	"$PY" - "$@" <<-\EOF
	import sys, numpy as np
	def load(f):
	    a = np.genfromtxt(f, delimiter=",", names=True, dtype=None, encoding=None)
	    return {int(r["id"]): (r["x"], r["y"]) for r in a}
	a, b = load(sys.argv[1]), load(sys.argv[2])
	assert len(a) > 30 and a.keys() == b.keys(), (len(a), len(b))
	d = max(np.hypot(a[k][0] - b[k][0], a[k][1] - b[k][1]) for k in a)
	print(sys.argv[1], "max offset %.4f px" % d)
	assert d < float(sys.argv[3]), d
	EOF
}
test_expect_success 'placements agree with astropy within 0.03 px on both dates' '
	compare placed_spring.csv ref_spring.csv 0.03 &&
	compare placed_autumn.csv ref_autumn.csv 0.03
'
test_expect_success '... and the stars moved by pixels between the dates' '
	! compare placed_spring.csv placed_autumn.csv 1.0 2>/dev/null
'
test_expect_success 'without a date, the catalog positions at their epoch' '
	cut -d, -f1-4 stars.csv > still.csv &&
	run -o a.fits --placed still.csv.placed still.csv &&
	run -o b.fits --placed nodate.csv stars.csv &&
	compare nodate.csv still.csv.placed 1e-9
'
test_expect_success '--epoch moves rows without an epoch cell' '
	printf "ra dec pa name seed date\n268 -29 0 e - 57571.125\n" > e.txt &&
	printf "id,ra,dec,mag,pmra,pmdec\n1,268,-29,21,0,1000\n" > pm.csv &&
	printf "id,ra,dec,mag,pmra,pmdec\n1,268,-29,21,0,0\n" > pm0.csv &&
	run --pointings e.txt --allow-sun-angle --epoch 2015.5 -o "e_%s.fits" --placed "e_%s.csv" pm.csv &&
	run -o e0.fits --placed e0.csv pm0.csv &&
	"$PY" -c "
import numpy as np
a = np.genfromtxt(\"e_e.csv\", delimiter=\",\", names=True, dtype=None, encoding=None)
b = np.genfromtxt(\"e0.csv\", delimiter=\",\", names=True, dtype=None, encoding=None)
d = np.hypot(a[\"x\"] - b[\"x\"], a[\"y\"] - b[\"y\"])
assert abs(d - 1.0 / 0.11) < 0.2, d   # 1000 mas in a year, ~9.1 px
"
'
test_expect_success 'bad motion values are refused with their place' '
	printf "ra,dec,mag,pmra\n268,-29,21,abc\n" > bad.csv &&
	test_must_fail --status 1 run -o bad.fits bad.csv 2> err &&
	test_grep "bad.csv:2: column .pmra.: not a number" err &&
	printf "ra,dec,mag,parallax\n268,-29,21,1e6\n" > bad2.csv &&
	test_must_fail --status 1 run -o bad.fits bad2.csv 2> err &&
	test_grep "bad2.csv:2: column .parallax.: out of range" err &&
	printf "x,y,mag,pmra\n10,10,21,5\n" > bad3.csv &&
	test_must_fail --status 1 run -o bad.fits bad3.csv 2> err &&
	test_grep "need .ra. and .dec." err &&
	! test -e bad.fits
'
test_expect_success 'a pointings header names its columns in any order' '
	printf "date name pa dec ra\n61670.25 x 0 -29 268\n" > named.txt &&
	run --pointings named.txt -o "n_%s.fits" --placed "n_%s.csv" stars.csv &&
	cmp n_x.csv placed_autumn.csv &&
	printf "date name pa dec ra\n61670.25 x 0 -29 268 7\n" > long.txt &&
	test_must_fail --status 1 run --pointings long.txt -o "s_%s.fits" stars.csv 2> err &&
	test_grep "long.txt:2: the header names 5 columns, this line has more" err
'
test_done
