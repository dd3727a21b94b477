#!/bin/sh
# contrib/king, the demo catalog generator: format, determinism, zstd
# output, the King profile it promises, a plausible luminosity function,
# speed, and its errors.
. "$(dirname "$0")/lib.sh"

KING=$BUILD/contrib/king
[ -x "$KING" ] || skip_all "build/contrib/king is not built"

test_expect_success 'CSV with the header id,ra,dec,mag,type and 10^5 stars by default' '
	"$KING" > a.csv && test "$(head -n 1 a.csv)" = "id,ra,dec,mag,type" &&
	test "$(wc -l < a.csv)" = 100001 &&
	test_grep "^100000,[0-9.]*,[0-9.]*,[0-9.]*,point$" a.csv
'
test_expect_success 'the same seed gives the same list, another seed another' '
	"$KING" -n 500 -s 42 > s1 && "$KING" -n 500 -s 42 > s2 && test_cmp s1 s2 &&
	"$KING" -n 500 -s 43 > s3 && ! cmp -s s1 s3
'
test_expect_success '-z writes the same list as zstd' '
	"$KING" -n 2000 -z > b.csv.zst && zstd -q -d -c b.csv.zst > b.csv &&
	"$KING" -n 2000 > b2.csv && test_cmp b2.csv b.csv
'
# CPU time, not wall time: the suite runs tests in parallel on busy machines.
if [ -x /usr/bin/time ]; then
	test_expect_success '10^5 stars take well under a second of CPU' '
		/usr/bin/time -f "%U %S" -o cpu "$KING" > /dev/null &&
		awk "{ exit !(\$1 + \$2 < 0.8) }" cpu
	'
else
	test_skip '10^5 stars take well under a second of CPU' '/usr/bin/time is absent (Debian package time)'
fi
test_expect_success '-h prints the usage on stdout' '
	"$KING" -h > h && test_grep "^usage: king" h && test_grep "\-z" h
'
for bad in "-f F999" "-c 5 -t 1" "-n 1.5" "-n -3" "-s x" "-d 95" "-M 0.01" "extra"; do
	test_expect_success "bad arguments '$bad': exit 1 and a message, no output" "
		test_must_fail --status 1 \"\$KING\" $bad > out 2> err && test -s err && test ! -s out
	"
done
test_expect_success 'a full stdout is an error' '
	test_must_fail --status 2 "$KING" > /dev/full 2> err &&
	test_grep "No space left on device" err
'

if have_python; then
	test_expect_success 'radii follow the projected King profile (KS test)' '
		"$PY" - a.csv <<-EOT
		import sys, numpy as np
		d = np.genfromtxt(sys.argv[1], delimiter=",", skip_header=1, usecols=(1, 2, 3))
		ra, dec = np.radians(d[:, 0]), np.radians(d[:, 1])
		ra0, dec0 = np.radians(250.4235), np.radians(36.4613)
		r = np.degrees(np.arccos(np.clip(np.sin(dec) * np.sin(dec0) +
		    np.cos(dec) * np.cos(dec0) * np.cos(ra - ra0), -1, 1))) * 60
		rc, rt = 0.62, 21.0
		def n(R):
		    x = (R / rc) ** 2; u = 1 + x; ut = 1 + (rt / rc) ** 2
		    return np.log(u) - 4 * (np.sqrt(u) - 1) / np.sqrt(ut) + x / ut
		r = np.sort(r)
		assert r[-1] < rt
		cdf = n(r) / n(rt)
		emp = np.arange(1, len(r) + 1) / len(r)
		ks = np.max(np.abs(cdf - emp))
		assert ks < 1.63 / np.sqrt(len(r)), ks     # 1% level
		EOT
	'
	test_expect_success 'magnitudes: RGB tip near 11, turn-off near 18, MS to 25, white dwarfs' '
		"$PY" - a.csv <<-EOT
		import sys, numpy as np
		m = np.genfromtxt(sys.argv[1], delimiter=",", skip_header=1, usecols=(3,))
		assert 10 < m.min() < 12.5, m.min()
		assert np.all(np.isfinite(m))
		h, e = np.histogram(m, bins=np.arange(8, 32))
		# many more dwarfs than giants; a turn-off jump near 18-19
		assert (m < 17).sum() < 0.005 * len(m) and (m < 17).sum() > 50
		assert (m > 26).sum() > 0.05 * len(m)               # white dwarfs
		assert h[19 - 8] > 2 * h[17 - 8]
		EOT
	'
else
	test_skip 'King profile and luminosity function' 'python3 with numpy is absent (Debian package python3-numpy)'
fi

test_done
