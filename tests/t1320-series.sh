#!/bin/sh
# A series of exposures drawn in passes: --memory holds a few exposures at
# a time (their tiles and PSF grids), the rest wait for later passes over
# the catalogs, and every file is the same bytes as a run that holds them
# all; a catalog on stdin is kept in a temporary file for the passes.
. "$(dirname "$0")/lib.sh"
require_python

# 16 rows of SCA 1: 16 x 4088 x 8 bytes of tiles and 56 MB for grids and
# the rest, about 56.5 MB an exposure, 40 MB for the run, and 25.7 MB for
# each exposure but the first (its placements of a chunk of 65536 rows):
# 190 MB holds two exposures, not three.
run() { "$WFS" --filter F158 --sca 1 --ra 268 --dec -29 --rows 2040-2055 "$@"; }

test_expect_success 'a lensed star, moving stars and seven dated exposures' '
	"$PY" -c "
print(\"id,ra,dec,mag,type,pmra,pmdec,parallax,t0,te,u0\")
for k in range(60):
    print(\"%d,%.6f,%.6f,%.2f,point,%d,%d,%d,,,\" % (k + 1, 267.99 + 0.0004 * k, -29.0 + 0.00001 * k, 18 + k % 7, k - 30, 20 - k, k % 9))
print(\"61,268.0,-29.0,19,microlens,0,0,0,61505,8,0.2\")
" > stars.csv &&
	"$PY" -c "
for k in range(7): print(\"268 -29 0 d%d - %.3f\" % (k, 61500 + 2.5 * k))
" > dates.txt
'
test_expect_success 'with memory for all seven: one pass' '
	run --memory 1000 -v --pointings dates.txt -o "all_%s.fits" --placed "all_%s.csv" \
		stars.csv 2> err &&
	! grep -q "passes over" err
'
test_expect_success 'with memory for two: four passes, said with -v' '
	run --memory 190 -v --pointings dates.txt -o "few_%s.fits" --placed "few_%s.csv" \
		stars.csv 2> err &&
	test_grep "7 exposures in 4 passes over the catalogs, at most 2 at a time" err &&
	run --memory 160 -v --pointings dates.txt -o "one_%s.fits" stars.csv 2> err &&
	test_grep "7 exposures in 7 passes over the catalogs, at most 1 at a time" err
'
test_expect_success '... and the same bytes in every file' '
	for k in 0 1 2 3 4 5 6; do
		cmp all_d$k.fits few_d$k.fits && cmp all_d$k.csv few_d$k.csv || return 1
	done &&
	! cmp all_d0.csv all_d3.csv
'
test_expect_success 'stdin is kept in a temporary file for the passes' '
	run --memory 190 -v --pointings dates.txt -o "in_%s.fits" - < stars.csv 2> err &&
	test_grep "<stdin>: [0-9]* bytes kept in a temporary file for 4 passes" err &&
	for k in 0 1 2 3 4 5 6; do cmp in_d$k.fits all_d$k.fits || return 1; done
'
test_done
