#!/bin/sh
# Models that change with the exposure's date (model.h, edition 3): a
# microlensed star's placed flux over its baseline is the point-lens
# magnification, and a variable star's flux follows its light curve
# (sinusoid, RR Lyrae, eclipsing binary, a curve file), each against an
# independent computation; both are drawn as point sources.
. "$(dirname "$0")/lib.sh"
require_python

run() { "$WFS" --filter F158 --sca 1 --ra 268 --dec -29 --rows 2000-2100 "$@"; }

test_expect_success 'a catalog of lensed, variable and constant stars' '
	cat > stars.csv <<-\EOF &&
	id,ra,dec,mag,type,t0,te,u0,fs,period,amplitude,phase,shape,depth2,width
	1,268.000,-29.000,20,microlens,61500,20,0.1,1,,,,,,
	2,268.004,-29.000,20,microlens,61500,20,0.02,1,,,,,,
	3,268.008,-29.000,20,microlens,61500,20,0.7,0.4,,,,,,
	4,268.012,-29.000,20,point,,,,,,,,,,
	5,268.016,-29.000,19,variable,61400,,,,0.61,0.8,0.1,0,,
	6,268.020,-29.000,19,variable,61400,,,,0.55,1.1,0.3,1,,
	7,268.024,-29.000,19,variable,61400,,,,2.3,0.9,0,2,0.4,0.06
	8,268.028,-29.000,19,variable,61400,,,,1.7,,0.25,3,,
	EOF
	printf "# phase dm\n0 -0.3\n0.2 0.1\n0.5 0.4\n0.9 0\n" > curve.txt &&
	"$PY" -c "
