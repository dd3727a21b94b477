#!/bin/sh
# `wfiscene psf` writes the STPSF/WebbPSF gridded format: 9 planes with
# DET_YX*, NUM_PSFS, FILTER, DETECTOR, OVERSAMP, PIXELSCL, readable by
# photutils' GriddedPSFModel, and read back by wfiscene itself.
. "$(dirname "$0")/lib.sh"
require_python

test_expect_success 'F129 SCA01 ePSF grid with the STPSF keywords' '
	$WFS psf --filter F129 --sca 1 -o g.fits &&
	"$PY" - <<-\EOT
	from astropy.io import fits
	import numpy as np
	h = fits.open("g.fits")[0]
	d, k = h.data, h.header
	assert d.shape == (9, 177, 177), d.shape
	assert k["NUM_PSFS"] == 9 and k["FILTER"] == "F129"
	assert k["DETECTOR"] == "SCA01" and k["OVERSAMP"] == 4
	assert abs(k["PIXELSCL"] - 0.0275) < 1e-12 and k["WFSKIND"] == "EPSF"
	yx = [tuple(map(float, k["DET_YX%d" % i].strip("()").split(",")))
	      for i in range(9)]
	assert yx[0] == (0, 0) and yx[1] == (2048, 0) and yx[3] == (0, 2048), yx
	assert yx[8] == (4095, 4095)
	# an ePSF: samples one pixel apart hold the pixel fractions, IPC included
	s = d[4, 88::4, 88::4].sum() + d[4, 88::-4, 88::4].sum() \
	    + d[4, 88::4, 88::-4].sum() + d[4, 88::-4, 88::-4].sum() \
	    - d[4, 88, 88::4].sum() - d[4, 88, 88::-4].sum() \
	    - d[4, 88::4, 88].sum() - d[4, 88::-4, 88].sum() + d[4, 88, 88]
	assert abs(s - 0.9946) < 1e-3, s
	assert np.argmax(d[4]) == 88 * 177 + 88
	EOT
'

test_expect_success 'photutils GriddedPSFModel reads it' '
	"$PY" - <<-\EOT
	from astropy.io import fits
	from astropy.nddata import NDData
	import numpy as np
	from photutils.psf import GriddedPSFModel
	h = fits.open("g.fits")[0]
	k = h.header
	xy = []
	for i in range(k["NUM_PSFS"]):
	    y, x = map(float, k["DET_YX%d" % i].strip("()").split(","))
	    xy.append((x, y))
	nd = NDData(h.data, meta={"grid_xypos": xy, "oversampling": k["OVERSAMP"]})
	m = GriddedPSFModel(nd)
	yy, xx = np.mgrid[1000:1045, 1500:1545]
	m.x_0, m.y_0, m.flux = 1522.3, 1021.7, 1.0
	v = m(xx, yy).sum()
	assert abs(v - 0.9946) < 3e-3, v
	EOT
'

test_expect_success '--kind psf: optical planes that sum to 1' '
	$WFS psf --filter F129 --sca 1 --kind psf -o p.fits &&
	"$PY" -c "
