#!/bin/sh
# The plugin ABI's promises, held by test plugins the host knows nothing
# about: a model that is neither point nor Sérsic gets exactly one
# prepare() and footprint() per row and SCA it lands on; --report lists each
# model's settings as the model declares them; a plugin built against the
# first edition of model.h still loads and draws the same pixels; a plugin
# with an unresolved symbol is refused when loaded, not mid-run; a type
# with a setting of its name resolves to that family's model; a model's
# rows are written in romanisim's convention by what it declares.
. "$(dirname "$0")/lib.sh"
require_python

mkdir plugins
# build NAME SOURCE INCLUDE [FLAGS...]: tests/plugins/SOURCE.c to plugins/NAME.so
build() {
	name=$1 src=$2 inc=$3
	shift 3
	${CC:-cc} -std=c11 -Wall -Wextra -Wno-unused-parameter -shared -fPIC \
		-fvisibility=hidden -I"$inc" "$@" -o "plugins/$name.so" \
		"$TOP/tests/plugins/$src.c" -lm
}
run() { "$WFS" --filter F158 --sca 1,2 --ra 10 --dec 20 --plugin-path "$TRASH/plugins" "$@"; }

test_expect_success 'the counting plugin builds against model.h, with -z defs' '
	build counts counts "$TOP/include" -Wl,-z,defs
'
test_expect_success '... and against the first edition of model.h' '
	build counts-old counts "$TOP/tests/plugins/abi1" -Wl,-z,defs \
		-DCOUNTS_NAME="\"counts-old\""
'

# Where SCAs 1 and 2 are on the sky: their RA_APER, DEC_APER.
test_expect_success 'the SCA centres of the pointing' '
	printf "x,y,flux,type\n100,100,1,counts\n" > one.csv &&
	run -o centres.fits one.csv &&
	"$PY" -c "
