#!/bin/sh
# --into a FITS image cut short (a copy or a download that stopped): bad
# input, exit 1, wherever the cut falls.  The message names the image (not
# the output) and where it ends, with nothing dangling after a colon; it
# comes before anything is drawn, so neither the output, nor --placed, nor
# --report, nor a temporary is left, and the image is not touched.
. "$(dirname "$0")/lib.sh"
require_python

# stars SEED N: N stars of AB 18-24 over 0.12 degrees about (10, 20)
stars() { "$BUILD/contrib/starfield" -s "$1" -n "$2" -r 10 -d 20 -w 0.12 -m 18 -M 24; }

# The target: wfiscene's own image of two SCAs, 64 rows each (float32,
# 16352 bytes a row, the data not a whole number of 2880-byte blocks), and
# where its HDUs lie: H1, D1 the header and data of HDU 1 'WFI01', H2, D2
# those of HDU 2 'WFI04', SIZE the whole file.
test_expect_success 'setup: an image of WFI01 and WFI04, 64 rows each' '
	stars 1 200 > a.csv && stars 2 40 > b.csv &&
	"$WFS" --filter F158 --ra 10 --dec 20 --pa 30 --sca 1,4 --rows 1-64 -o t.fits a.csv &&
	"$WFS" --filter F158 --sca 1,4 --into t.fits -o whole.fits b.csv &&
	"$PY" -c "
