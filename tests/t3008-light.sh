#!/bin/sh
# Every star keeps the same fraction of its PSF's light, whatever its
# brightness (psf-extent=noise, the default, with psf-diffuse=grid): one
# star at a time in F129 on SCA 1, 139.8 s, no noise, AB 6 to 28, at the
# SCA's centre, 25 pixels from a corner and 12 from an edge, in both
# geometries; the image's sum over the star's flux varies by at most 0.2%
# (it was 0.968 for faint stars and 0.994 for bright ones when the light
# beyond a faint star's box was left out).  --report's drawn light,
# --placed's flux and the image agree; a crowded field keeps its light,
# and its wing light shows beside the stars.
. "$(dirname "$0")/lib.sh"
require_python

# one MAG X Y GEOM [extra]: the light drawn over the flux requested (a
# star of temperature $TEFF in filter $FILT when set), from the report;
# for the brightest and the faintest of a sweep the image (one$m.fits) and
# report (one$m.json) are kept, for sweep to check the report's drawn
# light against the image's sum; the others write no 64 MB image
# (/dev/null)
one() {
	m=$1 x=$2 y=$3 g=$4
	shift 4
	case $m in 6 | 28) img=one$m.fits ;; *) img=/dev/null ;; esac
	printf 'x,y,sca,flux,teff\n%s,%s,1,%s,%s\n' "$x" "$y" "$m" "${TEFF-}" > one.csv &&
	"$WFS" --filter "${FILT:-F129}" --sca 1 --exptime 139.8 --flux-unit abmag --geometry "$g" \
		--report one.json -o "$img" "$@" one.csv &&
	case $m in 6 | 28) cp one.json one$m.json ;; esac &&
	sed -n 's/.*{"sca": 1, "requested": \([^,]*\), "placed": \([^}]*\)}.*/\2 \1/p' one.json |
		awk 'NF == 2 && $2 > 0 { printf "%.6f\n", $1 / $2; n++ } END { exit n != 1 }'
}

# sweep X Y GEOM: the ratios from AB 6 to 28, then max/min - 1 <= 0.002;
# AB 6's and 28's report against their image (one python3 call: its
# start-up, some 0.4 s, once)
sweep() {
	for m in 6 10 14 18 20 22 28; do
		one $m "$1" "$2" "$3" >> "ratios.$1.$2.$3${TEFF:+.$TEFF}" || return 1
	done
	"$PY" -c '
import json, sys
from astropy.io import fits
for m in (6, 28):
    r = json.load(open("one%d.json" % m))["flux"][0]
    s = fits.getdata("one%d.fits" % m, 1).astype(float).sum()
    assert abs(r["placed"] / s - 1) < 1e-6, (m, r, s)
v = [float(l) for l in open(sys.argv[1])]
print(sys.argv[1], v, max(v) / min(v) - 1)
assert max(v) / min(v) - 1 <= 0.002' "ratios.$1.$2.$3${TEFF:+.$TEFF}"
}

for g in siaf stips; do
	for pos in "2044.5 2044.5" "25 25" "2044.5 12"; do
		set -- $pos
		test_expect_success "$g geometry at ($1, $2): the same fraction of light at AB 6-28" "
			sweep $1 $2 $g
		"
	done
done

# Coloured stars (F146, where the spectral classes differ most), away from
# their blended cell's centre: a red and a blue star keep the same fraction
# of their light at every brightness too.
for t in 3000 30000; do
	test_expect_success "a $t K star in F146: the same fraction of light at AB 6-28" "
		FILT=F146 && TEFF=$t && sweep 1900.3 2300.6 siaf; r=\$?
		unset FILT TEFF
		test \$r = 0
	"
done

test_expect_success 'the fraction is the PSF light the model draws, about 0.994 in F129' '
	"$PY" -c "
