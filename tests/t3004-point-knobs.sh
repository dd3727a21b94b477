#!/bin/sh
# The point model's settings: psf-interp, psf-core, psf-wing, psf-box
# (adaptive, with psf-box-noise and psf-box-sigma), psf-blend (source, cell,
# core) and psf-cell.  Each one's effect on the image, and bad values
# refused with a message naming the key and no output left behind.
. "$(dirname "$0")/lib.sh"
require_python

# one bright star and one faint one, far apart, off pixel centres
cat > stars.csv <<EOT
id,x,y,flux
1,1000.3,1000.6,100000
2,3000.7,3000.2,2
EOT
# pixel statistics of an image: the images differ where and as expected.
#   px.py A B CHECK [ARG] [CHECK [ARG]]...: each CHECK of A against B, the
#   two images read once
cat > px.py <<'EOT'
import sys
import numpy as np
from astropy.io import fits
a = fits.getdata(sys.argv[1], 1).astype(float)
b = fits.getdata(sys.argv[2], 1).astype(float)
d = np.abs(a - b)
def cheb(x, y):   # distance to the nearer star along the farther axis (0-based pixels)
    return np.minimum(np.maximum(abs(x - 999.3), abs(y - 999.6)),
                      np.maximum(abs(x - 2999.7), abs(y - 2999.2)))
def near(cx, cy):  # the pixels of b that are not 0 less than 30 px from (cx, cy) each way
    x0, y0 = int(np.floor(cx - 30)) + 1, int(np.floor(cy - 30)) + 1
    y, x = np.nonzero(b[y0:int(np.ceil(cy + 30)), x0:int(np.ceil(cx + 30))])
    return y + y0, x + x0
def one_factor(r):  # beyond R px of each star a / b is one number per star
    for cx, cy in ((999.3, 999.6), (2999.7, 2999.2)):
        y, x = near(cx, cy)
        far = np.maximum(abs(x - cx), abs(y - cy)) >= r
        q = a[y[far], x[far]] / b[y[far], x[far]]
        assert len(q) > 1000 and q.max() - q.min() < 2e-5 * q.max() and abs(q[0] - 1) < 5e-2, \
            (cx, q.min(), q.max())
nonzero = []  # np.nonzero(d), found once
def differ():
    if not nonzero:
        nonzero.extend(np.nonzero(d))
    return nonzero
args = sys.argv[3:]
while args:
    what = args.pop(0)
    if what not in ("outside-core", "bright-same"):
        arg = args.pop(0)
    if what == "core-only":      # differ within R px of a star, and by one factor beyond
        r = float(arg)
        y, x = differ()
        assert len(x) > 0, "no difference"
        assert np.any(cheb(x, y) < r), "no difference in the core"
        one_factor(r)
    elif what == "outside-core":  # differ, and not within 4 px of a star
        y, x = differ()
        assert len(x) > 0, "no difference"
        assert np.all(cheb(x, y) >= 4), (x, y)
    elif what == "close":         # differ, by less than a fraction of the peak
        f = float(arg)
        assert d.max() > 0, "no difference"
        assert d.max() < f * b.max(), (d.max(), b.max())
        assert abs(a.sum() - b.sum()) < f * b.sum(), (a.sum(), b.sum())
    elif what == "same-core":     # identical within R px of the stars
        r = float(arg)
        y, x = differ()
        assert len(x) > 0, "no difference"
        assert np.all(cheb(x, y) >= r), (x, y)
    elif what == "scaled-outside":  # beyond R px of the faint star: one factor, within 5 % of 1
        r = float(arg)
        for cx, cy in ((2999.7, 2999.2),):
            y, x = near(cx, cy)
            far = np.maximum(abs(x - cx), abs(y - cy)) >= r
            q = a[y[far], x[far]] / b[y[far], x[far]]
            assert len(q) > 1000 and q.max() - q.min() < 1e-5 and abs(q[0] - 1) < 5e-2, \
                (cx, q.min(), q.max())
    elif what == "bright-same":    # the bright star identical, the faint one not
        assert np.array_equal(a[900:1100, 900:1100], b[900:1100, 900:1100])
        assert not np.array_equal(a[2950:3050, 2950:3050], b[2950:3050, 2950:3050])
    elif what == "faint-box":     # the faint star's box shrinks, the bright one's not
        h = int(arg)
        fa = np.count_nonzero(a[2950:3050, 2950:3050])
        fb = np.count_nonzero(b[2950:3050, 2950:3050])
        assert fa <= (2 * h) ** 2 and fb == 44 * 44, (fa, fb)
        assert np.array_equal(a[900:1100, 900:1100], b[900:1100, 900:1100])
    else:
        sys.exit("px.py: unknown check " + what)
