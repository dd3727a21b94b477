#!/bin/sh
# The bad-catalog corpus, one test per case through the command line.
#
# tests/corpus/bad/* are stored catalogs that must be refused with the
# message and exit status of wfiscene-catalog(5) DIAGNOSTICS and
# wfiscene(1) EXIT STATUS; tests/corpus/good/* are odd but valid catalogs
# that must render.  Cases that are large, binary or made by a tool (long
# lines, truncated and corrupt zstd and gzip streams, FITS tables with
# the wrong column types) are made here.  Every refused run must leave
# neither the output file nor a temporary .out.fits.* behind, and must
# end by exit(), never by a signal.
. "$(dirname "$0")/lib.sh"

CORPUS=$TOP/tests/corpus
# cfitsio sizes allocations from header values and relies on calloc
# returning NULL for absurd ones (see cfitsio-garbage-header.fits below);
# an ASan build must return NULL too rather than abort.
ASAN_OPTIONS=${ASAN_OPTIONS:+$ASAN_OPTIONS:}allocator_may_return_null=1
export ASAN_OPTIONS

# refused FILE STATUS MESSAGE: run FILE (a path) in a fresh directory;
# exit status STATUS, "wfiscene: NAME" and MESSAGE (fixed text) on stderr,
# nothing left in the directory but the catalog.
refused() {
	file=$1 status=$2 msg=$3
	name=$(basename "$file")
	test_expect_success "refused ($status): $name: $msg" '
		d=$(mktemp -d "$TRASH/run.XXXXXX") && cp "$file" "$d/$name" && cd "$d" &&
		test_must_fail --status $status "$WFS" --filter F129 --ra 270 --dec -30 \
			-o out.fits "$name" 2>err &&
		test_grep "^wfiscene: $name" err &&
		grep -F -e "$msg" err >/dev/null || { cat err; false; } &&
		test "$(ls -A | grep -v -x -e "$name" -e err)" = ""
	'
}

# accepted FILE: renders, and leaves out.fits and nothing else.
accepted() {
	file=$1
	name=$(basename "$file")
	test_expect_success "accepted: $name" '
		d=$(mktemp -d "$TRASH/run.XXXXXX") && cp "$file" "$d/$name" && cd "$d" &&
		"$WFS" --filter F129 --ra 270 --dec -30 -o out.fits "$name" &&
		test -s out.fits &&
		test "$(ls -A | grep -v -x -e "$name" -e out.fits)" = ""
	'
}

B=$CORPUS/bad
refused $B/no-flux.csv 1 ":1: no flux column: need 'flux' or 'mag'"
refused $B/header-no-flux.csv 1 ":1: no flux column"
refused $B/no-position.csv 1 ":1: no position columns: need 'ra' and 'dec', or 'x' and 'y'"
refused $B/ra-without-dec.csv 1 ":1: column 'ra' without 'dec'"
refused $B/x-without-y.csv 1 ":1: column 'x' without 'y'"
refused $B/duplicate-column.csv 1 ":1: duplicate column 'flux' (columns 3 and 4)"
refused $B/empty-column-name.csv 1 ":1: empty column name (column 2)"
refused $B/not-a-number.csv 1 ":3: column 'flux': not a number: 'abc'"
refused $B/trailing-junk.csv 1 ":2: column 'flux': not a number: '100abc'"
refused $B/hex-float.csv 1 ":2: column 'flux': not a number: '0x1p4'"
refused $B/nan.csv 1 ":2: column 'flux': not a finite number: 'NaN'"
refused $B/inf.csv 1 ":2: column 'flux': not a finite number: 'inf'"
refused $B/minus-inf-dec.csv 1 ":2: column 'dec': not a finite number: '-Infinity'"
refused $B/overflow.csv 1 ":2: column 'flux': not a finite number: '1e999'"
refused $B/empty-value.csv 1 ":2: column 'flux': empty value"
refused $B/negative-flux.csv 1 ":2: column 'flux': flux must be positive: '-5'"
refused $B/tiny-negative-flux.csv 1 ":2: column 'flux': flux must be positive: '-1e-300'"
refused $B/zero-flux.csv 1 ":2: column 'flux': flux must be positive: '0'"
test_expect_success 'refused: a flux beyond what a float32 image holds (1e32 per source)' '
	d=$(mktemp -d "$TRASH/run.XXXXXX") && cd "$d" &&
	printf "x,y,flux\n100,100,10\n200,100,1e300\n" > huge.csv &&
	test_must_fail --status 1 "$WFS" --filter F129 -o out.fits huge.csv 2> err &&
	test_grep "huge.csv:3: column .flux.: 1e300 (counts/s) gives 1e+300 counts/s on SCA 1, more than the 1e32" err &&
	printf "x,y,flux\n100,100,1.0000001e32\n" > edge.csv &&
	test_must_fail --status 1 "$WFS" --filter F129 -o out.fits edge.csv 2> err &&
	test_grep "edge.csv:2: column .flux.: 1.0000001e32 (counts/s) gives 1.0000001e+32 counts/s on SCA 1" err &&
	printf "x,y,flux\n100,100,1e30\n" > big.csv &&
	test_must_fail --status 1 "$WFS" --filter F129 --bunit counts --exptime 1000 \
		-o out.fits big.csv 2> err &&
	test_grep "big.csv:2: column .flux.: 1e30 (counts/s) gives 1e+33 counts" err &&
	test "$(ls -A | sort | tr "\n" " ")" = "big.csv edge.csv err huge.csv "
