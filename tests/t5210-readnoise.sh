#!/bin/sh
# Correlated read noise (wfiscene(1), DETECTOR MODEL, --detector
# correlated): the same bytes for any thread count and for runs split by
# rows; on by default (--detector none: the white noise's bytes); the reference pixels
# carry the channels' noise; level 2's reference correction leaves a rate
# whose scatter is what VAR_RNOISE and VAR_POISSON say, which the
# uncorrected noise would exceed.  tests/unit/readnoise_stats measures the
# CDS and total noise and the spectrum along a channel.
. "$(dirname "$0")/lib.sh"
require_python

printf 'ra,dec,flux\n0,0,5e4\n' > one.csv
run() { "$WFS" --filter F129 --sca 1 --allow-sun-angle --background 0.54 "$@" one.csv; }

test_expect_success 'the same bytes for 1 and 2 threads; parts by rows are the whole' '
	run --level 1 --detector correlated --rows 1-60 --threads 2 -o w.fits &&
	run --level 1 --detector correlated --rows 1-60 --threads 1 --tile 64 -o t1.fits &&
	cmp w.fits t1.fits &&
	run --level 1 --detector correlated --rows 1-25 -o p1.fits &&
	run --level 1 --detector correlated --rows 26-60 --threads 1 -o p2.fits &&
	$PY -c "
import numpy as np
from astropy.io import fits
p = [fits.open(f)[1].data for f in (\"p1.fits\", \"p2.fits\")]
w = fits.open(\"w.fits\")[1].data
assert (np.concatenate(p, axis=1) == w).all(), \"the parts are the whole\"
"
'

test_expect_success 'level 2: the same correction whoever asks: parts by rows are the whole' '
	run --level 2 --detector correlated --rows 1-60 -o w2.fits &&
	run --level 2 --detector correlated --rows 1-25 --threads 1 -o q1.fits &&
	run --level 2 --detector correlated --rows 26-60 --tile 64 -o q2.fits &&
	$PY -c "
import numpy as np
from astropy.io import fits
p = [fits.open(f) for f in (\"q1.fits\", \"q2.fits\")]
w = fits.open(\"w2.fits\")
for k in range(1, 6):
    assert (np.concatenate([q[k].data for q in p]) == w[k].data).all(), k
"
'

test_expect_success 'on by default; off, the white noise bytes; on, the reference pixels move' '
	run --level 1 --rows 1-60 --threads 1 -o a.fits &&
	cmp a.fits w.fits &&
	run --level 1 --detector none --rows 1-60 -o d.fits &&
	run --level 1 --detector persistence --rows 1-60 -o p.fits &&
	cmp d.fits p.fits &&
	! cmp -s d.fits w.fits &&
	$PY -c "
import numpy as np
from astropy.io import fits
hw, hd = fits.open(\"w.fits\")[1].header, fits.open(\"d.fits\")[1].header
# RNCORR records the correlated noise; RDNOISE keeps its meaning (a read)
assert hw[\"RNCORR\"] is True and \"RNCORR\" not in hd, (hw.get(\"RNCORR\"), hd.get(\"RNCORR\"))
assert hw[\"RDNOISE\"] == hd[\"RDNOISE\"], (hw[\"RDNOISE\"], hd[\"RDNOISE\"])
w = fits.open(\"w.fits\")[1].data.astype(float)
d = fits.open(\"d.fits\")[1].data.astype(float)
# the bottom reference rows, resultant 1 less resultant 0, mean per channel:
# white noise averages out over 4 x 128 pixels, the channel offsets do not
def chan(a):
    x = (a[1, :4] - a[0, :4]).reshape(4, 32, 128)
    return x.mean(axis=(0, 2)).std()
cw, cd = chan(w), chan(d)
print(\"channel means of the bottom reference rows: %.2f DN against %.2f white\" % (cw, cd))
assert cw > 3 * cd
"
'

test_expect_success 'level 2: the corrected rate scatters as VAR_RNOISE + VAR_POISSON say' '
	run --level 2 --detector correlated --rows 2000-2200 -o c2.fits &&
	run --level 2 --detector none --rows 2000-2200 -o n2.fits &&
	$PY -c "
import numpy as np
from astropy.io import fits
for f in (\"c2.fits\", \"n2.fits\"):
    h = fits.open(f)
    r = h[1].data[:, 100:4000].astype(float)
    vr, vp = (h[k].data[:, 100:4000].astype(float) for k in (4, 5))
    want = np.sqrt(np.median(vr + vp))
    # robust scatter, the star and the cosmic rays aside
    got = 1.4826 * np.median(np.abs(r - np.median(r)))
    print(f, \"rate scatter %.4f, from the variances %.4f\" % (got, want))
    assert abs(got / want - 1) < 0.08, (f, got, want)
"
'

test_done
