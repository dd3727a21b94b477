#!/bin/sh
# Detector levels 1 and 2 through the command line: the file layout, the
# rate of a flat sky against its ERR, saturation flags, the same bytes for
# any threads and tiles and for runs split by rows (merged), and the
# options that do not go with the levels refused.
. "$(dirname "$0")/lib.sh"
require_python

run() { "$WFS" --filter F129 --ra 0 --dec 0 --background 0.54 "$@"; }

printf 'ra,dec,flux\n' > none.csv
# a star bright enough to saturate its core in the first resultants, on
# WFI01's centre (--pointing-ref wfi01 puts ra 0 dec 0 there)
printf 'ra,dec,flux\n0,0,5e7\n' > bright.csv

cat > l2stats.py <<\PYEOF
import sys
import numpy as np
from astropy.io import fits
h = fits.open(sys.argv[1])
names = [x.name for x in h[1:]]
assert names == ["WFI01", "WFI01_ERR", "WFI01_DQ", "WFI01_VAR_POISSON", "WFI01_VAR_RNOISE"], names
r, e, q = (np.asarray(h[k].data, dtype=np.float64) for k in (1, 2, 3))
vp, vr = (np.asarray(h[k].data, dtype=np.float64) for k in (4, 5))
assert h[3].data.dtype.kind == "u", h[3].data.dtype
# the layout of wfiscene(1) "Files of levels 1 and 2", in every HDU
units = ["counts/s", "counts/s", None, "(counts/s)^2", "(counts/s)^2"]
for x, unit in zip(h[1:], units):
    hd = x.header
    assert x.data.shape == (4088, 4088), (x.name, x.data.shape)
    assert hd["BITPIX"] == (32 if x.name.endswith("_DQ") else -32), (x.name, hd["BITPIX"])
    assert hd.get("BUNIT") == unit, (x.name, hd.get("BUNIT"))
    assert hd["LEVEL"] == "2" and hd["MATABLE"] == 4 and hd["NRESULT"] == 9, x.name
    assert hd["READTIME"] == 3.16247 and hd["GAIN"] == 2 and hd["SATURATE"] == 55000, x.name
    assert hd["MAREAD1"] == "1-1" and hd["MAREAD9"] == "44-44" and "MAREAD10" not in hd, x.name
    assert hd["PEDESTAL"] == 10000 and hd["NLBETA"] == -6e-7 and hd["DARKCURR"] == 0.049, x.name
    assert abs(hd["RDNOISE"] - 17.49 / 2 ** 0.5) < 1e-3 and abs(hd["EXPTIME"] - 139.149) < 1e-3, x.name
    assert hd["RAMPFIT"] == "OPTIMAL" and hd["JUMPTHR"] == 5, x.name
    assert hd["CTYPE1"].startswith("RA---TAN"), x.name
assert h[3].header["BZERO"] == 2147483648
assert np.allclose(e * e, vp + vr, rtol=1e-5)
m = q == 0
med = np.median(r[m])
sig = 1.4826 * np.median(np.abs(r[m] - med))
print("%.6f %.6f %.6f %.6f" % (med, sig, np.sqrt(np.mean(e[m] ** 2)), np.mean(q == 4)))
PYEOF

within() { awk -v g="$1" -v w="$2" -v t="$3" 'BEGIN { d = g - w; if (d < 0) d = -d; exit !(d <= t) }'; }

