#!/bin/sh
# A damaged persistence state (wfiscene(1), --persistence-state): each
# field of a saved state put beyond what a run can save (a header line, a
# pixel number, an amplitude, an end time) is refused, exit 1, with a
# message naming the file, the line or the SCA block's pixel, the value and
# what was wanted; the run writes no image and leaves the state as it was.
# States as saved, of any rows, still load.
. "$(dirname "$0")/lib.sh"
[ -x "$PY" ] || skip_all "python3 is absent"

# a star at WFI01's centre: its core is kept in the state
printf 'ra,dec,flux\n0,0,5e7\n' > bright.csv
run() { "$WFS" --filter F129 --sca 1 --allow-sun-angle --background 0.54 --rows 1950-2150 \
	--detector persistence "$@" bright.csv; }
# the top two rows of the SCA under a sky bright enough that every pixel
# is kept: the last pixel of the state is the SCA's last
top() { "$WFS" --filter F129 --sca 1 --allow-sun-angle --background 2 --exptime 1000 \
	--rows 4087-4088 --detector persistence "$@" bright.csv; }

# header FROM N TEXT: bad.bin, FROM with its header line N (1-based) made TEXT
header() { { head -n $(($2 - 1)) "$1" && printf '%s\n' "$3" && tail -n +$(($2 + 1)) "$1"; } > bad.bin; }

cat > poke.py <<\PYEOF
# poke.py FROM TO WHAT INDEX VALUE: FROM with the value of entry INDEX
# (0-based, negative from the end) of its first SCA block made VALUE: WHAT
# is pix (uint32), scale (float32) or tend (float64), little-endian.
import struct, sys
src, dst, what, i, v = sys.argv[1:]
d = bytearray(open(src, "rb").read())
off = 0
for _ in range(6):
    off = d.index(b"\n", off) + 1
n = int(d[:off].split(b"\n")[5].split()[2])
i = int(i) % n
fmt, base, size = {"pix": ("<I", 0, 4), "scale": ("<f", 4 * n, 4), "tend": ("<d", 8 * n, 8)}[what]
struct.pack_into(fmt, d, off + base + i * size, int(v) if what == "pix" else float(v))
open(dst, "wb").write(d)
PYEOF
# poke FROM WHAT INDEX VALUE: bad.bin, FROM with one value changed
poke() { _from=$1; shift; "$PY" poke.py "$_from" bad.bin "$@"; }

# refused RUN PATTERN: a run (run or top) taking up bad.bin fails with
# exit 1 and PATTERN on stderr, writes no image, leaves bad.bin as it was
refused() {
	cp bad.bin before.bin &&
	test_must_fail --status 1 "$1" --persistence-state bad.bin -o out.fits 2> err &&
	test_grep "$2" err && ! test -e out.fits && cmp bad.bin before.bin
}

test_expect_success 'saved states load and carry on' '
	run --date 61000 --persistence-state scene.bin -o a.fits &&
	head -n 6 scene.bin > h && test_grep "^sca 1 [1-9]" h && test_grep "^end 5270400001$" h &&
	cp scene.bin again.bin &&
	run --date 61001 --persistence-state again.bin -o b.fits &&
	test_grep "^exposures 2$" again.bin &&
	top --persistence-state top.bin -o t.fits &&
	test_grep "^sca 1 8176$" top.bin &&
	top --persistence-state top.bin -o t2.fits &&
	# level 1 keeps the row either side of --rows (IPC brings its charge in)
	"$WFS" --filter F129 --sca 1 --allow-sun-angle --background 0.54 --rows 1950-2150 \
		--level 1 --date 61000 --persistence-state l1.bin -o l1.fits bright.csv &&
	"$PY" -c "