from astropy.io import fits; import numpy as np
d = fits.getdata(\"p.fits\"); h = fits.getheader(\"p.fits\")
assert h[\"WFSKIND\"] == \"PSF\"
assert np.allclose(d.sum(axis=(1, 2)), 1, atol=1e-5), d.sum(axis=(1, 2))"
'

test_expect_success '--kind epsf-noipc: the ePSF without IPC, WFSKIND EPSFNOIPC' '
	$WFS psf --filter F129 --sca 1 --kind epsf-noipc -o n.fits &&
	"$PY" - <<-\EOT
	from astropy.io import fits
	import numpy as np
	h = fits.open("n.fits")[0]
	d, e = h.data, fits.getdata("g.fits")
	assert h.header["WFSKIND"] == "EPSFNOIPC", h.header["WFSKIND"]
	# samples one pixel apart through the centre (88 = 4 x 22): without
	# IPC they hold all the light; the IPC kernel of STIPS keeps 99.46 %
	# of it and moves some light of the centre pixel to its neighbours
	n, w = d[4, 0::4, 0::4].sum(), e[4, 0::4, 0::4].sum()
	assert abs(n - 1) < 1e-4 and abs(w - 0.9946 * n) < 1e-4, (n, w)
	assert d[4].max() > 1.05 * e[4].max(), (d[4].max(), e[4].max())
	assert np.argmax(d[4]) == 88 * 177 + 88
	EOT
'

test_expect_success 'epsf-noipc written ahead: a level-1 run builds no grid; --psf warns where IPC is twice or missing' '
	mkdir nc &&
	$WFS psf --filter F129 --sca 1 --kind epsf-noipc --cache-dir nc -o nb.fits &&
	$WFS psf --filter F129 --sca 1 --kind epsf-noipc --halo 256 --cache-dir nc -o nh.fits &&
	printf "x,y,mag\n2044.3,2044.8,16\n" > one.csv &&
	WFISCENE_CACHE=$PWD/nc "$WFS" --filter F129 --flux-unit abmag --level 1 --report r.json \
		-o l1.fits one.csv &&
	"$PY" -c "
import json; g = json.load(open(\"r.json\"))[\"psf_grids\"]
assert g[\"built\"] == 0 and g[\"loaded\"] == 2, g" &&
	"$WFS" --filter F129 --flux-unit abmag --level 1 --psf nb.fits -o l1n.fits one.csv 2> err &&
	! grep -q "IPC" err &&
	"$WFS" --filter F129 --flux-unit abmag --level 1 --psf g.fits -o l1e.fits one.csv 2> err &&
	test_grep "IPC folded in" err &&
	"$WFS" --filter F129 --flux-unit abmag --psf nb.fits -o sn.fits one.csv 2> err &&
	test_grep "warning: nb.fits: an ePSF without IPC (WFSKIND EPSFNOIPC); the scene level" err &&
	"$WFS" --filter F129 --flux-unit abmag --psf g.fits -o se.fits one.csv 2> err &&
	! grep -q "IPC" err
'

test_expect_success '--psf FILE places planes by DET_YX, not by their order' '
	"$PY" - <<-\EOT &&
	from astropy.io import fits
	h = fits.open("p.fits")[0]
	d, k = h.data, h.header
	perm = [8, 3, 5, 0, 7, 1, 6, 2, 4]
	moved = k.copy()
	for i, p in enumerate(perm):
	    moved["DET_YX%d" % i] = k["DET_YX%d" % p]
	# the planes shuffled with their positions, and (a control that must
	# change the image) shuffled with the positions left in place
	fits.PrimaryHDU(d[perm], moved).writeto("shuffled.fits")
	fits.PrimaryHDU(d[perm], k).writeto("wrong.fits")
	EOT
	printf "x,y,flux\n10,10,1000\n2044,2044,1000\n4080,3000,1000\n1000,4000,1000\n" > four.csv &&
	"$WFS" --filter F129 --psf p.fits -o a.fits four.csv &&
	"$WFS" --filter F129 --psf shuffled.fits -o b.fits four.csv &&
	"$WFS" --filter F129 --psf wrong.fits -o c.fits four.csv &&
	"$PY" -c "
from astropy.io import fits; import numpy as np
a, b, c = (fits.getdata(f, 1) for f in (\"a.fits\", \"b.fits\", \"c.fits\"))
assert a.sum() > 3000 and np.array_equal(a, b)
assert np.abs(a - c).max() > 1e-3 * a.max(), np.abs(a - c).max()"
'

test_expect_success 'the grids wfiscene psf writes draw what the built-in PSF draws' '
	printf "x,y,mag\n10,10,20\n2044.3,2044.8,19\n4080,3000,21\n1000,4000,22\n" > fm.csv &&
	"$WFS" --filter F129 -o bi.fits fm.csv &&
	"$WFS" --filter F129 --psf g.fits -o ge.fits fm.csv &&
	"$WFS" --filter F129 --psf p.fits -o gp.fits fm.csv &&
	"$PY" -c "
from astropy.io import fits; import numpy as np
a, b, c = (fits.getdata(f, 1) for f in (\"bi.fits\", \"ge.fits\", \"gp.fits\"))
assert a.max() > 100 and np.array_equal(a, b) and np.array_equal(a, c)"
'

# cfitsio's first message line often ends "... of file:", its name on
# the next: the two are joined, and no message ends in a colon.  A file
# that can be read but holds no whole FITS cube is bad input, exit 1.
test_expect_success '--psf FILE cut short or empty: exit 1, the message names it, no trailing colon' '
	head -c 20000 g.fits > cut.fits &&
	: > empty.fits &&
	for f in cut.fits empty.fits; do
		test_must_fail --status 1 "$WFS" --filter F129 --psf $f -o no.fits fm.csv \
			2> err &&
		test_grep "^wfiscene: $f: .* $f\$" err &&
		! grep -q ":\$" err &&
		! test -e no.fits || return 1
	done
'
test_expect_success '--psf FILE of another filter or SCA: a warning (not with -q)' '
	"$WFS" --filter F158 --psf p.fits -o w1.fits four.csv 2> err &&
	test_grep "warning: p.fits: PSF for filter F129, the scene.s is F158" err &&
	cp p.fits p01.fits && cp p.fits p02.fits &&
	printf "x,y,sca,flux\n100,100,1,1000\n100,100,2,1000\n" > two.csv &&
	"$WFS" --filter F129 --sca 1,2 --psf "p%02d.fits" -o w2.fits two.csv 2> err &&
	test_grep "warning: p02.fits: PSF for SCA 1 serves SCA 2" err &&
	! test_grep "p01.fits" err 2> /dev/null &&
	"$WFS" -q --filter F158 --psf p.fits -o w3.fits four.csv 2> err && ! test -s err
'

test_expect_success 'several SCAs: one file per SCA named _wfiNN' '
	$WFS psf --filter F129 --sca 1,2 -o two.fits &&
	test -f two_wfi01.fits && test -f two_wfi02.fits && ! test -f two.fits
'

test_expect_success 'a rebuild without the cache gives the same planes' '
	$WFS psf --filter F129 --sca 1 --kind psf --no-cache -o q.fits &&
	"$PY" -c "
from astropy.io import fits; import numpy as np
a = fits.getdata(\"p.fits\"); b = fits.getdata(\"q.fits\")
assert np.array_equal(a, b)"
'

test_expect_success 'bad filter, size or kind: exit 1 naming the value, no file' '
	test_must_fail --status 1 $WFS psf --filter F999 --sca 1 -o bad.fits 2>err &&
	test_grep "F999" err &&
	test_must_fail --status 1 $WFS psf --filter F129 --sca 1 --size 100 -o bad.fits 2>err &&
	test_grep "177, 353 or 705" err &&
	test_must_fail --status 1 $WFS psf --filter F129 --sca 1 --kind nope -o bad.fits 2>err &&
	test_grep "want epsf, epsf-noipc or psf, not .nope." err &&
	test_must_fail --status 1 $WFS psf --filter F129 --sca 1 --grid 1000000 -o bad.fits 2>err &&
	test_grep "grid: not an integer from 1 to 100000: .1000000." err &&
	test_must_fail --status 1 $WFS psf --filter F129 --sca 99 -o bad.fits 2>err &&
	test_must_fail --status 1 $WFS psf --filter F129 --sca 1 2>err &&
	! test -f bad.fits
'

test_expect_success 'an unwritable output: exit 2, no temporary left' '
	mkdir ro && chmod 555 ro &&
	if [ "$(id -u)" = 0 ]; then out=/proc/nonexistent/x.fits; else out=ro/x.fits; fi &&
	test_must_fail --status 2 $WFS psf --filter F129 --sca 1 -o $out 2>err &&
	test_grep "x.fits" err &&
	test -z "$(ls -A ro)"
'

if have_shared; then
test_expect_success 'the STPSF sample of STIPS reads as a 3x3 grid' '
	"$PY" -c "
from astropy.io import fits
h = fits.getheader(\"$SHARED/stips-psf/psf_WFI_2.0.0_F129_wfi01.fits\")
assert h[\"NUM_PSFS\"] == 9"
'
if [ -x "$BUILD/tests/psf_grid" ]; then
test_expect_success 'psf_grid reads the STPSF sample: shape, nodes, sums, ePSF' '
	WFS_SHARED=$SHARED "$BUILD/tests/psf_grid" > out 2>&1 &&
	! grep -e "^not ok" -e "# skip" out || { cat out; false; }
'
else
test_skip 'psf_grid reads the STPSF sample' "$BUILD/tests/psf_grid is not built (make unit)"
fi
else
test_skip 'the STPSF sample of STIPS reads as a 3x3 grid' '../shared is absent'
test_skip 'psf_grid reads the STPSF sample' '../shared is absent'
fi

test_done
