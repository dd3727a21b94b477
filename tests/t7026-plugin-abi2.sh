#!/bin/sh
# A plugin built against model.h as it was before the exposure's time was
# added (edition 2, frozen in tests/plugins/abi2/) still loads and draws
# the same pixels, with the same calls, beside the time-aware models of
# edition 3, in a run of dated exposures.
. "$(dirname "$0")/lib.sh"
require_python

mkdir plugins
build() {
	name=$1 inc=$2
	shift 2
	${CC:-cc} -std=c11 -Wall -Wextra -Wno-unused-parameter -shared -fPIC \
		-fvisibility=hidden -I"$inc" -Wl,-z,defs "$@" -o "plugins/$name.so" \
		"$TOP/tests/plugins/counts.c" -lm
}
run() { "$WFS" --filter F158 --sca 1 --ra 268 --dec -29 --rows 1900-2200 \
	--plugin-path "$TRASH/plugins" "$@"; }
counted() { sed -n "s/^wfiscene: $2: prepare \([0-9]*\) footprint \([0-9]*\) reach \([0-9]*\)$/\1 \2 \3/p" "$1"; }

test_expect_success 'the counting plugin builds against edition 2 and today'"'"'s model.h' '
	build counts2 "$TOP/tests/plugins/abi2" -DCOUNTS_NAME="\"counts2\"" &&
	build counts "$TOP/include" &&
	! grep -q "mjd" "$TOP/tests/plugins/abi2/wfiscene/model.h"
'
test_expect_success 'a catalog of squares and a lensed star, two dated exposures' '
	printf "ra,dec,flux,type,side,t0,te,u0\n" > new.csv &&
	for k in 0 1 2 3; do
		printf "268.00%d,-29.00%d,%d00,TYPE,%d,,,\n" $((2 * k)) $k $((k + 1)) $((2 * k + 1))
	done >> new.csv &&
	printf "268.01,-29.01,300,microlens,,61500,10,0.3\n" >> new.csv &&
	sed s/TYPE/counts2/ new.csv > old.csv && sed -i s/TYPE/counts/ new.csv &&
	printf "268 -29 0 a - 61500\n268 -29 0 b - 61507\n" > dates.txt
'
test_expect_success 'the edition-2 plugin draws the same pixels as today'"'"'s' '
	run --pointings dates.txt -o "new_%s.fits" --placed "new_%s.csv" new.csv 2> new.err &&
	run --pointings dates.txt -o "old_%s.fits" --placed "old_%s.csv" old.csv 2> old.err &&
	"$PY" -c "
from astropy.io import fits
for e in \"ab\":
    a, b = fits.getdata(\"new_%s.fits\" % e, 1), fits.getdata(\"old_%s.fits\" % e, 1)
    assert (a == b).all() and a.sum() > 0, e
" &&
	test "$(counted new.err counts)" = "4 4 4
4 4 4" &&
	test "$(counted old.err counts2)" = "4 4 4
4 4 4"
'
test_expect_success '... and the lensed star beside it brightens at t0' '
	"$PY" -c "
import numpy as np
a = np.genfromtxt(\"old_a.csv\", delimiter=\",\", names=True, dtype=None, encoding=None)
b = np.genfromtxt(\"old_b.csv\", delimiter=\",\", names=True, dtype=None, encoding=None)
u = 0.3; A = (u * u + 2) / (u * np.sqrt(u * u + 4))
u = np.hypot(0.3, 0.7); B = (u * u + 2) / (u * np.sqrt(u * u + 4))
fa, fb = a[\"flux\"][a[\"model\"] == \"microlens\"][0], b[\"flux\"][b[\"model\"] == \"microlens\"][0]
assert abs(fa / fb / (A / B) - 1) < 1e-5, (fa / fb, A / B)
"
'
# drawn_by: a model that only changes the source, drawn by point
bdrawn() {
	name=$1
	shift
	${CC:-cc} -std=c11 -Wall -Wextra -Wno-unused-parameter -shared -fPIC \
		-fvisibility=hidden -I"$TOP/include" -Wl,-z,defs -DDRAWN_NAME="\"$name\"" "$@" \
		-o "plugins/$name.so" "$TOP/tests/plugins/drawn.c" -lm
}
test_expect_success 'a model drawn by point: its flux and position, point'"'"'s pixels' '
	bdrawn drawn &&
	printf "x,y,flux,type,dx\n2000.3,2050.6,500,drawn,3.5\n" > d.csv &&
	printf "x,y,flux,type\n2003.8,2050.6,1000,point\n" > p.csv &&
	run -o d.fits --placed d-placed.csv d.csv && run -o p.fits p.csv &&
	"$PY" -c "
from astropy.io import fits
a, b = fits.getdata(\"d.fits\", 1), fits.getdata(\"p.fits\", 1)
assert (a == b).all() and a.sum() > 0
" &&
	grep -q "^1,1,2003.8000,2050.6000,1000,.*,drawn$" d-placed.csv
'
test_expect_success 'a model drawn by itself, or by a model drawn by another, is refused' '
	bdrawn selfish -DDRAWN_BY="\"selfish\"" &&
	printf "x,y,flux,type\n2000,2050,500,selfish\n" > s.csv &&
	test_must_fail --status 3 run -o s.fits s.csv 2> err &&
	test_grep "model .selfish.*drawn_by names the model itself" err &&
	bdrawn chain -DDRAWN_BY="\"microlens\"" &&
	printf "x,y,flux,type\n2000,2050,500,chain\n" > c.csv &&
	test_must_fail --status 3 run -o c.fits c.csv 2> err &&
	test_grep "model .chain.*drawn_by names .microlens., which is drawn by another model" err &&
	! test -e s.fits && ! test -e c.fits
'
test_done
