#!/bin/sh
# Persistence: a star that saturates in one exposure leaves, in the next
# exposure 60 s later at its pixels, an afterglow whose growth over the
# resultants follows the SCA's measured decay curve scaled by the fermi
# model (wfiscene(1), PERSISTENCE); DQ PERSISTENCE at level 2; the state
# carried across runs through --persistence-state, the same bytes as one
# run, for any thread count; states of another SCA set or rows refused.
. "$(dirname "$0")/lib.sh"
require_python

# the star on WFI01's centre in exposure a; exposure b looks 36" away, so
# its pixels there see the sky alone, 60 s after exposure a's last read
# (MA table 4: 139.149 s)
printf 'ra,dec,flux\n0,0,5e7\n' > bright.csv
$PY -c "
t0, T = 61000.0, 44 * 3.16247
print('0 0 0 a 11 %.9f' % t0)
print('0 0.01 0 b 12 %.9f' % (t0 + (T + 60) / 86400))
" > pts.txt
sed -n 1p pts.txt > pts-a.txt
sed -n 2p pts.txt > pts-b.txt

run() { "$WFS" --filter F129 --sca 1 --allow-sun-angle --background 0.54 --rows 1950-2150 "$@"; }

cat > glow.py <<\PYEOF
# The afterglow in exposure b's resultants (with persistence minus
# without: the same keyed noise, so the difference is the afterglow)
# against the model: SCU 1's fit a e^-bt + d e^-et + c
# (WFI_Persistence_exp_fits.ecsv) times the fermi amplitude of each
# pixel's fluence in exposure a over that of 1e5 e-.
import sys
import numpy as np
from astropy.io import fits
a, b, nb = (fits.open(f)[1].data.astype(np.float64) for f in sys.argv[1:4])
hd = fits.open(sys.argv[2])[1].header
groups = [tuple(int(v) for v in hd["MAREAD%d" % (r + 1)].split("-")) for r in range(hd["NRESULT"])]
rate = fits.open(sys.argv[4])[1].data.astype(np.float64)
lag = float(sys.argv[5])
A, B, C, D, E = (0.0630975242491005, 0.00223961641358588, 0.00257429338240526,
                 0.746862190043635, 0.011286859153504)
dt, gain, dark, T = 3.16247, 2.0, 0.049, 44 * 3.16247
def Q(u0, u1):   # charge released between u0 and u1 s after the stimulus
    f = lambda u: -A / B * np.exp(-B * u) - D / E * np.exp(-E * u) + C * u
    return f(u1) - f(u0)
def fermi(x):
    x0, dx, al, hw = 6e4, 5e4, 0.045, 5e4
    f = lambda x: (x / x0) ** al / (1 + np.exp(-(x - x0) / dx))
    return np.where(x < hw, f(hw) * x / hw, f(np.maximum(x, hw)))
sat = a[-1][:, 4:-4] >= 54990
core = sat.copy()
for dy in (-1, 0, 1):
    for dx in (-1, 0, 1):
        core &= np.roll(np.roll(sat, dy, 0), dx, 1)
assert core.sum() > 300, core.sum()
scale = fermi((rate[core] + dark) * T) / fermi(1e5)
meas = np.array([((b[r] - nb[r])[:, 4:-4][core] * gain).mean() for r in range(len(groups))])
model = np.array([np.mean([Q(lag, lag + k * dt) for k in range(g0, g1 + 1)]) * scale.mean()
                  for g0, g1 in groups])
tbar = np.array([dt * (g0 + g1) / 2 for g0, g1 in groups])
# the growth from one resultant to the next: the curve's current there
mr = np.diff(meas) / np.diff(tbar)
cr = np.diff(model) / np.diff(tbar)
worst = np.max(np.abs(mr / cr - 1))
print("%d %.4f %.4f %.4f" % (core.sum(), meas[-1], model[-1], worst))
PYEOF

test_expect_success 'a saturated star leaves an afterglow that follows the SCU 1 curve within 10 %' '
	run --level 1 --pointings pts.txt -o "l1_%s.fits" bright.csv &&
	run --level 1 --pointings pts.txt --detector correlated -o "n1_%s.fits" bright.csv &&
	run --pointings pts-a.txt -o "rate_%s.fits" bright.csv &&
	$PY glow.py l1_a.fits l1_b.fits n1_b.fits rate_a.fits 60 > s && read n got want worst < s &&
	say "core pixels $n: afterglow in the last resultant $got e- (model $want), worst growth rate off by $worst" &&
	awk -v g="$got" -v w="$want" -v x="$worst" "BEGIN { exit !(g > 10 && g / w > 0.9 && g / w < 1.1 && x < 0.1) }" &&
	# the first exposure of a run has no afterglow: the same bytes
	cmp l1_a.fits n1_a.fits
