#!/bin/sh
# The built-in PSF on each SCA's own pixels (the SIAF geometry): every grid
# node's optical PSF seen through the SIAF's local Jacobian there, checked
# by tests/psfgrid_check.py against the SIAF XML itself: the corner plane's
# shape is the square-pixel plane's under A = J / 0.11" (to 2e-3; the pixels
# there are 0.1101 x 0.1074"), the JXX..JYY keywords are the SIAF's J, and a
# star drawn at that corner of SCA 1 changes its widths along x and y as the
# local scales predict.  --geometry stips keeps the square grid.  A galaxy
# of a romanisim catalog (pa on the sky, ba, half_light_radius in arcsec)
# drawn in the SIAF geometry has the axis ratio, orientation and size of
# its sky ellipse mapped through the local Jacobian of the image's own WCS.
. "$(dirname "$0")/lib.sh"
require_python
require_shared
SIAF=$SHARED/roman/roman_siaf.xml

test_expect_success 'wfiscene psf: the optical PSF on the SCA'"'"'s pixels, keywords say so' '
	"$WFS" psf --filter F158 --sca 1 --kind psf -o si.fits &&
	"$WFS" psf --filter F158 --sca 1 --kind psf --geometry stips -o st.fits &&
	"$PY" "$TOP/tests/psfgrid_check.py" optical "$SIAF" 1 si.fits st.fits &&
	"$PY" -c "
from astropy.io import fits
assert fits.getheader(\"si.fits\")[\"GEOMETRY\"] == \"siaf\"
assert fits.getheader(\"st.fits\")[\"GEOMETRY\"] == \"stips\"
"
'
test_expect_success 'a star at the corner of SCA 1: widths along x and y follow the SIAF scales' '
	printf "id,x,y,sca,flux\n1,20.3,20.7,1,100\n" > star.csv &&
	"$WFS" --filter F158 --sca 1 --rows 1-60 --set psf-extent=stips -o a.fits star.csv &&
	"$WFS" --filter F158 --sca 1 --rows 1-60 --set psf-extent=stips --geometry stips -o b.fits star.csv &&
	"$PY" "$TOP/tests/psfgrid_check.py" star "$SIAF" 1 20.3 20.7 si.fits st.fits a.fits b.fits
'
test_expect_success 'the grid written by wfiscene psf, read with --psf, draws the same star; a mismatch warns' '
	"$WFS" --filter F158 --sca 1 --rows 1-60 --set psf-extent=stips --psf si.fits -o c.fits star.csv &&
	"$PY" -c "
from astropy.io import fits; import numpy as np
a, c = fits.getdata(\"a.fits\", 1), fits.getdata(\"c.fits\", 1)
assert a.max() > 10 and np.array_equal(a, c), np.abs(a - c).max()
" &&
	"$WFS" --filter F158 --sca 1 --rows 1-60 --psf si.fits --geometry stips -o d.fits star.csv 2> err &&
	grep "si.fits: PSF sampled on the SIAF.s pixels, the scene.s geometry is stips" err &&
	"$WFS" --filter F158 --sca 1 --rows 1-60 --psf st.fits -o d.fits star.csv 2> err &&
	grep "st.fits: PSF sampled on square 0.11\" pixels, the scene.s geometry is siaf" err
'
test_expect_success 'a galaxy given on the sky (romanisim pa, ba) takes the shape of SCA 9'"'"'s pixels' '
	: > empty.csv &&
	"$WFS" --filter F158 --sca 9 --rows 2045-2045 -o e9.fits empty.csv &&
	"$PY" - <<-\EOT &&
	from astropy.io import fits
	from astropy.wcs import WCS
	w = WCS(fits.getheader("e9.fits", 1))
	ra, dec = w.all_pix2world([[2044, 0]], 0)[0]   # row 2045 of the SCA
	head = "# %ECSV 1.0\n# ---\n# datatype:\n" + "".join(
	    "# - {name: %s, datatype: %s}\n" % (c, "string" if c == "type" else "float64")
	    for c in "ra dec type n half_light_radius pa ba F158".split()) + \
	    "# schema: astropy-2.0\nra dec type n half_light_radius pa ba F158\n"
	for name, row in (("gal", "SER 1.0 1.0 30.0 0.3"), ("star9", "PSF -1.0 0.0 0.0 1.0")):
	    open(name + ".ecsv", "w").write(head + "%.10f %.10f %s 1e-7\n" % (ra, dec, row))
	open("radec", "w").write("%.10f %.10f\n" % (ra, dec))
	EOT
	# The shape is read from unweighted second moments, which the default
	# noise cuts of the galaxy footprint (sersic-noise-cut) and of its
	# gradient planes (sersic-moment-cut: 3e-3 of the axis ratio here)
	# would change.
	"$WFS" --filter F158 --sca 9 --set psf-extent=stips --set sersic-noise-cut=0 \
		--set sersic-moment-cut=0 --rows 1845-2245 -o gal.fits gal.ecsv &&
	"$WFS" --filter F158 --sca 9 --set psf-extent=stips --rows 1845-2245 -o star9.fits star9.ecsv &&
	read ra dec < radec &&
	"$PY" "$TOP/tests/psfgrid_check.py" galaxy gal.fits star9.fits $ra $dec 30 0.3 1.0
'
test_expect_success 'an unknown --geometry of wfiscene psf is a usage error' '
	test_must_fail "$WFS" psf --filter F158 --sca 1 --geometry square -o x.fits 2> err &&
	grep "siaf" err && test ! -e x.fits
'
test_done
