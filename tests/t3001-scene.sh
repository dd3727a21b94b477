#!/bin/sh
# Scenes of point sources: input paths (stdin, compressed, several catalogs),
# outputs (file, stdout, one file per SCA, --placed), determinism, edges.
. "$(dirname "$0")/lib.sh"
require_python

cat > stars.csv <<EOT
id,x,y,flux
1,100.3,200.7,1000
2,2045,2045,50000
3,4088,1,300
4,-3,500,200
5,9000,9000,5
EOT
run() { "$WFS" --filter F129 --psf "$PSF" "$@"; }

test_expect_success 'a star catalog gives one WFI01 image' '
	run -o a.fits stars.csv && fitsinfo a.fits > info &&
	test_grep "^WFI01 " info && test "$(wc -l < info)" = 1
'
test_expect_success 'the brightest pixel is where the catalog puts the star' '
	read name sum max x y < info && test "$x $y" = "2044 2044"
'
test_expect_success 'stdin, gzip and zstd input give the same image' '
	run -o b.fits < stars.csv && gzip -c stars.csv | run -o c.fits - &&
	zstd -q -c stars.csv > stars.csv.zst && run -o d.fits stars.csv.zst &&
	fitsinfo --same a.fits b.fits && fitsinfo --same a.fits c.fits &&
	fitsinfo --same a.fits d.fits
'
test_expect_success 'several catalogs are read into one scene' '
	head -n 3 stars.csv > part1.csv && { head -n 1 stars.csv; tail -n +4 stars.csv; } > part2.csv &&
	run -o e.fits part1.csv part2.csv && fitsinfo --same a.fits e.fits
'
test_expect_success 'the image does not depend on threads, tile size or chunk size' '
	run --threads 1 -o t1.fits stars.csv && run --threads 2 -o t2.fits stars.csv &&
	run --threads 3 --tile 64 --chunk 2 -o t3.fits stars.csv &&
	cmp a.fits t1.fits && cmp a.fits t2.fits && cmp a.fits t3.fits
'
test_expect_success '-o - streams the same bytes as a file' '
	run -o - stars.csv > s.fits && cmp a.fits s.fits
'
# cfitsio's own "-" would hold the whole file (here 3 SCAs, 200 MB) in
# memory; wfiscene streams it.  Its exit status (time passes it on) is kept
# aside: a pipeline's status is that of wc.
if san=$(sanitizer); then
	test_skip '-o - of 3 SCAs runs in bounded memory' "$san build: its shadow memory is not ours"
elif [ -x /usr/bin/time ]; then
	test_expect_success '-o - of 3 SCAs (200 MB) runs in bounded memory' '
		{ /usr/bin/time -f %M -o rss "$WFS" --filter F129 --psf "$PSF" --sca 1-3 \
			-o - stars.csv; echo $? > rc; } | wc -c > size &&
		test "$(cat rc)" = 0 &&
		test "$(cat size)" -gt 200000000 && test "$(tail -n 1 rss)" -lt 80000
	'
else
	test_skip '-o - of 3 SCAs runs in bounded memory' '/usr/bin/time is absent (Debian package time)'
fi
test_expect_success 'one file per SCA with %d' '
	run --sca 1,2 -o "sca%02d.fits" stars.csv && fitsinfo sca01.fits > i1 &&
	fitsinfo sca02.fits > i2 && test_grep "^WFI01 " i1 && test_grep "^WFI02 " i2 &&
	! test -e "sca%02d.fits"
'
test_expect_success 'x, y rows go to the SCA of their sca column' '
	printf "x,y,flux,sca\n500,600,1000,2\n" > on2.csv &&
	run --sca 1,2 -o two.fits on2.csv && fitsinfo two.fits > i &&
	awk "\$1 == \"WFI01\" && \$2 == 0 { a = 1 } \$1 == \"WFI02\" && \$2 > 900 { b = 1 } END { exit !(a && b) }" i
'
test_expect_success 'a star just off the edge lights the edge; a far one is dropped' '
	printf "x,y,flux\n-3,500,1000\n" > edge.csv && run -o edge.fits edge.csv &&
	v=$(fitsinfo --pix edge.fits WFI01 0 499) && awk "BEGIN { exit !($v > 0.1) }" &&
	printf "x,y,flux\n-300,500,1000\n" > far.csv && run -o far.fits far.csv &&
	fitsinfo far.fits > i && read n sum rest < i && test "$sum" = 0
'
test_expect_success '--placed lists the sources that landed, 1-based' '
	run -o p.fits --placed placed.csv stars.csv &&
	head -n 1 placed.csv > h && test_grep "^id,sca,x,y,flux,mag,model$" h &&
	test "$(grep -c , placed.csv)" = 5 &&
	test_grep "^2,1,2045.0000,2045.0000,50000," placed.csv && ! test_grep "^5," placed.csv
'
test_expect_success 'an empty catalog gives a valid blank image' '
	: > empty.csv && run -o empty.fits empty.csv && fitsinfo empty.fits > i &&
	read n sum rest < i && test "$n $sum" = "WFI01 0"
'
test_expect_success 'an unknown source type names the line, exit 1, no output' '
	printf "x,y,flux,type\n10,10,5,point\n20,20,5,comet\n" > t.csv &&
	test_must_fail --status 1 run -o bad.fits t.csv 2> err &&
	test_grep "t.csv:3.*unknown source type .comet." err && ! test -e bad.fits &&
	test -z "$(ls -a | grep "^\.bad")"
'
test_expect_success 'a bad model name cannot reach the file system' '
	printf "x,y,flux,type\n10,10,5,../../etc/passwd\n" > t2.csv &&
	test_must_fail --status 1 run -o bad.fits t2.csv 2> err &&
	test_grep "unknown source type" err
'
test_expect_success 'a magnitude exactly at a box limit is drawn (STIPS skips it)' '
	printf "x,y,mag\n1000,1000,14\n3000,3000,3\n" > lim.csv &&
	run --flux-unit abmag -o lim.fits --placed lim-placed.csv lim.csv &&
	test "$(grep -c point lim-placed.csv)" = 2 && fitsinfo lim.fits > i &&
	read n sum rest < i && awk "BEGIN { exit !($sum > 1e9) }"
'
test_done
