#!/bin/sh
# The built-in PSF cache: a miss builds and stores, a hit loads, a corrupt
# or truncated file is rebuilt, two runs at once both succeed, and the
# cache can be turned off.  Cheap settings (2 wavelengths, coarse pupil)
# keep it fast; the key includes them, so these files never serve a scene.
. "$(dirname "$0")/lib.sh"

C=$TRASH/cache-own
C2=$TRASH/cache-two
cheap='--filter F158 --sca 3 --nwave 2 --pupil-n 128'
nfiles() { find "$1" -type f | wc -l | tr -d ' '; }
samedata() { "$PY" -c '
import sys; from astropy.io import fits; import numpy as np
a, b = (fits.getdata(f) for f in sys.argv[1:3])
sys.exit(0 if a.shape == b.shape and np.array_equal(a, b) else 1)' "$1" "$2"; }

test_expect_success 'a miss builds the grid and stores one file' '
	WFISCENE_CACHE=$C $WFS psf $cheap -v -o a.fits 2>err &&
	test_grep "built with 2 wavelengths" err &&
	test "$(nfiles $C)" = 1
'

test_expect_success 'a hit loads it, same data, in milliseconds' '
	WFISCENE_CACHE=$C $WFS psf $cheap -v -o b.fits 2>err &&
	test_grep "cache .*ms)" err &&
	! grep -q built err &&
	samedata a.fits b.fits
'

test_expect_success 'a scene run with -q says nothing about the cache; -v does' '
	printf "x,y,flux\n100,100,10\n" > one.csv &&
	"$WFS" -q --filter F129 -o q1.fits one.csv 2>err &&
	! test -s err &&
	"$WFS" -v --filter F129 -o q2.fits one.csv 2>err &&
	test_grep "PSF F129 SCA01 177: cache" err
'

# A cache shared on a cluster is read by other users: its files and
# directories get the usual mode, 0666 (0777) less the umask, not mkstemp's
# 0600; and no temporary is left beside them.
test_expect_success 'cache files and directories get 0666/0777 less the umask' '
	( umask 002 && WFISCENE_CACHE=$TRASH/cache-mode/sub $WFS psf $cheap -o m.fits ) &&
	f=$(find "$TRASH/cache-mode" -type f) && test -n "$f" &&
	test "$(stat -c %a $f)" = 664 && test "$(stat -c %a "$TRASH/cache-mode/sub")" = 775 &&
	test "$(stat -c %a m.fits)" = 664 &&
	test -z "$(find "$TRASH/cache-mode" -name ".*")" &&
	( umask 077 && $WFS psf $cheap -o m2.fits ) && test "$(stat -c %a m2.fits)" = 600
'

test_expect_success 'other settings are other keys' '
	WFISCENE_CACHE=$C $WFS psf $cheap --kind psf -o p.fits 2>err &&
	test "$(nfiles $C)" = 2
'

test_expect_success 'a corrupt file (bytes changed) is rebuilt' '
	f=$(ls $C/*epsf*.fits) &&
	printf "garbage!" | dd of="$f" bs=1 seek=20000 conv=notrunc 2>/dev/null &&
	WFISCENE_CACHE=$C $WFS psf $cheap -v -o c.fits 2>err &&
	test_grep "built" err &&
	samedata a.fits c.fits &&
	WFISCENE_CACHE=$C $WFS psf $cheap -v -o d.fits 2>err &&
	test_grep "cache" err
'

if have_python; then
	test_expect_success 'a whole file under the name whose key does not match (stale): rebuilt' '
		f=$(ls $C/*epsf*.fits) &&
		"$PY" -c "
import sys; from astropy.io import fits
with fits.open(sys.argv[1], mode=\"update\") as h:
    h[0].header[\"WFSKEY\"] = \"0123456789abcdef\"
    h[0].add_checksum()" "$f" &&
		WFISCENE_CACHE=$C $WFS psf $cheap -v -o s.fits 2>err &&
		test_grep "built" err && samedata a.fits s.fits &&
		WFISCENE_CACHE=$C $WFS psf $cheap -v -o s2.fits 2>err &&
		test_grep "cache" err
	'
else
	test_skip 'a stale file is rebuilt' 'no python3 with astropy (Debian package python3-astropy)'
fi

test_expect_success 'a truncated file is rebuilt' '
	f=$(ls $C/*epsf*.fits) &&
	head -c 5000 "$f" > t && mv t "$f" &&
	WFISCENE_CACHE=$C $WFS psf $cheap -v -o e.fits 2>err &&
	test_grep "built" err &&
	samedata a.fits e.fits
'

test_expect_success 'two runs at once on an empty cache both succeed' '
	(WFISCENE_CACHE=$C2 $WFS psf $cheap -j1 -o r1.fits 2>e1; echo $? > s1) &
	(WFISCENE_CACHE=$C2 $WFS psf $cheap -j1 -o r2.fits 2>e2; echo $? > s2) &
	wait &&
	test "$(cat s1)" = 0 && test "$(cat s2)" = 0 &&
	samedata r1.fits r2.fits && samedata a.fits r1.fits &&
	test "$(nfiles $C2)" = 1 &&
	WFISCENE_CACHE=$C2 $WFS psf $cheap -v -o r3.fits 2>err &&
	test_grep "cache" err
'

test_expect_success '--no-cache and an empty WFISCENE_CACHE store nothing' '
	C3=$TRASH/cache-none && mkdir $C3 &&
	WFISCENE_CACHE=$C3 $WFS psf $cheap --no-cache -o n1.fits &&
	HOME=$C3 XDG_CACHE_HOME= WFISCENE_CACHE= $WFS psf $cheap -o n2.fits &&
	test "$(nfiles $C3)" = 0 &&
	samedata a.fits n1.fits
'

test_expect_success 'XDG_CACHE_HOME is used when WFISCENE_CACHE is unset' '
	(unset WFISCENE_CACHE; XDG_CACHE_HOME=$TRASH/xdg $WFS psf $cheap -o x.fits) &&
	test "$(nfiles $TRASH/xdg/wfiscene)" = 1
'

test_expect_success 'the planes do not depend on the thread count' '
	$WFS psf $cheap --no-cache -j1 -o j1.fits &&
	$WFS psf $cheap --no-cache -j3 -o j3.fits &&
	samedata a.fits j1.fits && samedata a.fits j3.fits
'

test_expect_success 'an unwritable cache is not an error' '
	WFISCENE_CACHE=/proc/no/such/dir $WFS psf $cheap -o u.fits &&
	samedata a.fits u.fits
'

# The limit: WFISCENE_CACHE_MAX mebibytes of grids, the ones used longest
# ago removed after a grid is stored; only this program's grids, by name
# and by header.  A fake grid: the header of one under the key its name
# holds, SIZE bytes (sparse), dated DATE.
mkfake() {
	k=$(basename "$1" .fits) && k=${k##*-} &&
	{ printf "%-80s" "SIMPLE  =                    T" "WFSKEY  = '$k' / cache key" END; } > "$1" &&
	truncate -s "${3:-1048576}" "$1" && touch -d "$2" "$1"
}

test_expect_success 'over the limit, the grids used longest ago go; the new one stays' '
	L=$TRASH/cache-lim && mkdir $L &&
	mkfake $L/psf-F158-sca97-177-epsf-0000000000000001.fits 2009-01-01 &&
	mkfake $L/psf-F158-sca98-177-epsf-0000000000000002.fits 2010-01-01 &&
	mkfake $L/notes.fits 2001-01-01 && mkfake $L/psf-notes.txt 2001-01-01 &&
	head -c 1048576 /dev/urandom > $L/psf-F158-sca96-177-epsf-00000000000000ff.fits &&
	touch -d 2001-01-01 $L/psf-F158-sca96-177-epsf-00000000000000ff.fits &&
	mkfake $TRASH/target.fits 2001-01-01 &&
	ln -s $TRASH/target.fits $L/psf-F158-sca95-177-epsf-00000000000000aa.fits &&
	WFISCENE_CACHE=$L WFISCENE_CACHE_MAX=4 $WFS psf $cheap -v -o l1.fits 2>err &&
	test_grep "removed 1 grid used longest ago (1.0 MiB), to keep it within 4 MiB" err &&
	! test -e $L/psf-F158-sca97-177-epsf-0000000000000001.fits &&
	test -e $L/psf-F158-sca98-177-epsf-0000000000000002.fits &&
	test "$(ls $L/psf-F158-sca03-*.fits | wc -l)" = 1 &&
	WFISCENE_CACHE=$L WFISCENE_CACHE_MAX=1 $WFS psf $cheap --kind psf -o l2.fits &&
	! test -e $L/psf-F158-sca98-177-epsf-0000000000000002.fits &&
	test "$(ls $L/psf-F158-sca03-*.fits | wc -l)" = 1 &&
	test -e $L/notes.fits && test -e $L/psf-notes.txt &&
	test -e $L/psf-F158-sca96-177-epsf-00000000000000ff.fits &&
	test -L $L/psf-F158-sca95-177-epsf-00000000000000aa.fits && test -s $TRASH/target.fits
'

test_expect_success 'a grid read from the cache is used now: the limit keeps it' '
	L=$TRASH/cache-lru && mkdir $L &&
	WFISCENE_CACHE=$L $WFS psf $cheap -o g1.fits &&
	g=$(ls $L/psf-*.fits) && touch -d 2001-01-01 "$g" &&
	mkfake $L/psf-F158-sca98-177-epsf-0000000000000003.fits 2010-01-01 &&
	WFISCENE_CACHE=$L WFISCENE_CACHE_MAX=0 $WFS psf $cheap -v -o g2.fits 2>err &&
	test_grep "cache" err && samedata g1.fits g2.fits &&
	test "$(stat -c %Y "$g")" -gt "$(date -d 2020-01-01 +%s)" &&
	WFISCENE_CACHE=$L WFISCENE_CACHE_MAX=3 $WFS psf $cheap --kind psf -o g3.fits &&
	test -e "$g" && ! test -e $L/psf-F158-sca98-177-epsf-0000000000000003.fits
'

test_expect_success 'WFISCENE_CACHE_MAX not a number: said once, and nothing removed' '
	L=$TRASH/cache-bad && mkdir $L &&
	mkfake $L/psf-F158-sca97-177-epsf-0000000000000004.fits 2009-01-01 6000000000 &&
	WFISCENE_CACHE=$L WFISCENE_CACHE_MAX=lots $WFS psf --filter F158 --sca 3-4 --nwave 2 \
		--pupil-n 128 -o b1.fits 2>err &&
	test "$(grep -c "WFISCENE_CACHE_MAX=lots: not a whole number of mebibytes" err)" = 1 &&
	test -e $L/psf-F158-sca97-177-epsf-0000000000000004.fits &&
	WFISCENE_CACHE=$L WFISCENE_CACHE_MAX=lots "$WFS" -q --filter F129 -o b2.fits one.csv 2>err &&
	! test -s err && test -e $L/psf-F158-sca97-177-epsf-0000000000000004.fits &&
	WFISCENE_CACHE=$L $WFS psf $cheap --kind psf --nwave 3 -o b3.fits &&
	! test -e $L/psf-F158-sca97-177-epsf-0000000000000004.fits
'

test_done
