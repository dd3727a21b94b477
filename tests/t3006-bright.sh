#!/bin/sh
# Bright stars (psf-extent=noise, the default): drawn out to where the PSF
# sinks below 0.1 of the noise per pixel, with the optical model's wing and
# spikes out there, and no edge.  The reference is the built-in optics' own
# large PSF (`wfiscene psf --halo 512`: +-512 pixels computed directly, no
# tail), against which the drawn wing is compared out to 300 pixels (the
# image beyond 256 pixels is the model's power-law tail).
. "$(dirname "$0")/lib.sh"
require_python

cat > check.py <<'EOT'
import json, sys
import numpy as np
from astropy.io import fits

def ref_profile(ref, px, py):
    """annulus medians and enclosed light of the reference for a star at
    fractional pixel (px, py) = (0.5, 0.5): its 2x samples at half-integer
    offsets are the pixels' values"""
    a = fits.getdata(ref).astype(float)
    if a.ndim == 3:
        a = a[0]
    n = a.shape[0]
    c = (n - 1) // 2
    # pixel i has offset i - x; at x = X + 0.5 the offsets are k + 0.5
    sub = a[1::2, 1::2]          # samples at odd indices: offsets (j - c) / 2 = k + 1/2
    off = (np.arange(1, n, 2) - c) / 2.0
    yy, xx = np.meshgrid(off, off, indexing="ij")
    return sub, np.hypot(xx, yy)

what = sys.argv[1]
if what == "annuli":
    ref, clean, noisy, flux = sys.argv[2], sys.argv[3], sys.argv[4], float(sys.argv[5])
    x0, y0 = 1999.5, 1999.5      # 0-based centre of the catalog's 2000.5, 2000.5
    sub, rr = ref_profile(ref, 0.5, 0.5)
    c = fits.getdata(clean, 1).astype(float)
    z = fits.getdata(noisy, 1).astype(float)
    y, x = np.indices(c.shape)
    r = np.hypot(x - x0, y - y0)
    sky = np.median(z[r > 1500])
    last = None
    for R in (60, 100, 150, 200, 300):
        m = (r >= R - 2) & (r < R + 2)
        mr = (rr >= R - 2) & (rr < R + 2)
        want = flux * np.median(sub[mr])
        got, gotn = np.median(c[m]), np.median(z[m]) - sky
        print("# %3d px: reference %.4g, drawn %.4g, noisy - sky %.4g" % (R, want, got, gotn))
        assert gotn > 0 and got > 0, (R, got, gotn)
        assert abs(got / want - 1) < 0.15, (R, got, want)
        # the noisy image's median follows the wing (within its noise)
        assert abs(gotn - got) < 0.2 * got + 0.5, (R, gotn, got)
        assert last is None or got < last, (R, got, last)
        last = got
    inside = c[r < 300].sum()
    want = flux * sub[rr < 300].sum()
    print("# within 300 px: drawn %.6g of %.6g (%.4f)" % (inside, want, inside / want))
    assert 0.99 <= inside / want <= 1.01, (inside, want)
elif what == "edge":           # edge IMG REPORT [IMG REPORT]...: each in turn
  for img, rep in zip(sys.argv[2::2], sys.argv[3::2]):
    sigma = float(json.load(open(rep))["error_budget"]["pixel_sigma"])
    a = fits.getdata(img, 1).astype(float)
    drawn = a != 0
    assert drawn.any()
    border = np.zeros_like(drawn)
    # drawn pixels with an undrawn neighbour on the detector
    for sl_in, sl_out in (((slice(1, None), slice(None)), (slice(None, -1), slice(None))),
                          ((slice(None, -1), slice(None)), (slice(1, None), slice(None))),
                          ((slice(None), slice(1, None)), (slice(None), slice(None, -1))),
                          ((slice(None), slice(None, -1)), (slice(None), slice(1, None)))):
        border[sl_in] |= drawn[sl_in] & ~drawn[sl_out]
    worst = np.abs(a[border]).max() if border.any() else 0.0
    print("# %s: %d border pixels, largest %.3g = %.4f sigma (sigma %.4g)" %
          (img, border.sum(), worst, worst / sigma, sigma))
    assert worst < 0.1 * sigma, (img, worst, sigma)
EOT

test_expect_success 'the built-in optics'"'"' own large PSF (+-512 pixels)' '
	"$WFS" psf --filter F158 --sca 1 --halo 512 -o ref.fits &&
	printf "id,x,y,flux\n1,2000.5,2000.5,2\n" > two.csv
