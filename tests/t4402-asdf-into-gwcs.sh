#!/bin/sh
# --into a Roman level-2 ASDF file places the sources by the file's gwcs
# (meta.wcs), evaluated in C (src/gwcs_eval.c): a gwcs that python3-gwcs
# and python3-asdf wrote as romancal's assign_wcs builds it (velocity
# aberration step, RotationSequence3D), 2" and 0.02 degrees away from the
# file's meta.wcsinfo; its inverse the file's, or none (Newton's method);
# a transform not evaluated falls back to meta.wcsinfo with a warning.
. "$(dirname "$0")/lib.sh"
require_modules "python3-asdf, python3-asdf-astropy, python3-gwcs" asdf gwcs asdf_astropy

CHECK=$SHARED/tools/roman-asdf-check
printf 'ra,dec,flux\n200,60,5e5\n' > stars.csv

test_expect_success 'a level 2 file, and its gwcs rewritten as romancal builds it' '
	"$WFS" --filter F158 --ra 200 --dec 60 --pa 30 --date 2027-07-01 --level 2 \
		--ma-table 3 --sca 9 -o l2.asdf stars.csv &&
	"$PY" "$TOP/tests/asdf_rewrite.py" l2.asdf rc.asdf --gwcs romancal nw.asdf --gwcs newton \
		un.asdf --gwcs unsupported &&
	! grep -aq "inverse:" nw.asdf &&
	grep -aq "ma_table_name: \"UNKNOWN\"" l2.asdf &&
	"$WFS" --filter F158 --level 2 --ma-table 4 --sca 9 -o l4.asdf stars.csv &&
	grep -aq "ma_table_name: \"C2A_IMG_HLWAS\"" l4.asdf && rm l4.asdf &&
	"$PY" "$TOP/tests/asdf_va_check.py" grid rc.asdf > grid.csv &&
	head -n 2 grid.csv > one.csv
'

inj() { "$WFS" --filter F158 --sca 9 --into "$1" -o "$2" --placed "$3" "$4"; }

test_expect_success 'placed where the gwcs says (its inverse), not where wcsinfo says' '
	inj rc.asdf out.asdf p.csv grid.csv 2> err && ! test -s err &&
	"$PY" "$TOP/tests/asdf_placed_check.py" rc.asdf p.csv grid.csv l2.asdf p.csv grid.csv > out &&
	test $(wc -l < out) = 2 &&
	{
		read x d && say "romancal gwcs: $x $d" && awk -v a="$d" "BEGIN { exit !(a < 0.01) }" &&
		read x d && say "against wcsinfo: $x $d" && awk -v a="$d" "BEGIN { exit !(a > 5) }"
	} < out
'

test_expect_success 'the light added where the gwcs says, the rest kept, the injection recorded' '
	SOURCE_DATE_EPOCH=1800000000 "$WFS" --filter F158 --sca 9 --into rc.asdf -o one.asdf \
		--placed p1.csv one.csv &&
	ra=$(sed -n 2p one.csv | cut -d, -f1) && dec=$(sed -n 2p one.csv | cut -d, -f2) &&
	"$PY" "$TOP/tests/asdf_into_check.py" rc.asdf one.asdf p1.csv 2 "$ra" "$dec" > out &&
	say "$(cat out)" && test_grep "^ok" out &&
	"$PY" -c "
import warnings, asdf, asdf.tags.core.ndarray as nd
warnings.simplefilter(\"ignore\")
nd._datatype_names.setdefault(\"float16\", \"f2\")
with asdf.open(\"one.asdf\") as af:
    m = af.tree[\"roman\"][\"meta\"]
    h = af.tree[\"history\"][\"entries\"][-1]
    assert m[\"filename\"] == \"one.asdf\", m[\"filename\"]
    assert str(m[\"file_date\"]).startswith(\"2027-01-15T08:00:00\"), m[\"file_date\"]
    assert h[\"software\"][\"name\"] == \"wfiscene\", h
    assert \"1 source of one.csv drawn in F158 on WFI09\" in h[\"description\"], h
    assert h[\"time\"] == \"2027-01-15T08:00:00Z\", h
print(\"history\")" > out && test_grep history out &&
	if have_shared && [ -x "$CHECK" ]; then "$CHECK" --expect wfi_image one.asdf; fi
'

test_expect_success 'a gwcs without an inverse: Newton on the forward transform' '
	inj nw.asdf out.asdf p.csv grid.csv 2> err && ! test -s err &&
	"$PY" "$TOP/tests/asdf_placed_check.py" nw.asdf p.csv grid.csv > out &&
	say "no inverse: $(cat out)" && read x d < out &&
	awk -v a="$d" "BEGIN { exit !(a < 0.01) }"
'

test_expect_success 'a transform not evaluated: meta.wcsinfo, with a warning naming it' '
	inj un.asdf out.asdf p.csv grid.csv 2> err &&
	test_grep "un.asdf: meta.wcs step 3: sine1d: this transform is not evaluated" err &&
	"$PY" "$TOP/tests/asdf_placed_check.py" l2.asdf p.csv grid.csv > out &&
	say "by wcsinfo: $(cat out)" && read x d < out &&
	awk -v a="$d" "BEGIN { exit !(a < 0.01) }"
'

test_expect_success 'the fallback applies meta.velocity_aberration as romancal does' '
	LC_ALL=C sed "s/^      scale_factor: 1$/      scale_factor: 1.0003/" un.asdf > va.asdf &&
	grep -aq "scale_factor: 1.0003$" va.asdf &&
	inj va.asdf out.asdf p.csv grid.csv 2> err && test_grep "sine1d" err &&
	"$PY" "$TOP/tests/asdf_placed_check.py" va.asdf p.csv grid.csv wcsinfo \
		un.asdf p.csv grid.csv wcsinfo > out &&
	test $(wc -l < out) = 2 &&
	{
		read x d && say "by wcsinfo and scale 1.0003: $x $d" &&
		awk -v a="$d" "BEGIN { exit !(a < 0.01) }" &&
		read x d && awk -v a="$d" "BEGIN { exit !(a > 0.3) }"
	} < out
'

test_done
