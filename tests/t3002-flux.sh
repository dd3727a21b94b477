#!/bin/sh
# Flux conservation: noise-free stars at every eighth-pixel phase, on tile
# boundaries and edges, on all 18 SCAs: each image's sum equals the catalog
# flux times the ePSF's enclosed fraction, computed by an independent
# implementation of the documented evaluation, to 1e-6.
. "$(dirname "$0")/lib.sh"
require_python

test_expect_success 'a synthetic ePSF grid and stars at all phases on 18 SCAs' '
	"$PY" "$TOP/tests/flux_check.py" grid epsf.fits &&
	"$PY" "$TOP/tests/flux_check.py" stars 1,2,3,4,5,6,7,8,9,10,11,12,13,14,15,16,17,18 5 > stars.csv
'
test_expect_success 'flux placed = flux x enclosed fraction, to 1e-6, every SCA' '
	"$WFS" --filter F129 --sca 1-18 --psf epsf.fits --compress gzip --tile 128 \
		-o img.fits stars.csv &&
	"$PY" "$TOP/tests/flux_check.py" check epsf.fits stars.csv img.fits 1e-6
'
test_expect_success 'and the same with one thread and another tile size (SCAs 1, 9, 18)' '
	"$WFS" --filter F129 --sca 1,9,18 --psf epsf.fits --compress gzip --tile 300 \
		--threads 1 -o img2.fits stars.csv &&
	"$PY" "$TOP/tests/flux_check.py" check epsf.fits stars.csv img2.fits 1e-6
'
test_done
