#!/bin/sh
# Backgrounds and noise through the command line: the statistics of a
# flat field, identical images for any thread count and tile size and for
# runs split by SCA, independent noise on every SCA and filter, extreme
# settings that stay finite, and bad values refused.
. "$(dirname "$0")/lib.sh"

# The noise model's statistics need a flat field: STIPS's geometry, whose
# pixels all have the same area.  (In the default SIAF geometry the
# background follows each pixel's area: the last test here, and t4102.)
run() { "$WFS" --filter F129 --ra 0 --dec 0 --geometry stips "$@"; }

# An empty catalog: the image is background and noise alone.
printf 'ra,dec,flux\n' > none.csv
printf 'ra,dec,flux\n0,0,5000\n0.01,0.01,300\n' > two.csv

# stats.py FILE HDU: median, robust sigma (1.4826 MAD), min, max, and the
# count of non-finite pixels.
cat > stats.py <<\PYEOF
import sys
import numpy as np
from astropy.io import fits
d = np.asarray(fits.open(sys.argv[1])[sys.argv[2]].data, dtype=np.float64)
f = d[np.isfinite(d)]
med = np.median(f)
print("%.9g %.9g %.9g %.9g %d" % (med, 1.4826 * np.median(np.abs(f - med)),
      f.min(), f.max(), d.size - f.size))
PYEOF

# same_hdus.py A B...: every image HDU of each B is in A (by EXTNAME) with
# equal data (A read once, one python3 start for all the Bs).
cat > same_hdus.py <<\PYEOF
import sys
import numpy as np
from astropy.io import fits
a = {h.name: h.data for h in fits.open(sys.argv[1]) if h.is_image and h.data is not None}
for b in sys.argv[2:]:
    for h in fits.open(b):
        if h.is_image and h.data is not None:
            if h.name not in a or not np.array_equal(a[h.name], h.data):
                print("%s: HDU %s differs from %s's" % (b, h.name, sys.argv[1]))
                sys.exit(1)
PYEOF

# corr.py A HDU_A B HDU_B [A HDU_A B HDU_B...]: correlation of two images,
# as |r| * sqrt(N), one line per pair (one python3 start for all).
cat > corr.py <<\PYEOF
import sys
import numpy as np
from astropy.io import fits
for i in range(1, len(sys.argv), 4):
    a, ha, b, hb = sys.argv[i:i + 4]
    x = np.asarray(fits.open(a)[ha].data, dtype=np.float64).ravel()
    y = np.asarray(fits.open(b)[hb].data, dtype=np.float64).ravel()
    r = np.corrcoef(x, y)[0, 1]
    print("%.3f" % (abs(r) * np.sqrt(x.size)))
PYEOF

within() { awk -v g="$1" -v w="$2" -v t="$3" 'BEGIN { d = g - w; if (d < 0) d = -d; exit !(d <= t) }'; }

test_expect_success '--noise none --background 0.5 gives exactly 0.5' '
	run --noise none --background 0.5 -o flat.fits none.csv &&
	$PY stats.py flat.fits WFI01 > s && read med sig min max bad < s &&
	test "$min" = 0.5 && test "$max" = 0.5 && test "$bad" = 0
'
test_expect_success 'the SIAF geometry: 0.5 times each pixel'"'"'s area (0.974-0.998 on SCA 1)' '
	"$WFS" --filter F129 --ra 0 --dec 0 --noise none --background 0.5 -o siaf.fits none.csv &&
	$PY stats.py siaf.fits WFI01 > s && read med sig min max bad < s && cat s &&
	within "$min" 0.4870 0.0002 && within "$max" 0.4991 0.0002 && test "$bad" = 0
'

# F129 avg background on SCA 1: 0.003 thermal + (0.54 - 0.003) x 0.96746
# (SCA 1's zodiacal response, data/background.tsv) = 0.5225 counts/s; dark
# 0.028 e-/s, 100 s: Poisson mean 55.05 e-; variance 55.05 + 12^2 +
# (0.0037 * 100)^2 + (55.05 * 0.00068)^2 = 199.2 e-^2, robust sigma 14.11
# e- = 0.1411 counts/s (cosmic-ray residuals touch ~1e-3 of the pixels and
# do not move median or MAD).
test_expect_success '--noise all --background avg: median and sigma of a flat field' '
	run --sca 1 --noise all --background avg --exptime 100 --seed 7 -o all.fits none.csv &&
	$PY stats.py all.fits WFI01 > s && read med sig min max bad < s &&
	cat s && test "$bad" = 0 &&
	within "$med" 0.5505 0.01 && within "$sig" 0.1411 0.002
'
# The stage options through the command line: --readnoise sets sigma;
# --cosmic-rate and --cosmic-residual set the dose, a mean of rate * 1e-6
# cm^2 * t * (600 + 5000) e- * residual per pixel (sampling sigma of the
# SCA mean ~1.3 e- for the first, 0.5% of the mean).
cat > mean.py <<\PYEOF
import sys
import numpy as np
from astropy.io import fits
print("%.9g" % np.asarray(fits.open(sys.argv[1])[sys.argv[2]].data, dtype=np.float64).mean())
PYEOF
test_expect_success '--readnoise 3: sigma 3 e-' '
	run --sca 2 --noise readnoise --readnoise 3 --bunit counts -o rn.fits none.csv &&
	$PY stats.py rn.fits WFI02 > s && read med sig min max bad < s && cat s &&
	within "$med" 0 0.01 && within "$sig" 3 0.02
