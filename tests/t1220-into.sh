#!/bin/sh
# --into: sources added to an existing image, placed by its own WCS.  The
# difference image is a run on an empty image; the header and WCS are kept.
# An image of another SCA, filter or unit is refused before anything is
# written.
. "$(dirname "$0")/lib.sh"
require_python

stars() {
	"$PY" -c "
import random, sys
r = random.Random(int(sys.argv[1]))
print('ra,dec,mag')
for i in range(int(sys.argv[2])):
    print('%.8f,%.8f,%.3f' % (10 + r.uniform(-0.06, 0.06), 20 + r.uniform(-0.06, 0.06),
                              r.uniform(18, 24)))" "$@"
}

# Per mapped HDU: the largest |(out - base) - added| relative to the
# added light's peak; and whether each header card of base is in out
# unchanged (out may only add HISTORY cards).
cat > check.py <<'PY'
import sys
import numpy as np
from astropy.io import fits
base, out, added = (fits.open(p) for p in sys.argv[1:4])
pick = lambda hl, name: hl[int(name[1:])] if name[0] == "#" else hl[name]
names = sys.argv[4].split(",")
for k, name in enumerate(names):
    b, o = pick(base, name), pick(out, name)
    a = pick(added, sys.argv[5].split(",")[k]).data.astype(float)
    d = o.data.astype(float) - b.data.astype(float)
    ny, nx = d.shape
    peak = np.abs(a).max()
    err = np.abs(d - a[:ny, :nx]).max() / peak if peak > 0 else np.abs(d).max()
    assert peak > 0, "no light added on " + name
    assert np.abs(a[ny:, :]).max(initial=0) == 0 and np.abs(a[:, nx:]).max(initial=0) == 0
    extra = [c for c in o.header.cards if c.keyword not in b.header or c.keyword == "HISTORY"]
    lost = [c.keyword for c in b.header.cards
            if c.keyword not in ("HISTORY", "COMMENT", "") and o.header.get(c.keyword) != c.value]
    assert not lost, lost
    assert all(c.keyword == "HISTORY" for c in extra), extra
    nh = lambda h: sum(1 for c in h.cards if c.keyword == "HISTORY")
    assert nh(o.header) == nh(b.header) + 1, (nh(o.header), nh(b.header))
    assert err < 1e-6, (name, err)
    print(name, "%.2g" % err)
PY

test_expect_success 'setup: a simulated exposure of two SCAs, with noise' '
	stars 1 300 > a.csv && stars 2 60 > b.csv &&
	"$WFS" --filter F129 --ra 10 --dec 20 --pa 30 --sca 1,4 --background avg --noise all \
		-o base.fits a.csv
'
test_expect_success 'injected into wfiscene'"'"'s own image: the difference is the empty run' '
	"$WFS" --filter F129 --sca 1,4 --into base.fits --placed inj.csv -o inj.fits b.csv &&
	"$WFS" --filter F129 --ra 10 --dec 20 --pa 30 --sca 1,4 --placed empty.csv -o empty.fits b.csv &&
	test_cmp empty.csv inj.csv &&
	"$PY" check.py base.fits inj.fits empty.fits WFI01 WFI01
'
test_expect_success 'the image is kept whole: its other HDUs and header untouched' '
	"$WFS" --filter F129 --sca 1 --into base.fits -o inj1.fits b.csv &&
	"$PY" -c "
