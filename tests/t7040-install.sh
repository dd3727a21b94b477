#!/bin/sh
# make install, and a model plugin written outside the tree: the installed
# files are all there; the installed wfiscene finds its own plugins with no
# help (also when installed under DESTDIR and run from there); the complete
# model of wfiscene-model(7), taken from the page as mandoc renders it,
# builds with nothing but
#   cc -shared -fPIC $(pkg-config --cflags wfiscene-model) square.c -o square.so
# against the installed files, and renders in a scene, found through
# --plugin-path, WFISCENE_PLUGIN_PATH and the installed plugin directory.
. "$(dirname "$0")/lib.sh"
require_python

inst=$TRASH/inst
PKG_CONFIG_PATH=$inst/lib/pkgconfig
export PKG_CONFIG_PATH

test_expect_success 'make install PREFIX=... after make: program, plugins, header, .pc, man pages' '
	wfs_install "$inst" >install.log 2>&1 || { cat install.log; false; } &&
	test -x "$inst/bin/wfiscene" &&
	for m in point sersic-quick sersic-precise; do
		test -f "$inst/lib/wfiscene/$m.so" || { echo "no $m.so"; exit 1; }
	done &&
	cmp "$TOP/include/wfiscene/model.h" "$inst/include/wfiscene/model.h" &&
	test -f "$inst/share/man/man1/wfiscene.1" &&
	test -f "$inst/share/man/man5/wfiscene-catalog.5" &&
	test -f "$inst/share/man/man7/wfiscene-model.7" &&
	test "$(pkg-config --variable=plugindir wfiscene-model)" = "$inst/lib/wfiscene" &&
	test "$(echo $(pkg-config --cflags wfiscene-model))" = "-I$inst/include -fvisibility=hidden" &&
	test "$(echo $(pkg-config --libs wfiscene-model))" = "-Wl,-z,defs"
'

printf 'x,y,flux,type\n1000.5,1200.25,1000,point\n' >star.csv
test_expect_success 'the installed wfiscene finds its installed plugins by itself' '
	mkdir elsewhere && cd elsewhere &&
	env -u WFISCENE_PLUGIN_PATH "$inst/bin/wfiscene" --filter F129 --sca 1 \
		--psf "$PSF" -o inst.fits ../star.csv &&
	"$WFS" --filter F129 --sca 1 --psf "$PSF" -o build.fits ../star.csv &&
	cmp build.fits inst.fits
'

test_expect_success 'its search path ends with the installed plugin directory' '
	printf "x,y,flux,type\n10,10,1,nosuchmodel\n" >nosuch.csv &&
	test_must_fail --status 1 env -u WFISCENE_PLUGIN_PATH "$inst/bin/wfiscene" \
		--filter F129 --sca 1 -o x.fits nosuch.csv 2>err &&
	test_grep "plugin path $inst/lib/wfiscene$" err
'

test_expect_success 'make install DESTDIR=...: staged files name PREFIX, and run from the stage' '
	wfs_install /opt/wfiscene-test DESTDIR="$TRASH/stage" >stage.log 2>&1 ||
		{ cat stage.log; false; } &&
	st=$TRASH/stage/opt/wfiscene-test &&
	test -x "$st/bin/wfiscene" && test -f "$st/lib/wfiscene/point.so" &&
	test -f "$st/include/wfiscene/model.h" &&
	test -f "$st/share/man/man7/wfiscene-model.7" &&
	test_grep "^plugindir=/opt/wfiscene-test/lib/wfiscene$" "$st/lib/pkgconfig/wfiscene-model.pc" &&
	! test -e /opt/wfiscene-test &&
	env -u WFISCENE_PLUGIN_PATH "$st/bin/wfiscene" --filter F129 --sca 1 \
		--psf "$PSF" -o staged.fits star.csv &&
	"$WFS" --filter F129 --sca 1 --psf "$PSF" -o build.fits star.csv &&
	cmp build.fits staged.fits
'