'
test_expect_success '--cosmic-rate 50 --cosmic-residual 1: dose 280 e- per pixel in 1000 s' '
	run --sca 2 --noise cosmic --exptime 1000 --cosmic-rate 50 --cosmic-residual 1 \
		--bunit counts -o cr.fits none.csv &&
	$PY mean.py cr.fits WFI02 > m && cat m && within "$(cat m)" 280 7
'
test_expect_success '--cosmic-residual 0.01 (the default): 2.8 e-; --cosmic-rate 0: no hits' '
	run --sca 2 --noise cosmic --exptime 1000 --cosmic-rate 50 --bunit counts -o cr1.fits none.csv &&
	$PY mean.py cr1.fits WFI02 > m && cat m && within "$(cat m)" 2.8 0.07 &&
	run --sca 2 --noise cosmic --exptime 1000 --cosmic-rate 0 --bunit counts -o cr0.fits none.csv &&
	$PY stats.py cr0.fits WFI02 > s && read med sig min max bad < s && test "$max" = 0
'
test_expect_success '--bunit counts leaves the image in counts' '
	run --sca 1 --noise poisson --background avg --exptime 100 --bunit counts -o c.fits none.csv &&
	$PY stats.py c.fits WFI01 > s && read med sig min max bad < s && cat s &&
	within "$med" 52.25 1.01 && within "$sig" 7.23 0.3 && test "$bad" = 0
'
test_expect_success 'the same seed gives the same image for any --threads and --tile' '
	run --sca 3 --noise all --background avg --exptime 100 --seed 11 --threads 1 --tile 256 -o t1.fits two.csv &&
	run --sca 3 --noise all --background avg --exptime 100 --seed 11 --threads 2 --tile 128 -o t2.fits two.csv &&
	$PY "$TOP/tests/fitsinfo.py" --same t1.fits t2.fits
'
test_expect_success 'runs split by SCA give the HDUs of one run' '
	run --sca 1,2,17 --noise all --background avg --exptime 100 --seed 5 -o whole.fits two.csv &&
	run --sca 1,2 --noise all --background avg --exptime 100 --seed 5 -o part1.fits two.csv &&
	run --sca 17 --noise all --background avg --exptime 100 --seed 5 --threads 1 -o part2.fits two.csv &&
	$PY same_hdus.py whole.fits part1.fits part2.fits
'
test_expect_success 'different SCAs, filters and seeds never share a noise pattern' '
	run --sca 1 --noise poisson,readnoise --background avg --exptime 100 --seed 5 --filter F158 -o f158.fits none.csv &&
	run --sca 1 --noise all --background avg --exptime 100 --seed 6 -o s6.fits none.csv &&
	$PY corr.py whole.fits WFI01 whole.fits WFI02 whole.fits WFI01 f158.fits WFI01 \
		whole.fits WFI17 s6.fits WFI01 > r &&
	test $(wc -l < r) = 3 &&
	sed -n 1p r > r1 && sed -n 2p r > r2 && sed -n 3p r > r3 &&
	cat r1 r2 r3 &&
	{ within "$(cat r1)" 0 5 || { echo "WFI01 and WFI02 of one run correlate: $(cat r1)"; false; }; } &&
	{ within "$(cat r2)" 0 5 || { echo "F129 and F158 on WFI01 correlate: $(cat r2)"; false; }; } &&
	{ within "$(cat r3)" 0 5 || { echo "seeds 5 (WFI17) and 6 (WFI01) correlate: $(cat r3)"; false; }; }
'
# Every combination is scanned on image regions by tests/unit/noise_tiles;
# here three extreme corners go through the whole program.
for tb in "1e-3 1e6" "1e6 0" "1e6 1e6"; do
	set -- $tb
	test_expect_success "--exptime $1 --background $2: every pixel finite" "
		run --sca 18 --noise all --background $2 --exptime $1 -o x.fits two.csv &&
		\$PY stats.py x.fits WFI18 > s && cat s && read med sig min max bad < s &&
		test \"\$bad\" = 0
	"
done
test_expect_success 'bad noise options are refused, leaving no file' '
	test_must_fail --status 1 run --noise poisson,bogus -o bad.fits none.csv 2> err &&
	test_grep "unknown stage .bogus." err && ! test -e bad.fits &&
	test_must_fail --status 1 run --readnoise -3 -o bad.fits none.csv 2> err &&
	test_grep "readnoise" err && ! test -e bad.fits &&
	test_must_fail --status 1 run --cosmic-residual 2 -o bad.fits none.csv 2> err &&
	test_grep "cosmic-residual" err && ! test -e bad.fits
'

test_expect_success '--set poisson-normal: the normal above a mean, exact with inf, bad values named' '
	run --noise poisson --background 2000 --exptime 1 --bunit counts --rows 1-64 -q \
		-o pn.fits none.csv &&
	run --noise poisson --background 2000 --exptime 1 --bunit counts --rows 1-64 -q \
		--set poisson-normal=inf -o pe.fits none.csv &&
	"$PY" - <<-\EOF &&
	import numpy as np
	from astropy.io import fits
	a = np.asarray(fits.open("pn.fits")[1].data, dtype=np.float64)
	b = np.asarray(fits.open("pe.fits")[1].data, dtype=np.float64)
	assert (a != b).mean() > 0.9, "the knob changes the counts"
	for d in (a, b):
	    assert np.all(d == np.round(d)), "whole counts"
	    m, v = d.mean(), d.var()
	    print(m, v)
	    assert abs(m / 2000 - 1) < 0.0005 and abs(v / 2000 - 1) < 0.02, (m, v)
	EOF
	test_must_fail --status 1 run --noise poisson --rows 1-4 --set poisson-normal=5 \
		-o bad.fits none.csv 2> err &&
	test_grep "poisson-normal=5: expected a mean of 10 or more" err && ! test -e bad.fits
'
test_done
