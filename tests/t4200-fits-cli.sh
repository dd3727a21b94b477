#!/bin/sh
# FITS output through the command line: the STIPS layout (empty primary
# with the settings, one float32 WFInn HDU per SCA with a WCS), tile
# compression, stdout, a full disk, an unwritable directory, and a run
# interrupted while it writes.  The catalog is a small globular cluster
# from contrib/king.
. "$(dirname "$0")/lib.sh"
require_python

KING=$BUILD/contrib/king
[ -x "$KING" ] || skip_all "build/contrib/king is not built"
"$KING" -n 3000 -s 3 > m13.csv
run() { "$WFS" --filter F129 --psf "$PSF" --ra 250.4235 --dec 36.4613 "$@"; }

# check.py FILE [SCA...] [--same REF]: astropy verifies the file and its
# layout; with --same, each image HDU's data also equals REF's HDU of that
# name, compared as fitsinfo.py --same does (FILE read once).
cat > check.py <<'EOT'
import sys
import numpy as np
from astropy.io import fits
from astropy.wcs import WCS
args = sys.argv[1:]
ref = None
if "--same" in args:
    ref = fits.open(args[args.index("--same") + 1])
    args = args[:args.index("--same")]
path, scas = args[0], [int(s) for s in args[1:]]
with fits.open(path) as h:
    h.verify("exception")
    p = h[0].header
    assert p["NAXIS"] == 0 and p["EXTEND"] is True, "primary"
    assert p["FILTER"] == "F129" and p["INSTRUME"] == "WFI", "primary keywords"
    for k in ("EXPTIME", "SEED", "RA_TARG", "DEC_TARG", "NOISE"):
        assert k in p, "primary lacks " + k
    names = [x.name for x in h[1:]]
    assert names == ["WFI%02d" % s for s in scas], names
    for x in h[1:]:
        assert x.data.dtype.name == "float32", x.data.dtype
        assert x.data.shape == (4088, 4088), x.data.shape
        assert np.all(np.isfinite(x.data)), "non-finite pixels"
        w = WCS(x.header)
        assert w.wcs.ctype[0].startswith("RA---TAN"), w.wcs.ctype
        assert x.header["DETECTOR"] == x.name
        if ref is not None:
            y = ref[x.name].data
            assert x.data.shape == y.shape and np.array_equal(x.data, y), \
                "HDU %s differs from %s's" % (x.name, ref.filename())
if ref is not None:
    assert [x.name for x in ref[1:]] == names, "other HDUs than the reference's"
EOT
check() { "$PY" check.py "$@"; }

test_expect_success 'a cluster on SCAs 1-3: primary plus WFI01..WFI03, astropy-clean' '
	run --sca 1-3 -o m13.fits m13.csv && check m13.fits 1 2 3 &&
	test -z "$(ls -A | grep "^\.m13")"
'
test_expect_success 'the cluster centre lights WFI01' '
	fitsinfo m13.fits > info && awk "\$1 == \"WFI01\" && \$2 > 0 { ok = 1 } END { exit !ok }" info
'
test_expect_success 'zstd catalog from king -z gives the same image' '
	"$KING" -n 3000 -s 3 -z > m13.csv.zst && run --sca 1-3 -o z.fits m13.csv.zst &&
	cmp m13.fits z.fits
'
test_expect_success '-o - through a pipe is the file, byte for byte' '
	run --sca 1-3 -o - m13.csv | cat > piped.fits && cmp m13.fits piped.fits
'
test_expect_success '--compress gzip is lossless' '
	run --sca 1-3 --compress gzip -o g.fits m13.csv && check g.fits 1 2 3 --same m13.fits &&
	test $(wc -c < g.fits) -lt $(wc -c < m13.fits)
'
test_expect_success '--compress rice is close, smaller, and reproducible' '
	run --sca 1-3 --compress rice -o r.fits m13.csv && check r.fits 1 2 3 &&
	run --sca 1-3 --compress rice -o r2.fits m13.csv && cmp r.fits r2.fits &&
	test $(wc -c < r.fits) -lt $(wc -c < m13.fits) &&
	"$PY" -c "
