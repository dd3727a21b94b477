#!/bin/sh
# An exposure whose SCAs do not fit --memory is drawn in groups of SCAs,
# one pass over the catalogs a group: every file (one FITS file of several
# SCAs, one per SCA, levels 0, 1 and 2, --placed in both conventions, a
# series with persistence) is the same bytes as one pass, the report the
# same but for its timings, and a catalog on stdin is kept in a temporary
# file and read once per pass.
. "$(dirname "$0")/lib.sh"

# 16 rows of each SCA: 16 x 4088 x 8 bytes of tiles and 62 MB for grids,
# the models and the default halo's lists, 63 MB an SCA as -v says, and
# 136 MB for the run at the default chunk of 262144 rows (206 at levels 1
# and 2; 40 and 110 in a series, whose chunk here is 65536): --memory 1000
# holds the four SCAs, 270 two, 200 one.
run() { "$WFS" --filter F158 --ra 10 --dec 20 --pointing-ref boresight --sca 1-4 \
	--flux-unit abmag --rows 2040-2055 "$@"; }

"$BUILD/contrib/starfield" -n 100000 -r 10 -d 20 -w 0.9 -m 14 -M 25 -s 5 > sky.csv
"$BUILD/contrib/starfield" -n 300 -r 10 -d 20 -w 0.9 -m 8 -M 11 -s 6 |
	awk -F, 'NR > 1 { print $1 + 1000000 "," $2 "," $3 "," $4 }' >> sky.csv

# A report without its timings (and the CPU figures of the run), and with
# the grids built and loaded as one count: the first run builds what the
# cache lacks, the later ones load it.
untimed() {
	"$PY" -c "
import json, sys
r = json.load(open(sys.argv[1]))
del r['seconds']
g = r['psf_grids']
g['made'] = g.pop('built') + g.pop('loaded')
print(json.dumps(r, indent=1, sort_keys=True))
" "$1"
}

test_expect_success 'one pass, then two and four groups: said with -v' '
	run --memory 1000 -v -o one.fits --placed one.csv --report one.json sky.csv 2> err &&
	! grep -q "passes over" err &&
	run --memory 270 -v -o two.fits --placed two.csv --report two.json sky.csv 2> err &&
	test_grep "4 SCAs in 2 passes over the catalogs, 2 at most at a time" err &&
	run --memory 200 -v -o four.fits --placed four.csv --report four.json sky.csv 2> err &&
	test_grep "4 SCAs in 4 passes over the catalogs, 1 at most at a time" err
'
test_expect_success '... the same bytes, placed list and report' '
	test $(wc -l < one.csv) -gt 100 &&
	cmp one.fits two.fits && cmp one.fits four.fits &&
	test_cmp one.csv two.csv && test_cmp one.csv four.csv &&
	untimed one.json > one.txt && untimed four.json > four.txt &&
	test_cmp one.txt four.txt &&
	test_grep "\"placed_on\"\\|\"flux\"" one.txt
'
test_expect_success 'romanisim placed lists: a row once, in the order of one pass' '
	run --set placed=romanisim -o r1.fits --placed r1.csv sky.csv &&
	run --memory 200 --set placed=romanisim -o r4.fits --placed r4.csv sky.csv &&
	test_cmp r1.csv r4.csv
'
test_expect_success 'levels 1 and 2, one file per SCA' '
	for L in 1 2; do
		run --level $L --background avg -o "a${L}_%d.fits" sky.csv &&
		run --level $L --background avg --memory 180 -v -o "b${L}_%d.fits" \
			sky.csv 2> err &&
		test_grep "4 SCAs in 4 passes" err &&
		for s in 1 2 3 4; do cmp a${L}_$s.fits b${L}_$s.fits || return 1; done
	done
'
test_expect_success 'a series in groups, persistence carried from one to the next' '
	printf "10 20 0 e1 - 61500.0\n10 20 0 e2 - 61500.01\n" > two.txt &&
	run --level 1 --allow-sun-angle --pointings two.txt -o "s_%s.fits" sky.csv &&
	run --level 1 --allow-sun-angle --pointings two.txt --memory 180 -v \
		-o "g_%s.fits" sky.csv 2> err &&
	test_grep "4 SCAs in 4 passes over the catalogs per exposure" err &&
	cmp s_e1.fits g_e1.fits && cmp s_e2.fits g_e2.fits &&
	run --level 1 --allow-sun-angle --pointings two.txt --detector correlated \
		-o "n_%s.fits" sky.csv &&
	cmp s_e1.fits n_e1.fits && ! cmp -s s_e2.fits n_e2.fits