'
refused $B/mag-99.csv 1 ":2: column 'mag': magnitude out of range [-20, 50]: '99'"
refused $B/mag-bright.csv 1 ":2: column 'mag': magnitude out of range [-20, 50]: '-25'"
refused $B/abmag-flux.csv 1 ":3: column 'flux': magnitude out of range [-20, 50]: '75'"
refused $B/dec-range.csv 1 ":2: column 'dec': out of range [-90, 90]: '-91'"
refused $B/sca-range.csv 1 ":2: column 'sca': not an SCA (1 to 18): '19'"
refused $B/sca-zero.csv 1 ":2: column 'sca': not an SCA (1 to 18): '0'"
refused $B/id-not-integer.csv 1 ":2: column 'id': not an integer: '1.5'"
refused $B/unknown-unit.csv 1 ":2: column 'units': unknown unit 'furlong' (want c, j, p, e or m)"
refused $B/unknown-fluxunit.csv 1 ": metadata 'fluxunit': unknown unit 'furlongs' (want counts, abmag, jy or maggies)"
refused $B/unknown-type.csv 1 ": unknown catalog type 'bogus' (want internal, mixed, multifilter or generic)"
refused $B/phoenix-type.tbl 1 ": catalog type 'phoenix' needs stellar or galaxy spectra"
refused $B/internal-no-filter.tbl 1 ": catalog type 'internal' needs metadata 'filter'"
refused $B/mixed-missing-units.tbl 1 "catalog type 'mixed' needs a 'units' column"
refused $B/multifilter-no-column.tbl 1 "catalog type 'multifilter' has no column 'F129' for the scene's filter"
refused $B/unknown-model.csv 1 ":2: unknown source type 'comet'"
refused $B/sersic-n-zero.csv 1 ":3: model 'sersic-quick': column 'n': Sérsic index must be > 0, got 0"
refused $B/sersic-n-range.csv 1 ":2: model 'sersic-quick': column 'n': Sérsic index 25 is outside the supported range 0.05 to 20"
refused $B/sersic-empty-re.csv 1 ":2: model 'sersic-precise': column 're': empty value"
refused $B/sersic-ratio.csv 1 ":2: model 'sersic-quick': column 'ratio': axis ratio must be in (0, 1], got 1.0000001"
refused $B/too-many-fields.csv 1 ":2: row has 4 fields, the header has 3"
refused $B/too-few-fields.csv 1 ":2: row has 2 fields, the header has 3"
refused $B/unterminated-quote.csv 1 ":2: unterminated quoted field"
refused $B/lone-cr.csv 1 ":1: stray carriage return (lines must end in LF or CRLF)"
refused $B/cr-in-middle.csv 1 ":3: stray carriage return"
refused $B/nul-byte.csv 1 ":2: binary data: byte 0x00 at byte 10 of the line"
refused $B/control-byte.csv 1 ":2: binary data: byte 0x1b at byte 12 of the line"
refused $B/invalid-utf8.csv 1 ":2: invalid UTF-8 at byte 16 of the line"
refused $B/overlong-utf8.csv 1 ":2: invalid UTF-8 at byte 13 of the line"
refused $B/png-garbage.csv 1 ":1: invalid UTF-8 at byte 1 of the line"
refused $B/ipac-after-pipe.tbl 1 ":2: data beyond the last column"
# Found by the fuzzer: a FITS file with a damaged extension header on which
# cfitsio 4.2 (ffthdu -> ffmahd -> ffgext) reads an uninitialised stack
# value and may ask calloc for petabytes.  wfiscene must still refuse it
# cleanly.  Its damaged header is the file's last, incomplete block.
refused $B/cfitsio-garbage-header.fits 1 ": truncated FITS file: the header of extension 1"
test_expect_success 'the damaged FITS header with the fuzzer settings (F062, chunk 1)' '
	d=$(mktemp -d "$TRASH/run.XXXXXX") && cd "$d" &&
	test_must_fail --status 1 "$WFS" --filter F062 --chunk 1 -o out.fits \
		"$B/cfitsio-garbage-header.fits" 2>err &&
	test_grep "cfitsio-garbage-header.fits: " err && test "$(ls -A)" = err