'
test_expect_success 'a 2-mag star: annulus medians at 60-300 px positive, falling as the optics'"'"' wing; 99 % within 300 px' '
	"$WFS" --filter F158 --flux-unit abmag --report clean.json -o clean.fits two.csv &&
	"$WFS" --filter F158 --flux-unit abmag --noise all --background avg -o noisy.fits two.csv &&
	flux=$("$PY" -c "import json; print(json.load(open(\"clean.json\"))[\"flux\"][0][\"requested\"])") &&
	"$PY" check.py annuli ref.fits clean.fits noisy.fits $flux
'
test_expect_success 'no jump above 0.1 sigma at the edge of what is drawn, stars of 0 to 28 mag' '
	set -- &&
	for m in 0 2 4 6 8 10 12 14 16 18 20 22 24 26 28; do
		printf "id,x,y,flux\n1,2000.3,2000.6,$m\n" > m$m.csv &&
		"$WFS" --filter F158 --flux-unit abmag --exptime 100 --report m$m.json \
			-o m$m.fits m$m.csv &&
		set -- "$@" m$m.fits m$m.json || return 1
	done &&
	"$PY" check.py edge "$@"
'
test_expect_success 'and with the noise stages'"'"' sigma (psf-box-sigma sets it by hand)' '
	"$WFS" --filter F158 --flux-unit abmag --exptime 100 --set psf-box-sigma=0.5 \
		--report s.json -o s.fits m14.csv &&
	"$PY" -c "
