#!/bin/sh
# Roman ASDF products (-o NAME.asdf, --format asdf): levels 1 and 2 that
# the Roman schemas (RAD 2.1.0) accept, their arrays those of the FITS
# products of the same seed, the gwcs of level 2 against the FITS TAN-SIP
# WCS, the same bytes for any threads, and the settings an ASDF file does
# not go with refused, nothing written.
. "$(dirname "$0")/lib.sh"
require_modules "python3-asdf, python3-asdf-astropy, python3-gwcs" asdf gwcs asdf_astropy

CHECK=$SHARED/tools/roman-asdf-check
run() { "$WFS" --filter F129 --ra 90 --dec 0 --background 0.54 --date 2027-03-20T06:30 "$@"; }
printf 'ra,dec,flux\n90,0,5e5\n90.01,0.01,3e4\n89.98,0.03,2e7\n' > stars.csv

test_expect_success 'level 2: a wfi_image file, its arrays the FITS level 2 over the gain' '
	run --level 2 -o l2.asdf stars.csv &&
	run --level 2 -o l2.fits stars.csv &&
	head -n 2 l2.asdf > head && printf "#ASDF 1.0.0\n#ASDF_STANDARD 1.6.0\n" > want &&
	test_cmp want head &&
	"$PY" "$TOP/tests/asdf_arrays.py" 2 l2.asdf l2.fits 1 > out && say "$(cat out)" &&
	test_grep "^ok" out
'

# A cosmic-ray jump makes its pixel's chisq far larger than float16's
# largest finite value, 65504: about 1300 pixels of five faint stars'
# SCA at the default MA table (4) and at table 3.  They hold 65504, not
# infinity; no float16 array has an infinity; a DO_NOT_USE pixel's chisq
# is NaN.  f16.py FILE...: prints each file's count at 65504.
cat > f16.py <<'EOF'
import sys
import warnings

import numpy as np
import asdf
import asdf.tags.core.ndarray as nd

warnings.simplefilter("ignore")
nd._datatype_names.setdefault("float16", "f2")
for path in sys.argv[1:]:
    with asdf.open(path, copy_arrays=False) as af:
        r = af.tree["roman"]
        dq = np.asarray(r["dq"])
        for k in ("err", "var_poisson", "var_rnoise", "chisq", "dumo"):
            x = np.asarray(r[k])
            assert x.dtype == np.float16, (path, k, x.dtype)
            assert not np.isinf(x).any(), (path, k, np.isinf(x).sum())
        c = np.asarray(r["chisq"])
        top = c == np.float16(65504)
        assert not (c > np.float16(65504)).any() and not (c < 0).any(), path
        assert (dq[top] & 4).all(), (path, "65504 without JUMP_DET", ((dq[top] & 4) == 0).sum())
        assert np.isnan(c[(dq & 1) != 0]).all(), (path, "DO_NOT_USE, chisq not NaN")
        print(path, int(top.sum()))
EOF

test_expect_success 'level 2: a chisq beyond float16 is 65504, no float16 array infinite' '
	"$BUILD/contrib/starfield" -n 5 -x -m 18 -M 22 -s 1 > s5.csv &&
	: > top.out &&
	for t in 4 3; do
		"$WFS" --filter F158 --level 2 --ma-table $t -o s5_$t.asdf s5.csv &&
		"$PY" f16.py s5_$t.asdf >> top.out && rm s5_$t.asdf || return 1
	done &&
	say "at 65504:" $(cat top.out) &&
	test $(wc -l < top.out) = 2 &&
	while read f n; do test "$n" -ge 1000 || return 1; done < top.out
'

if have_shared && [ -x "$CHECK" ]; then
test_expect_success 'level 2 validates against RAD 2.1.0; a broken file does not' '
	"$CHECK" --expect wfi_image l2.asdf &&
	sed "s|roman/tags/wfi_image-2.1.0|roman/tags/wfi_science_raw-2.1.0|" l2.asdf > raw.asdf &&
	sed "s|^      detector: \"WFI01\"|      detector: \"WFI19\"|" l2.asdf > bad.asdf &&
	test_must_fail "$CHECK" raw.asdf bad.asdf > out &&
	test_grep "^raw.asdf: INVALID" out && test_grep "^bad.asdf: INVALID" out &&
	rm raw.asdf bad.asdf
'
else
test_skip 'level 2 validates against RAD 2.1.0' '../shared/tools/roman-asdf-check is absent'
fi