test_expect_success 'level 2 of a flat sky: the sky rate, its scatter as ERR, few jumps' '
	# stips geometry: every pixel the nominal area, so the sky is flat at
	# 0.54 (the SIAF pixels of WFI01 are about 1 % smaller: t5002)
	# (white read noise: with the correlated part each channel keeps a
	# rate offset of ~0.008 counts/s rms after the reference correction,
	# t5210)
	run --geometry stips --level 2 --detector none -o l2.fits none.csv &&
	$PY l2stats.py l2.fits > s && read med sig err jump < s && say "$med $sig $err $jump" &&
	within "$med" 0.54 0.0054 &&
	within "$(awk -v a="$sig" -v b="$err" "BEGIN { print a / b }")" 1 0.1 &&
	# jumps: the pixels hit (2 x 5 hits/cm^2/s x 1e-6 cm^2 x 139 s =
	# 0.0014), and some of the four neighbours of a 5,000 e- hit, to
	# which IPC gives 65 to 76 e-: between 0.0014 and 0.0014 (1 + 4 / 2)
	awk -v j="$jump" "BEGIN { exit !(j >= 0.0010 && j <= 0.0042) }"
'

test_expect_success 'level 2 split by rows and merged is the whole run, byte for byte' '
	# the default model: the correlated read noise and its correction
	run --geometry stips --level 2 -o l2c.fits none.csv &&
	run --geometry stips --level 2 --rows 1-2044 -o p1.fits none.csv &&
	run --geometry stips --level 2 --rows 2045-4088 --threads 1 --tile 128 -o p2.fits none.csv &&
	"$WFS" merge -o merged.fits p2.fits p1.fits &&
	test_cmp l2c.fits merged.fits
'

test_expect_success 'level 1: a 16-bit cube with the reference border, the same for any threads and tiles' '
	# stips geometry: every pixel the nominal area, so the sky is flat
	# (t5002 holds the SIAF pixel areas at levels 1 and 2)
	# (white read noise: the reference rows at the pedestal within 1 DN)
	run --geometry stips --level 1 --rows 1-100 --threads 1 --tile 64 --detector none -o a.fits none.csv &&
	run --geometry stips --level 1 --rows 1-100 --threads 2 --tile 256 --detector none -o b.fits none.csv &&
	test_cmp a.fits b.fits &&
	$PY -c "