import json; r = json.load(open(\"s.json\")); r[\"error_budget\"][\"pixel_sigma\"] = \"0.5\"
json.dump(r, open(\"s2.json\", \"w\"))" &&
	"$PY" check.py edge s.fits s2.json
'
# The halo's pixels above the level are drawn by vector loops of two
# widths (AVX-512 sixteen pixels a step, over each row's chunks; AVX2
# eight, over its runs) and a plain loop, each taken where the processor
# has it: the same bits, on a field whose stars' halos cross tile edges,
# each other and their boxes, at every sub-pixel phase, with the default
# tiles and with tiles of 40 pixels (a chunk then often crosses a tile's
# edge).  Each width is compared where this processor has it.
grep -q '^flags.* avx2' /proc/cpuinfo 2>/dev/null && has_avx2=1 || has_avx2=
grep -q '^flags.* avx512f' /proc/cpuinfo 2>/dev/null && has_avx512=1 || has_avx512=
test_expect_success 'bright stars: a field of halos, drawn with the plain loops' '
	"$BUILD/contrib/starfield" -n 400 -x -m 12 -M 20 -s 9 > br.csv &&
	WFISCENE_NO_SIMD=1 "$WFS" --filter F158 --flux-unit abmag --exptime 139.8 \
		--rows 1-1200 -o p.fits br.csv &&
	WFISCENE_NO_SIMD=1 "$WFS" --filter F158 --flux-unit abmag --exptime 139.8 \
		--rows 1-1200 --tile 40 -o p40.fits br.csv &&
	"$PY" -c "
from astropy.io import fits
import numpy as np
a = fits.getdata(\"p.fits\", 1)
assert (a != 0).mean() > 0.2, (a != 0).mean()
"
'
if [ -n "$has_avx2" ]; then
	test_expect_success 'bright stars: the AVX2 loops draw the same bits as the plain ones' '
		WFISCENE_NO_SIMD=avx512 "$WFS" --filter F158 --flux-unit abmag --exptime 139.8 \
			--rows 1-1200 -o v2.fits br.csv &&
		test_cmp p.fits v2.fits &&
		WFISCENE_NO_SIMD=avx512 "$WFS" --filter F158 --flux-unit abmag --exptime 139.8 \
			--rows 1-1200 --tile 40 -o v240.fits br.csv &&
		test_cmp p40.fits v240.fits
	'
else
	test_skip 'bright stars: the AVX2 loops draw the same bits as the plain ones' \
		'this processor has no AVX2'
fi
if [ -n "$has_avx512" ]; then
	test_expect_success 'bright stars: the AVX-512 loops draw the same bits as the plain ones' '
		"$WFS" --filter F158 --flux-unit abmag --exptime 139.8 --rows 1-1200 -o v.fits br.csv &&
		test_cmp p.fits v.fits &&
		"$WFS" --filter F158 --flux-unit abmag --exptime 139.8 --rows 1-1200 --tile 40 \
			-o v40.fits br.csv &&
		test_cmp p40.fits v40.fits
	'
else
	test_skip 'bright stars: the AVX-512 loops draw the same bits as the plain ones' \
		'this processor has no AVX-512'
fi
test_expect_success 'psf-extent=stips: the square boxes of STIPS, the light beyond them left out' '
	"$WFS" --filter F158 --flux-unit abmag --set psf-extent=stips -o st.fits two.csv &&
	"$PY" -c "
import numpy as np
from astropy.io import fits
a = fits.getdata(\"st.fits\", 1)
y, x = np.nonzero(a)
assert x.max() - x.min() + 1 == 176 and y.max() - y.min() + 1 == 176, (x.min(), x.max())
"
'
test_expect_success 'the report gives the noise the extent follows and the light left out' '
	"$PY" -c "
import json
r = json.load(open(\"clean.json\"))
b = r[\"error_budget\"]
m = r[\"model_settings\"][\"point\"]
assert m[\"psf-extent\"] == \"noise\" and m[\"psf-extent-noise\"] == \"0.1\", m
assert float(b[\"pixel_sigma\"]) > 0, b
f = r[\"flux\"][0]
assert 0.98 < f[\"placed\"] / f[\"requested\"] < 1, f
"
'
# F062's shortest wavelengths put the halo's 2 samples per pixel beyond
# lambda / D: the optics fold the pupil's raster into the transform's
# period (once "pupil does not fit the FFT (2748 > 2160)", exit 1).
test_expect_success 'a 14-mag star in F062 at the defaults: finite, its halo drawn, the flux of the stips box' '
	printf "id,x,y,flux\n1,300.5,100.5,14\n" > f062.csv &&
	"$WFS" --filter F062 --sca 1 --flux-unit abmag --rows 1-200 --report f062.json \
		-o f062.fits f062.csv &&
	"$WFS" --filter F062 --sca 1 --flux-unit abmag --rows 1-200 --set psf-extent=stips \
		-o f062s.fits f062.csv &&
	"$PY" -c "
import json
import numpy as np
from astropy.io import fits
a = fits.getdata(\"f062.fits\", 1).astype(float)
b = fits.getdata(\"f062s.fits\", 1).astype(float)
f = json.load(open(\"f062.json\"))[\"flux\"][0]
print(\"# drawn %.6g, placed %.6g, requested %.6g, stips box %.6g; %d pixels (box 1936)\" %
      (a.sum(), f[\"placed\"], f[\"requested\"], b.sum(), (a != 0).sum()))
assert np.isfinite(a).all() and a.min() >= 0, a.min()
assert (a != 0).sum() > 2 * 44 * 44, (a != 0).sum()
assert abs(a.sum() / f[\"placed\"] - 1) < 1e-6, (a.sum(), f)
assert 0.98 < a.sum() / f[\"requested\"] <= 1, (a.sum(), f)
assert abs(a.sum() / b.sum() - 1) < 0.02, (a.sum(), b.sum())
assert abs(a.max() / b.max() - 1) < 0.02, (a.max(), b.max())
"
'
# The smallest halos (psf-halo-radius 32 to 43 pixels) are narrower than
# the 88- and 176-pixel boxes: the core's scale then takes the model's
# tail where the array has no sample (it read past the array once, and
# an AB 10 star came out beyond float range).  Each star keeps the light
# it keeps with the default halo, to 0.5 %, faint and bright alike.
test_expect_success 'halos narrower than the bright boxes (psf-halo-radius 32): finite, the same light' '
	for m in 0 3 10 14 18 22; do
		printf "id,x,y,flux\n1,2044.5,2044.5,$m\n" > r$m.csv &&
		"$WFS" --filter F158 --flux-unit abmag --exptime 139.8 --report r$m-256.json \
			-o r$m-256.fits r$m.csv &&
		"$WFS" --filter F158 --flux-unit abmag --exptime 139.8 --set psf-halo-radius=32 \
			--report r$m-32.json -o r$m-32.fits r$m.csv || return 1
	done &&
	"$PY" -c "
import json
import numpy as np
from astropy.io import fits
for m in (0, 3, 10, 14, 18, 22):
    kept = []
    for r in (256, 32):
        a = fits.getdata(\"r%d-%d.fits\" % (m, r), 1).astype(float)
        f = json.load(open(\"r%d-%d.json\" % (m, r)))[\"flux\"][0]
        assert np.isfinite(a).all() and a.max() < 1e30, (m, r, a.max())
        kept.append(a.sum() / f[\"requested\"])
    print(\"# AB %d: light kept %.5f (radius 256), %.5f (32)\" % (m, kept[0], kept[1]))
    assert abs(kept[1] / kept[0] - 1) < 5e-3, (m, kept)
"
'
for kv in psf-extent=box psf-extent-noise=0 psf-extent-max=x psf-halo-power=2 \
	psf-halo-radius=8 psf-halo-taper=x psf-halo-far=x; do
	key=${kv%%=*}
	test_expect_success "--set $kv is refused, naming $key" "
		test_must_fail \"\$WFS\" --filter F158 --flux-unit abmag --set $kv \
			-o bad.fits two.csv 2> err &&
		test_grep \"$key: expected\" err &&
		! test -e bad.fits
	"
done
test_done
