#!/bin/sh
# A flux refused once it is in counts/s names it as the catalog gave it.
#
# A row's flux passes the catalog's own checks and still fails on the
# SCA: a model takes it to 0 or to infinity (not a positive finite
# number), or it brings more than the 1e32 counts/s one source may put in
# a float32 image.  The message names the column the value came from
# ('flux', 'mag', a romanisim filter column), the cell as written and the
# unit it was read in (the column's, the file's, or the row's units cell),
# never a "flux" the user did not write.  Each refusal exits 1 and leaves
# no image behind.
. "$(dirname "$0")/lib.sh"

# A variable star (shape 3, period 0: the curve's first column is MJD)
# dimmed by 1000 mag, to 0 counts/s, or brightened by 100 mag, past 1e32.
xrun() { "$WFS" --filter F158 --sca 1 --ra 150 --dec 0 --rows 1-200 --date 61540.3 "$@"; }
printf '61000 1000\n62000 1000\n' > dark.txt
printf '61000 -100\n62000 -100\n' > bright.txt

# refused NAME CATALOG-TEXT MESSAGE-FOR-DARK MESSAGE-FOR-BRIGHT: the
# catalog's rows with the dark and the bright curve, each refused with
# exit status 1 and its message (fixed text after "wfiscene: NAME:"), and
# no output file.
refused() {
	name=$1 text=$2 dark=$3 bright=$4
	test_expect_success "$name: $dark" '
		d=$(mktemp -d "$TRASH/run.XXXXXX") && cd "$d" &&
		printf "$text" > "$name" &&
		for curve in dark bright; do
			if [ $curve = dark ]; then msg=$dark; else msg=$bright; fi &&
			test_must_fail --status 1 xrun --set variable-curve="$TRASH/$curve.txt" \
				-o out.fits "$name" 2> err &&
			grep -F -e "wfiscene: $name:$msg" err >/dev/null ||
			{ echo "want: wfiscene: $name:$msg"; cat err; exit 1; } &&
			test "$(ls -A | grep -v -x -e "$name" -e err)" = "" || exit 1
		done
	'
}

ZERO="becomes, by its model, 0 counts/s on SCA 1: not a positive finite number"
PAST="becomes, by its model, 3.38064836e+42 counts/s on SCA 1, more than the 1e32 that one source may put in a float32 image"

refused flux.csv 'id,x,y,flux,type,period,shape\n1,100,100,20,variable,0,3\n' \
	"2: column 'flux': 20 (counts/s) $ZERO" \
	"2: column 'flux': 20 (counts/s) becomes, by its model, 2e+41 counts/s on SCA 1, more than the 1e32"
refused mag.csv 'id,x,y,mag,type,period,shape\n1,100,100,20,variable,0,3\n' \
	"2: column 'mag': 20 (AB mag) $ZERO" \
	"2: column 'mag': 20 (AB mag) $PAST"
refused abmag.csv '\\fluxunit=abmag\nid,x,y,flux,type,period,shape\n1,100,100, 20 ,variable,0,3\n' \
	"3: column 'flux': 20 (AB mag) $ZERO" \
	"3: column 'flux': 20 (AB mag) $PAST"
# romanisim's convention: the filter's column, in maggies
refused roman.csv 'id,x,y,F158,type,period,shape\n1,100,100,1e-8,variable,0,3\n' \
	"2: column 'f158': 1e-8 (maggies) $ZERO" \
	"2: column 'f158': 1e-8 (maggies) $PAST"
# a units column: each row's own unit, an empty cell the file's
refused units.csv 'id,x,y,flux,units,type,period,shape\n1,100,100,20,,point,,\n2,100,100,1e3, nmgy ,variable,0,3\n' \
	"3: column 'flux': 1e3 (nanomaggies) $ZERO" \
	"3: column 'flux': 1e3 (nanomaggies) becomes, by its model, 3.38064836e+44 counts/s"

# Without a model: the catalog's value converts to more than 1e32.
test_expect_success 'a flux in Jy past 1e32 counts/s: the column, the value as written, Jy' '
	printf "x,y,flux,units\n100,100,1,c\n100,100,1e30,J\n" > jy.csv &&
	test_must_fail --status 1 xrun -o out.fits jy.csv 2> err &&
	test_grep "^wfiscene: jy.csv:3: column .flux.: 1e30 (Jy) gives 9.3[0-9]*e+36 counts/s on SCA 1, more than the 1e32" err &&
	! test -e out.fits
'
test_expect_success 'a STIPS multifilter catalog past 1e32: the filter'"'"'s column' '
	printf "\\\\type=multifilter\nx y F158\n100 100 10\n100 100 2e32\n" > multi.tbl &&
	test_must_fail --status 1 xrun -o out.fits multi.tbl 2> err &&
	test_grep "^wfiscene: multi.tbl:4: column .f158.: 2e32 (counts/s) gives 2e+32 counts/s on SCA 1, more than the 1e32" err &&
	! test -e out.fits
'

test_done