from astropy.io import fits
import numpy as np
h = fits.open(\"a.fits\")[1]
assert h.name == \"WFI01\" and h.data.shape == (9, 104, 4096), h.data.shape
assert h.header[\"BITPIX\"] == 16 and h.header[\"BZERO\"] == 32768
assert h.header[\"MATABLE\"] == 4 and h.header[\"GAIN\"] == 2 and h.header[\"READTIME\"] == 3.16247
assert h.header[\"MAREAD4\"] == \"5-9\" and abs(h.header[\"EXPTIME\"] - 139.149) < 1e-3
d = h.data.astype(float)
# reference rows: the pedestal of 10000 e- seen through the non-linearity,
# (10000 - 6e-7 10000^2) / 2 = 4970 DN
ref = d[:, :4, :]
sci = d[:, 10:, 10:4000]    # science: the sky (and dark) ramps up
assert abs(ref.mean() - 4970) < 1, ref.mean()
# per pixel, without the few that a cosmic ray hit (5 robust sigmas)
rise = (sci[8] - sci[0]).ravel()
med = np.median(rise)
sig = 1.4826 * np.median(np.abs(rise - med))
rise = rise[np.abs(rise - med) < 5 * sig].mean()
want = (0.54 + 0.049) * (44 - 1) * 3.16247 / 2 * (1 - 2 * 6e-7 * 10000)
assert abs(rise / want - 1) < 0.02, (rise, want)
"
'

test_expect_success 'a saturating star: DQ SATURATED, and a rate from the reads before' '
	run --level 2 --rows 2000-2090 -o sat.fits bright.csv &&
	$PY -c "
from astropy.io import fits
import numpy as np
h = fits.open(\"sat.fits\")
q = h[\"WFI01_DQ\"].data
assert (q & 2).sum() > 10, (q & 2).sum()
r = h[\"WFI01\"].data
assert np.isfinite(r).all() and r.max() > 1e4, r.max()
"
'

test_expect_success 'around a saturating star every rate but DO_NOT_USE is within 10 % of the light' '
	# IPC shares the charge after each pixel is clipped: a saturated
	# pixel beside fainter ones levels off below the clip, which the fit
	# must take as saturation, not as a flat ramp or jumps
	run --level 2 --rows 1990-2100 -o star2.fits bright.csv &&
	run --exptime 139.149 --rows 1990-2100 -o star0.fits bright.csv &&
	$PY -c "
from astropy.io import fits
import numpy as np
r = fits.getdata(\"star2.fits\", \"WFI01\").astype(float)
q = fits.getdata(\"star2.fits\", \"WFI01_DQ\").astype(np.int64)
m = fits.getdata(\"star0.fits\", \"WFI01\").astype(float) + 0.049
y0, x0 = np.unravel_index(np.argmax(m), m.shape)
yy, xx = np.mgrid[0:m.shape[0], 0:m.shape[1]]
near = (np.hypot(yy - y0, xx - x0) < 30) & ((q & 1) == 0)
ratio = r[near] / m[near]
off = (np.abs(ratio - 1) > 0.1).sum()
assert near.sum() > 1000 and ((q[near] & 2) != 0).sum() > 500, (near.sum(), (q & 2).sum())
assert off < 0.01 * near.sum() and ratio.min() > 0.5, (off, near.sum(), ratio.min())
"
'
test_expect_success 'options that do not go with the levels are refused' '
	test_must_fail --status 1 run --level 2 --exptime 100 -o bad.fits none.csv 2> err &&
	test_grep "MA table 4 lasts 139.149 s" err && ! test -e bad.fits &&
	run --level 2 --exptime 139.149 --rows 1-8 -o ok.fits none.csv &&
	test_must_fail --status 1 run --level 1 --noise all -o bad.fits none.csv 2> err &&
	test_grep "simulate the detector" err && ! test -e bad.fits &&
	test_must_fail --status 1 run --level 1 -o - none.csv > /dev/null 2> err &&
	test_grep "need a file" err &&
	mkfifo pipe && test_must_fail --status 1 run --level 1 -o pipe none.csv 2> err &&
	test_grep "pipe with --level 1: .*need a file that can seek, not a pipe" err &&
	test -p pipe &&
	test_must_fail --status 1 run --level 2 --compress rice -o bad.fits none.csv 2> err &&
	test_grep "uncompressed" err && ! test -e bad.fits &&
	test_must_fail --status 1 run --level 2 --ma-table 2 -o bad.fits none.csv 2> err &&
	test_grep "no MultiAccum table 2 (there are 3, 4" err && ! test -e bad.fits &&
	test_must_fail --status 1 run --ma-table 3 -o bad.fits none.csv 2> err &&
	test_grep "without --level 1 or 2" err && ! test -e bad.fits &&
	test_must_fail --status 1 run --level 3 -o bad.fits none.csv 2> err &&
	test_grep "expected scene, 1 or 2" err && ! test -e bad.fits &&
	test_must_fail --status 1 run --level 1 --bunit counts -o bad.fits none.csv 2> err &&
	test_grep "DN" err && ! test -e bad.fits &&
	for o in readnoise=0 dark-current=1000 cosmic-rate=1e6 cosmic-residual=1; do
		test_must_fail --status 1 run --level 2 --$o -o bad.fits none.csv 2> err &&
		test_grep "^wfiscene: --${o%=*} with --level 2: it sets the scene level" err &&
		! test -e bad.fits || return 1
	done
'

test_expect_success 'wfiscene(1) states the constants of data/detector.tsv' '
	$PY - "$TOP/data/detector.tsv" "$TOP/man/wfiscene.1" <<-\EOF
	import re, sys
	rows = [l.rstrip("\n").split("\t") for l in open(sys.argv[1]) if not l.startswith("#")]
	c = {r[1]: float(r[2]) for r in rows[1:] if r[0] == "const"}
	ipc = {r[1]: float(r[2]) for r in rows[1:] if r[0] == "ipc"}
	rn = [float(r[2]) for r in rows[1:] if r[0] == "readnoise"]
	dk = [float(r[2]) for r in rows[1:] if r[0] == "dark"]
	man = open(sys.argv[2]).read()
	sect = man[man.index(".SH DETECTOR LEVELS"):man.index(".SH OUTPUT")]
	sect = sect.replace("\\~", " ").replace("\\(mi", "-").replace("\\(mu", "x")
	def has(text, what):
	    assert text in sect, (what, text)
	has("every 3.16247 s", "read_time")
	has("Gain %g e-/DN" % c["gain"], "gain")
	has("Saturation at %s DN (%s e- measured" % (format(int(c["saturation"]), ","),
	    format(int(c["saturation"] * c["gain"]), ",")), "saturation")
	has("Pedestal %s e- with a reset noise of %g e-" % (format(int(c["pedestal"]), ","),
	    c["reset_noise"]), "pedestal")
	has("-6x10\\(ha-7 per e-", "nonlinearity_beta") if c["nonlinearity_beta"] == -6e-7 else sys.exit("beta")
	has("two populations of %g hits/cm\\(ha2/s each (%g and" % (c["cosmic_rate"], c["cosmic_e_low"]), "cosmic")
	has("%s e- per hit" % format(int(c["cosmic_e_high"]), ","), "cosmic_e_high")
	has("10\\(ha-6 cm\\(ha2", "pixel_area") if c["pixel_area"] == 1e-6 else sys.exit("area")
	has("more than %g \\(*s" % c["jump_threshold"], "jump_threshold")
	has("exceeds %g %%" % (100 * c["nonlinear_flag"]), "nonlinear_flag")
	has("centre %.4f" % ipc["+0,+0"], "ipc centre")
	edges = [ipc[k] for k in ("+0,-1", "-1,+0", "+1,+0", "+0,+1")]
	corners = [ipc[k] for k in ("-1,-1", "+1,-1", "-1,+1", "+1,+1")]
	has("edges %.4f to %.4f" % (min(edges), max(edges)), "ipc edges")
	has("corners %.4f" % min(corners), "ipc corners")
	has("to %.4f)" % max(corners), "ipc corners")
	has("(%.1f to %.1f e-)" % (min(rn), max(rn)), "read noise range")
	has("(%.3f to\n%.3f e-/s)" % (min(dk), max(dk)), "dark range")
	print("ok", len(c), "constants")
	EOF
'

test_expect_success 'merge refuses the row parts of a level-1 cube' '
	run --level 1 --rows 1-8 -o c1.fits none.csv &&
	test_must_fail --status 1 "$WFS" merge -o m.fits c1.fits 2> err &&
	test_grep "level 1 cube" err
'
cat > ipccov.py <<\PYEOF
# IPC shares the collected charge, Poisson noise included: in a flat
# field's difference of resultants, d = K * c + n with c the charge (iid,
# variance Vc) and n the read noise and the 16-bit rounding (iid, Vn), so
# var(d) = Vc sum K^2 + Vn and cov(d(p), d(p + e)) = Vc sum_q K(q) K(q + e).
import sys
import numpy as np
from astropy.io import fits
from scipy.signal import correlate2d
h = fits.open(sys.argv[1])[1]
rows = [l.rstrip("\n").split("\t") for l in open(sys.argv[2]) if not l.startswith("#")]
K = np.zeros((3, 3))
for r in rows:
    if r[0] == "ipc":
        dx, dy = (int(v) for v in r[1].split(","))
        K[dy + 1, dx + 1] = float(r[2])
rn, g = h.header["RDNOISE"], h.header["GAIN"]
c = h.data.astype(np.float64)
d = (c[-1] - c[0])[8:, 8:-8]     # last less first resultant, science pixels
med = np.median(d)
sig = 1.4826 * np.median(np.abs(d - med))
# without the cosmic rays, and the charge IPC shared from them
bad = np.abs(d - med) > 5 * sig
bad[1:] |= bad[:-1].copy(); bad[:-1] |= bad[1:].copy()
bad[:, 1:] |= bad[:, :-1].copy(); bad[:, :-1] |= bad[:, 1:].copy()
x = np.where(bad, np.nan, d - np.nanmean(np.where(bad, np.nan, d)))
var = np.nanmean(x * x)
# the first and last resultants are single reads: read noise and rounding
vn = 2 * (rn / g) ** 2 + 2 / 12
A = correlate2d(K, K)            # A[2 + ey, 2 + ex] = sum_q K(q) K(q + e)
vc = (var - vn) / A[2, 2]
fail = 0
for ey, ex in ((0, 1), (1, 0), (1, 1), (1, -1)):
    H, W = x.shape
    a = x[:H - ey, max(0, -ex):W - max(0, ex)]       # pixel p
    b = x[ey:, max(0, ex):W - max(0, -ex)]           # pixel p + e
    p = a * b
    n = np.isfinite(p).sum()
    cov = np.nanmean(p)
    want = vc * A[2 + ey, 2 + ex]
    err = np.sqrt((var * var + want * want) / n)   # sampling error of the mean product
    print("offset (%d,%d): cov/var %.5f, kernel %.5f, %.1f sigma (n %d)" %
          (ex, ey, cov / var, want / var, (cov - want) / err, n))
    fail |= bool(abs(cov - want) > 4 * err)
# and the nearest neighbours' ratio is about twice the coupling alpha
alpha = (K[1, 0] + K[1, 2] + K[0, 1] + K[2, 1]) / 4
print("alpha %.5f, 2 alpha %.5f" % (alpha, 2 * alpha))
sys.exit(1 if fail else 0)
PYEOF

test_expect_success 'level 1: IPC shares the Poisson noise of a flat field with the neighbours as its kernel says' '
	# 50 e-/s of sky, 6,800 e- in the difference: the charge'"'"'s noise
	# dominates the read noise; stips geometry, for a flat field
	# (white read noise: the correlated noise of the channels would add its own
	# covariance between neighbours)
	run --geometry stips --background 50 --level 1 --rows 1-300 --detector none -o flat.fits none.csv &&
	$PY ipccov.py flat.fits "$TOP/data/detector.tsv" > s && say "$(cat s)"
'

test_expect_success 'level 1 split by rows: the rows of the whole run, byte for byte' '
	run --geometry stips --background 50 --level 1 --rows 151-300 --threads 1 --detector none \
		--tile 32 -o part.fits none.csv &&
	$PY -c "
from astropy.io import fits
import numpy as np
w = fits.open(\"flat.fits\")[1].data
p = fits.open(\"part.fits\")[1].data
assert p.shape == (9, 150, 4096), p.shape
assert (w[:, 154:304] == p).all(), (w[:, 154:304] != p).sum()
"
'
test_expect_success 'a --psf ePSF with IPC folded in: a warning at level 1, none at the scene level' '
	"$WFS" psf --filter F129 --sca 1 --kind epsf -o e.fits &&
	run --psf e.fits --level 1 --rows 1-8 -o w1.fits none.csv 2> err &&
	test_grep "IPC again" err &&
	run --psf e.fits --rows 1-8 -o w0.fits none.csv 2> err0 &&
	! grep "IPC again" err0
'
test_expect_success 'the vector loops and the plain ones (WFISCENE_NO_SIMD) give the same bytes' '
	# the SIAF geometry (a sky that varies with pixel area), a saturating
	# star, a faint and a bright sky (small Poisson means and the normal
	# form above poisson-normal), levels 1 and 2 and the scene level
	for bg in 0.54 50; do
		for lv in "--level 1" "--level 2" "--noise all"; do
			run --background $bg $lv --rows 1990-2100 -o v.fits bright.csv &&
			WFISCENE_NO_SIMD=1 run --background $bg $lv --rows 1990-2100 \
				-o p.fits bright.csv &&
			test_cmp v.fits p.fits || return 1
		done
	done
'
test_done
