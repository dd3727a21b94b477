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

test_expect_success 'the spectrum along a channel'"'"'s readout: the model'"'"'s 1/f over a white floor' '
	run --level 1 --ma-table 3 --rows 1-2048 -o sp.fits &&
	run --level 1 --ma-table 3 --rows 1-2048 --detector none -o spn.fits &&
	$PY -c "
import numpy as np
from astropy.io import fits
t = [l.split() for l in open(\"$TOP/data/readnoise.tsv\") if l.startswith(\"WFI01\")][0]
cpink, upink = float(t[5]), float(t[6])
# the pink series of MA table 3 (18 reads): 20 frames of 4096 rows
h = 20 * 4096 // 2
K = (cpink ** 2 + upink ** 2) / (sum(4.0 / j for j in range(1, h)) + 1.0 / h)
def spectrum(f):
    x = fits.open(f)[1]
    g = x.header[\"GAIN\"]
    P = 0
    # the single reads (resultants 0 and 4: reads 1 and 18); the mean of
    # the 4 left (channel 0) and the 4 right (channel 31) reference
    # columns of each row, e-, the channels reading them first
    for r in (0, 4):
        for c in (slice(0, 4), slice(-4, None)):
            v = x.data[r, 4:-4, c].astype(float).mean(axis=1) * g
            L = v.size
            w = 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(L) / L)
            X = np.fft.rfft((v - v.mean()) * w)
            P = P + np.abs(X[1:L // 2]) ** 2 / (w * w).sum() / 4
    return P, L
P, L = spectrum(\"sp.fits\")
Pn, _ = spectrum(\"spn.fits\")
m = np.arange(1, L // 2)
# the white floor: that of the white model (measured) less its read
# noise, plus the white and slow parts (4 columns averaged)
hi = m > L // 4
white, slow = float(t[3]), float(t[8])
rn = fits.open(\"spn.fits\")[1].header[\"RDNOISE\"]
floor = Pn[hi].mean() - (rn ** 2 - white ** 2 - slow ** 2) / 4
# the model: two-sided density 2 K / nu, nu = m / L cycles a row
model = 2 * K * L / m + floor
for a in (4, 8, 16, 32, 64):
    s = (m >= a) & (m < 2 * a)
    print(\"m %3d-%3d: power %8.1f model %8.1f white %6.1f\" % (a, 2 * a, P[s].sum(), model[s].sum(), Pn[s].sum()))
s = (m >= 4) & (m < 128)
r = P[s].sum() / model[s].sum()
print(\"m 4-127 of %d rows: power / model %.3f; white noise alone %.3f of it\" % (L, r, Pn[s].sum() / P[s].sum()))
assert abs(r - 1) < 0.2, r
# the octaves above the floor hold the same power: 1/f (log slope 0;
# white -1, 1/f^2 +1 per octave); the octaves of one exposure scatter by
# 30 %, so within 0.5
o = [P[(m >= a) & (m < 2 * a)].sum() - floor * a for a in (4, 8, 16, 32, 64)]
sl = np.polyfit(np.log([4, 8, 16, 32, 64]), np.log(o), 1)[0]
print(\"log slope of the octave sums %.3f (1/f: 0)\" % sl)
assert abs(sl) < 0.5, sl
assert Pn[s].sum() < 0.25 * P[s].sum()
"
'

test_done