v = [float(l) for l in open(\"ratios.2044.5.2044.5.siaf\")]
assert all(0.990 < x < 0.996 for x in v), v"
'

test_expect_success 'psf-diffuse=none leaves a faint star its box: 0.96-0.975' '
	v=$(one 24 2044.5 2044.5 siaf --set psf-diffuse=none) &&
	"$PY" -c "assert 0.96 < $v < 0.975, $v"
'

test_expect_success 'a 16-22 mag catalog places at least 0.99 of its flux; --placed, --report and the image agree' '
	"$PY" -c "
import numpy as np
r = np.random.default_rng(3)
n = 2000
print(\"id,x,y,flux\")
for i, (x, y, m) in enumerate(zip(r.uniform(200, 3888, n), r.uniform(200, 3888, n), r.uniform(16, 22, n))):
    print(\"%d,%.3f,%.3f,%.3f\" % (i + 1, x, y, m))
" > mid.csv &&
	"$WFS" --filter F129 --sca 1 --exptime 139.8 --flux-unit abmag --report mid.json \
		--placed mid-placed.csv -o mid.fits mid.csv &&
	"$PY" -c "
import csv, json
from astropy.io import fits
r = json.load(open(\"mid.json\"))[\"flux\"][0]
s = fits.getdata(\"mid.fits\", 1).astype(float).sum()
placed = sum(float(row[\"flux\"]) for row in csv.DictReader(open(\"mid-placed.csv\")))
print(r, s, placed)
assert abs(placed / r[\"requested\"] - 1) < 1e-5
assert abs(r[\"placed\"] / s - 1) < 1e-6
assert s / placed >= 0.99, s / placed
"
'

# A crowded field: 10^6 faint stars (AB 22-27) in x 1000-2000, y 1000-3088;
# none within 1000 pixels of an SCA edge, so the light beyond that reach
# (a few 1e-4) is all that falls off.
test_expect_success 'a field of 10^6 faint stars keeps the fraction of a bright star' '
	"$PY" -c "
import numpy as np
r = np.random.default_rng(7)
n = 1000000
x = r.uniform(1000, 2000, n); y = r.uniform(1000, 3088, n); m = r.uniform(22, 27, n)
# the bytes np.savetxt(fmt=\"%.3f\") writes, in a third of its time
with open(\"crowd.csv\", \"w\") as f:
    f.write(\"x,y,flux\\n\" + \"\".join([\"%.3f,%.3f,%.3f\\n\" % v for v in zip(x.tolist(), y.tolist(), m.tolist())]))
" &&
	"$WFS" --filter F129 --sca 1 --exptime 139.8 --flux-unit abmag --report crowd.json \
		-o crowd.fits crowd.csv &&
	"$WFS" --filter F129 --sca 1 --exptime 139.8 --flux-unit abmag --set psf-diffuse=none \
		-o crowd0.fits crowd.csv &&
	f=$(one 12 1500.5 2044.5 siaf) &&
	"$PY" -c "
import json
import numpy as np
from astropy.io import fits
f = $f
r = json.load(open(\"crowd.json\"))[\"flux\"][0]
a = fits.getdata(\"crowd.fits\", 1).astype(float)
b = fits.getdata(\"crowd0.fits\", 1).astype(float)
print(\"fraction of a bright star\", f, \"field\", a.sum() / r[\"requested\"], \"without the wings\", b.sum() / r[\"requested\"])
assert abs(a.sum() / r[\"requested\"] / f - 1) < 1e-3
# the wing light beside the field: nothing drawn there without it, and
# with it a light that falls off with distance from the field
s = [a[1200:2900, 2000 + d0:2000 + d1].mean() for d0, d1 in ((30, 60), (100, 200), (400, 600))]
z = b[1200:2900, 2030:2600]
print(\"beside the field\", s, \"without\", z.max())
assert z.max() == 0 and s[0] > s[1] > s[2] > 0
# between the stars: the field is lit by the wings, 2-3% of its light
d = a[1100:2988, 1100:1900].sum() / b[1100:2988, 1100:1900].sum() - 1
print(\"wing light inside the field\", d)
assert 0.01 < d < 0.03
"
'

test_expect_success 'the same bytes with one thread and another tile size' '
	"$WFS" --filter F129 --sca 1 --exptime 139.8 --flux-unit abmag --threads 1 --tile 300 \
		-o crowd1.fits crowd.csv &&
	"$PY" -c "
import numpy as np
from astropy.io import fits
a = fits.getdata(\"crowd.fits\", 1); b = fits.getdata(\"crowd1.fits\", 1)
assert np.array_equal(a, b), np.abs(a - b).max()
"
'

# Aperture photometry calibrated on bright stars reads faint ones right:
# 100 isolated AB 24 stars on a 400-pixel lattice against the same of AB
# 16 (each field in its own image, so that the neighbours' light is the
# same share of a star's), no noise, apertures of 10 to 100 pixels.  With
# the wings beyond a faint star's box left out, faint stars read 0.015
# mag too faint at 50 pixels.
test_expect_success 'aperture photometry: faint and bright stars agree to 0.003 mag, 10-100 px' '
	for m in 16 24; do
		"$PY" -c "
print(\"id,x,y,mag\")
k = 0
for j in range(10):
    for i in range(10):
        k += 1
        print(\"%d,%.3f,%.3f,$m\" % (k, 250 + 400 * i + 0.37 * (k % 3), 250 + 400 * j + 0.61 * (k % 5)))
" > lat$m.csv &&
		"$WFS" --filter F129 --sca 1 --geometry stips --exptime 139.8 --flux-unit abmag \
			--placed lat$m-placed.csv -o lat$m.fits lat$m.csv || return 1
	done &&
	"$PY" -c "
import numpy as np
from astropy.io import fits
def phot(m, R):
    d = fits.getdata(\"lat%d.fits\" % m, 1).astype(float)
    t = np.genfromtxt(\"lat%d-placed.csv\" % m, delimiter=\",\", names=True, dtype=None, encoding=\"ascii\")
    yy, xx = np.mgrid[-R:R + 1, -R:R + 1]
    dm = []
    for x, y, f in zip(t[\"x\"] - 1, t[\"y\"] - 1, t[\"flux\"]):
        ix, iy = int(round(x)), int(round(y))
        a = np.hypot(xx + ix - x, yy + iy - y) <= R
        dm.append(-2.5 * np.log10(d[iy - R:iy + R + 1, ix - R:ix + R + 1][a].sum() / f))
    return np.median(dm)
for R in (10, 30, 50, 100):
    b, f = phot(16, R), phot(24, R)
    print(R, b, f, f - b)
    assert abs(f - b) <= 0.003
"
'

# psf-halo-near (default 1): within the halo's array a bright star draws
# only the pixels at or above the drawing level, the rest spread on the
# grid.  The whole disc (0) keeps the same fractions; the two images of a
# bright star differ by less than the drawing level in every pixel; a
# field of bright and faint stars gives the same bytes for any threads
# and tiles.
test_expect_success 'psf-halo-near=0 (the whole disc): the same fraction of light at AB 6-28' '
	for m in 6 10 14 18 20 22 28; do
		one $m 2044.5 2044.5 siaf --set psf-halo-near=0 >> ratios.disc || return 1
	done &&
	"$PY" -c "
v = [float(l) for l in open(\"ratios.disc\")]
w = [float(l) for l in open(\"ratios.2044.5.2044.5.siaf\")]
print(v, w)
assert max(v) / min(v) - 1 <= 0.002
assert max(abs(a / b - 1) for a, b in zip(v, w)) <= 1e-3
"
'

test_expect_success 'psf-halo-near: a bright star within 0.11 sigma of the whole disc in every pixel' '
	for m in 12 15 17; do
		printf "x,y,flux\n2044.3,2044.6,$m\n" > b$m.csv &&
		for f in 0 1; do
			"$WFS" --filter F129 --sca 1 --exptime 139.8 --flux-unit abmag \
				--set psf-halo-near=$f --report b$m-$f.json -o b$m-$f.fits b$m.csv || return 1
		done &&
		"$PY" -c "
import json
import numpy as np
from astropy.io import fits
sig = float(json.load(open(\"b$m-1.json\"))[\"error_budget\"][\"pixel_sigma\"])
a = fits.getdata(\"b$m-1.fits\", 1).astype(float); b = fits.getdata(\"b$m-0.fits\", 1).astype(float)
d = np.abs(a - b) / sig
print($m, \"max\", d.max(), \"pixels that differ\", (d > 0).sum(), \"sums\", a.sum() / b.sum() - 1)
assert d.max() < 0.11 and (d > 1e-9).sum() > 100
assert abs(a.sum() / b.sum() - 1) < 1e-3
" || return 1
	done
'

# An extreme factor: halo_near times the level underflows to 0 (1e-320,
# every pixel of the array's disc drawn) or passes every step (1e300,
# none drawn, all of the disc's light on the grid); either way finite
# pixels and the light of the whole disc's drawing.
test_expect_success 'psf-halo-near=1e-320 and 1e300: finite, the light kept' '
	for f in 1e-320 1e300; do
		"$WFS" --filter F129 --sca 1 --exptime 139.8 --flux-unit abmag \
			--set psf-halo-near=$f -o b12-$f.fits b12.csv || return 1
	done &&
	"$PY" -c "
import numpy as np
from astropy.io import fits
b = fits.getdata(\"b12-0.fits\", 1).astype(float)
for f in (\"1e-320\", \"1e300\"):
    a = fits.getdata(\"b12-%s.fits\" % f, 1).astype(float)
    print(f, \"sums\", a.sum() / b.sum() - 1, \"peak\", a.max() / b.max() - 1)
    assert np.isfinite(a).all() and abs(a.sum() / b.sum() - 1) < 1e-3
    assert abs(a.max() / b.max() - 1) < 1e-3
"
'

test_expect_success 'psf-halo-near: the same bytes with one thread and another tile size' '
	"$PY" -c "
import numpy as np
r = np.random.default_rng(11)
n = 3000
x = r.uniform(1, 4088, n); y = r.uniform(1, 4088, n); m = r.uniform(13, 24, n)
np.savetxt(\"mixb.csv\", np.c_[x, y, m], fmt=\"%.3f\", delimiter=\",\", header=\"x,y,flux\", comments=\"\")
" &&
	"$WFS" --filter F129 --sca 1 --exptime 139.8 --flux-unit abmag -o mixb2.fits mixb.csv &&
	"$WFS" --filter F129 --sca 1 --exptime 139.8 --flux-unit abmag --threads 1 --tile 300 \
		--chunk 1000 -o mixb1.fits mixb.csv &&
	"$PY" -c "
import numpy as np
from astropy.io import fits
a = fits.getdata(\"mixb2.fits\", 1); b = fits.getdata(\"mixb1.fits\", 1)
assert np.array_equal(a, b), np.abs(a - b).max()
"
'

test_expect_success 'psf-halo-near: a negative value is refused, naming the key' '
	test_must_fail --status 1 "$WFS" --filter F129 --sca 1 --set psf-halo-near=-1 \
		-o bad.fits one.csv 2>err &&
	grep "psf-halo-near" err && ! test -e bad.fits
'

test_expect_success 'psf-diffuse-cell: a bad value is refused, naming the key' '
	test_must_fail --status 1 "$WFS" --filter F129 --sca 1 --set psf-diffuse-cell=20 \
		-o bad.fits one.csv 2>err &&
	grep "psf-diffuse-cell" err && ! test -e bad.fits
'

test_done
