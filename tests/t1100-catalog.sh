#!/bin/sh
# Catalogs through the command line: every format and compression on files
# and stdin, empty catalogs, and each bad catalog refused with exit status 1,
# a message naming file, line, column and value, and no output file left.
. "$(dirname "$0")/lib.sh"

run() { "$WFS" --filter F129 --ra 270 --dec -30 "$@"; }

printf 'ra,dec,flux\n270,-30,100\n270.001,-30,50\n' > ok.csv

test_expect_success 'a CSV catalog renders' '
	run -o ok.fits ok.csv && test -s ok.fits
'
test_expect_success 'zstd and gzip catalogs, from files and stdin' '
	zstd -q -c ok.csv > ok.csv.zst && gzip -c ok.csv > ok.gz &&
	run -o a.fits ok.csv.zst && run -o b.fits ok.gz &&
	run -o c.fits - < ok.csv.zst && gzip -dc ok.gz | run -o d.fits &&
	test -s a.fits && test -s b.fits && test -s c.fits && test -s d.fits
'
test_expect_success 'CRLF, BOM, comments and blank lines' '
	printf "\357\273\277# stars\r\nra,dec,flux\r\n\r\n270,-30,100\r\n# more\n270,-30,5\n" > crlf.csv &&
	run -o crlf.fits crlf.csv
'
test_expect_success 'an empty file is an empty catalog' '
	: > empty.csv && run -o e.fits empty.csv && test -s e.fits
'
test_expect_success 'a header-only file is an empty catalog' '
	printf "ra dec flux\n" > hdr.txt && run -o h.fits hdr.txt && test -s h.fits
'
test_expect_success 'the IPAC example of wfiscene-catalog(5)' '
	cat > ex.tbl <<-\EOF &&
	\type = '"'"'internal'"'"'
	\filter = '"'"'F129'"'"'
	|       ra|      dec| flux|   type| n| re| phi| ratio| id|
	  270.6231  -29.7712  15.2  sersic  1  10   30    0.5   1
	EOF
	"$WFS" --filter F129 --ra 270.6231 --dec -29.7712 -o ex.fits ex.tbl
'
test_expect_success 'the other examples of wfiscene-catalog(5)' '
	printf "ra,dec,mag\n270.6231,-29.7712,21.3\n270.6229,-29.7720,24.05\n" > m.csv &&
	printf "\\\\fluxunit=jy\n# ra dec flux\nra         dec       flux\n270.6231   -29.7712  1.1e-5\n" > j.txt &&
	printf "x,y,sca,flux,type,n,re,phi,ratio\n2044.5,2044.5,3,500,sersic,4,8.5,45,0.7\n" > g.csv &&
	"$WFS" --filter F129 --ra 270.6231 --dec -29.7712 -o m.fits m.csv &&
	"$WFS" --filter F129 --ra 270.6231 --dec -29.7712 -o j.fits j.txt &&
	"$WFS" --filter F129 --sca 3 -o g.fits g.csv
'
if have_python; then
	test_expect_success 'astropy FITS, ECSV and IPAC tables' '
		"$PY" -c "