from astropy.io import fits
for h in fits.open(\"centres.fits\")[1:]:
    print(h.header[\"RA_APER\"], h.header[\"DEC_APER\"])
" > centres && test "$(wc -l < centres)" = 2
'
# 5 sky rows well inside each SCA, 3 far from both, 2 pixel rows (one per
# SCA): 12 rows land on one SCA each, 3 on none.
test_expect_success 'a catalog of rows on SCA 1, on SCA 2 and on neither' '
	"$PY" -c "
c = [l.split() for l in open(\"centres\")]
print(\"ra,dec,flux,type,side\")
k = 0
for ra, dec in c:
    for d in (-0.02, -0.01, 0, 0.01, 0.02):
        k += 1
        print(\"%.8f,%.8f,%d,TYPE,%d\" % (float(ra) + d, float(dec) - d, 100 * k, 2 * (k % 4) + 1))
for d in (3, 4, 5):
    print(\"%.8f,%.8f,100,TYPE,3\" % (float(c[0][0]) + d, float(c[0][1])))
" > sky.csv &&
	printf "x,y,sca,flux,type,side\n500.2,600.7,1,300,TYPE,7\n1500.2,1600.7,2,300,TYPE,1\n" > pix.csv &&
	sed s/TYPE/counts/ sky.csv > counts-sky.csv && sed s/TYPE/counts/ pix.csv > counts-pix.csv &&
	sed s/TYPE/counts-old/ sky.csv > counts-old-sky.csv &&
	sed s/TYPE/counts-old/ pix.csv > counts-old-pix.csv
'

# counted FILE MODEL: "prepare footprint reach" as the model said at fini()
counted() { sed -n "s/^wfiscene: $2: prepare \([0-9]*\) footprint \([0-9]*\) reach \([0-9]*\)$/\1 \2 \3/p" "$1"; }

test_expect_success 'one prepare() and footprint() per row and SCA it lands on' '
	run --report new.json --placed new-placed.csv -o new.fits counts-sky.csv counts-pix.csv 2> err &&
	test "$(counted err counts)" = "12 12 13" &&
	test "$(($(wc -l < new-placed.csv) - 1))" = 12 &&
	"$PY" -c "
import json
r = json.load(open(\"new.json\"))[\"rows\"]
assert r[\"placements\"] + r[\"off_detector\"] == 12 and r[\"culled_far\"] == 3, r
"
'
test_expect_success '... in every exposure of a --pointings run' '
	printf "10 20 0 a\n10.0001 20 0 b\n" > two.txt &&
	run --pointings two.txt -o "p_%s.fits" counts-sky.csv counts-pix.csv 2> err &&
	test "$(counted err counts)" = "12 12 13
12 12 13"
'
test_expect_success '--report lists the settings the model declares, with their values' '
	"$PY" -c "
import json
s = json.load(open(\"new.json\"))[\"model_settings\"]
assert s == {\"counts\": {\"counts-gain\": \"1\"}}, s
" &&
	run --set counts-gain=2.5 --report gain.json -o gain.fits counts-sky.csv counts-pix.csv 2> err &&
	"$PY" -c "
import json
s = json.load(open(\"gain.json\"))[\"model_settings\"]
assert s == {\"counts\": {\"counts-gain\": \"2.5\"}}, s
"
'
test_expect_success 'a plugin of the first edition of model.h loads and draws the same pixels' '
	run --report old.json -o old.fits counts-old-sky.csv counts-old-pix.csv 2> err &&
	"$PY" -c "
from astropy.io import fits
a, b = fits.open(\"new.fits\"), fits.open(\"old.fits\")
assert len(a) == len(b) == 3
for i in (1, 2):
    assert (a[i].data == b[i].data).all() and a[i].data.sum() > 0, i
"
'
# Without reach() the host learns a row'"'"'s reach the old way: one more
# prepare() and footprint() per sky row (13), and no reach() call.
test_expect_success '... with one more prepare() per sky row, and no settings to report' '
	test "$(counted err counts-old)" = "25 25 0" &&
	"$PY" -c "
import json
s = json.load(open(\"old.json\"))[\"model_settings\"]
assert s == {\"counts-old\": {}}, s
"
'

test_expect_success 'a plugin needing a symbol nobody defines does not link with -z defs' '
	test_must_fail build unresolved unresolved "$TOP/include" -Wl,-z,defs 2> err &&
	test_grep "wfs_host_internal_function" err
'
test_expect_success '... and, linked without, is refused when loaded: exit 3, no output' '
	build unresolved unresolved "$TOP/include" &&
	printf "x,y,flux,type\n100,100,1,unresolved\n" > u.csv &&
	test_must_fail --status 3 run -o u.fits u.csv 2> err &&
	test_grep "model .unresolved.*undefined symbol: wfs_host_internal_function" err &&
	test_grep "z,defs" err &&
	! ls -A | grep -q "u\.fits"
'

test_expect_success 'a type with a setting of its name is drawn by that family member' '
	build counts-alt counts "$TOP/include" -DCOUNTS_NAME="\"counts-alt\"" &&
	run --set counts=alt --report alt.json -o alt.fits counts-sky.csv counts-pix.csv 2> err &&
	test "$(counted err counts-alt)" = "12 12 13" &&
	"$PY" -c "
import json
r = json.load(open(\"alt.json\"))
assert r[\"rows\"][\"by_model\"] == {\"counts-alt\": 12}, r[\"rows\"]
" &&
	test_must_fail --status 1 run --set counts=nosuch -o no.fits counts-sky.csv counts-pix.csv 2> err &&
	test_grep "no model plugin .counts-nosuch.so." err
'
# The counting model as a user's sersic-quick, ahead of the built-in one
# on the plugin path, with shape columns of its own names (model.h,
# column_roles, roman_type).
placed_rows() { grep -v "^#" "$1" | sed 1d | cut -d, -f7-11; }
test_expect_success 'a model that declares its shape and romanisim type is written as SER' '
	mkdir shaped && build ../shaped/sersic-quick counts "$TOP/include" \
		-DCOUNTS_NAME="\"sersic-quick\"" -DCOUNTS_SHAPE &&
	printf "x,y,sca,flux,type,side,index,hl,q,angle\n" > shape.csv &&
	printf "500,600,1,300,TYPE,3,2.5,4,0.25,-30\n" >> shape.csv &&
	sed s/TYPE/sersic/ shape.csv > shape-ser.csv &&
	"$WFS" --filter F158 --sca 1 --ra 10 --dec 20 --plugin-path "$TRASH/shaped" \
		--set placed=romanisim --placed ser.ecsv -o ser.fits shape-ser.csv &&
	test "$(placed_rows ser.ecsv)" = "SER,2.5,0.22,330,0.25"
'
test_expect_success '... under its own name when SER would be drawn by another model' '
	sed s/TYPE/sersic-quick/ shape.csv > shape-own.csv &&
	"$WFS" --filter F158 --sca 1 --ra 10 --dec 20 --plugin-path "$TRASH/shaped" \
		--sersic precise --set placed=romanisim --placed own.ecsv -o own.fits shape-own.csv &&
	test "$(placed_rows own.ecsv)" = "sersic-quick,2.5,0.22,330,0.25"
'
test_expect_success '... and without the declarations, no type and no shape of romanisim' '
	build ../shaped/sersic-quick counts "$TOP/include" -DCOUNTS_NAME="\"sersic-quick\"" &&
	"$WFS" --filter F158 --sca 1 --ra 10 --dec 20 --plugin-path "$TRASH/shaped" \
		--set placed=romanisim --placed bare.ecsv -o bare.fits shape-ser.csv &&
	test "$(placed_rows bare.ecsv)" = "sersic-quick,-1,0,0,1"
'
# A key a model declares is known to the warning about --set keys that
# nothing reads even when the model does not read it: a misspelling of it
# is answered with it, and the key itself is named without a suggestion.
test_expect_success 'a declared key the model never reads: suggested, never itself' '
	mkdir unread && build ../unread/counts counts "$TOP/include" -DCOUNTS_UNREAD &&
	printf "x,y,sca,flux,type\n100,100,1,1,counts\n" > unread.csv &&
	"$WFS" --filter F158 --sca 1 --plugin-path "$TRASH/unread" --set counts-unred=1 \
		--set counts-unread=1 -o unread.fits unread.csv 2> err &&
	test_grep "counts-unred: .*misspelt key; did you mean counts-unread?)\$" err &&
	test_grep "counts-unread: .*misspelt key)\$" err
'
test_done
