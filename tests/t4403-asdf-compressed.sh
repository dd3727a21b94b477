#!/bin/sh
# --into reads a Roman level-2 ASDF file whose blocks python3-asdf
# compressed (zlib, and lz4 in asdf's framing, as romancal's files often
# are), with python3-asdf's MD5s; the result is the same image as from
# the uncompressed file; a corrupt compressed block is refused with the
# file and block named, nothing written.  wfiscene writes compressed
# blocks too (--set asdf-compression=zlib|lz4): levels 1 and 2 that the
# schemas accept, whose arrays python3-asdf reads equal to the uncompressed
# file's, lz4 byte for byte as python3-asdf frames it, the same bytes for
# any thread count; --into reads them back and keeps or changes their
# compression; a bad value is refused, nothing written.
. "$(dirname "$0")/lib.sh"
require_modules "python3-asdf, python3-asdf-astropy, python3-gwcs, python3-lz4" \
	asdf gwcs asdf_astropy lz4.block

CHECK=$SHARED/tools/roman-asdf-check
printf 'ra,dec,flux\n200,60,5e5\n' > stars.csv

# One python3 call rewrites l2.asdf four ways: c.asdf, and the corrupt
# copies z, l and m.asdf of the third test, each block compressed once.
test_expect_success 'a level 2 file, its blocks compressed by python3-asdf' '
	"$WFS" --filter F158 --ra 200 --dec 60 --pa 30 --date 2027-07-01 --level 2 \
		--ma-table 3 --sca 9 -o l2.asdf stars.csv &&
	"$PY" "$TOP/tests/asdf_rewrite.py" l2.asdf c.asdf --md5 --compress data=lz4 \
		--compress var_poisson=zlib --compress err=lz4 --compress dq=zlib \
		--compress amp33=lz4 \
		z.asdf --compress var_poisson=zlib --corrupt var_poisson \
		l.asdf --compress data=lz4 --corrupt data \
		m.asdf --md5 --compress data=lz4 --corrupt data &&
	"$PY" "$TOP/tests/asdf_va_check.py" grid l2.asdf > grid.csv &&
	head -n 2 grid.csv > one.csv
'

# One python3 call checks the injection into c.asdf and that out_c.asdf
# holds out_u.asdf's arrays (out_c.asdf decompressed once).
test_expect_success '--into the compressed file: the image of the uncompressed one' '
	"$WFS" --filter F158 --sca 9 --into c.asdf -o out_c.asdf --placed p.csv one.csv &&
	"$WFS" --filter F158 --sca 9 --into l2.asdf -o out_u.asdf one.csv &&
	ra=$(sed -n 2p one.csv | cut -d, -f1) && dec=$(sed -n 2p one.csv | cut -d, -f2) &&
	"$PY" "$TOP/tests/asdf_into_check.py" c.asdf out_c.asdf p.csv 2 "$ra" "$dec" \
		out_u.asdf > out &&
	say "$(cat out)" && test_grep "^ok" out && test_grep "^same" out &&
	if have_shared && [ -x "$CHECK" ]; then "$CHECK" --expect wfi_image out_c.asdf; fi
'

test_expect_success 'a corrupt compressed block: file and block named, exit 1, nothing written' '
	test_must_fail --status 1 "$WFS" --filter F158 --sca 9 --into z.asdf -o bad.asdf \
		one.csv 2> err &&
	test_grep "z.asdf: block [0-9]*: its zlib data .*corrupt" err &&
	test_must_fail --status 1 "$WFS" --filter F158 --sca 9 --into l.asdf -o bad.asdf \
		one.csv 2> err &&
	test_grep "l.asdf: block 0: .*lz4\\|l.asdf: block 0: its MD5" err &&
	test_must_fail --status 1 "$WFS" --filter F158 --sca 9 --into m.asdf -o bad.asdf \
		one.csv 2> err &&
	test_grep "m.asdf: block 0: " err &&
	! ls -a | grep -q "bad\\.asdf" &&
	rm z.asdf l.asdf m.asdf
'

# zlib at level 1 (asdf-zlib-level), twice as fast as the default 6: the
# same deflate call with another number.  One python3 call compares both
# files (l2.asdf read once), lz4's blocks as python3-asdf frames them,
# zlib's read with python3-asdf's checksum checks on (asdf_checksum.py's).
test_expect_success 'level 2 with zlib and lz4 blocks: the arrays of the uncompressed file' '
	for c in zlib lz4; do
		"$WFS" --filter F158 --ra 200 --dec 60 --pa 30 --date 2027-07-01 --level 2 \
			--ma-table 3 --sca 9 --set asdf-compression=$c --set asdf-zlib-level=1 \
			-o l2_$c.asdf stars.csv || return 1
	done &&
	"$PY" "$TOP/tests/asdf_same.py" l2.asdf l2_zlib.asdf zlib --checksums \
		l2.asdf l2_lz4.asdf lz4 --lz4-as-asdf > out &&
	say "$(cat out)" && test "$(grep -c "^ok" out)" = 2 &&
	if have_shared && [ -x "$CHECK" ]; then
		"$CHECK" --expect wfi_image l2_zlib.asdf l2_lz4.asdf
	fi
