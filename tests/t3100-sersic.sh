#!/bin/sh
# Sersic galaxies from the command line: mixed with stars in one catalog,
# the flux they carry, the methods and flux meanings, and bad rows.
. "$(dirname "$0")/lib.sh"
require_python

# catalog x, y are 1-based pixels on SCA 1
cat > mix.csv <<'CSV'
x,y,flux,type,n,re,phi,ratio
100.3,100.6,1000,point,,,,
200.3,100.6,1000,sersic,1,0.01,0,1
300.3,100.6,1000,sersic-precise,1,0.01,0,1
400.5,400.5,5000,sersic-precise,1,4,30,0.5
600.5,400.5,5000,sersic-quick,1,4,30,0.5
CSV

# sum of the image in a (2h+1)^2 box about 1-based (x, y)
cat > boxsum.py <<'PY'
import sys
from astropy.io import fits
d = [h.data for h in fits.open(sys.argv[1]) if h.data is not None][0].astype(float)
h = int(sys.argv[2])
for a in sys.argv[3:]:
    x, y = (float(v) for v in a.split(","))
    i, j = int(round(x - 1)), int(round(y - 1))
    print("%.6f" % d[j - h:j + h + 1, i - h:i + h + 1].sum())
PY

test_expect_success 'stars and galaxies render from one catalog' '
	"$WFS" --filter F129 -o mix.fits mix.csv && test -s mix.fits
'
test_expect_success 'a galaxy with re = 0.01 carries a point source'"'"'s flux' '
	"$PY" boxsum.py mix.fits 25 100.3,100.6 200.3,100.6 300.3,100.6 > sums &&
	"$PY" -c "
