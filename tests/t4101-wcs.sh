#!/bin/sh
# Sources given by RA/Dec land where astropy's reading of the output header
# says they should, on every SCA, for several position angles, near the poles
# and across RA = 0/360.  --placed prints positions to 1e-4 px.
. "$(dirname "$0")/lib.sh"
require_python

# Where sources land does not depend on the PSF: a small synthetic ePSF
# grid (t3002's) spares the built-in grids of 18 SCAs (up to 36 grids to build
# in a cold cache) and gives the same --placed list.
"$PY" "$TOP/tests/flux_check.py" grid epsf.fits || exit 1

# check NAME SCAS OPTIONS: all 18 SCAs once, the layout's corners otherwise.
# The header is that of a tile-compressed output; the run that places the
# catalog is looked at only through --placed, its image thrown away
# (-o /dev/null: no gzip of 18 images, 10 s each time, for the same list).
check() {
	name=$1; scas=$2; shift 2
	test_expect_success "WCS round trip: $name" "
		: > empty.csv &&
		\"\$WFS\" --filter F129 --sca $scas --compress gzip $* -o hdr.fits empty.csv &&
		\"\$PY\" \"\$TOP/tests/wcs_check.py\" make hdr.fits 20 7 > cat.csv &&
		\"\$WFS\" --filter F129 --sca $scas --psf epsf.fits $* \
			-o /dev/null --placed placed.csv cat.csv &&
		\"\$PY\" \"\$TOP/tests/wcs_check.py\" compare cat.csv placed.csv 0.001
	"
}
check 'PA 0, all SCAs' 1-18 --ra 10 --dec 20 --pa 0
check 'PA 90, all SCAs' 1-18 --ra 10 --dec 20 --pa 90
check 'PA 217, boresight, all SCAs' 1-18 --ra 200 --dec -35 --pa 217 --pointing-ref boresight
check 'near the north pole' 1,7,15,18 --ra 45 --dec 89.9 --pa 30
check 'near the south pole' 1,7,15,18 --ra 300 --dec -89.95 --pa 300
check 'across RA 0/360' 1,7,15,18 --ra 0.05 --dec 0 --pa 10

test_expect_success 'the layout turns with PA: SCA centres rotate about WFI01' '
	: > empty.csv &&
	"$WFS" --filter F129 --sca 1,10 --compress gzip --ra 0 --dec 0 --pa 0 -o p0.fits empty.csv &&
	"$WFS" --filter F129 --sca 1,10 --compress gzip --ra 0 --dec 0 --pa 90 -o p90.fits empty.csv &&
	"$PY" -c "
from astropy.io import fits
a = [fits.getheader(\"p0.fits\", k) for k in (1, 2)]
b = [fits.getheader(\"p90.fits\", k) for k in (1, 2)]
# WFI10 sits 489 arcsec along -x of WFI01: east at PA 0, south at PA 90
d0 = ((a[1][\"CRVAL1\"] - a[0][\"CRVAL1\"]) * 3600, (a[1][\"CRVAL2\"] - a[0][\"CRVAL2\"]) * 3600)
d90 = ((b[1][\"CRVAL1\"] - b[0][\"CRVAL1\"]) * 3600, (b[1][\"CRVAL2\"] - b[0][\"CRVAL2\"]) * 3600)
assert abs(d0[0] - 488.8) < 1 and abs(d0[1]) < 1, d0
assert abs(d90[0]) < 1 and abs(d90[1] + 488.8) < 1, d90
"
'
test_done
