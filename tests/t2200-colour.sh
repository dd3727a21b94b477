#!/bin/sh
# Colour: a source's spectrum (teff, beta or an AB colour) in its counts.
#
#  - a row without a spectrum, and a flat f_nu (beta 0), keep the bytes of
#    a catalog without spectrum columns;
#  - an AB magnitude or a flux in Jy is f_nu at the filter's pivot: its
#    counts are the flat source's times sum(A S / lam) / sum(A / lam),
#    computed here independently from data/throughput.tsv; counts/s are
#    counts whatever the spectrum;
#  - a colour gives the slope beta = colour / (2.5 log10(l1 / l2));
#  - bad spectra are refused naming file, row and column, exit 1, no file.
. "$(dirname "$0")/lib.sh"
require_python

cat > plain.csv <<EOF
x,y,flux
1000,1000,18
1200,1300,19
EOF
cat > spec.csv <<EOF
x,y,flux,teff,beta,color_f106_f158
1000,1000,18,,,
1200,1300,19,,,
EOF
cat > beta0.csv <<EOF
x,y,flux,teff,beta,color_f106_f158
1000,1000,18,,,
1200,1300,19,,0,
EOF
test_expect_success 'rows without a spectrum: the same bytes as no spectrum columns' '
	"$WFS" --filter F146 --flux-unit abmag --placed p0.csv -o plain.fits plain.csv &&
	"$WFS" --filter F146 --flux-unit abmag -o spec.fits spec.csv &&
	cmp plain.fits spec.fits
'
test_expect_success 'a flat f_nu (beta 0) keeps the counts of the AB zeropoint' '
	"$WFS" --filter F146 --flux-unit abmag --placed pflat.csv -o beta0.fits beta0.csv &&
	test_cmp p0.csv pflat.csv
'

# the colour term from the throughput table, by the sums spectrum.h states
cat > term.py <<'EOF'
import math, sys
filt, sca, kind, v = sys.argv[1], int(sys.argv[2]), sys.argv[3], float(sys.argv[4])
piv = {}
for line in open(sys.argv[5] + "/filters.tsv"):
    f = line.rstrip("\n").split("\t")
    if f[0].startswith("F"):
        piv[f[0]] = float(f[4])
lp = piv[filt]
def fnu(l):
    if kind == "beta":
        return (l / lp) ** -v
    c2 = 14387.77
    return (lp / l) ** 3 * math.expm1(c2 / (lp * v)) / math.expm1(c2 / (l * v))
sa = sas = 0
for line in open(sys.argv[5] + "/throughput.tsv"):
    f = line.split()
    if f and f[0] == filt:
        l, a = float(f[1]), float(f[1 + sca])
        sa += a / l
        sas += a * fnu(l) / l
print("%.9g" % (sas / sa))
EOF
cat > one.csv <<EOF
x,y,flux,teff
500,500,20,3000
600,600,20,30000
EOF
test_expect_success 'AB magnitudes through a blackbody: the flat counts times the colour term' '
	"$WFS" --filter F146 --sca 7 --flux-unit abmag --placed p.csv -o one.fits one.csv &&
	"$WFS" --filter F146 --sca 7 --flux-unit abmag --placed flat.csv -o flat.fits plain.csv &&
	flat=$(sed -n 2p flat.csv | cut -d, -f5) &&
	k3=$("$PY" term.py F146 7 teff 3000 "$TOP/data") &&
	k30=$("$PY" term.py F146 7 teff 30000 "$TOP/data") &&
	got3=$(sed -n 2p p.csv | cut -d, -f5) && got30=$(sed -n 3p p.csv | cut -d, -f5) &&
	say "flat $flat, 3000 K x$k3 -> $got3, 30000 K x$k30 -> $got30" &&
	"$PY" -c "