for k in range(30): print(\"268 -29 0 e%02d - %.5f\" % (k, 61500 + 0.173 * k - 2))
print(\"268 -29 0 t0 - 61500\")
" > dates.txt
'
test_expect_success 'every exposure places every star' '
	run --set variable-curve=curve.txt --pointings dates.txt -o "img_%s.fits" \
		--placed "placed_%s.csv" stars.csv &&
	run -o still.fits --set variable-curve=curve.txt --placed still.csv stars.csv &&
	test "$(wc -l < placed_t0.csv)" = 9 && test "$(wc -l < still.csv)" = 9
'
# The placed flux (6 digits) against the formulas, written afresh here.
test_expect_success 'the lensed stars at t0: A(u0) over the baseline, within 0.5 %' '
	"$PY" -c "
import numpy as np
a = np.genfromtxt(\"placed_t0.csv\", delimiter=\",\", names=True, dtype=None, encoding=None)
b = np.genfromtxt(\"still.csv\", delimiter=\",\", names=True, dtype=None, encoding=None)
f = dict(zip(a[\"id\"], a[\"flux\"])); f0 = dict(zip(b[\"id\"], b[\"flux\"]))
A = lambda u: (u * u + 2) / (u * np.sqrt(u * u + 4))
for i, u0, fs in ((1, 0.1, 1), (2, 0.02, 1), (3, 0.7, 0.4)):
    want = fs * A(u0) + 1 - fs
    got = f[i] / f0[i]
    print(i, got, want)
    assert abs(got / want - 1) < 0.005, (i, got, want)
assert f[4] == f0[4]
"
'
test_expect_success '... and the image holds that light (aperture sums, 1 %)' '
	run -o t0.fits --set psf-extent=stips --set variable-curve=curve.txt \
		--date 61500 stars.csv &&
	run -o base.fits --set psf-extent=stips --set variable-curve=curve.txt stars.csv &&
	"$PY" -c "
import numpy as np
from astropy.io import fits
a = fits.getdata(\"t0.fits\", 1).astype(float); b = fits.getdata(\"base.fits\", 1).astype(float)
p = np.genfromtxt(\"still.csv\", delimiter=\",\", names=True, dtype=None, encoding=None)
A = lambda u: (u * u + 2) / (u * np.sqrt(u * u + 4))
x, y = int(round(p[\"x\"][0])) - 1, int(round(p[\"y\"][0])) - 2000
sa = a[y - 12:y + 13, x - 12:x + 13].sum(); sb = b[y - 12:y + 13, x - 12:x + 13].sum()
print(sa / sb, A(0.1))
assert sb > 0 and abs(sa / sb / A(0.1) - 1) < 0.01
"
'
test_expect_success 'the variable stars follow their light curves' '
	"$PY" -c "
import numpy as np
cat = np.genfromtxt(\"stars.csv\", delimiter=\",\", names=True, dtype=None, encoding=None)
base = {r[\"id\"]: r[\"flux\"] for r in np.genfromtxt(\"still.csv\", delimiter=\",\", names=True, dtype=None, encoding=None)}
cx, cy = np.loadtxt(\"curve.txt\", unpack=True)
def dm(r, t):
    ph = ((t - r[\"t0\"]) / r[\"period\"] + r[\"phase\"]) % 1.0
    A, s = r[\"amplitude\"], r[\"shape\"]
    if s == 0: return -A / 2 * np.cos(2 * np.pi * ph)
    if s == 1: return A * (1 - (1 - ph / 0.85) ** 2) - A / 2 if ph < 0.85 else A * (0.5 + 0.5 * np.cos(np.pi * (ph - 0.85) / 0.15)) - A / 2
    if s == 2:
        d1, d2, w = min(ph, 1 - ph), abs(ph - 0.5), r[\"width\"]
        return A * np.sqrt(1 - (d1 / w) ** 2) if d1 < w else A * r[\"depth2\"] * np.sqrt(1 - (d2 / w) ** 2) if d2 < w else 0.0
    return np.interp(ph, np.r_[cx, cx[0] + 1], np.r_[cy, cy[0]])
seen = {}
for line in open(\"dates.txt\"):
    name, t = line.split()[3], float(line.split()[5])
    p = np.genfromtxt(\"placed_%s.csv\" % name, delimiter=\",\", names=True, dtype=None, encoding=None)
    for r in cat[cat[\"type\"] == \"variable\"]:
        got = p[\"flux\"][p[\"id\"] == r[\"id\"]][0] / base[r[\"id\"]]
        want = 10 ** (-0.4 * dm(r, t))
        seen.setdefault(r[\"id\"], []).append(got)
        assert abs(got / want - 1) < 1e-5, (r[\"id\"], t, got, want)
for k, v in seen.items():
    print(k, \"flux from %.3f to %.3f of the catalog'"'"'s\" % (min(v), max(v)))
    assert max(v) / min(v) > 1.3, (k, v)
"
'
test_expect_success 'without a date, the catalog flux' '
	"$PY" -c "
import numpy as np
b = np.genfromtxt(\"still.csv\", delimiter=\",\", names=True, dtype=None, encoding=None)
assert np.allclose(b[\"mag\"], [20, 20, 20, 20, 19, 19, 19, 19]), b[\"mag\"]
"
'
test_expect_success 'bad parameters are refused with the row and column' '
	printf "ra,dec,mag,type,t0,te,u0\n268,-29,20,microlens,61500,20,0\n" > bad.csv &&
	test_must_fail --status 1 run -o bad.fits bad.csv 2> err &&
	test_grep "bad.csv:2: model .microlens.: column .u0." err &&
	printf "ra,dec,mag,type,period,amplitude,shape\n268,-29,20,variable,1,1,7\n" > bad.csv &&
	test_must_fail --status 1 run -o bad.fits bad.csv 2> err &&
	test_grep "bad.csv:2: model .variable.: column .shape.: want 0, 1, 2 or 3" err &&
	printf "ra,dec,mag,type,period,amplitude,shape\n268,-29,20,variable,1,1,3\n" > bad.csv &&
	test_must_fail --status 1 run -o bad.fits bad.csv 2> err &&
	test_grep "variable-curve=FILE" err &&
	printf "0 0\nzero 1\n" > badcurve.txt &&
	test_must_fail --status 1 run --set variable-curve=badcurve.txt -o bad.fits bad.csv 2> err &&
	test_grep "badcurve.txt:2: want two numbers" err &&
	mkdir curvedir &&
	test_must_fail --status 1 run --set variable-curve=curvedir -o bad.fits bad.csv 2> err &&
	test_grep "variable-curve curvedir: is a directory" err &&
	printf "0 0\n0.5 0.3\n1.5 0\n" > mjdish.txt &&
	test_must_fail --status 1 run --set variable-curve=mjdish.txt -o bad.fits bad.csv 2> err &&
	test_grep "bad.csv:2: model .variable.: column .period.: 1 days reads variable-curve mjdish.txt as phases from 0 to 1, but its first column runs from 0 to 1.5" err &&
	printf "0 0\n0.5 0.3\n1 0\n" > whole.txt &&
	run --set variable-curve=whole.txt -o whole.fits bad.csv &&
	printf "ra,dec,mag,type,period,amplitude,shape\n268,-29,20,variable,0,1,3\n" > mjd.csv &&
	run --set variable-curve=mjdish.txt -o mjd.fits mjd.csv &&
	rm -f whole.fits mjd.fits &&
	printf "ra,dec,mag,type,t0,te,u0\n268,-29,20,microlens,61500,20,1e-300\n" > huge.csv &&
	test_must_fail --status 1 run --date 61500 -o bad.fits huge.csv 2> err &&
	test_grep "huge.csv:2: column .mag.: 20 (AB mag) becomes, by its model" err &&
	! test -e bad.fits
'
# Extreme but valid parameters, each row on its own.  Where u is past
# 1e154 (te tiny, or t0 far from the date) A = 1 + 2/u^4 is 1 to the last
# bit, and with fs = 0 the star is its baseline whatever A is: each such
# star is drawn exactly as a point source of the catalog's flux.
xrun() { "$WFS" --filter F158 --sca 1 --ra 150 --dec 0 --rows 1-200 --date 61540.3 "$@"; }
test_expect_success 'lensed stars at extreme u or with fs = 0: the baseline, finite' '
	printf "id,x,y,mag,type\n1,100,100,20,point\n" > pt.csv &&
	xrun -o pt.fits --placed pt_p.csv pt.csv &&
	k=0 &&
	for row in 61540.2,1e-300,1e-300,1 1e300,1,1,1 1e150,1e-6,1,1 \
		-1.7e308,1e-300,1,1 61540.3,1,1e-310,0 61540.3,1,5e-324,0
	do
		k=$((k + 1)) &&
		printf "id,x,y,mag,type,t0,te,u0,fs\n1,100,100,20,microlens,%s\n" \
			"$row" > ext.csv &&
		xrun -o ext_$k.fits --placed ext_$k.csv ext.csv &&
		test "$(cut -d, -f5 ext_$k.csv)" = "$(cut -d, -f5 pt_p.csv)" ||
		{ echo "row $row: $(cat ext_$k.csv)"; exit 1; }
	done &&
	"$PY" -c "
import glob
import numpy as np
from astropy.io import fits
b = fits.getdata(\"pt.fits\", 1)
names = sorted(glob.glob(\"ext_*.fits\"))
assert len(names) == 6, names
for n in names:
    a = fits.getdata(n, 1)
    print(n, a.sum(), b.sum())
    assert np.isfinite(a).all() and a.sum() > 0, n
    assert (a == b).all(), n
"
'
test_expect_success '... and A past the largest double is refused by the 1e32 limit, not NaN' '
	for u0 in 1e-310 5e-324
	do
		printf "id,x,y,mag,type,t0,te,u0,fs\n1,100,100,20,microlens,61540.3,1,%s,1\n" \
			"$u0" > tiny.csv &&
		test_must_fail --status 1 xrun -o bad.fits tiny.csv 2> err &&
		test_grep "tiny.csv:2: column .mag.: 20 (AB mag) becomes, by its model, .* more than the 1e32" err &&
		! grep -qi nan err && ! test -e bad.fits || exit 1
	done &&
	# A faint enough star (flux 1e-300) is magnified by A = 1/u = 1e310
	# to a finite 1e10, as the formula has it.
	printf "id,x,y,flux,type,t0,te,u0,fs\n1,100,100,1e-300,microlens,61540.3,1,1e-310,1\n" > faint.csv &&
	xrun -o faint.fits --placed faint_p.csv faint.csv &&
	test "$(sed -n 2p faint_p.csv | cut -d, -f5)" = 1e+10
'
test_done
