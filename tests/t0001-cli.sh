#!/bin/sh
# The command line: help, version, and every bad option is refused with a
# message naming the option and the value, exit status 1, and no output.
. "$(dirname "$0")/lib.sh"

printf 'x,y,flux\n100,100,10\n' > cat.csv

test_expect_success '--help prints usage on stdout and exits 0' '
	"$WFS" --help > out && test_grep "usage: wfiscene" out
'
test_expect_success '--version' '
	"$WFS" --version > out && test_grep "^wfiscene [0-9]" out
'
test_expect_success 'an unknown option is a usage error' '
	test_must_fail --status 1 "$WFS" --frobnicate 2> err && test_grep "usage" err
'
test_expect_success '--filter is required' '
	test_must_fail --status 1 "$WFS" -o out.fits cat.csv 2> err &&
	test_grep "filter is required" err && ! test -e out.fits
'
test_expect_success 'an unknown filter is named' '
	test_must_fail --status 1 "$WFS" --filter F999 -o out.fits cat.csv 2> err &&
	test_grep "unknown filter .F999." err
'
test_expect_success 'filters are case-insensitive' '
	"$WFS" --filter f129 --help > /dev/null
'
test_expect_success 'the filters --help and the messages list are those --filter takes' '
	test_must_fail --status 1 "$WFS" --filter F999 -o out.fits cat.csv 2> err &&
	list=$(sed -n "s/.*use one of //p" err) && test "$(echo $list | wc -w)" = 8 &&
	for f in $list; do "$WFS" --filter $f --help > /dev/null || exit 1; done &&
	"$WFS" --help > help && test_grep "--filter F  *$list (required)" help &&
	test_must_fail --status 1 "$WFS" -o out.fits cat.csv 2> err &&
	test_grep "filter is required ($list)" err
'
for bad in 0 19 1-20 5-3 x WFI 1,,2 "1,"; do
	test_expect_success "--sca '$bad' is refused" "
		test_must_fail --status 1 \"\$WFS\" --filter F129 --sca '$bad' -o out.fits cat.csv 2> err &&
		test_grep 'bad SCA list\\|empty SCA list' err && ! test -e out.fits
	"
done
test_expect_success '--exptime must be a positive number' '
	test_must_fail --status 1 "$WFS" --filter F129 --exptime abc -o o.fits cat.csv 2> err &&
	test_grep "exptime: not a number: .abc." err &&
	test_must_fail --status 1 "$WFS" --filter F129 --exptime -5 -o o.fits cat.csv 2> err &&
	test_grep "out of range" err &&
	test_must_fail --status 1 "$WFS" --filter F129 --exptime 1e999 -o o.fits cat.csv 2> err &&
	test_grep "exptime: 1e999 is out of range" err &&
	test_must_fail --status 1 "$WFS" --filter F129 --exptime nan -o o.fits cat.csv 2> err &&
	test_grep "exptime: not a number: .nan." err
'
test_expect_success 'a number below the smallest double reads as 0 or a subnormal' '
	"$WFS" --filter F129 --ra=1e-320 --dec=-4e-324 -o tiny.fits cat.csv
'
test_expect_success '--dec outside [-90, 90] is refused' '
	test_must_fail --status 1 "$WFS" --filter F129 --dec 91 -o o.fits cat.csv 2> err &&
	test_grep "dec" err
'
test_expect_success 'only one %d in an output name' '
	test_must_fail --status 1 "$WFS" --filter F129 -o "a%d%d.fits" cat.csv 2> err &&
	test_grep "only one" err &&
	test_must_fail --status 1 "$WFS" --filter F129 -o "a%s.fits" cat.csv 2> err
'
test_expect_success 'stdout cannot be tile-compressed' '
	test_must_fail --status 1 "$WFS" --filter F129 --compress rice -o - cat.csv 2> err > /dev/null &&
	test_grep "cannot be tile-compressed" err
'
test_expect_success 'a bad --noise stage is named' '
	test_must_fail --status 1 "$WFS" --filter F129 --noise poisson,sparkles -o o.fits cat.csv 2> err &&
	test_grep "sparkles" err
'
test_expect_success 'a bad choice lists the valid ones' '
	test_must_fail --status 1 "$WFS" --filter F129 --bunit electrons -o o.fits cat.csv 2> err &&
	test_grep "counts/s, counts" err
'
test_expect_success '--xbright-limit fainter than --bright-limit is refused' '
	test_must_fail --status 1 "$WFS" --filter F129 --bright-limit 10 --xbright-limit 12 -o o.fits cat.csv 2> err &&
	test_grep "xbright-limit" err
'
test_expect_success 'a missing catalog file is an I/O error (2) and leaves nothing' '
	test_must_fail --status 2 "$WFS" --filter F129 -o o.fits no-such.csv 2> err &&
	test_grep "no-such.csv" err && ! test -e o.fits && test -z "$(ls -A | grep "^\.o\.fits")"
'
test_done
