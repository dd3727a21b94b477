#!/bin/sh
# The default (SIAF) geometry against an independent implementation of the
# SIAF chain written in tests/siaf_check.py from the SIAF's definitions: it
# reads ../shared/roman/roman_siaf.xml itself, takes random pixels over all
# 18 SCAs to the sky, and wfiscene must place those rows within 1e-3 px of
# where they came from and back on the sky within 0.1 mas; astropy's
# reading of the TAN-SIP headers (forward, AP/BP and its own iterative
# inverse) within 0.005 px of the same chain; the background of every
# pixel in proportion to its area on the sky.  --pa is the position angle
# of the reference aperture's +y_idl (checked by siaf_check.py itself).
. "$(dirname "$0")/lib.sh"
require_python
require_shared
SIAF=$SHARED/roman/roman_siaf.xml

check() {
	name=$1; ra=$2; dec=$3; pa=$4; ref=$5; seed=$6
	test_expect_success "SIAF chain: $name" "
		\"\$PY\" \"\$TOP/tests/siaf_check.py\" make \"\$SIAF\" $ra $dec $pa $ref 12 $seed \
			> cat.csv &&
		\"\$WFS\" --filter F129 --sca 1-18 --psf \"\$PSF\" \
			--ra $ra --dec $dec --pa $pa --pointing-ref $ref \
			-o img.fits --placed placed.csv cat.csv &&
		\"\$PY\" \"\$TOP/tests/siaf_check.py\" compare \"\$SIAF\" $ra $dec $pa $ref \
			cat.csv placed.csv &&
		\"\$PY\" \"\$TOP/tests/siaf_check.py\" sip \"\$SIAF\" $ra $dec $pa $ref img.fits &&
		rm img.fits
	"
}
check 'PA 30 about WFI01' 10 20 30 wfi01 1
check 'PA 217 about the boresight' 200 -35 217 boresight 2
check 'near the north pole' 45 89.9 300 wfi01 3
check 'across RA 0/360' 0.02 -5 95 boresight 4

test_expect_success 'the background follows each pixel'"'"'s area (SIAF), is flat (stips)' '
	: > empty.csv &&
	"$WFS" --filter F129 --sca 1,9,18 --compress gzip --background 0.7 -o b.fits empty.csv &&
	"$PY" "$TOP/tests/siaf_check.py" bkg "$SIAF" 0.7 b.fits &&
	"$WFS" --filter F129 --sca 9 --compress gzip --background 0.7 --geometry stips \
		-o t.fits empty.csv &&
	"$PY" -c "
from astropy.io import fits; import numpy as np
d = fits.getdata(\"t.fits\", 1)
assert np.all(d == np.float32(0.7)), (d.min(), d.max())
"
'
test_expect_success 'siaf is the default, --geometry stips the old layout' '
	: > empty.csv &&
	"$WFS" --filter F129 --sca 9 --compress gzip -o d.fits empty.csv &&
	"$WFS" --filter F129 --sca 9 --compress gzip --geometry siaf -o s.fits empty.csv &&
	"$WFS" --filter F129 --sca 9 --compress gzip --geometry STIPS -o t.fits empty.csv &&
	"$PY" -c "
from astropy.io import fits
d, s, t = (fits.getheader(f, 1) for f in (\"d.fits\", \"s.fits\", \"t.fits\"))
assert d[\"CTYPE1\"] == s[\"CTYPE1\"] == \"RA---TAN-SIP\", d[\"CTYPE1\"]
assert t[\"CTYPE1\"] == \"RA---TAN\" and \"A_ORDER\" not in t
assert fits.getheader(\"d.fits\", 0)[\"GEOMETRY\"] == \"siaf\"
assert fits.getheader(\"t.fits\", 0)[\"GEOMETRY\"] == \"stips\"
"
'
test_expect_success 'an unknown geometry is a usage error naming the choices' '
	: > empty.csv &&
	test_must_fail --status 1 "$WFS" --filter F129 --geometry tan -o x.fits empty.csv 2>err &&
	grep -q "geometry.*tan.*siaf, stips" err
'
test_done