'

# Every stored case has its test above.
test_expect_success 'every file of tests/corpus/bad has a test in this script' '
	for f in "$B"/*; do
		grep -q "^refused \$B/$(basename "$f") " "$TOP/tests/t8001-badcat.sh" ||
			{ echo "no test for $f"; exit 1; }
	done
'

for f in "$CORPUS"/good/*; do accepted "$f"; done

# Made here: too large, binary, or made by a tool.
G=$TRASH/gen
mkdir "$G"
{ printf 'ra,dec,flux,notes\n270,-30,100,'; head -c 17000000 /dev/zero | tr '\0' a; echo; } > "$G/line-17MiB.csv"
refused "$G/line-17MiB.csv" 1 ":2: line longer than 16 MiB"
# Longer than the 8 MiB read buffer, shorter than the 16 MiB limit: fine.
{ printf 'ra,dec,flux,notes\n270,-30,100,'; head -c 9000000 /dev/zero | tr '\0' b; echo; } > "$G/line-9MiB.csv"
accepted "$G/line-9MiB.csv"
# A header line longer than any buffer.
{ head -c 17000000 /dev/zero | tr '\0' c; echo; } > "$G/header-17MiB.csv"
refused "$G/header-17MiB.csv" 1 ":1: line longer than 16 MiB"
head -c 300 "$WFS" > "$G/executable.csv"
refused "$G/executable.csv" 1 ":1: binary data: byte 0x7f at byte 1 of the line"

# A flux in maggies or nanomaggies out of the magnitude range: the message
# gives the value as written and the magnitude it is.
printf 'x,y,flux,units\n100,100,1e-30,maggies\n' > "$G/maggies-faint.csv"
refused "$G/maggies-faint.csv" 1 ":2: column 'flux': 1e-30 maggies is AB 75, out of the magnitude range [-20, 50]"
printf 'x,y,flux,units\n100,100,10,nmgy\n100,100,1e30,nmgy\n' > "$G/nmgy-bright.csv"
refused "$G/nmgy-bright.csv" 1 ":3: column 'flux': 1e30 nanomaggies is AB -52.5, out of the magnitude range [-20, 50]"
printf '\\fluxunit=maggies\nx,y,flux\n100,100,1e10\n' > "$G/fluxunit-maggies.csv"
refused "$G/fluxunit-maggies.csv" 1 ":3: column 'flux': 1e10 maggies is AB -25, out of the magnitude range [-20, 50]"

# An unknown unit in a column's header names the line it is on.
printf '%s\n' '# %ECSV 1.0' '# ---' '# datatype:' '# - {name: x, datatype: float64}' \
	'# - {name: y, datatype: float64}' '# - name: Flux' '#   unit: furlong' \
	'#   datatype: float64' 'x y flux' '100 100 5' > "$G/unit.ecsv"
refused "$G/unit.ecsv" 1 "unit.ecsv:7: column 'flux': unknown unit 'furlong' (want counts/s, mag(AB), Jy or maggies)"
printf '%s\n' '\ a comment' '|    x|    y|   flux|' '|double|double|double|' \
	'|     |     |furlong|' '  100   100       5' > "$G/unit.tbl"
refused "$G/unit.tbl" 1 "unit.tbl:4: column 'flux': unknown unit 'furlong' (want counts/s"

seq 1 20000 | sed 's/.*/270,-30,&/' | sed '1i ra,dec,flux' > "$G/many.csv"
zstd -q -c "$G/many.csv" > "$G/many.csv.zst"
gzip -n -c "$G/many.csv" > "$G/many.csv.gz"
head -c 3000 "$G/many.csv.zst" > "$G/cut.zst"
head -c 3000 "$G/many.csv.gz" > "$G/cut.gz"
refused "$G/cut.zst" 1 ": truncated zstd stream (input ends inside a frame)"
refused "$G/cut.gz" 1 ": truncated gzip stream (input ends inside a member)"
printf '\050\265\057\375' > "$G/magic-only.zst"
printf '\037\213' > "$G/magic-only.gz"
refused "$G/magic-only.zst" 1 ": truncated zstd stream"
refused "$G/magic-only.gz" 1 ": truncated gzip stream"
# A good frame followed by a cut one: concatenated streams are one stream.
{ cat "$G/many.csv.zst"; head -c 100 "$G/many.csv.zst"; } > "$G/second-cut.zst"
refused "$G/second-cut.zst" 1 ": truncated zstd stream"
{ cat "$G/many.csv.gz"; head -c 100 "$G/many.csv.gz"; } > "$G/second-cut.gz"
refused "$G/second-cut.gz" 1 ": truncated gzip stream"
# Corrupt: bytes flipped inside the compressed data and the gzip CRC.
flip() { # flip FILE OFFSET: invert one byte in place
	b=$(od -An -tu1 -j "$2" -N1 "$1" | tr -d ' ')
	printf "\\$(printf %03o $((255 - b)))" | dd of="$1" bs=1 seek="$2" conv=notrunc 2>/dev/null
}
cp "$G/many.csv.zst" "$G/flipped.zst" && flip "$G/flipped.zst" 1000
cp "$G/many.csv.gz" "$G/flipped.gz" && flip "$G/flipped.gz" 1000
refused "$G/flipped.zst" 1 ": corrupt zstd stream"
refused "$G/flipped.gz" 1 ": corrupt gzip stream"
printf 'ra,dec,flux\n270,-30,100\n' | gzip -n -c > "$G/crc.gz"
n=$(wc -c < "$G/crc.gz") && flip "$G/crc.gz" $((n - 8))
refused "$G/crc.gz" 1 ": corrupt gzip stream: incorrect data check"
# Compressed garbage: the decoder is fine, the text is not.
head -c 300 "$WFS" | zstd -q -c > "$G/elf.zst"
refused "$G/elf.zst" 1 ":1: binary data: byte 0x7f at byte 1 of the line"
test_expect_success 'a truncated stream on stdin: status 1, <stdin> named, no output' '
	d=$(mktemp -d "$TRASH/run.XXXXXX") && cd "$d" &&
	test_must_fail --status 1 "$WFS" --filter F129 -o out.fits - < "$G/cut.zst" 2>err &&
	test_grep "<stdin>: truncated zstd stream" err && test "$(ls -A)" = err