import numpy as np
from astropy.io import fits
a, b = fits.open(\"m13.fits\"), fits.open(\"r.fits\")
for x, y in zip(a[1:], b[1:]):
    d = np.abs(x.data.astype(float) - y.data)
    # quantization steps are a quarter of the noise: tiny next to it
    assert d.max() <= 0.5 * np.std(x.data) + 1e-6, (x.name, d.max(), np.std(x.data))
"
'
test_expect_success 'one compressed file per SCA' '
	run --sca 2,3 --compress gzip -o "sca%d.fits" m13.csv &&
	check sca2.fits 2 && check sca3.fits 3 && ! test -e sca1.fits
'
test_expect_success '--compress gzip to stdout is refused' '
	test_must_fail --status 1 run --compress gzip -o - m13.csv >out 2>err &&
	test_grep "tile-compressed\|tile compression" err && test ! -s out
'
test_expect_success '-o /dev/null writes in place and leaves the device alone' '
	run -o /dev/null m13.csv && test -c /dev/null
'
test_expect_success 'an existing file is kept when the new run fails' '
	cp m13.fits keep.fits &&
	printf "x,y,flux,type\n10,10,5,comet\n" > bad.csv &&
	test_must_fail --status 1 run -o keep.fits bad.csv 2>err &&
	cmp m13.fits keep.fits && test -z "$(ls -A | grep "^\.keep")"
'
test_expect_success 'unwritable directory: exit 2, the name and the cause' '
	mkdir ro && chmod 555 ro &&
	if touch ro/probe 2>/dev/null; then
		rm -f ro/probe; target=/sys/wfs-test.fits   # root: use sysfs
	else
		target=ro/out.fits
	fi &&
	test_must_fail --status 2 run -o $target m13.csv 2>err &&
	test_grep "$target: cannot create temporary file .*Permission denied" err &&
	test -z "$(ls -A ro)"
'

SHIM=$TRASH/enospc.so
# full_run DIR ARGS...: a run whose writes into DIR hit a full disk after
# a megabyte (tests/shim/enospc.c).
full_run() {
	dir=$1; shift
	env WFS_ENOSPC_MATCH="$TRASH/$dir/" WFS_ENOSPC_AFTER=1000000 LD_PRELOAD="$SHIM" \
		"$WFS" --filter F129 --psf "$PSF" --ra 250.4235 --dec 36.4613 "$@"
}
if cc -shared -fPIC -o "$SHIM" "$TOP/tests/shim/enospc.c" -ldl 2>/dev/null; then
	for comp in none gzip; do
		test_expect_success "disk full ($comp): exit 2, message, no file or temporary" "
			mkdir -p full-$comp &&
			test_must_fail --status 2 full_run full-$comp --sca 1,2 --compress $comp \
				-o full-$comp/out.fits m13.csv 2>err &&
			test_grep 'full-$comp/out.fits: write error: No space left on device' err &&
			test -z \"\$(ls -A full-$comp)\"
		"
	done
else
	test_skip 'disk full' 'cannot build tests/shim/enospc.c'
fi

test_expect_success 'disk full on stdout: exit 2 and a message' '
	test_must_fail --status 2 run -o - m13.csv >/dev/full 2>err &&
	test_grep "<stdout>: write error: No space left on device" err
'

# SIGTERM while the file is being written: wait for the temporary file to
# appear, then signal.  A machine fast enough to finish first skips.
# (Not through run(): the pid must be wfiscene's, not a subshell's.)
"$WFS" --filter F129 --psf "$PSF" --ra 250.4235 --dec 36.4613 --sca 1-6 \
	-o big.fits m13.csv 2>err.sig &
pid=$!
seen=
i=0
while [ $i -lt 1000 ] && kill -0 $pid 2>/dev/null; do
	if [ -n "$(ls -A | grep '^\.big\.fits\.')" ]; then
		kill -TERM $pid && seen=1
		break
	fi
	sleep 0.01 2>/dev/null || sleep 1
	i=$((i + 1))
done
wait $pid
rc=$?
if [ -n "$seen" ]; then
	test_expect_success 'SIGTERM while writing: exit 4, no file, no temporary' "
		test $rc -eq 4 && ! test -e big.fits &&
		test -z \"\$(ls -A | grep '^\\.big')\" &&
		test_grep 'interrupted' err.sig
	"
else
	test_skip 'SIGTERM while writing' 'the run finished before it could be interrupted'
fi

test_done
