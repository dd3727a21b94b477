#!/bin/sh
# Catalogs in romanisim's convention: its columns read as romanisim means
# them (maggies per filter column, half_light_radius in arcsec, pa on the
# sky east of north, ba, type PSF/SER) give the image of the equivalent
# wfiscene catalog, and --set placed=romanisim writes a list that reads
# back to the same image.
. "$(dirname "$0")/lib.sh"
require_python

# STIPS's geometry: square pixels, so that an angle on the sky and one on
# the detector are the same angle.  (In the SIAF geometry a galaxy takes
# the shape of the local pixels, see wfiscene-catalog(5); t4103 checks it.)
POINT="--geometry stips --filter F158 --ra 270 --dec 66 --pa 20"

cat > rom.ecsv <<'EOF'
# %ECSV 1.0
# ---
# datatype:
# - {name: ra, datatype: float64}
# - {name: dec, datatype: float64}
# - {name: type, datatype: string}
# - {name: n, datatype: float64}
# - {name: half_light_radius, datatype: float64}
# - {name: pa, datatype: float64}
# - {name: ba, datatype: float64}
# - {name: F087, datatype: float64}
# - {name: F158, datatype: float64}
# schema: astropy-2.0
ra dec type n half_light_radius pa ba F087 F158
270.0000 66.0000 PSF -1.0 0.0 0.0 1.0 1e-9 2.97e-10
270.0200 66.0100 SER 1.6 0.6 165.6 0.9 1e-9 1.80e-09
269.9800 65.9900 SER 3.6 0.4 71.5 0.7 1e-9 3.35e-09
270.0500 66.0400 SER 1.0 1.1 300.0 0.3 1e-9 1.61e-09
269.9500 65.9600 ser 0.8 0.3 4.3 1.0 1e-9 9.99e-10
EOF

# The wfiscene catalog of the same sources, written independently: AB mag
# from maggies, re in 0.11" pixels along the major axis (romanisim's
# half_light_radius is the circularised sqrt(a b): GalSim's shear keeps
# the area, so re = half_light_radius / sqrt(ba)), phi = pa minus the position angle of
# the detector's +y axis at the source, read from the image's own WCS.
cat > equiv.py <<'PY'
import math, sys
from astropy.io import fits
from astropy.table import Table
from astropy.wcs import WCS
t = Table.read(sys.argv[1], format="ascii.ecsv")
w = WCS(fits.open(sys.argv[2])[1].header)
print("ra,dec,mag,type,n,re,phi,ratio")
for r in t:
    (x0, x1), (y0, y1) = zip(*w.all_world2pix([[r["ra"], r["dec"]],
                                                [r["ra"], r["dec"] + 1e-4]], 0))
    north = math.degrees(math.atan2(x1 - x0, y1 - y0))
    kind = "point" if r["type"].upper() == "PSF" else "sersic"
    print("%.10f,%.10f,%.15g,%s,%.15g,%.15g,%.15g,%.15g" % (
        r["ra"], r["dec"], -2.5 * math.log10(r["F158"]), kind, r["n"],
        r["half_light_radius"] / 0.11 / math.sqrt(r["ba"]), r["pa"] - north, r["ba"]))
PY

# Largest pixel difference relative to the image's peak, over all HDUs.
cat > diff.py <<'PY'
import sys
import numpy as np
from astropy.io import fits
a, b = fits.open(sys.argv[1]), fits.open(sys.argv[2])
worst = 0.0
for ha, hb in zip(a, b):
    if ha.data is None:
        continue
    d = np.abs(ha.data.astype(float) - hb.data.astype(float)).max()
    worst = max(worst, d / np.abs(ha.data).max())
print("%.3g" % worst)
sys.exit(not worst < float(sys.argv[3]))
PY

test_expect_success 'a romanisim catalog draws its stars and galaxies' '
	"$WFS" $POINT -o rom.fits rom.ecsv &&
	fitsinfo rom.fits > info && test_grep "^WFI01 " info
'
test_expect_success 'it gives the image of the equivalent wfiscene catalog' '
	"$PY" equiv.py rom.ecsv rom.fits > equiv.csv &&
	"$WFS" $POINT -o equiv.fits equiv.csv &&
	"$PY" diff.py rom.fits equiv.fits 1e-7
'
test_expect_success 'its pa is on the sky: turning the pointing turns the galaxies with it' '
	"$PY" equiv.py rom.ecsv rom.fits > e20.csv &&
	"$WFS" --geometry stips --filter F158 --ra 270 --dec 66 --pa 80 -o rom80.fits rom.ecsv &&
	"$PY" equiv.py rom.ecsv rom80.fits > e80.csv &&
	! cmp -s e20.csv e80.csv &&
	"$WFS" --geometry stips --filter F158 --ra 270 --dec 66 --pa 80 -o equiv80.fits e80.csv &&
	"$PY" diff.py rom80.fits equiv80.fits 1e-5