'

# zlib's chunks are primed with the previous one's tail: the one layout
# that could depend on the threads (lz4's chunks stand alone).
test_expect_success 'the same compressed bytes with one thread' '
	mkdir -p b &&
	for c in zlib; do
		"$WFS" --filter F158 --ra 200 --dec 60 --pa 30 --date 2027-07-01 --level 2 \
			--ma-table 3 --sca 9 --set asdf-compression=$c --set asdf-zlib-level=1 \
			--threads 1 --tile 512 \
			-o b/l2_$c.asdf stars.csv &&
		cmp l2_$c.asdf b/l2_$c.asdf || return 1
	done &&
	rm -r b
'

# Level 1 with lz4 only: its blocks go through the writer zlib's do at
# level 2, and a zlib cube costs a minute of the suite.
test_expect_success 'level 1 with lz4 blocks: the arrays of the uncompressed file' '
	l1() { "$WFS" --filter F158 --ra 200 --dec 60 --pa 30 --date 2027-07-01 --level 1 \
		--ma-table 3 --sca 9 "$@" stars.csv; } &&
	l1 -o l1.asdf &&
	for c in lz4; do
		l1 --set asdf-compression=$c -o l1_$c.asdf &&
		"$PY" "$TOP/tests/asdf_same.py" l1.asdf l1_$c.asdf $c > out &&
		say "$c: $(cat out)" && test_grep "^ok" out || return 1
		if have_shared && [ -x "$CHECK" ]; then "$CHECK" --expect wfi_science_raw l1_$c.asdf || return 1; fi
	done &&
	rm -f l1.asdf l1_lz4.asdf
'

# The four outputs against out_u.asdf in one python3 call (out_u.asdf
# read once), in_no.asdf with python3-asdf's checksum checks on.  The
# zlib file is kept compressed at level 1 (asdf-zlib-level), as it was
# written: level 6 made it the slowest run here.
test_expect_success '--into our own compressed file: kept compressed, or stored as told' '
	"$WFS" --filter F158 --sca 9 --into l2_lz4.asdf -o in_lz4.asdf one.csv &&
	"$WFS" --filter F158 --sca 9 --into l2_zlib.asdf --set asdf-zlib-level=1 \
		-o in_zlib.asdf one.csv &&
	"$WFS" --filter F158 --sca 9 --into l2.asdf --set asdf-compression=lz4 -o in_to.asdf \
		one.csv &&
	"$WFS" --filter F158 --sca 9 --into c.asdf --set asdf-compression=none -o in_no.asdf \
		one.csv &&
	"$PY" "$TOP/tests/asdf_same.py" out_u.asdf in_lz4.asdf lz4 out_u.asdf in_zlib.asdf zlib \
		out_u.asdf in_to.asdf lz4 out_u.asdf in_no.asdf none --checksums > out &&
	say "$(cat out)" && test "$(grep -c "^ok" out)" = 4 &&
	# c.asdf carried an MD5 in every block: in_no.asdf keeps one each, right
	grep "^ok in_no.asdf: .* \([0-9]*\) blocks, .*; \1 MD5s right" out &&
	if have_shared && [ -x "$CHECK" ]; then
		"$CHECK" --expect wfi_image in_lz4.asdf in_zlib.asdf in_to.asdf in_no.asdf
	fi
'

test_expect_success 'asdf-compression=gzip: refused naming the key and value, nothing written' '
	test_must_fail --status 1 "$WFS" --filter F158 --ra 200 --dec 60 --level 2 --sca 9 \
		--set asdf-compression=gzip -o g.asdf stars.csv 2> err &&
	test_grep "asdf-compression=gzip: expected none, zlib or lz4" err &&
	test_must_fail --status 1 "$WFS" --filter F158 --sca 9 --into l2.asdf \
		--set asdf-compression=gzip -o g.asdf one.csv 2> err &&
	test_grep "asdf-compression=gzip" err &&
	for l in 0 10 x; do
		test_must_fail --status 1 "$WFS" --filter F158 --level 2 --sca 9 \
			--set asdf-compression=zlib --set asdf-zlib-level=$l -o g.asdf stars.csv \
			2> err && test_grep "asdf-zlib-level=$l: expected a level from 1" err || return 1
	done &&
	! ls -a | grep -q "^\.*g\.asdf"
'

test_done