from astropy.io import fits
h = fits.open(\"t.fits\")
assert [x.name for x in h] == [\"PRIMARY\", \"WFI01\", \"WFI04\"]
assert h[1].data.shape == (64, 4088) and h[1].header[\"BITPIX\"] == -32
i1, i2 = h.fileinfo(1), h.fileinfo(2)
print(\"H1=%d D1=%d H2=%d D2=%d\" % (i1[\"hdrLoc\"], i1[\"datLoc\"], i2[\"hdrLoc\"], i2[\"datLoc\"]))
" > offsets.sh &&
	echo "SIZE=$(wc -c < t.fits)" >> offsets.sh
'
[ -f "$TRASH/offsets.sh" ] && . "$TRASH/offsets.sh"
ROW=16352

# refused TITLE CUT SCA MSG [SPEC]: the target's first CUT bytes as
# cut.fits, given to --into (as SPEC, cut.fits by default) for --sca SCA:
# exit 1, one line "wfiscene: cut.fits: MSG" (fixed text) naming neither
# the output nor anything after a final colon, nothing left in o/, and
# cut.fits as it was.
refused() {
	title=$1 cut=$2 sca=$3 msg=$4 spec=${5:-cut.fits}
	test_expect_success "cut $title ($cut bytes), --into $spec --sca $sca: exit 1" '
		d=$(mktemp -d "$TRASH/run.XXXXXX") && cd "$d" && mkdir o &&
		head -c $cut ../t.fits > cut.fits && cp cut.fits cut0.fits &&
		test_must_fail --status 1 "$WFS" --filter F158 --sca $sca --into "$spec" \
			-o o/out.fits --placed o/placed.csv --report o/report.json ../b.csv 2>err &&
		test "$(wc -l < err)" -eq 1 &&
		grep -F -x -e "wfiscene: cut.fits: $msg" err >/dev/null ||
			{ sed "s/^/| /" err; false; } &&
		! grep -e "out.fits" -e ":[[:space:]]*\$" err &&
		test -z "$(ls -A o)" &&
		cmp cut.fits cut0.fits
	'
}

HDU1="HDU 1 'WFI01' needs $H2 bytes, the file has"
HDU2="HDU 2 'WFI04' needs $SIZE bytes, the file has"

refused 'to nothing' 0 1,4 "truncated FITS file: it is empty (0 bytes)"
refused 'inside the primary header' 1000 1,4 \
	"truncated FITS file: it ends inside its primary header (1000 bytes)"
refused 'inside the primary header' $((H1 - 1)) 1 \
	"truncated FITS file: it ends inside its primary header ($((H1 - 1)) bytes)"
refused "inside WFI01's header" $((H1 + 1000)) 1,4 \
	"truncated FITS file: the header of HDU 1 ends at byte $((H1 + 1000)), incomplete"
refused "inside WFI01's header" $((D1 - 1)) 1 \
	"truncated FITS file: the header of HDU 1 ends at byte $((D1 - 1)), incomplete"
refused "between WFI01's header and data" $D1 1,4 \
	"truncated FITS file: $HDU1 $D1: it ends before its data"
refused "inside WFI01's data" $((D1 + 20 * ROW + 100)) 1 \
	"truncated FITS file: $HDU1 $((D1 + 20 * ROW + 100)): it ends in row 21 of 64"
refused "inside WFI01's data" $((D1 + 20 * ROW + 100)) 1 \
	"truncated FITS file: $HDU1 $((D1 + 20 * ROW + 100)): it ends in row 21 of 64" \
	"cut.fits[1]"
refused "inside WFI01's padding" $((H2 - 1)) 1,4 \
	"truncated FITS file: $HDU1 $((H2 - 1)): it ends after its 64 rows"
refused "inside WFI04's header" $((H2 + 100)) 1 \
	"truncated FITS file: the header of HDU 2 ends at byte $((H2 + 100)), incomplete"
refused "inside WFI04's header" $((H2 + 5)) 1,4 \
	"truncated FITS file: the header of HDU 2 ends at byte $((H2 + 5)), incomplete"
refused "between WFI04's header and data" $D2 1 \
	"truncated FITS file: $HDU2 $D2: it ends before its data"
refused "inside WFI04's data" $((D2 + 63 * ROW)) 1,4 \
	"truncated FITS file: $HDU2 $((D2 + 63 * ROW)): it ends in row 64 of 64"
refused "inside WFI04's data" $((D2 + 63 * ROW)) 4 \
	"truncated FITS file: $HDU2 $((D2 + 63 * ROW)): it ends in row 64 of 64" \
	"cut.fits[WFI04]"
refused 'short of its last byte' $((SIZE - 1)) 1 \
	"truncated FITS file: $HDU2 $((SIZE - 1)): it ends after its 64 rows"

# A cut on an HDU's edge leaves a whole FITS file of fewer HDUs: what it
# lacks is refused as for any image, exit 1 too.
test_expect_success "cut on WFI04's edge ($H2 bytes): a whole file without it, exit 1" '
	mkdir edge edge/o && cd edge &&
	head -c $H2 ../t.fits > cut.fits &&
	test_must_fail --status 1 "$WFS" --filter F158 --sca 1,4 --into cut.fits -o o/out.fits \
		../b.csv 2>err &&
	test_grep "^wfiscene: --into cut.fits: no image HDU .WFI04. for SCA 4" err &&
	test -z "$(ls -A o)"
'
test_expect_success 'bytes after the last HDU that are no HDU: damaged, exit 1' '
	mkdir junk junk/o && cd junk &&
	cp ../t.fits tail.fits && printf "garbage tail" >> tail.fits && cp tail.fits tail0.fits &&
	test_must_fail --status 1 "$WFS" --filter F158 --sca 1 --into tail.fits -o o/out.fits \
		../b.csv 2>err &&
	grep -F -x -e "wfiscene: tail.fits: damaged FITS file: the 12 bytes after its last HDU (HDU 2 '"'"'WFI04'"'"', from byte $SIZE) are not an HDU" err >/dev/null ||
		{ sed "s/^/| /" err; false; } &&
	test -z "$(ls -A o)" && cmp tail.fits tail0.fits
'
if command -v gzip >/dev/null; then
	test_expect_success 'a gzip-compressed image cut short: the same, exit 1' '
		mkdir gz gz/o && cd gz &&
		gzip -c ../t.fits > t.fits.gz &&
		head -c $(($(wc -c < t.fits.gz) / 2)) t.fits.gz > cut.fits.gz &&
		test_must_fail --status 1 "$WFS" --filter F158 --sca 1,4 --into cut.fits.gz \
			-o o/out.fits ../b.csv 2>err &&
		test_grep "^wfiscene: cut.fits.gz: truncated FITS file: HDU [12] .WFI0[14]. needs" err &&
		test -z "$(ls -A o)" &&
		"$WFS" --filter F158 --sca 1,4 --into t.fits.gz -o o/out.fits ../b.csv &&
		cmp o/out.fits ../whole.fits
	'
else
	test_skip 'a gzip-compressed image cut short' 'no gzip'
fi
test_done