'
test_expect_success '--set placed=romanisim writes a list that reads back to the same image' '
	"$WFS" $POINT --set placed=romanisim --placed rt.ecsv -o a.fits rom.ecsv &&
	test_grep "^id,sca,x,y,ra,dec,type,n,half_light_radius,pa,ba,F158$" rt.ecsv &&
	test $(grep -c ",SER," rt.ecsv) = 4 && test $(grep -c ",PSF," rt.ecsv) = 1 &&
	"$PY" -c "from astropy.table import Table; t = Table.read(\"rt.ecsv\", format=\"ascii.ecsv\"); assert len(t) == 5" &&
	"$WFS" $POINT --set placed=romanisim --placed rt2.ecsv -o b.fits rt.ecsv &&
	"$PY" diff.py a.fits b.fits 1e-6 &&
	test_cmp rt.ecsv rt2.ecsv
'
test_expect_success 'a source on two SCAs is listed once in romanisim'"'"'s convention' '
	printf "ra,dec,type,n,half_light_radius,pa,ba,F158\n" > edge.csv &&
	"$PY" -c "
from astropy.io import fits
from astropy.wcs import WCS
w = WCS(fits.open(\"a.fits\")[1].header)
ra, dec = w.all_pix2world([[2044.0, -60.0]], 0)[0]
print(\"%.10f,%.10f,SER,1,20,0,1,1e-8\" % (ra, dec))" >> edge.csv &&
	# in the gap, 59 px off SCA 1 and 643 px off SCA 2: the default
	# sersic-noise-eps trims its reach short of SCA 2, a cut of 1 % of
	# its light keeps it on both
	"$WFS" $POINT --sca 1,2 --set sersic-noise-eps=0.01 --placed pl.csv -o /dev/null edge.csv &&
	"$WFS" $POINT --sca 1,2 --set sersic-noise-eps=0.01 --set placed=romanisim \
		--placed pr.ecsv -o /dev/null edge.csv &&
	test $(grep -c "^1," pl.csv) = 2 && test $(grep -c "^1," pr.ecsv) = 1
'
test_expect_success 'a flux column in maggies or nanomaggies is an AB magnitude' '
	printf "x,y,mag\n100,100,21.5\n" > m.csv &&
	printf "# %%ECSV 1.0\n# ---\n# delimiter: '"','"'\n# datatype:\n# - {name: x, datatype: float64}\n# - {name: y, datatype: float64}\n# - {name: flux, unit: nmgy, datatype: float64}\nx,y,flux\n100,100,%s\n" \
		$("$PY" -c "print(10 ** (-0.4 * (21.5 - 22.5)))") > n.ecsv &&
	printf "\\\\fluxunit=maggies\nx,y,flux\n100,100,%s\n" \
		$("$PY" -c "print(10 ** (-0.4 * 21.5))") > g.csv &&
	"$WFS" --filter F158 -o m.fits m.csv && "$WFS" --filter F158 -o n.fits n.ecsv &&
	"$WFS" --filter F158 -o g.fits g.csv &&
	"$PY" diff.py m.fits n.fits 1e-6 && "$PY" diff.py m.fits g.fits 1e-6
'
test_expect_success 'a romanisim catalog without the scene'"'"'s filter column is refused' '
	test_must_fail --status 1 "$WFS" --filter F129 -o out.fits rom.ecsv 2> err &&
	test_grep "rom.ecsv:.*romanisim.*no column .F129. for the scene.s filter" err &&
	test ! -e out.fits
'
test_expect_success 'romanisim'"'"'s and wfiscene'"'"'s name for one quantity: refused' '
	printf "ra,dec,F158,half_light_radius,re\n270,66,1e-9,0.3,3\n" > both.csv &&
	test_must_fail --status 1 "$WFS" $POINT -o out.fits both.csv 2> err &&
	test_grep "both .half_light_radius. (romanisim.s) and .re. (wfiscene.s)" err &&
	printf "\\\\convention=stips\nra,dec,flux\n270,66,1\n" > conv.csv &&
	test_must_fail --status 1 "$WFS" $POINT -o out.fits conv.csv 2> err &&
	test_grep "conv.csv: metadata .convention.: unknown convention .stips." err &&
	test_must_fail --status 1 "$WFS" $POINT --set placed=astropy --placed p.csv \
		-o out.fits rom.ecsv 2> err &&
	test_grep "placed=astropy: want wfiscene or romanisim" err &&
	test ! -e out.fits && test ! -e p.csv
'
test_expect_success 'a zero flux in maggies names its place' '
	printf "ra,dec,F158\n270,66,1e-9\n270,66,0\n" > zero.csv &&
	test_must_fail --status 1 "$WFS" $POINT -o out.fits zero.csv 2> err &&
	test_grep "zero.csv:3: column .f158.: flux must be positive: .0." err
'
test_done