test_expect_success 'level 2: the gwcs within 0.01 pixel of the FITS WCS, three SCAs at dec 60' '
	"$WFS" --filter F158 --ra 200 --dec 60 --pa 30 --date 2027-07-01 --level 2 \
		--ma-table 3 --sca 1,9,16 -o g_%02d.asdf stars.csv &&
	"$WFS" --filter F158 --ra 200 --dec 60 --pa 30 --sca 1,9,16 -o g.fits stars.csv &&
	"$PY" "$TOP/tests/asdf_gwcs_check.py" g_01.asdf g.fits 1 g_09.asdf g.fits 9 \
		g_16.asdf g.fits 16 > out &&
	test $(wc -l < out) = 3 &&
	for s in 1 9 16; do
		read x fits y inv z ref w rc && say "WFI$s $x $fits $y $inv $z $ref $w $rc" &&
		awk -v a="$fits" -v b="$inv" -v c="$rc" "BEGIN { exit !(a < 0.01 && b < 0.01 && c < 0.01) }" || return 1
	done < out &&
	if [ -x "$CHECK" ]; then "$CHECK" --expect wfi_image g_01.asdf g_09.asdf g_16.asdf; fi
'

# --set velocity-aberration: off (the default) the file says scale 1 and
# romancal's WCS is the gwcs; on, sources move (up to 0.8 px at the
# corners of the outer SCAs) and the gwcs, the FITS WCS and romancal's
# WCS (which applies meta.velocity_aberration.scale_factor) all follow.
# One python3 call makes both grids, one checks the three placed lists.
test_expect_success 'velocity aberration: placed where the gwcs and romancal say, on and off' '
	grep -a -A3 "velocity_aberration:" g_09.asdf | grep -q "scale_factor: 1$" &&
	va() { "$WFS" --filter F158 --ra 200 --dec 60 --pa 30 --date 2027-07-01 --sca 9 "$@"; } &&
	va --level 2 --ma-table 3 --set velocity-aberration=on -o va.asdf stars.csv &&
	va --set velocity-aberration=on -o va.fits stars.csv &&
	"$PY" "$TOP/tests/asdf_gwcs_check.py" va.asdf va.fits 9 > out && say "on: $(cat out)" &&
	read x fits y inv z ref w rc < out &&
	awk -v a="$fits" -v c="$rc" "BEGIN { exit !(a < 0.01 && c < 0.01) }" &&
	! grep -a -A3 "velocity_aberration:" va.asdf | grep -q "scale_factor: 1$" &&
	"$PY" "$TOP/tests/asdf_va_check.py" grid va.asdf grid.csv g_09.asdf grid9.csv &&
	va --noise none --set velocity-aberration=on --placed on.csv -o p.fits grid.csv &&
	va --noise none --placed off.csv -o p.fits grid.csv &&
	va --noise none --placed off9.csv -o p.fits grid9.csv &&
	"$PY" "$TOP/tests/asdf_va_check.py" placed va.asdf on.csv va.asdf off.csv \
		g_09.asdf off9.csv > out &&
	test $(wc -l < out) = 3 &&
	{
		read x dg y drc && say "on: $x $dg $y $drc" &&
		awk -v a="$dg" -v c="$drc" "BEGIN { exit !(a < 0.01 && c < 0.01) }" &&
		read x dg y drc && say "off: $x $dg $y $drc" &&
		awk -v a="$dg" "BEGIN { exit !(a > 0.3) }" &&
		read x dg y drc && say "off: $x $dg $y $drc" &&
		awk -v a="$dg" -v c="$drc" "BEGIN { exit !(a < 0.01 && c < 0.01) }"
	} < out &&
	if [ -x "$CHECK" ]; then "$CHECK" --expect wfi_image va.asdf; fi &&
	test_must_fail --status 1 va --set velocity-aberration=yes -o p.fits stars.csv 2> err &&
	test_grep "velocity-aberration=yes: expected on or off" err &&
	test_must_fail --status 1 va --geometry stips --set velocity-aberration=on -o p.fits \
		stars.csv 2> err && test_grep "SIAF geometry" err
'

test_expect_success 'level 1: a wfi_science_raw file, data the FITS cube, amp33 as the border' '
	run --level 1 --ma-table 3 -o l1.asdf stars.csv &&
	run --level 1 --ma-table 3 -o l1.fits stars.csv &&
	"$PY" "$TOP/tests/asdf_arrays.py" 1 l1.asdf l1.fits 1 > out && say "$(cat out)" &&
	test_grep "^ok" out &&
	if [ -x "$CHECK" ]; then "$CHECK" --expect wfi_science_raw l1.asdf; fi
'

test_expect_success 'the same bytes with one thread, and with --format asdf for any name' '
	mkdir -p b &&
	run --level 1 --ma-table 3 --threads 1 --tile 128 --format asdf -o b/l1.fits stars.csv &&
	LC_ALL=C sed "s/\"l1.fits\"/\"l1.asdf\"/" b/l1.fits > b/l1.asdf &&
	test_cmp l1.asdf b/l1.asdf &&
	run --level 2 --threads 1 --tile 512 -o b/l2.asdf stars.csv &&
	test_cmp l2.asdf b/l2.asdf
