#!/bin/sh
# valgrind (memcheck, full leak check) over a tiny scene and over failing
# runs: no invalid access, no use of uninitialised memory, no leak, on the
# success path and on the error paths.  Image-wide noise stages are left
# out: under valgrind they take a minute (make check SANITIZE=1 covers them).
. "$(dirname "$0")/lib.sh"

command -v valgrind > /dev/null || skip_all "valgrind is absent (Debian package valgrind)"
# A sanitizer build cannot run under valgrind.
if nm "$WFS" 2>/dev/null | grep -q __asan_init; then skip_all "$WFS is an ASan build"; fi
if nm "$WFS" 2>/dev/null | grep -q __tsan_init; then skip_all "$WFS is a ThreadSanitizer build"; fi

VG="valgrind -q --error-exitcode=99 --leak-check=full --errors-for-leak-kinds=definite,possible"

printf 'x,y,flux,notes\n1000,1000,500,"a, b"\n1010,1020,50,c\n4100,10,80,edge\n' > tiny.csv
printf 'ra,dec,mag\n0,0,20\n0.001,0.001,22\n' | zstd -q -c > tiny.csv.zst

test_expect_success 'a tiny scene, placed list and report: clean' '
	$VG "$WFS" --filter F129 --sca 1 --threads 2 --psf "$PSF" --placed placed.csv \
		--report report.json -o out.fits tiny.csv &&
	test -s out.fits && test -s placed.csv && test -s report.json
'
test_expect_success 'a zstd catalog by RA/Dec: clean' '
	$VG "$WFS" --filter F129 --sca 1 --psf "$PSF" \
		-o out2.fits tiny.csv.zst && test -s out2.fits
'
test_expect_success 'a bad catalog (exit 1): clean' '
	printf "x,y,flux\n10,10,5\n10,10,NaN\n" > bad.csv &&
	$VG "$WFS" --filter F129 --psf "$PSF" -o out3.fits bad.csv 2> err; test $? -eq 1 &&
	test_grep "not a finite number" err && ! test -e out3.fits
'
test_expect_success 'an unknown source type (exit 1): clean' '
	printf "x,y,flux,type\n10,10,5,comet\n" > comet.csv &&
	$VG "$WFS" --filter F129 --psf "$PSF" -o out4.fits comet.csv 2> err; test $? -eq 1 &&
	test_grep "comet" err
'
test_expect_success 'an unwritable output (exit 2): clean' '
	$VG "$WFS" --filter F129 --psf "$PSF" -o no/such/out.fits tiny.csv 2> err; test $? -eq 2
'
test_done