from astropy.table import Table
t = Table({\"ra\": [270.0, 270.001], \"dec\": [-30.0, -30.0], \"flux\": [100.0, 5.0],
           \"type\": [\"point\", \"point\"]})
t.write(\"ap.fits\"); t.write(\"ap.ecsv\"); t.write(\"ap.ipac\", format=\"ascii.ipac\")
" &&
		run -o f1.fits ap.fits && run -o f2.fits ap.ecsv && run -o f3.fits ap.ipac &&
		gzip -c ap.fits | run -o f4.fits
	'
	# unsigned 64-bit ids (astropy writes uint64 as K with TZERO 2^63):
	# exact, and 2^63 on refused as out of range, not as "not an integer"
	test_expect_success 'uint64 ids from FITS and ECSV: exact, or refused as too large' '
		"$PY" -c "
import numpy as np
from astropy.table import Table
ids = np.array([2**53 + 1, 2**53, 2**63 - 1], dtype=np.uint64)
t = Table({\"id\": ids, \"x\": [100.0, 200.0, 300.0], \"y\": [100.0] * 3, \"flux\": [1e3] * 3})
t.write(\"u64.fits\"); t.write(\"u64.ecsv\")
t[\"id\"][2] = 2**63 + 5
t.write(\"u64big.fits\"); t.write(\"u64big.ecsv\")
" &&
		for f in u64.fits u64.ecsv; do
			"$WFS" --filter F129 --rows 90-110 --placed p.csv -o u.fits $f &&
			cut -d, -f1 p.csv > ids && printf "%s\\n" id 9007199254740993 \
				9007199254740992 9223372036854775807 > want && test_cmp want ids ||
			return 1
		done &&
		test_must_fail --status 1 "$WFS" --filter F129 -o u.fits u64big.fits 2> err &&
		test_grep "u64big.fits.1.:3: column .id.: 9223372036854775813 is out of range" err &&
		test_must_fail --status 1 "$WFS" --filter F129 -o u.fits u64big.ecsv 2> err &&
		test_grep "column .id.: 9223372036854775813 is out of range" err
	'
else
	test_skip 'astropy FITS, ECSV and IPAC tables' 'no python3 with astropy (Debian package python3-astropy)'
fi

# Very wide headers: each column name is checked against the others, and
# an ECSV unit matched to its column, through a hash, not by comparing
# every pair, which took minutes for 200 000 columns (the 16 MiB header
# line may hold two million).  Not timed: a quadratic reader shows as a
# test that does not end.
test_expect_success 'a CSV catalog of 200 000 columns and one row' '
	{ printf "x,y,flux," && seq 0 199999 | sed "s/^/c/" | paste -s -d, - &&
	  printf "100,100,500," && seq 200000 | sed "s/.*/1/" | paste -s -d, -; } > wide.csv &&
	run --rows 90-110 --placed wide-p.csv -o wide.fits wide.csv &&
	test_grep "^1,1,100.0000,100.0000,500," wide-p.csv
'
test_expect_success 'an ECSV catalog of 200 000 columns with units, and one row' '
	{ printf "%s\n" "# %ECSV 1.0" "# ---" "# datatype:" "# - {name: x, datatype: float64}" \
		"# - {name: y, datatype: float64}" "# - {name: flux, unit: ct/s, datatype: float64}" &&
	  seq 0 199999 | sed "s/.*/# - {name: c&, unit: m, datatype: int64}/" &&
	  printf "x y flux " && seq 0 199999 | sed "s/^/c/" | paste -s -d" " - &&
	  printf "100 100 500 " && seq 200000 | sed "s/.*/1/" | paste -s -d" " -; } > wide.ecsv &&
	run --rows 90-110 --placed wide-e.csv -o wide-e.fits wide.ecsv &&
	test_grep "^1,1,100.0000,100.0000,500," wide-e.csv
'

# Per-row units of a STIPS mixed catalog, converted as STIPS converts them
# (stips-behaviour.md 5.2: Jy / PHOTFNU, 'p' 1e23 h / (PHOTFNU AREA), 'e'
# 1e23 / (PHOTFNU AREA nu)) with either zeropoint table.  The expected
# counts/s are computed here from the zeropoint the image records
# (PHOTZPAB), STIPS's collecting area and F129's pivot wavelength.
cat > mixed.txt <<\EOT
\type = 'mixed'
\filter = 'F129'
x y sca flux type n re phi ratio id units
100 100 7 100 point 0 0 0 1 1 c
200 100 7 2e-6 point 0 0 0 1 2 j
300 100 7 100 point 0 0 0 1 3 p
400 100 7 1e-20 point 0 0 0 1 4 e
500 100 7 21.5 point 0 0 0 1 5 m
600 100 7 3e-6 point 0 0 0 1 6 J
EOT
for zp in rti stips; do
	test_expect_success "mixed units c, j, p, e, m with --zeropoints $zp" "
		\"\$WFS\" --filter F129 --sca 7 --zeropoints $zp --placed p-$zp.csv -o u-$zp.fits mixed.txt &&
		z=\$(grep -a -o 'PHOTZPAB= *[0-9.]*' u-$zp.fits | head -n 1 | sed 's/.*= *//') &&
		if [ $zp = stips ]; then test \"\$z\" = 26.47; fi &&
		awk -F, -v zp=\"\$z\" '
			BEGIN { fnu = 10 ^ (0.4 * (8.9 - zp)); A = 36076.7; h = 6.6260755e-27
				nu = 2.99792458e14 / 1.2901
				want[1] = 100; want[2] = 2e-6 / fnu; want[3] = 100 * 1e23 * h / (fnu * A)
				want[4] = 1e-20 * 1e23 / (fnu * A * nu); want[5] = 10 ^ (-0.4 * (21.5 - zp))
				want[6] = 3e-6 / fnu }
			NR > 1 { n++; d = \$5 / want[\$1] - 1; if (d < 0) d = -d
				if (d > 1e-5) { print \"id \" \$1 \": \" \$5 \" want \" want[\$1]; bad = 1 } }
			END { exit bad || n != 6 }' p-$zp.csv
	"
done

# bad NAME 'CONTENT' 'MESSAGE': the catalog is refused with status 1 and a
# message starting "wfiscene: NAME" and holding MESSAGE; no output is left.
bad() {
	printf "$2" > "$1"
	printf '%s\n' "$3" > "$1.want"
	test_expect_success "refused: $1: $3" "
		test_must_fail --status 1 \"\$WFS\" --filter F129 -o out.fits $1 2> err &&
		test_grep 'wfiscene: $1' err && grep -F -f $1.want err && ! test -e out.fits
	"
}
bad nan.csv 'ra,dec,flux\n1,2,3\n1,2,abc\n' ":3: column 'flux': not a number: 'abc'"
bad nan2.csv 'ra,dec,flux\n1,2,NaN\n' ":2: column 'flux': not a finite number: 'NaN'"
bad inf.csv 'ra,dec,flux\n1,inf,3\n' ":2: column 'dec': not a finite number: 'inf'"
bad neg.csv 'ra,dec,flux\n1,2,-1\n' ":2: column 'flux': flux must be positive: '-1'"
bad zero.csv 'ra,dec,flux\n1,2,0\n' ":2: column 'flux': flux must be positive: '0'"
bad mag.csv 'ra,dec,mag\n1,2,99\n' ":2: column 'mag': magnitude out of range"
bad nopos.csv 'flux\n1\n' ":1: no position columns"
bad noflux.csv 'ra,dec\n1,2\n' ":1: no flux column"
bad dup.csv 'ra,dec,flux,Flux\n1,2,3,4\n' ":1: duplicate column 'flux'"
bad fields.csv 'ra,dec,flux\n1,2,3,4\n' ":2: row has 4 fields, the header has 3"
bad nul.csv 'ra,dec,flux\n1,2,\0003\n' ":2: binary data: byte 0x00"
bad utf.csv 'ra,dec,flux\n1,2,\377\n' ":2: invalid UTF-8"
bad quote.csv 'ra,dec,flux\n1,2,"3\n' ":2: unterminated quoted field"
bad faroff.csv 'ra,dec,flux,type\n0,0,5,point\n120,40,5,comet\n' ":3: unknown source type 'comet'"
bad phoenix.tbl '\\type=phoenix\nra dec flux\n1 2 3\n' "catalog type 'phoenix' needs stellar or galaxy spectra"
bad other.tbl '\\type=internal\n\\filter=F158\nra dec flux\n1 2 3\n' "is for filter 'F158', the scene's is 'F129'"

test_expect_success 'refused: a line longer than 16 MiB' '
	{ printf "ra,dec,flux,notes\n1,2,3,"; head -c 17000000 /dev/zero | tr "\\0" a; echo; } > long.csv &&
	test_must_fail --status 1 "$WFS" --filter F129 -o out.fits long.csv 2> err &&
	test_grep "long.csv:2: line longer than 16 MiB" err && ! test -e out.fits
'
test_expect_success 'refused: truncated zstd and gzip streams, also on stdin' '
	seq 1 20000 | sed "s/.*/270,-30,&/" | sed "1i ra,dec,flux" > many.csv &&
	zstd -q -c many.csv | head -c 3000 > t.zst && gzip -c many.csv | head -c 3000 > t.gz &&
	test_must_fail --status 1 "$WFS" --filter F129 -o out.fits t.zst 2> err &&
	test_grep "t.zst: truncated zstd stream" err &&
	test_must_fail --status 1 "$WFS" --filter F129 -o out.fits - < t.gz 2> err &&
	test_grep "<stdin>: truncated gzip stream" err && ! test -e out.fits
'
test_expect_success 'refused: a missing catalog file is a system error (2)' '
	test_must_fail --status 2 "$WFS" --filter F129 -o out.fits nosuch.csv 2> err &&
	test_grep "nosuch.csv: cannot open" err && ! test -e out.fits
'
if command -v mandoc > /dev/null; then
	test_expect_success 'wfiscene-catalog(5) is mandoc -Tlint clean' '
		mandoc -Tlint -W style "$TOP/man/wfiscene-catalog.5" > lint 2>&1 &&
		test ! -s lint || { cat lint; false; }
	'
else
	test_skip 'wfiscene-catalog(5) is mandoc -Tlint clean' 'mandoc is absent (Debian package mandoc)'
fi
test_done