f, a, b, ka, kb = map(float, \"$flat $got3 $got30 $k3 $k30\".split())
# flat is the 18 mag row: the 20 mag rows are 10^-0.8 of it
f *= 10 ** -0.8
assert abs(a / (f * ka) - 1) < 2e-5 and abs(b / (f * kb) - 1) < 2e-5, (a, f * ka, b, f * kb)
assert ka < 0.95 < 1.1 < kb
"
'

cat > jy.csv <<EOF
x,y,flux,beta
500,500,1e-5,2
600,600,1e-5,-2
700,700,1e-5,0
EOF
test_expect_success 'Jy through a power law; counts/s keep their value' '
	"$WFS" --filter F129 --flux-unit jy --placed pj.csv -o jy.fits jy.csv &&
	kb=$("$PY" term.py F129 1 beta 2 "$TOP/data") && kr=$("$PY" term.py F129 1 beta -2 "$TOP/data") &&
	"$PY" -c "
import csv
r = [float(x[\"flux\"]) for x in csv.DictReader(open(\"pj.csv\"))]
assert abs(r[0] / r[2] / $kb - 1) < 2e-5 and abs(r[1] / r[2] / $kr - 1) < 2e-5, (r, $kb, $kr)
" &&
	"$WFS" --filter F129 --placed pc.csv -o c.fits jy.csv &&
	test "$(cut -d, -f5 pc.csv | sort -u | sed -n 1p)" = "1e-05"
'

cat > colour.csv <<EOF
x,y,flux,color_f106_f158
500,500,20,-0.5
EOF
cat > beta.csv <<EOF
x,y,flux,beta
500,500,20,BETA
EOF
test_expect_success 'an AB colour is the power law it implies' '
	beta=$("$PY" -c "
import math
p = {}
for l in open(\"$TOP/data/filters.tsv\"):
    f = l.split(\"\t\")
    if f[0].startswith(\"F\"): p[f[0]] = float(f[4])
print(repr(-0.5 / (2.5 * math.log10(p[\"F106\"] / p[\"F158\"]))))") &&
	say "color_f106_f158 = -0.5 is beta $beta" &&
	sed "s/BETA/$beta/" beta.csv > b.csv &&
	"$WFS" --filter F146 --flux-unit abmag --placed pa.csv -o a.fits colour.csv &&
	"$WFS" --filter F146 --flux-unit abmag --placed pb.csv -o b.fits b.csv &&
	test_cmp pa.csv pb.csv
'

test_expect_success 'colour-counts=band: the spectrum leaves the counts alone' '
	"$WFS" --filter F146 --flux-unit abmag --set colour-counts=band --placed pband.csv \
		-o band.fits one.csv &&
	printf "x,y,flux\n500,500,20\n" > flat20.csv &&
	"$WFS" --filter F146 --flux-unit abmag --placed pf20.csv -o f20.fits flat20.csv &&
	test "$(cut -d, -f5 pband.csv | sed 1d | sort -u)" = "$(sed -n 2p pf20.csv | cut -d, -f5)" &&
	test_must_fail --status 1 "$WFS" --filter F146 --set colour-counts=x -o x.fits one.csv 2>err &&
	test_grep "colour-counts: expected pivot or band, not .x." err && test ! -e x.fits
'

# The PSF of a source's spectrum: a red (3000 K) and a blue (30000 K) star
# of the same counts/s in F146, drawn from the spectral classes, against
# each star drawn alone with the exact ePSF grid of its own spectrum
# (wfiscene psf --teff, given as --psf, blended per source as the colour
# stars are): within 1e-3 of the peak, with all their light, the red one
# wider.
cat > rb.csv <<EOF
x,y,flux,teff
1001,1001,2000,3000
1501,1501,2000,30000
EOF
printf 'x,y,flux\n1001,1001,2000\n' > red.csv
printf 'x,y,flux\n1501,1501,2000\n' > blue.csv
cat > widths.py <<'EOF'
import sys
import numpy as np
from astropy.io import fits
img = fits.open(sys.argv[1])[1].data.astype(float)
red = fits.open(sys.argv[2])[1].data.astype(float)
blue = fits.open(sys.argv[3])[1].data.astype(float)
ref = red + blue
peak = ref.max()
d = np.abs(img - ref).max() / peak
def width(im, c):
    y, x = np.mgrid[c - 6:c + 7, c - 6:c + 7]
    s = im[c - 6:c + 7, c - 6:c + 7]
    return np.sqrt((s * ((x - c) ** 2 + (y - c) ** 2)).sum() / s.sum()), s.max()
wr, pr = width(img, 1000)
wb, pb = width(img, 1500)
print("# max |colour - exact| %.2e of the peak; r.m.s. radius within 6 px: red %.4f, "
      "blue %.4f px (ratio %.4f); peak pixel red %.2f, blue %.2f" % (d, wr, wb, wr / wb, pr, pb))
print("# light: colour %.6f, exact %.6f" % (img.sum(), ref.sum()))
assert d < 1e-3, d
assert wr / wb > 1.02 and pr < 0.97 * pb
assert abs(img.sum() / ref.sum() - 1) < 1e-4
EOF
test_expect_success 'a red and a blue star of the same counts: drawn with the ePSF of each spectrum' '
	"$WFS" --filter F146 --set psf-extent=stips -o rb.fits rb.csv &&
	"$WFS" psf --filter F146 --sca 1 --teff 3000 -o t3000.fits &&
	"$WFS" psf --filter F146 --sca 1 --teff 30000 -o t30000.fits &&
	"$WFS" --filter F146 --psf t3000.fits --set psf-blend=source --set psf-extent=stips \
		-o red.fits red.csv &&
	"$WFS" --filter F146 --psf t30000.fits --set psf-blend=source --set psf-extent=stips \
		-o blue.fits blue.csv &&
	"$PY" widths.py rb.fits red.fits blue.fits
'

# psf-colour-classes: with 3 classes a family instead of F146's 4, the
# report lists them (a family's ends unchanged), and the red star (its
# row of rb.csv alone) is still within 1e-3 of the peak of its exact ePSF
# with all its light (F146's 3 classes interpolate to 2.6e-4 of the peak
# for blackbodies, BENCHMARKS.md "Colour"); 1, 17 and a word are refused,
# exit 1, nothing written.
printf 'x,y,flux,teff\n1001,1001,2000,3000\n' > red3.csv
test_expect_success 'psf-colour-classes=3: three classes a family, the star within 1e-3' '
	"$WFS" --filter F146 --set psf-colour-classes=3 --set psf-extent=stips \
		--report r3.json -o red3.fits red3.csv &&
	"$PY" -c "
import json, numpy as np
from astropy.io import fits
c = json.load(open(\"r3.json\"))[\"psf_grids\"][\"spectral_classes\"]
assert len(c) == 6 and c[0][\"beta\"] == 3 and c[2][\"beta\"] == -3, c
assert c[3][\"teff\"] == 50000 and c[5][\"teff\"] == 2500, c
assert [k[\"class\"] for k in c if k[\"grids\"]] == [4, 5], c
a = fits.open(\"red3.fits\")[1].data.astype(float)
b = fits.open(\"red.fits\")[1].data.astype(float)
d = np.abs(a - b).max() / b.max()
print(\"# 3 classes: max |3000 K - exact| %.2e of the peak; light %.6f %.6f\" % (d, a.sum(), b.sum()))
assert d < 1e-3, d
assert abs(a.sum() / b.sum() - 1) < 1e-4
" &&
	for v in 1 17 x; do
		test_must_fail --status 1 "$WFS" --filter F146 --set psf-colour-classes=$v \
			-o bad3.fits red3.csv 2>err &&
		test_grep "psf-colour-classes" err && test ! -e bad3.fits || exit 1
	done
'

# Colour sources in blended cells (psf-colour-steps, default 1) against
# each blended at the source (0): 400 stars of random temperature and
# slope, faint and bright; the same light for each (so a faint and a
# bright star keep the same fraction of theirs), the images within 1e-3
# of the brightest peak, and the same bytes on 1 and 3 threads.
"$PY" - > field.csv <<'EOF'
import random
random.seed(3)
print("x,y,flux,teff")
for i in range(400):
    t = "%.0f" % (2500 * 20 ** random.random()) if i % 4 else ""
    print("%.3f,%.3f,%.4g,%s" % (random.uniform(20, 4068), random.uniform(20, 4068),
                                 10 ** random.uniform(0, 4), t))
EOF
# FILE against src.fits (each star blended at the source): within 1e-3 of
# the brightest peak, the same light to 1e-5.
near_per_source() {
	"$PY" - "$1" <<-\EOF
	import sys, numpy as np
	from astropy.io import fits
	a = fits.open(sys.argv[1])[1].data.astype(float)
	b = fits.open("src.fits")[1].data.astype(float)
	d = np.abs(a - b).max() / b.max()
	print("# %s: max |cells - per source| %.2e of the peak; light %.6f %.6f"
	      % (sys.argv[1], d, a.sum(), b.sum()))
	assert d < 1e-3, d
	assert abs(a.sum() / b.sum() - 1) < 1e-5, (a.sum(), b.sum())
	EOF
}
test_expect_success 'colour cells: the same light and within 1e-3 of the peak of per-source blends' '
	"$WFS" --filter F146 -o cells.fits field.csv &&
	"$WFS" --filter F146 --set psf-colour-steps=0 -o src.fits field.csv &&
	near_per_source cells.fits &&
	"$WFS" --filter F146 --threads 1 -o t1.fits field.csv &&
	"$WFS" --filter F146 --threads 3 --tile 300 -o t3.fits field.csv &&
	"$PY" "$TOP/tests/fitsinfo.py" --same t1.fits t3.fits &&
	"$PY" "$TOP/tests/fitsinfo.py" --same t1.fits cells.fits
'

# Faint stars (drawn from the colour cells) half-way between the ePSF's
# samples (1/8 pixel off a pixel's centre, where a bilinear read errs
# most), at temperatures across the classes: the pair's difference read
# with the cell's own Keys taps keeps each within 5e-4 of the peak of the
# per-source blend (when the difference was read bilinearly, before
# 2026-11-29: 1.75e-3).
"$PY" - > centred.csv <<'EOF'
print("x,y,flux,teff")
for i, t in enumerate((2500, 3000, 4200, 5800, 8000, 11345, 15000, 20000, 30000, 45000)):
    for j in range(4):
        print("%.3f,%.3f,20,%d" % (300.125 + 350 * i, 400.125 + 900 * j, t * (1 + 0.07 * j)))
EOF
test_expect_success 'colour cells: stars between the ePSF samples within 5e-4 of per-source peaks' '
	"$WFS" --filter F146 -o cc.fits centred.csv &&
	"$WFS" --filter F146 --set psf-colour-steps=0 -o cs.fits centred.csv &&
	"$PY" - > out <<-\EOF &&
	import numpy as np
	from astropy.io import fits
	a = fits.open("cc.fits")[1].data.astype(float)
	b = fits.open("cs.fits")[1].data.astype(float)
	d = np.abs(a - b).max() / b.max()
	print("max |cells - per source| %.2e of the peak" % d)
	assert d < 5e-4, d
	EOF
	say "$(cat out)"
'

# Pair cells (psf-colour-steps above 1): a cell between two classes takes
# its pair's difference from the lower class's cell, which threads may
# make and complete at once (point_poly.c, class_add).
test_expect_success 'psf-colour-steps=4: within 1e-3 of the per-source blends, the same bytes on 1 and 3 threads' '
	"$WFS" --filter F146 --set psf-colour-steps=4 --threads 1 -o p1.fits field.csv &&
	"$WFS" --filter F146 --set psf-colour-steps=4 --threads 3 --tile 300 -o p3.fits field.csv &&
	"$PY" "$TOP/tests/fitsinfo.py" --same p1.fits p3.fits &&
	near_per_source p1.fits &&
	rm p1.fits p3.fits
'
# The core of a colour star (its nearer class's cell and the other's,
# with Keys' taps or bilinear ones) in each vector width and in C.
test_expect_success 'colour stars: the AVX-512, AVX2 and plain loops give the same bytes' '
	for interp in core bilinear; do
		"$WFS" --filter F146 --set psf-interp=$interp -o w.fits field.csv &&
		WFISCENE_NO_SIMD=avx512 "$WFS" --filter F146 --set psf-interp=$interp -o w2.fits field.csv &&
		WFISCENE_NO_SIMD=1 "$WFS" --filter F146 --set psf-interp=$interp -o w0.fits field.csv &&
		cmp w.fits w2.fits && cmp w.fits w0.fits || return 1
	done &&
	rm w.fits w2.fits w0.fits
'

# Spectra beyond the classes' span take the end class: the coolest and
# hottest temperatures, slopes beyond the colour tables (|beta| > 8,
# summed per row); every star drawn, finite, with its ePSF's light.
cat > extreme.csv <<EOF
x,y,flux,teff,beta
300,300,18,1000,
600,600,18,100000,
900,900,18,,-20
1200,1200,18,,20
1500,1500,18,,8
1800,1800,18,,-8
EOF
test_expect_success 'extreme spectra: drawn with the end classes, all their light' '
	"$WFS" --filter F146 --flux-unit abmag --placed pe.csv --report re.json -o ext.fits extreme.csv &&
	test "$(sed 1d pe.csv | wc -l)" = 6 &&
	"$WFS" --filter F146 --flux-unit abmag --set psf-colour-steps=0 -o ext0.fits extreme.csv &&
	"$PY" -c "
import csv, json, numpy as np
from astropy.io import fits
a = fits.open(\"ext.fits\")[1].data.astype(float)
b = fits.open(\"ext0.fits\")[1].data.astype(float)
assert np.isfinite(a).all() and abs(a.sum() / b.sum() - 1) < 1e-5, (a.sum(), b.sum())
f = [float(r[\"flux\"]) for r in csv.DictReader(open(\"pe.csv\"))]
assert all(np.isfinite(f)) and f[2] > f[5] > 0 and f[3] > f[4] > 0, f
"
'

# Galaxies are convolved with the blend of their spectrum's two classes,
# rounded to 1/psf-colour-galaxy-steps (32): a compact galaxy of 3000 K (6.40
# of the way in F146's classes) against the same galaxy drawn with the
# exact grid of 3000 K (--psf), with the nearest class alone (steps 0)
# and with the default spectrum's.
cat > gal.csv <<EOF
x,y,flux,type,n,re,phi,ratio,teff
1001,1001,2000,sersic,1,1.5,30,0.7,3000
EOF
printf 'x,y,flux,type,n,re,phi,ratio\n1001,1001,2000,sersic,1,1.5,30,0.7\n' > gal0.csv
test_expect_success 'a galaxy with a spectrum: convolved with the blend of its classes' '
	"$WFS" --filter F146 --sersic precise -o gc.fits gal.csv &&
	"$WFS" --filter F146 --sersic precise --set psf-colour-galaxy-steps=16 \
		-o g16.fits gal.csv &&
	"$WFS" --filter F146 --sersic precise --set psf-colour-galaxy-steps=0 \
		-o gn.fits gal.csv &&
	"$WFS" --filter F146 --sersic precise --psf t3000.fits -o ge.fits gal0.csv &&
	"$WFS" --filter F146 --sersic precise -o gd.fits gal0.csv &&
	"$PY" -c "
import numpy as np
from astropy.io import fits
c, c16, n, e, d = (fits.open(f)[1].data.astype(float)
                   for f in (\"gc.fits\", \"g16.fits\", \"gn.fits\", \"ge.fits\", \"gd.fits\"))
pk = e.max()
dc, d16, dn, dd = (np.abs(a - e).max() / pk for a in (c, c16, n, d))
print(\"# galaxy: blend 1/32 %.2e, 1/16 %.2e, nearest class %.2e, default spectrum %.2e \"
      \"of the peak\" % (dc, d16, dn, dd))
assert dc < 2e-4 and d16 < 1.5e-3 and dn < 0.5 * dd and d16 < 0.1 * dn
for a in (c, c16, n):
    assert abs(a.sum() / e.sum() - 1) < 1e-3
"
'

test_expect_success 'psf-colour-galaxy-steps: refused beyond 0 to 64' '
	test_must_fail --status 1 "$WFS" --filter F146 --sersic precise \
		--set psf-colour-galaxy-steps=65 -o gx.fits gal.csv 2>err &&
	test_grep "psf-colour-galaxy-steps: expected a whole number 0 to 64" err &&
	test ! -e gx.fits
'

test_expect_success 'wfiscene psf --report: the classes, and the class of a spectrum' '
	"$WFS" psf --filter F146 --sca 1,9 --report --teff 3000 > rep.tsv &&
	test "$(grep -c "^1	[0-9]	" rep.tsv)" = 8 && test "$(grep -c "^9	[0-9]	" rep.tsv)" = 8 &&
	grep "^1	0	beta 3	" rep.tsv && grep "^1	7	teff 2500	" rep.tsv &&
	grep "^1	6\.[0-9]*	teff 3000	" rep.tsv &&
	"$WFS" psf --filter F146 --sca 1 --report --classes 3 > rep3.tsv &&
	test "$(grep -c "^1	[0-9]	" rep3.tsv)" = 6 &&
	test_must_fail --status 1 "$WFS" psf --filter F146 --sca 1 --teff 900 -o x.fits 2>err &&
	test_grep "teff: want a temperature from 1000 to 100000 K" err && test ! -e x.fits
'

test_expect_success 'the JSON report lists the spectral classes and the grids drawn with' '
	"$WFS" --filter F146 --report r.json -o rb2.fits rb.csv &&
	"$PY" -c "
import json
c = json.load(open(\"r.json\"))[\"psf_grids\"][\"spectral_classes\"]
assert len(c) == 8 and c[0][\"beta\"] == 3 and c[7][\"teff\"] == 2500, c
used = [k[\"class\"] for k in c if k[\"grids\"]]
assert set(used) <= {4, 5, 6, 7} and len(used) >= 2, used
print(\"# classes drawn with:\", used)
"
'

# refused NAME MESSAGE: the catalog NAME.csv is refused with MESSAGE, exit
# 1, nothing written
refused() {
	name=$1 msg=$2
	test_expect_success "refused: $name" '
		test_must_fail --status 1 "$WFS" --filter F146 --flux-unit abmag -o out.fits $name.csv 2>err &&
		grep -F -e "$msg" err >/dev/null || { cat err; false; } &&
		test ! -e out.fits && test -z "$(ls -A | grep "^out.fits")"
	'
}
printf 'x,y,flux,teff\n1,1,20,5000\n1,1,20,999\n' > cold.csv
refused cold "cold.csv:3: column 'teff': 999 K is outside 1000 to 100000 K"
printf 'x,y,flux,teff\n1,1,20,100001\n' > hot.csv
refused hot "hot.csv:2: column 'teff': 100001 K is outside 1000 to 100000 K"
printf 'x,y,flux,beta\n1,1,20,1\n1,1,20,inf\n' > inf.csv
refused inf "inf.csv:3: column 'beta': not a finite number: 'inf'"
printf 'x,y,flux,color_f106_f999\n1,1,20,0.5\n' > unk.csv
refused unk "unk.csv:1: column 'color_f106_f999': want color_F1_F2 (or colour_F1_F2) with two different filters"
printf 'x,y,flux,color_f158_f158\n1,1,20,0.5\n' > same.csv
refused same "same.csv:1: column 'color_f158_f158': want color_F1_F2"
printf 'x,y,flux,teff,beta\n1,1,20,5000,\n1,1,20,5000,1\n' > both.csv
refused both "both.csv:3: columns 'teff' and 'beta': give one spectrum per row"
printf 'x,y,flux,color_f106_f158\n1,1,20,1e308\n' > huge.csv
refused huge "huge.csv:2: column 'color_f106_f158': not a finite slope: '1e308'"
printf 'x,y,flux,beta\n1,1,20,20\n1,1,20,-200\n' > steep.csv
refused steep "steep.csv:3: column 'beta': '-200' gives the slope beta = -200, steeper than +-20"
printf 'x,y,flux,color_f106_f158\n1,1,20,9.5\n' > steepc.csv
refused steepc "steepc.csv:2: column 'color_f106_f158': '9.5' gives the slope beta = -21.92"
# the slope in full: 20.0001 is not "20"
printf 'x,y,flux,beta\n1,1,20,20.0001\n' > steep2.csv
refused steep2 "steep2.csv:2: column 'beta': '20.0001' gives the slope beta = 20.0001, steeper"
# the British spelling is the same column
printf 'x,y,flux,colour_f106_f158\n1,1,20,30\n' > steepb.csv
refused steepb "steepb.csv:2: column 'colour_f106_f158': '30' gives the slope beta = -69.2"
test_expect_success 'colour_F1_F2 reads as color_F1_F2; colour_index is a column of ours' '
	printf "x,y,flux,colour_f106_f158\n500,500,20,-0.5\n" > cb.csv &&
	printf "x,y,flux,color_f106_f158\n500,500,20,-0.5\n" > ca.csv &&
	"$WFS" --filter F146 --flux-unit abmag -o cb.fits cb.csv &&
	"$WFS" --filter F146 --flux-unit abmag -o ca.fits ca.csv && cmp ca.fits cb.fits &&
	printf "x,y,flux,colour_index\n500,500,20,0.7\n" > ci.csv &&
	printf "x,y,flux\n500,500,20\n" > cn.csv &&
	"$WFS" --filter F146 --flux-unit abmag -o ci.fits ci.csv &&
	"$WFS" --filter F146 --flux-unit abmag -o cn.fits cn.csv && cmp ci.fits cn.fits
'


# the steepest slopes allowed give finite counts: the flat counts times
# the colour term summed here from the throughput table (term.py)
cat > edge.csv <<EOF
x,y,flux,beta
500,500,20,20
600,600,20,-20
700,700,20,0
EOF
test_expect_success 'beta 20 and -20: finite counts, the colour term exact' '
	"$WFS" --filter F146 --flux-unit jy --placed pe.csv -o edge.fits edge.csv &&
	kb=$("$PY" term.py F146 1 beta 20 "$TOP/data") && kr=$("$PY" term.py F146 1 beta -20 "$TOP/data") &&
	say "beta 20 x$kb, beta -20 x$kr" &&
	"$PY" -c "
import csv, math
r = [float(x[\"flux\"]) for x in csv.DictReader(open(\"pe.csv\"))]
assert all(math.isfinite(v) and v > 0 for v in r), r
assert abs(r[0] / r[2] / $kb - 1) < 2e-5 and abs(r[1] / r[2] / $kr - 1) < 2e-5, (r, $kb, $kr)
"
'

test_done
