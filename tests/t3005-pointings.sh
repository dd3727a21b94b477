#!/bin/sh
# --pointings: several exposures from one reading of the catalog, each the
# same bytes as a run of that pointing alone with its seed.
. "$(dirname "$0")/lib.sh"
require_python

"$BUILD/contrib/starfield" -n 3000 -r 10 -d 20 -w 0.3 -m 18 -M 24 -s 3 > stars.csv
cat > dither.txt <<EOT
# ra dec pa name seed
ra dec pa name
10.000 20.000 0
10.001 20.0005 0 second
# a rotated one with its own seed
10.0 20.0 33.5 third 99
EOT
run() { "$WFS" --filter F129 --psf "$PSF" --sca 1,2 --flux-unit abmag --noise all \
	--background avg --exptime 100 --seed 40 "$@"; }

test_expect_success 'one invocation writes one file per pointing' '
	run --pointings dither.txt -o "exp_%s.fits" --placed "placed_%s.csv" stars.csv &&
	test -f exp_001.fits && test -f exp_second.fits && test -f exp_third.fits &&
	test -f placed_001.csv && test -f placed_third.csv
'
test_expect_success 'each exposure equals a single run of its pointing and seed' '
	run --ra 10 --dec 20 --pa 0 -o one.fits stars.csv && cmp exp_001.fits one.fits &&
	run --ra 10.001 --dec 20.0005 --pa 0 --seed 41 -o two.fits stars.csv &&
	cmp exp_second.fits two.fits &&
	run --ra 10 --dec 20 --pa 33.5 --seed 99 -o three.fits stars.csv &&
	cmp exp_third.fits three.fits
'
test_expect_success 'the catalog is read once for all exposures: from a pipe, chunk by chunk' '
	cat stars.csv | run --pointings dither.txt --chunk 500 -o "pipe_%s.fits" \
		--report "pipe_%s.json" - &&
	cmp exp_001.fits pipe_001.fits && cmp exp_second.fits pipe_second.fits &&
	cmp exp_third.fits pipe_third.fits &&
	for n in 001 second third; do
		"$PY" -c "import json, sys; r = json.load(open(sys.argv[1]))
assert r[\"rows\"][\"read\"] == 3000, r[\"rows\"]" pipe_$n.json || exit 1
	done
'
test_expect_success 'the exposures differ (pointing and noise)' '
	! cmp -s exp_001.fits exp_second.fits
'
test_expect_success '-o needs a %s with --pointings, and %s needs --pointings' '
	test_must_fail --status 1 run --pointings dither.txt -o exp.fits stars.csv 2> err &&
	test_grep "needs a .%s." err &&
	test_must_fail --status 1 run -o "exp_%s.fits" stars.csv 2> err &&
	test_grep "needs --pointings" err &&
	test_must_fail --status 1 run --pointings dither.txt -o - stars.csv 2> err > /dev/null
'
test_expect_success 'a bad pointings line is named, and nothing is written' '
	printf "10 20 0 a\n10 abc 0 b\n" > bad.txt &&
	test_must_fail --status 1 run --pointings bad.txt -o "bad_%s.fits" stars.csv 2> err &&
	test_grep "bad.txt:2: dec: not a number: .abc." err && ! ls bad_* 2> /dev/null &&
	printf "10 20 0 a\n10 20 5 a\n" > dup.txt &&
	test_must_fail --status 1 run --pointings dup.txt -o "d_%s.fits" stars.csv 2> err &&
	test_grep "used twice" err &&
	test_must_fail --status 2 run --pointings nosuch.txt -o "d_%s.fits" stars.csv 2> err &&
	test_grep "nosuch.txt" err
'
# A header of the column words alone must be one that can be read: one
# naming a column twice, or leaving out pa, was read past once, and its
# lines then misread by position (an exposure at RA 30, Dec 10, PA 20).
test_expect_success 'a header that names a column twice, or leaves out pa, is refused' '
	printf "pa ra dec pa\n30 10 20 40\n" > twice.txt &&
	test_must_fail --status 1 run --pointings twice.txt -o "t_%s.fits" stars.csv 2> err &&
	test_grep "twice.txt:1: the header names column .pa. twice" err && ! ls t_* 2> /dev/null &&
	printf "date ra dec\n2027-05-15 10 20\n" > nopa.txt &&
	test_must_fail --status 1 run --pointings nopa.txt -o "n_%s.fits" stars.csv 2> err &&
	test_grep "nopa.txt:1: the header names columns but not pa" err && ! ls n_* 2> /dev/null &&
	printf "RA Dec PA Comment\n10 20 0 kept\n" > own.txt &&
	run --pointings own.txt -o "o_%s.fits" stars.csv && test -s o_kept.fits
'
test_done