'

test_expect_success 'without persistence the same comparison fails' '
	$PY glow.py n1_a.fits n1_b.fits n1_b.fits rate_a.fits 60 > s0 && read n got want worst < s0 &&
	awk -v g="$got" -v w="$want" "BEGIN { exit !(g / w < 0.9) }"
'

test_expect_success 'the afterglow is smaller after a longer gap, as the curve says' '
	$PY -c "
t0, T = 61000.0, 44 * 3.16247
print(\"0 0 0 a 11 %.9f\" % t0)
print(\"0 0.01 0 b 12 %.9f\" % (t0 + (T + 600) / 86400))
" > late.txt &&
	run --level 1 --pointings late.txt -o "late_%s.fits" bright.csv &&
	$PY glow.py late_a.fits late_b.fits n1_b.fits rate_a.fits 600 > s6 && read n got want worst < s6 &&
	say "600 s later: $got e- (model $want)" &&
	awk -v g="$got" -v w="$want" -v g60="$(cut -d" " -f2 s)" \
		"BEGIN { exit !(g / w > 0.9 && g / w < 1.1 && g < g60 / 5) }"
'

test_expect_success 'level 2 flags DQ PERSISTENCE (32) where the afterglow is, and only there' '
	run --level 2 --pointings pts.txt -o "l2_%s.fits" bright.csv &&
	$PY -c "
import numpy as np
from astropy.io import fits
a = fits.open(\"l1_a.fits\")[1].data[-1][:, 4:-4]
q = fits.open(\"l2_b.fits\")[\"WFI01_DQ\"].data
rate = fits.open(\"rate_a.fits\")[1].data.astype(float)
p = (q & 32) != 0
sat = a >= 54990
# where the model puts 0.5 x 17.49 / sqrt(2) e- or more of afterglow: SCU 1
# releases 33.58 e- from 60 to 199 s after a full well; the fermi
# amplitude below the half well is linear, 0.6324 at 5e4 e-
x = (rate + 0.049) * 44 * 3.16247
amp = np.where(x < 5e4, 0.6324 * x / 5e4, 0.6324)
want = amp * 33.58 >= 0.5 * 17.49 / 2 ** 0.5
print(p.sum(), want.sum(), (p != want).sum(), (p & sat).sum(), sat.sum())
assert sat.sum() > 300 and (p & sat).sum() == sat.sum(), \"every saturated pixel of a flagged\"
assert (p != want).sum() < 0.05 * want.sum(), \"the flag where the model puts it\"
q0 = fits.open(\"l2_a.fits\")[\"WFI01_DQ\"].data
assert not ((q0 & 32) != 0).any(), \"no flag in the first exposure\"
"
'

test_expect_success 'a state carried across runs gives the bytes of one run, for any threads' '
	rm -f state.bin &&
	run --level 1 --pointings pts-a.txt --persistence-state state.bin -o "s1_%s.fits" bright.csv &&
	head -n 1 state.bin > magic && echo "wfiscene-persistence 1" > want && test_cmp want magic &&
	run --level 1 --pointings pts-b.txt --persistence-state state.bin --threads 1 --tile 128 \
		-o "s2_%s.fits" bright.csv &&
	cmp s1_a.fits l1_a.fits && cmp s2_b.fits l1_b.fits
'

test_expect_success 'runs split by rows through the star give the whole run, merged' '
	"$WFS" --filter F129 --sca 1 --allow-sun-angle --background 0.54 --rows 1950-2040 \
		--level 1 --pointings pts.txt -o "p1_%s.fits" bright.csv &&
	"$WFS" --filter F129 --sca 1 --allow-sun-angle --background 0.54 --rows 2041-2150 \
		--level 1 --pointings pts.txt --threads 1 -o "p2_%s.fits" bright.csv &&
	$PY -c "
import numpy as np
from astropy.io import fits
p = [fits.open(f)[1].data for f in (\"p1_b.fits\", \"p2_b.fits\")]
w = fits.open(\"l1_b.fits\")[1].data
assert (np.concatenate(p, axis=1) == w).all(), \"the parts are the whole\"
" &&
	"$WFS" --filter F129 --sca 1 --allow-sun-angle --background 0.54 --rows 1950-2040 \
		--level 2 --pointings pts.txt -o "q1_%s.fits" bright.csv &&
	"$WFS" --filter F129 --sca 1 --allow-sun-angle --background 0.54 --rows 2041-2150 \
		--level 2 --pointings pts.txt --tile 64 -o "q2_%s.fits" bright.csv &&
	$PY -c "
import numpy as np
from astropy.io import fits
p = [fits.open(f) for f in (\"q1_b.fits\", \"q2_b.fits\")]
w = fits.open(\"l2_b.fits\")
for k in range(1, 6):
    c = np.concatenate([x[k].data for x in p], axis=0)
    assert (c == w[k].data).all(), w[k].name
"
'

test_expect_success 'a state of other SCAs or rows is refused, naming the file; nothing written' '
	rm -f state.bin &&
	run --level 1 --pointings pts-a.txt --persistence-state state.bin -o "s1_%s.fits" bright.csv &&
	cp state.bin keep.bin &&
	test_must_fail --status 1 "$WFS" --filter F129 --sca 1,2 --allow-sun-angle --background 0.54 \
		--rows 1950-2150 --level 1 --pointings pts-b.txt --persistence-state state.bin \
		-o "bad_%s_%d.fits" bright.csv 2> err &&
	test_grep "state.bin: a persistence state of SCAs 1, rows 1950-2150; this run is of SCAs 1,2" err &&
	! test -e bad_b_1.fits && cmp state.bin keep.bin &&
	test_must_fail --status 1 "$WFS" --filter F129 --sca 1 --allow-sun-angle --background 0.54 \
		--rows 1950-2100 --level 1 --pointings pts-b.txt --persistence-state state.bin \
		-o "bad_%s.fits" bright.csv 2> err &&
	test_grep "rows 1950-2150; this run is of SCAs 1, rows 1950-2100" err && ! test -e bad_b.fits &&
	printf "not a state\n" > junk.bin &&
	test_must_fail --status 1 run --level 1 --pointings pts-b.txt --persistence-state junk.bin \
		-o "bad_%s.fits" bright.csv 2> err &&
	test_grep "junk.bin:1: not a wfiscene persistence state" err && ! test -e bad_b.fits &&
	head -c 150 keep.bin > short.bin &&
	test_must_fail --status 1 run --level 1 --pointings pts-b.txt --persistence-state short.bin \
		-o "bad_%s.fits" bright.csv 2> err &&
	test_grep "short.bin: persistence state damaged or truncated" err && ! test -e bad_b.fits &&
	# a state that cannot be saved is refused before any image is written
	# (it once left the images behind, the run failing only at the end)
	test_must_fail --status 2 run --level 1 --pointings pts-b.txt \
		--persistence-state nosuchdir/state.bin -o "bad_%s.fits" bright.csv 2> err &&
	test_grep "nosuchdir/state.bin: cannot write in" err && ! test -e bad_b.fits
'

test_expect_success 'exposures out of date order, and options that do not fit, are refused' '
	{ sed -n 2p pts.txt && sed -n 1p pts.txt; } > back.txt &&
	test_must_fail --status 1 run --level 1 --pointings back.txt -o "bad_%s.fits" bright.csv 2> err &&
	test_grep "exposure a begins .* before the previous one ends" err &&
	! test -e bad_b.fits && ! test -e bad_a.fits &&
	test_must_fail --status 1 run --persistence-state x.bin -o bad.fits bright.csv 2> err &&
	test_grep "persistence-state without persistence" err && ! test -e bad.fits && ! test -e x.bin &&
	test_must_fail --status 1 run --level 1 --detector persistance -o bad.fits bright.csv 2> err &&
	test_grep "unknown part .persistance." err &&
	test_must_fail --status 1 run --level 1 --pointings pts.txt --set persistence-floor=-1 \
		-o "bad_%s.fits" bright.csv 2> err &&
	test_grep "persistence-floor=-1: expected a number" err
'

test_expect_success 'the scene level takes the afterglow as a rate with --detector persistence' '
	run --pointings pts.txt --exptime 139.149 --detector persistence -o "sc_%s.fits" bright.csv &&
	run --pointings pts.txt --exptime 139.149 -o "sn_%s.fits" bright.csv &&
	cmp sc_a.fits sn_a.fits &&
	$PY -c "
import numpy as np
from astropy.io import fits
a = fits.open(\"sc_a.fits\")[1].data.astype(float)
b = fits.open(\"sc_b.fits\")[1].data.astype(float) - fits.open(\"sn_b.fits\")[1].data
x = a * 139.149
f = lambda x: (x / 6e4) ** 0.045 / (1 + np.exp(-(x - 6e4) / 5e4))
amp = np.where(x < 5e4, f(5e4) * x / 5e4, f(np.maximum(x, 5e4))) / f(1e5)
# SCU 1 releases 33.58 e- from 60 to 199 s after a full well
want = amp * 33.58 / 139.149
m = x > 1e4
print(m.sum(), b[m].mean(), want[m].mean(), np.abs(b - want)[m].max())
assert abs(b[m].mean() / want[m].mean() - 1) < 0.01 and np.abs(b - want).max() < 0.01
"
'

test_done