# The complete model of wfiscene-model(7), as a reader sees it.
test_expect_success 'the first model of wfiscene-model(7) is complete code' '
	mandoc -Tascii "$TOP/man/wfiscene-model.7" | sed "s/.\x08//g" |
		awk "/\\/\\* square\\.c - /{ on = 1 } on { print }
		     on && /^ *}\$/ && last ~ /square_model : NULL/ { exit }
		     { last = \$0 }" >square.c &&
	test_grep "wfs_model_entry" square.c && test "$(wc -l <square.c)" -gt 100
'

test_expect_success 'it builds with the bare pkg-config command against the installed files' '
	cc -shared -fPIC $(pkg-config --cflags wfiscene-model) square.c -o square.so &&
	nm -D --defined-only square.so | awk "{ print \$3 }" | grep -v "^_" >syms &&
	echo wfs_model_entry >want && test_cmp want syms &&
	${CC:-cc} -std=c11 -Wall -Wextra -pedantic -Werror -shared -fPIC \
		$(pkg-config --cflags wfiscene-model) square.c -o strict.so
'

# Two squares on SCA 1 (1-based catalog pixels): one whole, one cut by
# the detector's corner.  Each pixel holds the flux of the part of the
# square in it.
printf 'x,y,flux,type,side\n100.3,200.8,1000,square,3.5\n4088,4088,500,square,10\n' >sq.csv
cat >check.py <<'EOF'
import sys
import numpy as np
from astropy.io import fits
d = fits.getdata(sys.argv[1], 'WFI01').astype(np.float64)
# whole: 0-based centre (99.3, 199.8), half-side 1.75
cut = d[190:210, 90:110]
assert abs(cut.sum() - 1000) < 1e-3, cut.sum()
level = 1000 / 3.5 ** 2
assert abs(d[199, 99] - level) < 1e-4 * level, (d[199, 99], level)
assert abs(d[199, 98] - 0.95 * level) < 1e-4 * level, d[199, 98]
assert d[199, 97] == 0 and d[199, 102] == 0 and d[197, 99] == 0 and d[203, 99] == 0
assert abs(d[202, 99] - 0.05 * level) < 1e-4 * level, d[202, 99]
# cut: centre at the last pixel (4087, 4087), 5.5 x 5.5 of 10 x 10 inside
corner = d[4070:, 4070:].sum()
assert abs(corner - 500 * 0.55 ** 2) < 1e-3, corner
assert abs(d.sum() - 1000 - 500 * 0.55 ** 2) < 1e-2, d.sum()
print('ok')
EOF

test_expect_success 'the installed wfiscene renders it from --plugin-path' '
	env -u WFISCENE_PLUGIN_PATH "$inst/bin/wfiscene" --filter F129 --sca 1 \
		--plugin-path . -o sq1.fits sq.csv &&
	"$PY" check.py sq1.fits
'

test_expect_success 'the same from WFISCENE_PLUGIN_PATH, on any tiles and threads' '
	mkdir run && cd run &&
	WFISCENE_PLUGIN_PATH=$TRASH "$inst/bin/wfiscene" --filter F129 --sca 1 \
		--threads 3 --tile 64 -o sq2.fits ../sq.csv &&
	"$PY" -c "
import numpy as np
from astropy.io import fits
a = fits.getdata(\"sq2.fits\", \"WFI01\"); b = fits.getdata(\"../sq1.fits\", \"WFI01\")
assert np.array_equal(a, b)
"'

test_expect_success 'installed into the plugin directory, it needs no path at all' '
	install -m 755 square.so "$(pkg-config --variable=plugindir wfiscene-model)/" &&
	mkdir run2 && cd run2 &&
	env -u WFISCENE_PLUGIN_PATH "$inst/bin/wfiscene" --filter F129 --sca 1 \
		-o sq3.fits ../sq.csv &&
	"$PY" ../check.py sq3.fits
'

test_expect_success 'a bad row is refused with the page'"'"'s message' '
	printf "x,y,flux,type,side\n100,100,10,square,0\n" >bad.csv &&
	test_must_fail --status 1 env -u WFISCENE_PLUGIN_PATH "$inst/bin/wfiscene" \
		--filter F129 --sca 1 -o bad.fits bad.csv 2>err &&
	test_grep "^wfiscene: bad.csv:2: model .square.: side must be above 0 and at most 1000 pixels: 0$" err &&
	! test -e bad.fits
'

test_done
