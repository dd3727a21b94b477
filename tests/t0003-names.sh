#!/bin/sh
# File names from templates (wfiscene(1) FILE NAMES): %d is the SCA, %s the
# exposure, %% a '%', and nothing else is read.  Every option that names a
# file, given a value full of printf conversions, ends with a message naming
# it and exit status 1, and writes nothing.
. "$(dirname "$0")/lib.sh"

printf 'x,y,flux\n100,10,1000\n' > cat.csv
printf '10 20 0 a\n10 20.01 0 b\n' > dither.txt
run() { "$WFS" --filter F129 --psf "$PSF" "$@"; }
bad='%s%n%p%x%08x%s%s%s%s%n'

# refused OPTION-FOR-MESSAGE COMMAND...: exit 1, the option named, no crash,
# no file (hidden or not) beside the inputs
refused() {
	what=$1
	shift
	test_must_fail --status 1 "$@" 2> err > out &&
	test_grep "$what: '" err && test_grep "is not a field of a file name" err &&
	test ! -s out &&
	test "$(ls -A | grep -v "^\.out$" | sort | tr '\n' ' ')" = "cat.csv dither.txt err out "
}

test_expect_success "-o $bad: refused" '
	refused -o run -o "$bad" cat.csv
'
test_expect_success "--placed $bad: refused" '
	refused --placed run -o o.fits --placed "$bad" cat.csv
'
test_expect_success "--report $bad: refused" '
	refused --report run -o o.fits --report "$bad" cat.csv
'
test_expect_success "--psf $bad: refused (it was a segmentation fault)" '
	refused --psf run -o o.fits --psf "$bad" cat.csv &&
	test_must_fail --status 1 run -o o.fits --psf "x_%s.fits" cat.csv 2> err &&
	test_grep "no exposure.s name (.%s.) here" err
'
test_expect_success "--psf %d%d%d: refused (it read garbage into the name)" '
	test_must_fail --status 1 run -o o.fits --psf "p%d%d%d.fits" cat.csv 2> err &&
	test_grep "only one .%d." err
'
test_expect_success "with --pointings: -o, --placed, --report $bad refused" '
	refused -o run --pointings dither.txt -o "e_%s_$bad" cat.csv &&
	refused --placed run --pointings dither.txt -o "e_%s.fits" --placed "p_%s$bad" cat.csv &&
	refused --report run --pointings dither.txt -o "e_%s.fits" --report "$bad" cat.csv
'
test_expect_success "psf -o $bad: refused" '
	refused -o "$WFS" psf --filter F129 --sca 1 -o "$bad"
'
test_expect_success "preview -o $bad: refused" '
	refused -o "$WFS" preview -o "$bad" cat.csv
'
test_expect_success "merge -o $bad: refused" '
	refused -o "$WFS" merge -o "$bad" cat.csv
'
test_expect_success 'a lone %, %5s, %-3d, %ld and a %d wider than 16: refused' '
	for t in "a%" "%5s.fits" "a%-3d.fits" "a%ld.fits"; do
		test_must_fail --status 1 run -o "$t" cat.csv 2> err &&
		test_grep "is not a field of a file name" err || return 1
	done &&
	test_must_fail --status 1 run -o "a%17d.fits" cat.csv 2> err &&
	test_grep "at most 16 wide" err
'

# What the escapes give.
test_expect_success '%% is a percent sign, %02d the SCA, for -o and --placed' '
	run --sca 1,2 --rows 1-16 -o "p%%_%02d.fits" --placed "l%%.csv" cat.csv &&
	test -f "p%_01.fits" && test -f "p%_02.fits" && test -f "l%.csv" &&
	! ls -A | grep -v "^\.out$" | grep -q "^\."
'
test_expect_success 'a name with %% and no %d is one file for every SCA' '
	run --sca 1,2 --rows 1-16 -o "all%%.fits" cat.csv &&
	test "$(od -A n -c "all%.fits" | tr -d " \n" | grep -o XTENSION | wc -l)" = 2
'
test_expect_success '--psf with %% and %02d reads the expanded names' '
	"$WFS" psf --filter F129 --sca 1,2 --nwave 2 --pupil-n 128 -o "g%%_%02d.fits" &&
	test -f "g%_01.fits" && test -f "g%_02.fits" &&
	run --sca 2 --rows 1-16 --psf "g%%_%02d.fits" -o one.fits cat.csv &&
	run --sca 2 --rows 1-16 --psf "g%%_02.fits" -o two.fits cat.csv &&
	if have_python; then
		fitsinfo one.fits > i1 && fitsinfo two.fits > i2 && test_cmp i1 i2
	fi
'
test_expect_success 'preview -o and merge -o: %% is a percent sign' '
	run --rows 1-2044 -o a.fits cat.csv && run --rows 2045-4088 -o b.fits cat.csv &&
	"$WFS" merge -o "m%%.fits" a.fits b.fits && test -f "m%.fits" &&
	"$WFS" preview -o "v%%.png" "m%.fits" && test -f "v%.png"
'
test_done