'
test_expect_success 'a catalog on stdin, plain or compressed, is read in every pass' '
	run --memory 200 -v -o in.fits --placed in.csv - < sky.csv 2> err &&
	test_grep "<stdin>: [0-9]* bytes kept in a temporary file for 4 passes" err &&
	cmp one.fits in.fits && test_cmp one.csv in.csv &&
	gzip -c sky.csv > sky.csv.gz &&
	run --memory 200 -o gz.fits - < sky.csv.gz && cmp one.fits gz.fits
'
test_expect_success 'a row refused by the last group: exit 1, no file left' '
	printf "id,x,y,sca,flux,type,n,re,ratio,phi\n1,100,2048,4,20,sersic,-1,3,0.5,0\n" \
		> bad.csv &&
	test_must_fail --status 1 run --memory 200 -v -o "bad_%d.fits" sky.csv bad.csv 2> err &&
	test_grep "4 SCAs in 4 passes" err &&
	test_grep "bad.csv:2: .*Sérsic index must be > 0" err &&
	! ls | grep -q "^bad_"
'
# Without --memory, levels 1 and 2 take at most 2000 MB (half the RAM when
# that is less): all 18 SCAs in two passes of nine.  The scene level takes
# half the RAM.  A bad row stops each run in its first pass, before any
# ramp is drawn.
test_expect_success 'the default budget: 2000 MB at levels 1 and 2' '
	printf "id,x,y,sca,flux,type,n,re,ratio,phi\n1,100,2048,4,20,sersic,-1,3,0.5,0\n" \
		> bad18.csv &&
	half=$(awk "/^MemTotal:/ { print int(\$2 / 2048) }" /proc/meminfo) &&
	for L in 1 2; do
		test_must_fail --status 1 "$WFS" --filter F158 --sca 1-18 --level $L \
			--background avg -v -o "l18_%d.fits" bad18.csv 2> err &&
		test_grep "bad18.csv:2: .*Sérsic index must be > 0" err &&
		if test "$half" -ge 2000 && ! grep -q "[0-9]" /sys/fs/cgroup/memory.max 2>/dev/null
		then
			test_grep "18 SCAs in 2 passes over the catalogs, 9 at most at a time (190 MB each, 2000 MB of memory)" err
		else
			test_grep "18 SCAs in [0-9]* passes over the catalogs" err
		fi || return 1
	done &&
	test_must_fail --status 1 "$WFS" --filter F158 --sca 1-18 -v -o l18.fits bad18.csv \
		2> err &&
	! grep -q "2000 MB of memory" err &&
	! ls | grep -q "^l18"
'
test_expect_success 'stdin that cannot be kept: exit 2, nothing written' '
	test_must_fail --status 2 env TMPDIR=/nonexistent "$WFS" --filter F158 --ra 10 \
		--dec 20 --pointing-ref boresight --sca 1-4 --flux-unit abmag \
		--rows 2040-2055 --memory 200 -o no.fits - < sky.csv 2> err &&
	test_grep "4 passes over the catalogs (--memory)" err &&
	test_grep "/nonexistent" err &&
	! test -e no.fits
'
# With spectra the first SCA's classes' grids stay all run (every pass
# measures the sky rows' reach on it): the report counts each grid once,
# as one pass does
test_expect_success 'a catalog with spectra: the same bytes and report' '
	awk -F, "BEGIN { OFS = \",\"; srand(2) } NR == 1 { print \$0, \"teff\"; next }
		{ print \$0, exp(log(2500) + rand() * log(20)) }" sky.csv > skyc.csv &&
	run -o c1.fits --report c1.json skyc.csv &&
	run --memory 200 -v -o c4.fits --report c4.json skyc.csv 2> err &&
	test_grep "4 SCAs in 4 passes over the catalogs" err &&
	cmp c1.fits c4.fits &&
	untimed c1.json > c1.txt && untimed c4.json > c4.txt &&
	test_cmp c1.txt c4.txt
'

test_done
