#!/bin/sh
# Flux conservation: noise-free stars at every eighth-pixel phase, on tile
# boundaries and edges, on all 18 SCAs.  Each image's sum equals the catalog
# flux times the ePSF's enclosed fraction, computed by an independent
# implementation of the evaluation wfiscene(1) documents, to 1e-6: blended
# at each source (psf-blend=source), and with the defaults (blended per
# 512-pixel cell, the blend at the source restored in the core, the nearest
# sample beyond 8 pixels, all but the core scaled to keep the flux).  For a
# star wholly on the detector both give the enclosed fraction of the blend
# at the source (to 1e-6); for one partly off it, the part that lands
# follows each evaluation's own wings.  The default is within 1e-3 of the
# peak of the per-source image.
# The box evaluation is tested, so with STIPS's boxes (psf-extent=stips).
# The images are written uncompressed: --compress gzip (lossless, t4200's
# subject) cost the writer and each python3 read of 18 SCAs a tile at a
# time, a minute of the suite; each image is removed once read.
. "$(dirname "$0")/lib.sh"
require_python

test_expect_success 'a synthetic ePSF grid and stars at all phases on 18 SCAs' '
	"$PY" "$TOP/tests/flux_check.py" grid epsf.fits &&
	"$PY" "$TOP/tests/flux_check.py" stars 1,2,3,4,5,6,7,8,9,10,11,12,13,14,15,16,17,18 5 > stars.csv
'
test_expect_success 'flux placed = flux x enclosed fraction, to 1e-6, every SCA' '
	"$WFS" --filter F129 --sca 1-18 --psf epsf.fits --set psf-extent=stips --tile 128 \
		--set psf-blend=source -o img.fits stars.csv &&
	"$PY" "$TOP/tests/flux_check.py" check epsf.fits stars.csv img.fits 1e-6
'
test_expect_success 'and the same with one thread and another tile size (SCAs 1, 9, 18)' '
	"$WFS" --filter F129 --sca 1,9,18 --psf epsf.fits --set psf-extent=stips --tile 300 \
		--threads 1 --set psf-blend=source -o img2.fits stars.csv &&
	"$PY" "$TOP/tests/flux_check.py" check epsf.fits stars.csv img2.fits 1e-6 &&
	rm img2.fits
'
test_expect_success 'the default blend: stars wholly on the detector get the enclosed fraction at the source, to 1e-6' '
	"$PY" -c "
import csv, sys
r = list(csv.DictReader(open(\"stars.csv\")))
w = csv.DictWriter(sys.stdout, r[0].keys())
w.writeheader()
w.writerows(s for s in r if 30 < float(s[\"x\"]) < 4060 and 30 < float(s[\"y\"]) < 4060)
" > inner.csv &&
	"$WFS" --filter F129 --sca 1-18 --psf epsf.fits --set psf-extent=stips --tile 128 -o defin.fits inner.csv &&
	"$PY" "$TOP/tests/flux_check.py" check epsf.fits inner.csv defin.fits 1e-6 &&
	rm defin.fits
'
test_expect_success 'the default evaluation, edge stars too: to 1e-6, every SCA; 1e-3 of the peak' '
	"$WFS" --filter F129 --sca 1-18 --psf epsf.fits --set psf-extent=stips --tile 128 \
		-o def.fits stars.csv &&
	"$PY" "$TOP/tests/flux_check.py" check-default epsf.fits stars.csv def.fits 1e-6 &&
	"$PY" -c "
import numpy as np
from astropy.io import fits
with fits.open(\"img.fits\") as a, fits.open(\"def.fits\") as b:
    for x, y in zip(a[1:], b[1:]):
        # the difference in float64 without float64 copies of both images
        d = np.abs(np.subtract(x.data, y.data, dtype=np.float64)).max() / float(x.data.max())
        assert 0 < d < 1e-3, (x.name, d)
" &&
	rm img.fits def.fits
'
test_done