EOT
# the box evaluation itself: STIPS's boxes (psf-extent=stips), no halo
run() { out=$1; shift; "$WFS" --filter F129 --psf epsf.fits --set psf-extent=stips -o "$out" "$@" stars.csv; }

test_expect_success 'a synthetic ePSF grid; the defaults spelled out change nothing' '
	"$PY" "$TOP/tests/flux_check.py" grid epsf.fits &&
	run def.fits &&
	run expl.fits --set psf-interp=core --set psf-core=4 --set psf-wing=8 --set psf-box=fixed \
		--set psf-blend=core --set psf-cell=512 &&
	test_cmp def.fits expl.fits
'
test_expect_success 'psf-interp=bilinear changes the core (psf-core), and the rest by one factor' '
	run bil.fits --set psf-interp=bilinear &&
	"$PY" px.py bil.fits def.fits core-only 4 &&
	run src.fits --set psf-blend=source &&
	run c2.fits --set psf-blend=source --set psf-core=2 &&
	"$PY" px.py c2.fits src.fits core-only 4
'
test_expect_success 'psf-wing: the nearest sample beyond it, close to bilinear everywhere' '
	run w44.fits --set psf-wing=44 &&
	"$PY" px.py w44.fits def.fits same-core 4 close 1e-3 &&
	run w0.fits --set psf-wing=0 &&
	"$PY" px.py w0.fits def.fits same-core 4 close 1e-2 &&
	"$PY" px.py w0.fits w44.fits close 1e-2
'
test_expect_success 'psf-interp=bicubic changes only pixels beyond the core' '
	run bic.fits --set psf-interp=bicubic &&
	"$PY" px.py bic.fits def.fits outside-core
'
test_expect_success 'psf-blend=core (the default): a faint star is the cell scaled outside the core, close to source; a bright one is blended per source' '
	run cl.fits --set psf-blend=cell &&
	"$PY" px.py def.fits cl.fits scaled-outside 4 &&
	run def2.fits --set psf-core=2 &&
	run cl2.fits --set psf-blend=cell --set psf-core=2 &&
	"$PY" px.py def2.fits cl2.fits scaled-outside 2 &&
	"$PY" px.py def.fits src.fits close 2e-3 bright-same &&
	run bil.fits --set psf-blend=source --set psf-interp=bilinear &&
	run bilc.fits --set psf-interp=bilinear &&
	"$PY" px.py bilc.fits bil.fits close 2e-3
'
test_expect_success 'psf-blend=cell: one blended ePSF per cell, close to the default' '
	run cell.fits --set psf-blend=cell &&
	"$PY" px.py cell.fits def.fits close 0.05 &&
	run cell64.fits --set psf-blend=cell --set psf-cell=64 &&
	"$PY" px.py cell64.fits def.fits close 0.01
'
test_expect_success 'the plain loops draw the same bits as the vector ones' '
	"$BUILD/contrib/starfield" -n 3000 -x -s 7 > field.csv &&
	"$WFS" --filter F129 --psf epsf.fits --set psf-extent=stips --flux-unit abmag -o simd.fits field.csv &&
	WFISCENE_NO_SIMD=1 "$WFS" --filter F129 --psf epsf.fits --set psf-extent=stips --flux-unit abmag -o plain.fits field.csv &&
	test_cmp simd.fits plain.fits &&
	"$WFS" --filter F129 --psf epsf.fits --set psf-extent=stips --flux-unit abmag --set psf-interp=bilinear \
		--set psf-wing=3 -o simd2.fits field.csv &&
	WFISCENE_NO_SIMD=1 "$WFS" --filter F129 --psf epsf.fits --set psf-extent=stips --flux-unit abmag \
		--set psf-interp=bilinear --set psf-wing=3 -o plain2.fits field.csv &&
	test_cmp simd2.fits plain2.fits
'
test_expect_success 'psf-box=adaptive shrinks a faint star to the noise, not a bright one' '
	run ad.fits --set psf-box=adaptive --set psf-box-sigma=0.1 &&
	"$PY" px.py ad.fits def.fits faint-box 8 &&
	run ad2.fits --noise readnoise --readnoise 14 --exptime 139.8 --seed 1 --set psf-box=adaptive &&
	test -s ad2.fits
'
test_expect_success 'psf-box=adaptive without noise stages follows the nominal noise (sky and read noise)' '
	run nom.fits --set psf-box=adaptive --report nom.json &&
	"$PY" -c "