'
test_expect_success 'a missing catalog: status 2, cannot open' '
	d=$(mktemp -d "$TRASH/run.XXXXXX") && cd "$d" &&
	test_must_fail --status 2 "$WFS" --filter F129 -o out.fits nosuch.csv 2>err &&
	test_grep "nosuch.csv: cannot open" err && test "$(ls -A)" = err
'
test_expect_success 'a directory without catalog files as catalog: status 1' '
	d=$(mktemp -d "$TRASH/run.XXXXXX") && cd "$d" && mkdir cat.csv &&
	test_must_fail --status 1 "$WFS" --filter F129 -o out.fits cat.csv 2>err &&
	test_grep "cat.csv: a directory (a catalog tree) without catalog files" err &&
	test "$(ls -A | sort | tr "\n" " ")" = "cat.csv err "
'
test_expect_success 'a good catalog then a bad one: no output at all' '
	d=$(mktemp -d "$TRASH/run.XXXXXX") && cd "$d" &&
	cp "$CORPUS/good/crlf.csv" "$B/nan.csv" . &&
	test_must_fail --status 1 "$WFS" --filter F129 --ra 270 --dec -30 -o out.fits \
		--placed placed.csv crlf.csv nan.csv 2>err &&
	test_grep "nan.csv:2: column .flux.: not a finite number" err &&
	test "$(ls -A | sort | tr "\n" " ")" = "crlf.csv err nan.csv "
