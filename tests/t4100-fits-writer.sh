#!/bin/sh
# The FITS writer through its unit-test helper (build/tests/fitsout write
# PATH [none|rice|gzip]): a full disk, an unwritable directory, stdout
# against a file, and astropy's verdict on the files.
. "$(dirname "$0")/lib.sh"

W=$BUILD/tests/fitsout
[ -x "$W" ] || skip_all "build/tests/fitsout is not built (make unit)"

# The ENOSPC shim: writes to paths containing $WFS_ENOSPC_MATCH fail once
# $WFS_ENOSPC_AFTER bytes have gone through.
SHIM=$TRASH/enospc.so
cc -shared -fPIC -o "$SHIM" "$TOP/tests/shim/enospc.c" -ldl 2>"$TRASH/.cc" || SHIM=

full() { # full AFTER cmd...: run cmd on a disk that fills after AFTER bytes
	after=$1; shift
	WFS_ENOSPC_MATCH=$TRASH/full/ WFS_ENOSPC_AFTER=$after LD_PRELOAD=$SHIM "$@"
}

test_expect_success 'a file is written and nothing else is left' '
	mkdir d && "$W" write d/out.fits &&
	test "$(ls -A d)" = out.fits &&
	test $(($(wc -c <d/out.fits) % 2880)) -eq 0
'

test_expect_success 'stdout and the file are the same bytes' '
	"$W" write file.fits && "$W" write - >stdout.fits &&
	test_cmp file.fits stdout.fits
'

test_expect_success 'through a pipe too' '
	"$W" write - | cat >piped.fits && test_cmp file.fits piped.fits
'

# cfitsio's own "-" would hold all 200 MB in memory; ours holds a buffer.
if [ -x /usr/bin/time ]; then
	test_expect_success 'stdout streams 3 full SCAs (200 MB) in bounded memory' '
		/usr/bin/time -f %M -o rss "$W" big - 3 | wc -c > size &&
		test "$(cat size)" = 200554560 &&
		test "$(tail -n 1 rss)" -lt 30000
	'
else
	test_skip 'stdout streams in bounded memory' '/usr/bin/time is absent (Debian package time)'
fi

test_expect_success 'compression to stdout is refused with a clear message' '
	test_must_fail --status 1 "$W" write - rice >out 2>err &&
	test_grep "<stdout>: tile compression needs a regular file" err &&
	test ! -s out
'

for comp in none gzip rice; do
	for after in 0 4000 12000; do
		if [ -z "$SHIM" ]; then
			test_skip "disk full ($comp, after $after bytes)" "cannot build the shim"
			continue
		fi
		test_expect_success "disk full ($comp, after $after bytes): error, no file, no temporary" "
			rm -rf full && mkdir full &&
			test_must_fail --status 2 full $after \"\$W\" write full/out.fits $comp 2>err &&
			test_grep 'full/out.fits: .*No space left on device' err &&
			test -z \"\$(ls -A full)\"
		"
	done
done

test_expect_success 'disk full on stdout (/dev/full)' '
	test_must_fail --status 2 "$W" write - >/dev/full 2>err &&
	test_grep "<stdout>: write error: No space left on device" err
'

test_expect_success 'unwritable directory: error names the file, nothing left' '
	mkdir ro && chmod 555 ro &&
	if touch ro/probe 2>/dev/null; then
		rm -f ro/probe; target=/sys/wfs-test.fits   # root: use sysfs
	else
		target=ro/out.fits
	fi &&
	test_must_fail --status 2 "$W" write $target 2>err &&
	test_grep "$target: cannot create temporary file .*Permission denied" err &&
	test -z "$(ls -A ro)"
'

test_expect_success 'missing directory' '
	test_must_fail --status 2 "$W" write nodir/out.fits 2>err &&
	test_grep "nodir/out.fits: .*No such file or directory" err
'

if have_python; then
	test_expect_success 'astropy verifies plain, gzip and rice files' '
		"$W" write p.fits && "$W" write g.fits gzip && "$W" write r.fits rice &&
		"$PY" -c "
import sys
from astropy.io import fits
for name in sys.argv[1:]:
    with fits.open(name) as h:
        h.verify(\"exception\")
        assert [x.name for x in h] == [\"PRIMARY\", \"WFI01\", \"WFI02\"], name
        assert h[1].data.dtype.name == \"float32\" and h[1].data.shape == (23, 37)
        assert h[0].header[\"FILTER\"] == \"F129\"
" p.fits g.fits r.fits
	'
	test_expect_success 'gzip is lossless, rice within half a quantization step' '
		"$PY" -c "
import numpy as np
from astropy.io import fits
p, g, r = (fits.getdata(n, 1) for n in (\"p.fits\", \"g.fits\", \"r.fits\"))
assert np.array_equal(p, g)
assert np.abs(p - r).max() < 0.25, np.abs(p - r).max()
assert np.all(r[p == 0] == 0)   # SUBTRACTIVE_DITHER_2 keeps zeros
"
	'
else
	test_skip 'astropy verification' 'python3 with astropy is absent (Debian package python3-astropy)'
fi

test_done