import numpy as np
from astropy.io import fits
a, b = fits.open(\"base.fits\"), fits.open(\"inj1.fits\")
assert len(a) == len(b)
assert np.array_equal(a[\"WFI04\"].data, b[\"WFI04\"].data)
assert a[0].header == b[0].header
assert a[\"WFI04\"].header == b[\"WFI04\"].header"
'
test_expect_success 'an output name with cfitsio syntax is taken literally, no temporary left' '
	mkdir lit &&
	"$WFS" --filter F129 --sca 1 --into base.fits -o "lit/x[1].fits" b.csv &&
	"$PY" -c "
import numpy as np
from astropy.io import fits
a, b = fits.open(\"inj1.fits\"), fits.open(\"lit/x[1].fits\")
assert len(a) == len(b)
assert all(np.array_equal(x.data, y.data) for x, y in zip(a, b))" &&
	test "$(ls -A lit)" = "x[1].fits"
'

test_expect_success '-o naming the --into image itself is refused, the image intact' '
	cp base.fits self.fits &&
	test_must_fail --status 1 "$WFS" --filter F129 --sca 1 --into self.fits -o self.fits \
		b.csv 2>err &&
	test_grep "same file" err &&
	cmp base.fits self.fits
'

SHIM=$TRASH/enospc.so
if cc -shared -fPIC -o "$SHIM" "$TOP/tests/shim/enospc.c" -ldl 2>/dev/null; then
	test_expect_success 'the disk full while adding to the image: exit 2, nothing left' '
		# the scene (67 MB) fits, the image with it added (134 MB) does not
		mkdir full &&
		test_must_fail --status 2 env WFS_ENOSPC_MATCH="$TRASH/full/" \
			WFS_ENOSPC_AFTER=80000000 LD_PRELOAD="$SHIM" \
			"$WFS" --filter F129 --sca 1 --into base.fits -o full/inj.fits b.csv 2>err &&
		test_grep "full/inj.fits: error writing" err &&
		test -z "$(ls -A full)"
	'
else
	test_skip 'disk full while adding' 'cannot build tests/shim/enospc.c'
fi
test_expect_success '--noise poisson adds the photon noise of the added light only' '
	"$WFS" --filter F129 --sca 1 --into base.fits --noise poisson --seed 5 -o injn.fits b.csv &&
	"$PY" -c "
import numpy as np
from astropy.io import fits
base = fits.getdata(\"base.fits\", \"WFI01\").astype(float)
d = fits.getdata(\"injn.fits\", \"WFI01\").astype(float) - base
m = fits.getdata(\"empty.fits\", \"WFI01\").astype(float)
assert np.abs(d[m == 0]).max() < 1e-3
hot = m > 50
assert np.abs(d[hot] - m[hot]).max() > 1, \"no noise\"
z = (d[hot] - m[hot]) / np.sqrt(m[hot])
assert 0.8 < z.std() < 1.2, z.std()"
'

# An image from elsewhere: 1200 x 900 pixels of 0.08", rotated, with SIP
# distortion, in the primary HDU; and the same header on zeros.
cat > foreign.py <<'PY'
import numpy as np
from astropy.io import fits
h = fits.Header()
h["CTYPE1"], h["CTYPE2"] = "RA---TAN-SIP", "DEC--TAN-SIP"
h["CRVAL1"], h["CRVAL2"] = 10.0, 20.0
h["CRPIX1"], h["CRPIX2"] = 600.5, 450.5
c, s = np.cos(np.radians(20)), np.sin(np.radians(20))
sc = 0.08 / 3600
h["CD1_1"], h["CD1_2"], h["CD2_1"], h["CD2_2"] = -sc * c, sc * s, sc * s, sc * c
h["A_ORDER"], h["B_ORDER"] = 2, 2
h["A_2_0"], h["A_0_2"], h["B_1_1"] = 2e-6, -1e-6, 3e-6
h["BUNIT"] = "counts/s"
h["OBSERVER"] = "someone"
rng = np.random.default_rng(3)
fits.PrimaryHDU(rng.normal(100, 5, (900, 1200)).astype(np.float32), h).writeto("img.fits")
fits.PrimaryHDU(np.zeros((900, 1200), np.float32), h).writeto("zero.fits")
PY

test_expect_success 'any image with a celestial WCS (SIP): placed by its WCS' '
	"$PY" foreign.py &&
	"$WFS" --filter F129 --into img.fits --placed fp.csv -o fimg.fits b.csv &&
	"$WFS" --filter F129 --into "zero.fits[0]" -o fzero.fits b.csv &&
	"$PY" check.py img.fits fimg.fits fzero.fits "#0" "#0" &&
	"$PY" -c "
import numpy as np
from astropy.io import fits
from astropy.table import Table
from astropy.wcs import WCS
w = WCS(fits.getheader(\"img.fits\"))
cat, pl = Table.read(\"b.csv\"), Table.read(\"fp.csv\")
assert len(pl) > 5
for r in pl:
    x, y = w.all_world2pix([[cat[\"ra\"][r[\"id\"] - 1], cat[\"dec\"][r[\"id\"] - 1]]], 1)[0]
    assert abs(x - r[\"x\"]) < 2e-4 and abs(y - r[\"y\"]) < 2e-4, (x, y, r)
print(len(pl), \"placed by the SIP WCS\")"
'
test_expect_success 'bad --into: named with the file and HDU at fault' '
	test_must_fail --status 1 "$WFS" --filter F129 --sca 1,2 --into base.fits -o x.fits b.csv 2> err &&
	test_grep "no image HDU .WFI02. for SCA 2" err &&
	test_must_fail --status 1 "$WFS" --filter F129 --sca 1,4 --into "base.fits[1]" -o x.fits b.csv 2> err &&
	test_grep "one HDU stands for one SCA; the scene has 2" err &&
	test_must_fail --status 1 "$WFS" --filter F129 --into "base.fits[7]" -o x.fits b.csv 2> err &&
	test_grep "HDU 7: the file has HDUs 0 to 2" err &&
	test_must_fail --status 1 "$WFS" --filter F129 --into "base.fits[0]" -o x.fits b.csv 2> err &&
	test_grep "base.fits\[0\]: not a two-dimensional image" err &&
	"$PY" -c "
from astropy.io import fits
import numpy as np
fits.PrimaryHDU(np.zeros((10, 10), np.float32)).writeto(\"nowcs.fits\")" &&
	test_must_fail --status 1 "$WFS" --filter F129 --into nowcs.fits -o x.fits b.csv 2> err &&
	test_grep "nowcs.fits\[0\]: the WCS is not celestial" err &&
	test_must_fail --status 1 "$WFS" --filter F129 --into base.fits -o - b.csv 2> err &&
	test_grep "one output file, without --pointings, --rows" err &&
	test_must_fail --status 2 "$WFS" --filter F129 --into missing.fits -o x.fits b.csv 2> err &&
	test_grep "missing.fits" err &&
	test ! -e x.fits
'
# The light is drawn with the SCA's PSF and zeropoint, in --filter and
# --bunit: an image that says it is another (EXTNAME or DETECTOR WFInn,
# FILTER or ASDF optical_element, BUNIT) is refused, and nothing written.
test_expect_success 'an HDU of another SCA (EXTNAME or DETECTOR) is refused, nothing written' '
	"$WFS" --filter F129 --ra 10 --dec 20 --pa 30 --sca 1 -o one.fits a.csv &&
	test_must_fail --status 1 "$WFS" --filter F129 --sca 2 --into one.fits -o x.fits \
		--placed x.csv b.csv 2> err &&
	test_grep "one.fits\[1\] holds WFI01: give --sca 1 (and that SCA only)" err &&
	test_must_fail --status 1 "$WFS" --filter F129 --sca 4 --into "base.fits[WFI01]" \
		-o x.fits b.csv 2> err &&
	test_grep "base.fits\[1\] holds WFI01: give --sca 1 " err &&
	"$PY" -c "
from astropy.io import fits
h = fits.open(\"zero.fits\")
h[0].header[\"DETECTOR\"] = \"WFI03\"
h.writeto(\"det3.fits\")" &&
	test_must_fail --status 1 "$WFS" --filter F129 --into det3.fits -o x.fits b.csv 2> err &&
	test_grep "det3.fits\[0\] holds WFI03: give --sca 3 " err &&
	test ! -e x.fits && test ! -e x.csv &&
	"$WFS" --filter F129 --sca 3 --into det3.fits -o y3.fits b.csv &&
	"$WFS" --filter F129 --sca 1 --into one.fits --placed y1.csv -o y1.fits b.csv &&
	test_cmp empty.csv y1.csv &&
	"$PY" check.py one.fits y1.fits empty.fits WFI01 WFI01
'
test_expect_success 'an image of another filter (FILTER, ASDF optical_element) is refused' '
	test_must_fail --status 1 "$WFS" --filter F158 --sca 1 --into one.fits -o x.fits \
		--placed x.csv b.csv 2> err &&
	test_grep "one.fits\[1\] is in F129 (FILTER): give --filter F129, not F158" err &&
	test ! -e x.fits && test ! -e x.csv &&
	"$WFS" --filter F129 --ra 10 --dec 20 --pa 30 --sca 1 --level 2 --detector none \
		-o l2.asdf b.csv &&
	test_must_fail --status 1 "$WFS" --filter F158 --into l2.asdf -o x.asdf \
		--placed x.csv b.csv 2> err &&
	test_grep "l2.asdf is in F129 (meta.instrument.optical_element): give --filter F129, not F158" err &&
	test ! -e x.asdf && test ! -e x.csv &&
	"$WFS" --filter f129 --into l2.asdf -o y.asdf b.csv &&
	test -s y.asdf
'
test_expect_success 'an image in the other unit (BUNIT counts/s or counts) is refused' '
	test_must_fail --status 1 "$WFS" --filter F129 --sca 1 --bunit counts --exptime 100 \
		--into one.fits -o x.fits --placed x.csv b.csv 2> err &&
	test_grep "one.fits\[1\] is in counts/s (BUNIT): give --bunit counts/s, not counts" err &&
	"$WFS" --filter F129 --ra 10 --dec 20 --pa 30 --sca 1 --bunit counts --exptime 100 \
		-o cnt.fits a.csv &&
	test_must_fail --status 1 "$WFS" --filter F129 --sca 1 --into cnt.fits -o x.fits \
		--placed x.csv b.csv 2> err &&
	test_grep "cnt.fits\[1\] is in counts (BUNIT): give --bunit counts, not counts/s" err &&
	test ! -e x.fits && test ! -e x.csv &&
	"$WFS" --filter F129 --sca 1 --bunit counts --exptime 100 --into cnt.fits -o yc.fits b.csv &&
	"$WFS" --filter F129 --ra 10 --dec 20 --pa 30 --sca 1 --bunit counts --exptime 100 \
		-o cempty.fits b.csv &&
	"$PY" check.py cnt.fits yc.fits cempty.fits WFI01 WFI01
'
test_done