import sys
p, q, r = (float(v) for v in open(\"sums\"))
sys.exit(not (abs(q / p - 1) < 1e-3 and abs(r / p - 1) < 1e-3 and 980 < p < 1000))
"
'
test_expect_success 'extended galaxies carry their flux times the ePSF enclosed fraction' '
	"$PY" boxsum.py mix.fits 60 400.5,400.5 600.5,400.5 > sums &&
	"$PY" -c "
import sys
a, b = (float(v) for v in open(\"sums\"))
sys.exit(not (0.97 < a / 5000 < 1.0 and abs(b / a - 1) < 5e-3))
"
'
test_expect_success '--sersic-flux ie: the flux column is the intensity at re, total includes q' '
	printf "x,y,flux,type,n,re,phi,ratio\n400.5,400.5,1,sersic,1,3,0,0.5\n" > ie.csv &&
	"$WFS" --filter F129 --sersic-flux ie -o ie.fits ie.csv &&
	"$PY" boxsum.py ie.fits 60 400.5,400.5 > sums &&
	"$PY" -c "
import math, sys
b = 1.6783469900166612
want = 2 * math.pi * 0.5 * 9 * math.exp(b) / b**2
got = float(open(\"sums\").read())
sys.exit(not (0.98 < got / want < 1.0))
"
'
test_expect_success '--sersic precise draws type sersic with the precise model' '
	printf "x,y,flux,type,n,re,phi,ratio\n400.5,400.5,100,sersic,4,2,0,0.7\n" > s.csv &&
	"$WFS" --filter F129 --sersic precise -o p.fits s.csv &&
	"$WFS" --filter F129 --sersic quick -o q.fits s.csv &&
	"$PY" boxsum.py p.fits 40 400.5,400.5 > sp && "$PY" boxsum.py q.fits 40 400.5,400.5 > sq &&
	! cmp -s p.fits q.fits
'
for row in "0,2,0,1:column 'n'" "-1,2,0,1:column 'n'" "nan,2,0,1:column 'n'" \
	   "1,0,0,1:column 're'" "1,-2,0,1:column 're'" "1,2,0,0:column 'ratio'" \
	   "1,2,0,1.5:column 'ratio'" "1,2,nan,1:column 'phi'"; do
	vals=${row%%:*} want=${row#*:}
	test_expect_success "a row with n,re,phi,ratio = $vals is refused" "
		printf 'x,y,flux,type,n,re,phi,ratio\n10,10,5,point,,,,\n100,100,10,sersic,$vals\n' > bad.csv &&
		test_must_fail --status 1 \"\$WFS\" --filter F129 -o bad.fits bad.csv 2> err &&
		test_grep \"bad.csv:3: .*$want\" err && ! test -e bad.fits
	"
done
test_expect_success 'a refused value is quoted to the digit it differs by' '
	printf "x,y,flux,type,n,re,phi,ratio\n100,100,10,sersic,1,2,0,1.0000001\n100,100,10,sersic,0.04999999,2,0,1\n" > near.csv &&
	test_must_fail --status 1 "$WFS" --filter F129 -o near.fits near.csv 2> err &&
	test_grep "near.csv:2: .*column .ratio.: axis ratio must be in (0, 1\], got 1.0000001$" err &&
	! test -e near.fits &&
	sed -i 2d near.csv &&
	test_must_fail --status 1 "$WFS" --filter F129 -o near.fits near.csv 2> err &&
	test_grep "near.csv:2: .*Sérsic index 0.04999999 is outside" err && ! test -e near.fits
'
test_expect_success 'a galaxy centred off the detector lights its edge' '
	printf "x,y,flux,type,n,re,phi,ratio\n-3,500,10000,sersic,1,4,0,1\n" > off.csv &&
	"$WFS" --filter F129 -o off.fits off.csv &&
	"$PY" -c "
import sys
from astropy.io import fits
d = [h.data for h in fits.open(\"off.fits\") if h.data is not None][0]
s = d[:, :20].sum()
sys.exit(not (100 < s < 5000))
"
'
test_expect_success '--sersic-convolve no is --set sersic-convolve=no, and unconvolved' '
	printf "x,y,flux,type,n,re,phi,ratio\n200.3,300.7,1000,sersic,1.5,3,20,0.6\n" > g.csv &&
	"$WFS" -q --filter F129 --sersic-convolve no -o nc1.fits g.csv &&
	"$WFS" -q --filter F129 --set sersic-convolve=no -o nc2.fits g.csv &&
	"$WFS" -q --filter F129 -o cv.fits g.csv &&
	cmp nc1.fits nc2.fits && ! cmp -s nc1.fits cv.fits
'
test_expect_success '--sersic-trunc, --sersic-tol and --sersic-core reach the models' '
	"$WFS" -q --filter F129 --sersic precise --sersic-tol 1e-3 -o tol.fits g.csv &&
	"$WFS" -q --filter F129 --sersic precise -o def.fits g.csv &&
	! cmp -s tol.fits def.fits &&
	"$WFS" -q --filter F129 --sersic-trunc 0.1 -o tr.fits g.csv &&
	! cmp -s tr.fits cv.fits &&
	"$WFS" -q --filter F129 --sersic-core 3 -o core.fits g.csv &&
	! cmp -s core.fits cv.fits
'
for bad in "--sersic-core 2.5:not an integer" "--sersic-core 17:out of range" \
	   "--sersic-trunc 0.7:out of range" "--sersic-tol abc:not a number" \
	   "--sersic-convolve maybe:not one of yes, no"; do
	opt=${bad%%:*} want=${bad#*:}
	test_expect_success "$opt is refused before anything is drawn" "
		test_must_fail --status 1 \"\$WFS\" --filter F129 $opt -o o.fits g.csv 2> err &&
		test_grep \"$want\" err && ! test -e o.fits
	"
done
test_expect_success 'two catalogs whose galaxy columns stand in different places' '
	printf "x,y,flux,type,n,re,phi,ratio\n100.3,100.6,1000,sersic,1,2,0,1\n" > a.csv &&
	printf "ratio,phi,re,n,type,flux,y,x\n1,0,2,1,sersic,1000,100.6,100.3\n" > b.csv &&
	"$WFS" --filter F129 -o ab.fits a.csv b.csv &&
	"$WFS" --filter F129 -o aa.fits a.csv a.csv &&
	"$PY" boxsum.py ab.fits 25 100.3,100.6 > ab.sum &&
	"$PY" boxsum.py aa.fits 25 100.3,100.6 > aa.sum &&
	cmp ab.sum aa.sum
'
test_done
