#!/bin/sh
# contrib/moffat, the example model that is not in the core, built with its
# own Makefile the way an outside author would: against the header in the
# tree, and against an installed wfiscene through pkg-config.  The star it
# draws carries the row's flux, sits where the row says, and turns with
# theta; bad parameters are refused with a message.
. "$(dirname "$0")/lib.sh"
require_python

cp -R "$TOP/contrib/moffat" src-tree && cp -R "$TOP/contrib/moffat" src-inst

test_expect_success 'builds against the in-tree header with its Makefile' '
	make -s -C src-tree WFS_CFLAGS=-I"$TOP/include" &&
	test -f src-tree/moffat.so
'

test_expect_success 'exports wfs_model_entry and nothing else' '
	nm -D --defined-only src-tree/moffat.so | awk "{ print \$3 }" |
		grep -v "^_" >syms &&
	echo wfs_model_entry >want &&
	test_cmp want syms
'

# stars: three Moffat stars on SCA 1 (1-based catalog pixels) and the
# checks on the image: flux, centroid and orientation of each.
cat >stars.csv <<'EOF'
x,y,flux,type,beta,fwhm,ellip,theta
1000.3,1200.7,1000,moffat,3,2.5,,
2500,2500,500,moffat,4.765,1.2,0,0
3001.5,900.25,2000,moffat,2.5,4,0.5,30
EOF

cat >check.py <<'EOF'
import sys, math
import numpy as np
from astropy.io import fits
img = fits.getdata(sys.argv[1], 'WFI01').astype(np.float64)
stars = [(1000.3, 1200.7, 1000, None), (2500, 2500, 500, None),
         (3001.5, 900.25, 2000, 30.0)]
for x, y, flux, theta in stars:
    cx, cy = int(round(x)) - 1, int(round(y)) - 1
    h = 60
    cut = img[cy - h:cy + h + 1, cx - h:cx + h + 1]
    yy, xx = np.mgrid[cy - h:cy + h + 1, cx - h:cx + h + 1]
    tot = cut.sum()
    assert abs(tot / flux - 1) < 2e-3, ('flux', x, y, tot, flux)
    mx, my = (cut * xx).sum() / tot, (cut * yy).sum() / tot
    # catalog pixels are 1-based, numpy's 0-based
    assert abs(mx - (x - 1)) < 0.01 and abs(my - (y - 1)) < 0.01, ('centre', x, y, mx, my)
    if theta is not None:
        # second moments inside 3 FWHM: the major axis angle from +x to +y
        r2 = (xx - mx) ** 2 + (yy - my) ** 2
        w = cut * (r2 < 144)
        sxx = (w * (xx - mx) ** 2).sum(); syy = (w * (yy - my) ** 2).sum()
        sxy = (w * (xx - mx) * (yy - my)).sum()
        ang = 0.5 * math.degrees(math.atan2(2 * sxy, sxx - syy))
        assert abs(ang - theta) < 1, ('theta', ang, theta)
print('ok')
EOF

test_expect_success 'renders stars with the right flux, place and angle' '
	"$WFS" --filter F129 --sca 1 --plugin-path src-tree -o stars.fits stars.csv &&
	"$PY" check.py stars.fits
'

test_expect_success 'the same image on one thread and many, any tile size' '
	"$WFS" --filter F129 --sca 1 --plugin-path src-tree --threads 1 --tile 64 \
		-o one.fits stars.csv &&
	"$PY" -c "
import numpy as np
from astropy.io import fits
a = fits.getdata(\"one.fits\", \"WFI01\"); b = fits.getdata(\"stars.fits\", \"WFI01\")
assert np.array_equal(a, b), abs(a - b).max()
"'

bad() {
	printf 'x,y,flux,type,beta,fwhm,ellip\n100,100,10,moffat,%s,%s,%s\n' "$1" "$2" "$3" >bad.csv &&
	test_must_fail --status 1 "$WFS" --filter F129 --sca 1 --plugin-path src-tree \
		-o bad.fits bad.csv 2>err &&
	test_grep "bad.csv:2" err &&
	test_grep "$4" err &&
	! ls -A | grep -q "bad\.fits"
}

test_expect_success 'bad parameters are refused with the row and the reason' '
	bad 1 2 0 "beta must be above 1" &&
	bad 3 -1 0 "fwhm must be a positive" &&
	bad 3 2 1 "ellip must be at least 0 and below 1" &&
	bad 1.05 2 0 "beyond 512 pixels"
'

test_expect_success 'a missing required column is named' '
	printf "x,y,flux,type,fwhm\n100,100,10,moffat,2\n" >nobeta.csv &&
	test_must_fail "$WFS" --filter F129 --sca 1 --plugin-path src-tree \
		-o nobeta.fits nobeta.csv 2>err &&
	test_grep "beta" err &&
	! test -e nobeta.fits
'

# make install PREFIX=...: the program, header, pkg-config file and plugin
# directory an outside author builds against.
inst=$TRASH/inst
test_expect_success 'make install puts header, pkg-config file and man pages in place' '
	make -s -C "$TOP" install PREFIX="$inst" >install.log 2>&1 ||
		{ cat install.log; false; } &&
	test -f "$inst/include/wfiscene/model.h" &&
	test -f "$inst/lib/pkgconfig/wfiscene-model.pc" &&
	test -x "$inst/bin/wfiscene" &&
	test -d "$inst/lib/wfiscene" &&
	PKG_CONFIG_PATH=$inst/lib/pkgconfig pkg-config --cflags wfiscene-model >cflags &&
	test_grep "$inst/include" cflags &&
	test_grep "fvisibility=hidden" cflags &&
	PKG_CONFIG_PATH=$inst/lib/pkgconfig pkg-config --variable=plugindir wfiscene-model >dir &&
	test "$(cat dir)" = "$inst/lib/wfiscene"
'

test_expect_success 'builds against the installed copy through pkg-config' '
	PKG_CONFIG_PATH=$inst/lib/pkgconfig make -C src-inst >build.log 2>&1 ||
		{ cat build.log; false; } &&
	test_grep "$inst/include" build.log &&
	PKG_CONFIG_PATH=$inst/lib/pkgconfig make -s -C src-inst install &&
	test -f "$inst/lib/wfiscene/moffat.so"
'

test_expect_success 'the installed wfiscene finds it in the plugin directory' '
	env WFISCENE_PLUGIN_PATH="$inst/lib/wfiscene" "$inst/bin/wfiscene" \
		--filter F129 --sca 1 -o inst.fits stars.csv &&
	"$PY" check.py inst.fits
'

test_done