import array, sys
d = open(\"l1.bin\", \"rb\").read()
off = 0
for _ in range(6):
    off = d.index(b\"\n\", off) + 1
n = int(d[:off].split(b\"\n\")[5].split()[2])
pix = array.array(\"I\", d[off:off + 4 * n])
assert (min(pix) // 4088, max(pix) // 4088) == (1948, 2150), (min(pix), max(pix))
" &&
	"$WFS" --filter F129 --sca 1 --allow-sun-angle --background 0.54 --rows 1950-2150 \
		--level 1 --persistence-state l1.bin -o l1b.fits bright.csv &&
	# a state of no exposures: no end, no pixels
	printf "wfiscene-persistence 1\nscas 1\nrows 1950 2150\nexposures 0\nend nan\nsca 1 0\n" \
		> empty.bin &&
	run --persistence-state empty.bin -o e.fits && test_grep "^exposures 1$" empty.bin
'

test_expect_success 'exposures -5 is refused' '
	header scene.bin 4 "exposures -5" &&
	refused run "bad.bin:4: exposures .-5.: expected the count of exposures taken into the state, from 0 to 2147483647"
'

test_expect_success 'exposures beyond an int, or with more on the line, are refused' '
	header scene.bin 4 "exposures 3000000000" &&
	refused run "bad.bin:4: exposures .3000000000.: expected the count" &&
	header scene.bin 4 "exposures 1x" &&
	refused run "bad.bin:4: exposures .1x.: expected the count"
'

test_expect_success 'end nan after an exposure is refused' '
	header scene.bin 5 "end nan" &&
	refused run "bad.bin:5: end .nan.: expected the end of the last of its 1 exposures, a time in s (MJD x 86400) from -1857945600 to 1011796371200"
'

test_expect_success 'end inf, 3e38, before 1800 or with more on the line is refused' '
	header scene.bin 5 "end inf" && refused run "bad.bin:5: end .inf.: expected the end" &&
	header scene.bin 5 "end 3e38" && refused run "bad.bin:5: end .3e38.: expected the end" &&
	header scene.bin 5 "end -2e9" && refused run "bad.bin:5: end .-2e9.: expected the end" &&
	header scene.bin 5 "end 5270400001 s" &&
	refused run "bad.bin:5: end .5270400001 s.: not a number"
'

test_expect_success 'an end with no exposures, or pixels with none, is refused' '
	header scene.bin 4 "exposures 0" &&
	refused run "bad.bin:5: end .5270400001.: expected .nan. (the state has no exposures)" &&
	header scene.bin 4 "exposures 0" && mv bad.bin none.bin && header none.bin 5 "end nan" &&
	refused run "bad.bin:6: sca .1 [0-9]*.: expected no pixels (the state has no exposures)"
'

test_expect_success 'an SCA twice, rows or a block line with more on the line are refused' '
	header scene.bin 2 "scas 1 1" &&
	refused run "bad.bin:2: scas .1 1.: expected SCA numbers from 1 to 18, ascending, each once" &&
	header scene.bin 3 "rows 1950 2150 9" &&
	refused run "bad.bin:3: rows .1950 2150 9.: expected the first and last science rows, from 1 to 4088" &&
	n=$(sed -n "6s/^sca 1 //p" scene.bin) &&
	header scene.bin 6 "sca 1 $n 9" &&
	refused run "bad.bin:6: sca .1 $n 9.: expected .1 N., the block of SCA 1 and its count of pixels"
'

test_expect_success 'a block of more pixels than its rows hold is refused' '
	header scene.bin 6 "sca 1 829865" &&
	refused run "bad.bin:6: sca .1 829865.: expected from 0 to 829864 pixels (rows 1949-2151 of the SCA)"
'

test_expect_success 'a pixel past 4088 x 4088 is refused' '
	poke top.bin pix -1 16711744 &&
	refused top "bad.bin: sca 1 pixel 8176 of 8176: number 16711744: expected y . 4088 + x from 16699480 to 16711743 (rows 4086-4088 of the SCA)"
'

test_expect_success 'a pixel past the rows of the state, or before, is refused' '
	n=$(sed -n "6s/^sca 1 //p" scene.bin) &&
	poke scene.bin pix -1 8793288 &&
	refused run "bad.bin: sca 1 pixel $n of $n: number 8793288: expected y . 4088 + x from 7963424 to 8793287 (rows 1949-2151 of the SCA)" &&
	poke scene.bin pix 0 0 &&
	refused run "bad.bin: sca 1 pixel 1 of $n: number 0: expected y . 4088 + x from"
'

test_expect_success 'pixels out of order are refused' '
	n=$(sed -n "6s/^sca 1 //p" scene.bin) &&
	poke scene.bin pix 0 8789200 &&
	refused run "bad.bin: sca 1 pixel 2 of $n: number [0-9]* after 8789200: expected ascending numbers, each once"
'

test_expect_success 'an amplitude of 3e38 is refused' '
	poke scene.bin scale 5 3e38 &&
	refused run "bad.bin: sca 1 pixel 6 of [0-9]* (number [0-9]*): amplitude 3e+38: expected a number above 0, at most 5.07698e+15 (that of the largest fluence)"
'

test_expect_success 'an amplitude of inf, nan, 0 or below is refused' '
	poke scene.bin scale 0 inf && refused run "bad.bin: sca 1 pixel 1 of .*: amplitude inf: expected a number above 0" &&
	poke scene.bin scale 0 nan && refused run "bad.bin: sca 1 pixel 1 of .*: amplitude nan: expected a number above 0" &&
	poke scene.bin scale 0 0 && refused run "bad.bin: sca 1 pixel 1 of .*: amplitude 0: expected a number above 0" &&
	poke scene.bin scale 0 -1 && refused run "bad.bin: sca 1 pixel 1 of .*: amplitude -1: expected a number above 0"
'

test_expect_success 'an end time after the state ends, or far before, is refused' '
	poke scene.bin tend 3 1e300 &&
	refused run "bad.bin: sca 1 pixel 4 of .*: end time 1e+300: expected a time in s (MJD x 86400) from -1857945600 to the state.s end, 5270400001" &&
	poke scene.bin tend 3 5270400002 && refused run "bad.bin: sca 1 pixel 4 of .*: end time 5270400002: expected" &&
	poke scene.bin tend 3 -1e300 && refused run "bad.bin: sca 1 pixel 4 of .*: end time -1e+300: expected" &&
	poke scene.bin tend 3 nan && refused run "bad.bin: sca 1 pixel 4 of .*: end time nan: expected"
'

test_expect_success 'bytes after the last block are refused' '
	{ cat scene.bin && printf x; } > bad.bin &&
	refused run "bad.bin: persistence state damaged: more after the block of the last SCA (line 6)"
'

test_expect_success 'a directory as the state is refused as bad input' '
	mkdir sdir &&
	test_must_fail --status 1 run --persistence-state sdir -o out.fits 2> err &&
	test_grep "sdir: a directory, not a wfiscene persistence state" err &&
	! test -e out.fits && test -d sdir
'

test_done