import json
s = float(json.load(open(\"nom.json\"))[\"error_budget\"][\"pixel_sigma\"])
assert abs(s - (0.81 + 144) ** 0.5) < 1, s
" && ! test_cmp nom.fits def.fits >/dev/null
'
test_expect_success '--report names the point settings a run used, as point declares them' '
	run rep.fits --set psf-box=adaptive --set psf-box-sigma=0.1 --set psf-blend=cell \
		--report r.json &&
	"$PY" -c "
import json
b = json.load(open(\"r.json\"))[\"model_settings\"][\"point\"]
assert b[\"psf-interp\"] == \"core\" and b[\"psf-core\"] == \"4\", b
assert b[\"psf-wing\"] == \"8\" and b[\"psf-box-noise\"] == \"0.1\", b
assert b[\"psf-box\"] == \"adaptive\" and b[\"psf-blend\"] == \"cell\", b
assert b[\"psf-box-sigma\"] == \"0.1\" and b[\"psf-cell\"] == \"512\", b
assert list(b) == [\"psf-interp\", \"psf-core\", \"psf-wing\", \"psf-box\",
                   \"psf-box-noise\", \"psf-box-sigma\", \"psf-blend\", \"psf-cell\",
                   \"psf-extent\", \"psf-extent-noise\", \"psf-extent-max\",
                   \"psf-extent-min\", \"psf-extent-cut\", \"psf-colour-steps\",
                   \"psf-halo-colour-steps\", \"psf-halo-power\", \"psf-halo-taper\", \"psf-halo-far\",
                   \"psf-halo-near\", \"psf-diffuse\", \"psf-diffuse-cell\",
                   \"psf-diffuse-floor\"], b
"
'
for kv in psf-interp=cubic psf-core=-1 psf-wing=-2 psf-wing=x psf-box=small psf-box-noise=0 \
	psf-box-sigma=x psf-blend=tile psf-cell=0 psf-cell=10.5 psf-extent-cut=-1 psf-extent-cut=x \
	psf-colour-steps=2.5 psf-colour-steps=65 psf-halo-colour-steps=1.5 \
	psf-halo-colour-steps=65; do
	key=${kv%%=*}
	test_expect_success "--set $kv is refused, naming $key" "
		test_must_fail --status 1 run bad.fits --set $kv 2> err &&
		test_grep \"$key: expected\" err &&
		! test -e bad.fits
	"
done
# The point model keeps room for every blended cell of 18 SCAs from the
# start (a table that filled while several threads prepare would fail
# whichever row came last): a cell so small that this passes its limit is
# refused before any row, with the smallest that fits.
test_expect_success 'psf-cell too small for the table: refused at start, naming the least that fits' '
	test_must_fail --status 1 run bad.fits --set psf-cell=34 2> err &&
	test_grep "psf-cell: 34 pixels .*use 35 or more" err && ! test -e bad.fits &&
	test_must_fail --status 1 run bad.fits --set psf-blend=cell --set psf-cell=61 2> err &&
	test_grep "psf-cell: 61 pixels .*use 62 or more" err && ! test -e bad.fits &&
	run c35.fits --set psf-cell=35 && run c62.fits --set psf-blend=cell --set psf-cell=62
'
test_expect_success 'psf-extent-cut: faint stars in boxes cut by the noise, each pixel within the cut, flux kept; bright ones and STIPS boxes whole' '
	"$PY" -c "
import random
random.seed(3)
print(\"x,y,mag\")
for k in range(100):
    print(\"%.3f,%.3f,%.3f\" % (40 + 60 * (k % 10) + random.random(), 40 + 60 * (k // 10) + random.random(),
          random.uniform(20, 27)))
print(\"1500.4,1500.6,12\")
" > cut.csv &&
	cat > cut.py <<-\PY &&
	import json, sys
	import numpy as np
	from astropy.io import fits
	img = lambda f: [h.data for h in fits.open(f) if h.data is not None][0].astype(float)
	sig = float(json.load(open("cut1.json"))["error_budget"]["pixel_sigma"])
	cut, a, b = float(sys.argv[1]), img(sys.argv[2]), img(sys.argv[3])
	rows = [l.split(",") for l in open("cut.csv").read().split()[1:-1]]
	flux = moved = 0
	for r in rows:
	    x, y = int(float(r[0])), int(float(r[1]))
	    box = (slice(y - 29, y + 29), slice(x - 29, x + 29))
	    flux = max(flux, abs(b[box].sum() - a[box].sum()))
	    moved = max(moved, np.abs(b[box] - a[box]).sum())
	d = np.abs(b - a).max()
	print("cut %g %s: largest change %.3g sigma, flux %.3g sigma, light moved %.3g sigma"
	      % (cut, sys.argv[3], d / sig, flux / sig, moved / sig))
	# every pixel within the cut; the light of each star put back, to a
	# tenth of the cut; no more light moved than the cut leaves out and
	# puts back
	sys.exit(not (d <= cut * sig and flux <= 0.1 * cut * sig and moved <= 2 * cut * sig))
	PY
	"$WFS" --filter F129 --flux-unit abmag --report cut1.json -o cut1.fits cut.csv &&
	"$WFS" --filter F129 --flux-unit abmag --set psf-extent-cut=0 -o cut0.fits cut.csv &&
	"$WFS" --filter F129 --flux-unit abmag --set psf-extent-cut=1 -o cut9.fits cut.csv &&
	! cmp -s cut0.fits cut1.fits &&
	"$PY" cut.py 0.1 cut0.fits cut1.fits &&
	"$PY" cut.py 1 cut0.fits cut9.fits &&
	for set in psf-blend=source psf-interp=bicubic psf-core=8 psf-extent=stips; do
		"$WFS" --filter F129 --flux-unit abmag --set $set -o "c1-$set.fits" cut.csv &&
		"$WFS" --filter F129 --flux-unit abmag --set $set --set psf-extent-cut=0 \
			-o "c0-$set.fits" cut.csv &&
		"$PY" cut.py 0.1 "c0-$set.fits" "c1-$set.fits" || return 1
	done &&
	"$WFS" --filter F129 --flux-unit abmag --set psf-diffuse=none -o cutn1.fits cut.csv &&
	"$WFS" --filter F129 --flux-unit abmag --set psf-diffuse=none --set psf-extent-cut=0 \
		-o cutn0.fits cut.csv &&
	"$PY" -c "
import sys
import numpy as np
from astropy.io import fits
img = lambda f: [h.data for h in fits.open(f) if h.data is not None][0]
a, b = img(\"cutn0.fits\"), img(\"cutn1.fits\")
box = (slice(1499 - 60, 1499 + 60), slice(1499 - 60, 1499 + 60))
# the bright star, and STIPS boxes, untouched (the headers differ by their
# date); without the diffuse light, which the light of a cut box, taken
# from the blend of its cell, moves by some 1e-4 of the wing of a faint star
sys.exit(not (np.array_equal(a[box], b[box]) and
              np.array_equal(img(\"c0-psf-extent=stips.fits\"), img(\"c1-psf-extent=stips.fits\"))))
"
'
# A row's ePSF class follows its catalog magnitude exactly: a star at
# --bright-limit is drawn in the bright class, one an ulp fainter in the
# faint one, on SCAs where the flux's round trip (10^(-0.4 m) and back
# through log10) came back an ulp brighter (1, 4); also a variable star of
# no amplitude, which the point model draws (its flux left as it was).
printf 'id,x,y,mag\n1,2000,2000,14.000000000000002\n' > ulp.csv
printf 'id,x,y,mag\n1,2000,2000,14\n' > at.csv
printf 'id,x,y,mag,type,period,amplitude,phase,shape\n1,2000,2000,14.000000000000002,variable,1,0,0,0\n' > vulp.csv
printf 'id,x,y,mag,type,period,amplitude,phase,shape\n1,2000,2000,14,variable,1,0,0,0\n' > vat.csv
test_expect_success 'the ePSF class is decided from the row magnitude itself' '
	for s in 1 4; do
		for c in ulp at vulp vat; do
			for l in 13.9999 14 14.0001; do
				"$WFS" --filter F146 --sca $s --ra 268 --dec -29 --date 61500 \
					--set psf-extent=stips --bright-limit $l \
					-o "cl-$s-$c-$l.fits" $c.csv || return 1
			done
		done &&
		"$PY" -c "
import sys
import numpy as np
from astropy.io import fits
d = lambda c, l: fits.getdata(\"cl-$s-%s-%s.fits\" % (c, l), 1)
same = lambda a, b: np.array_equal(d(*a), d(*b))
# an ulp fainter: the faint class at the limit; at it: the bright one
sys.exit(not all(same((u, \"14\"), (u, \"13.9999\")) and
                 not same((u, \"14\"), (u, \"14.0001\")) and
                 same((a, \"14\"), (a, \"14.0001\")) and
                 not same((a, \"14\"), (a, \"13.9999\"))
                 for u, a in ((\"ulp\", \"at\"), (\"vulp\", \"vat\"))))
" || return 1
	done
'
test_done