'

# FITS tables with the wrong column types (astropy writes them).
if have_python; then
	"$PY" - "$G" <<-\EOF
	import sys, numpy as np
	from astropy.table import Table
	from astropy.io import fits
	d = sys.argv[1]
	Table({"ra": ["270.0"], "dec": [-30.0], "flux": [100.0]}).write(d + "/str-ra.fits")
	Table({"ra": [270.0], "dec": [-30.0], "flux": ["100"]}).write(d + "/str-flux.fits")
	Table({"ra": [270.0], "dec": [-30.0], "flux": [[100.0, 2.0]]}).write(d + "/vector-flux.fits")
	fits.PrimaryHDU(np.zeros((4, 4), dtype=np.float32)).writeto(d + "/image.fits")
	c = fits.Column(name="flux", format="C", array=np.array([1 + 2j]))
	fits.BinTableHDU.from_columns([fits.Column(name="ra", format="D", array=[270.0]),
		fits.Column(name="dec", format="D", array=[-30.0]), c]).writeto(d + "/complex-flux.fits")
	Table({"ra": [270.0], "dec": [np.nan], "flux": [100.0]}).write(d + "/nan-dec.fits")
	Table({"ra": [270.0], "dec": [-30.0], "flux": [-1.0]}).write(d + "/neg-flux.fits")
	fits.BinTableHDU.from_columns([fits.Column(name="ra", format="D", array=[270.0]),
		fits.Column(name="dec", format="D", array=[-30.0]),
		fits.Column(name="flux", format="D", unit="furlong", array=[1.0])]).writeto(d + "/unit.fits")
	EOF
	refused "$G/str-ra.fits" 1 ": column 'ra' is a string column, not a number"
	refused "$G/str-flux.fits" 1 ": column 'flux' is a string column, not a number"
	refused "$G/vector-flux.fits" 1 "column 'flux': vector column (2 values per row) is not supported"
	refused "$G/image.fits" 1 ": no table in this FITS file"
	refused "$G/complex-flux.fits" 1 "column 'flux'"
	refused "$G/nan-dec.fits" 1 "[1]:1: column 'dec': not a finite number"
	refused "$G/neg-flux.fits" 1 "[1]:1: column 'flux': flux must be positive"
	refused "$G/unit.fits" 1 "unit.fits[1] TUNIT3: column 'flux': unknown unit 'furlong'"
	head -c 4000 "$G/str-ra.fits" > "$G/cut.fits"
	refused "$G/cut.fits" 1 "cut.fits: truncated FITS file"
	# cut inside the primary header, inside the table's data, and the data
	# short of its last byte (3000 rows of 24 bytes fill 25 blocks: no
	# padding); from a file and from compressed stdin
	"$PY" -c "
from astropy.table import Table
n = 3000
Table({'ra': [270.0] * n, 'dec': [-30.0] * n, 'flux': [1.0] * n}).write('$G/long.fits')" &&
	for cut in 1000 6000 -1; do
		if [ $cut = -1 ]; then
			head -c "$(($(wc -c < "$G/long.fits") - 1))" "$G/long.fits" > "$G/cut$cut.fits"
		else
			head -c $cut "$G/long.fits" > "$G/cut$cut.fits"
		fi
		refused "$G/cut$cut.fits" 1 "cut$cut.fits: truncated FITS file"
		test_expect_success "refused: cut$cut.fits, zstd-compressed on stdin" "
			zstd -q -c \"$G/cut$cut.fits\" > cut.zst &&
			test_must_fail --status 1 \"\$WFS\" --filter F129 -o out.fits - < cut.zst 2> err &&
			test_grep '<stdin>: truncated FITS file' err && ! test -e out.fits
		"
	done
else
	test_skip 'FITS tables with wrong column types' 'no python3 with astropy (Debian package python3-astropy)'
fi

test_done