'

test_expect_success '--into a level 2 ASDF: the star in DN/s where the gwcs puts it, the rest kept' '
	printf "ra,dec,flux\n90.02,0.02,1e4\n" > inj.csv &&
	"$WFS" --filter F129 --into l2.asdf -o inj.asdf --placed placed.csv inj.csv &&
	"$PY" "$TOP/tests/asdf_into_check.py" l2.asdf inj.asdf placed.csv 2 90.02 0.02 > out &&
	say "$(cat out)" && test_grep "^ok" out &&
	if [ -x "$CHECK" ]; then "$CHECK" --expect wfi_image inj.asdf; fi
'

# broken copies of l2.asdf for --into, each refused with the file named
# and nothing written (python rewrites bytes: sed would do for the text)
test_expect_success '--into refuses a level 1 file, another model, an old standard' '
	inj() { "$WFS" --filter F129 --into "$1" -o out.asdf inj.csv; } &&
	test_must_fail --status 1 inj l1.asdf 2> err && test_grep "l1.asdf: a level 1 file" err &&
	LC_ALL=C sed "s|roman/tags/wfi_image-2.1.0|roman/tags/wfi_mosaic-2.1.0|" l2.asdf > m.asdf &&
	test_must_fail --status 1 inj m.asdf 2> err && test_grep "m.asdf: .roman. is wfi_mosaic" err &&
	LC_ALL=C sed "s|^#ASDF_STANDARD 1.6.0|#ASDF_STANDARD 1.5.0|" l2.asdf > old.asdf &&
	test_must_fail --status 1 inj old.asdf 2> err && test_grep "old.asdf: ASDF Standard 1.5.0" err &&
	LC_ALL=C sed "s|^roman: |romax: |" l2.asdf > nor.asdf &&
	test_must_fail --status 1 inj nor.asdf 2> err && test_grep "nor.asdf: the tree has no .roman." err &&
	test_must_fail --status 1 "$WFS" --filter F129 --sca 2 --into l2.asdf -o out.asdf inj.csv 2> err &&
	test_grep "holds WFI01: give --sca 1" err &&
	! ls -a | grep -q "out\.asdf" &&
	rm m.asdf old.asdf nor.asdf
'

test_expect_success '--into refuses a truncated file, a wrong block size or checksum' '
	inj() { "$WFS" --filter F129 --into "$1" -o out.asdf inj.csv; } &&
	head -c 100000000 l2.asdf > cut.asdf &&
	test_must_fail --status 1 inj cut.asdf 2> err && test_grep "cut.asdf: block .*truncated" err &&
	"$PY" "$TOP/tests/asdf_break.py" l2.asdf size.asdf size 0 sum.asdf md5 0 \
		good.asdf md5-right 0 &&
	test_must_fail --status 1 inj size.asdf 2> err && test_grep "size.asdf: block 0" err &&
	test_must_fail --status 1 inj sum.asdf 2> err && test_grep "sum.asdf: block 0: its MD5" err &&
	inj good.asdf &&
	"$PY" "$TOP/tests/asdf_break.py" out.asdf bad2.asdf md5 0 bad3.asdf md5 3 &&
	test_must_fail "$PY" "$TOP/tests/asdf_checksum.py" out.asdf bad2.asdf bad3.asdf > sums &&
	cat sums && test_grep "^out.asdf: ok" sums && test_grep "^bad2.asdf: FAILED" sums &&
	test_grep "^bad3.asdf: FAILED .*block 3.s MD5" sums &&
	rm out.asdf &&
	! ls -a | grep -q "out\.asdf" &&
	rm cut.asdf size.asdf sum.asdf good.asdf bad2.asdf bad3.asdf
'

test_expect_success 'what an ASDF file does not hold is refused, nothing written' '
	test_must_fail --status 1 run -o s.asdf stars.csv 2> err &&
	test_grep "add --level 1 or --level 2" err &&
	test_must_fail --status 1 run --level 2 --rows 1-100 -o s.asdf stars.csv 2> err &&
	test_grep "whole SCA" err &&
	test_must_fail --status 1 run --level 2 --format asdf -o - stars.csv > /dev/null 2> err &&
	test_grep "not stdout" err &&
	test_must_fail --status 1 run --level 2 --geometry stips -o s.asdf stars.csv 2> err &&
	test_grep "SIAF" err &&
	test_must_fail --status 1 run --level 2 --sca 1,2 -o s.asdf stars.csv 2> err &&
	test_grep "one SCA" err &&
	test_must_fail --status 1 run --level 2 --format xml -o s.asdf stars.csv 2> err &&
	! ls -a | grep -q "s\\.asdf"
'

test_done
