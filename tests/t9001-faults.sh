#!/bin/sh
# Faults: signals while reading a slow stdin and while writing, outputs that
# cannot be written, a broken pipe, an unusable PSF cache or PSF file.  Each
# run reports what happened, exits non-zero with the documented status, and
# leaves no partial output (nor a temporary .NAME.*) under the requested
# names.  Disk full is in t4100/t4200, plugin failures in t7020, bad
# catalogs in t8001.
. "$(dirname "$0")/lib.sh"

# nothing_left [NAME...]: the current directory holds none of NAME (default
# out.fits, placed.csv, report.json) nor a temporary of them.
nothing_left() {
	[ $# -gt 0 ] || set -- out.fits placed.csv report.json
	for n in "$@"; do
		if ls -A | grep -q -e "^$n\$" -e "^\.$n\."; then
			echo "left behind: $(ls -A | grep -e "$n")" >&2; return 1
		fi
	done
}

printf 'x,y,flux\n1000,1000,500\n1100,1200,50\n' > two.csv

# samedata A B: the same PSF planes (the headers differ in their dates).
samedata() {
	if have_python; then "$PY" -c '
import sys; from astropy.io import fits; import numpy as np
a, b = (fits.getdata(f) for f in sys.argv[1:3])
sys.exit(0 if a.shape == b.shape and np.array_equal(a, b) else 1)' "$1" "$2"
	else test -s "$1" && test -s "$2"; fi
}

# signal_reading SIG: wfiscene reads a FIFO that has sent the header and
# a few rows and then stays open; SIG arrives while it waits for more.
signal_reading() {
	sig=$1
	d=$TRASH/read-$sig && mkdir "$d" && cd "$d" || return 1
	mkfifo in
	"$WFS" --filter F129 --sca 1 --psf "$PSF" -o out.fits --placed placed.csv \
		--report report.json < in 2> err &
	pid=$!
	exec 3> in
	printf 'x,y,flux\n1000,1000,500\n' >&3
	wait_sigterm Cgt $pid && sleep 0.2
	kill -s "$sig" $pid
	wait $pid
	rc=$?
	exec 3>&-
	test $rc -eq 4 || { echo "exit $rc, want 4" >&2; cat err >&2; return 1; }
	test_grep "interrupted" err && nothing_left
}
for sig in INT TERM HUP; do
	test_expect_success "SIG$sig while reading a slow stdin: exit 4, nothing left" \
		"signal_reading $sig"
done

test_expect_success 'SIGINT while reading keeps an existing output file' '
	d=$TRASH/keep && mkdir "$d" && cd "$d" &&
	"$WFS" --filter F129 --sca 1 --psf "$PSF" -o out.fits ../two.csv &&
	cp out.fits before.fits && mkfifo in &&
	{ "$WFS" --filter F129 --sca 1 --psf "$PSF" -o out.fits < in 2> err & } &&
	pid=$! && exec 3> in && printf "x,y,flux\n" >&3 &&
	{ wait_sigterm Cgt $pid; sleep 0.2; kill -INT $pid; }; wait $pid; rc=$?; exec 3>&-
	test $rc -eq 4 && cmp before.fits out.fits && test -z "$(ls -A | grep "^\.out")"
'

# The one signal policy is set before any subcommand runs: psf (building a
# grid) and preview (waiting for the reader of its FIFO) are interrupted as
# the scene is, and --placed's temporary goes with the rest.
test_expect_success 'SIGTERM stops wfiscene psf and preview: exit 4, nothing left' '
	d=$TRASH/sig-sub && mkdir "$d" && cd "$d" &&
	{ "$WFS" psf --filter F158 --sca 3 --no-cache -o g.fits 2> err & } && pid=$! &&
	{ wait_sigterm Cgt $pid; kill -TERM $pid; }; wait $pid; rc=$?
	test $rc -eq 4 && test_grep "wfiscene psf: interrupted; partial output removed" err &&
	test -z "$(ls -A | grep -v "^err$")" &&
	"$WFS" --filter F129 --sca 1 --psf "$PSF" --rows 1-16 -o img.fits ../two.csv &&
	mkfifo png &&
	{ "$WFS" preview -o png img.fits 2> err & } && pid=$! &&
	{ wait_sigterm Cgt $pid; kill -TERM $pid; }; wait $pid; rc=$?
	test $rc -eq 4 && test_grep "wfiscene preview: interrupted" err
'
test_expect_success 'SIGINT while reading removes the --placed temporary' '
	d=$TRASH/sig-placed && mkdir "$d" && cd "$d" && mkfifo in &&
	{ "$WFS" --filter F129 --sca 1 --psf "$PSF" -o out.fits --placed p.csv \
		--report r.json < in 2> err & } &&
	pid=$! && exec 3> in && printf "x,y,flux\n" >&3 &&
	{ wait_sigterm Cgt $pid; i=0; while [ $i -lt 300 ] && ! ls -A | grep -q "^\.p\.csv\."; do
		sleep 0.1; i=$((i + 1)); done; ls -A > during; kill -INT $pid; }; wait $pid; rc=$?
	exec 3>&-
	test $rc -eq 4 && test_grep "^\.p\.csv\." during &&
	test -z "$(ls -A | grep -v "^err$\|^in$\|^during$")"
'

# A FITS catalog on stdin is copied to a scratch file that cfitsio opens
# by name: a signal during the copy removes it too.
test_expect_success 'SIGINT while a FITS catalog on stdin is copied: exit 4, no scratch file' '
	d=$TRASH/sig-fits && mkdir -p "$d/tmp" && cd "$d" &&
	printf "x,y,flux\n1000,1000,500\n1100,1200,50\n" | "$BUILD/contrib/csv2fits" cat.fits &&
	mkfifo in &&
	{ TMPDIR=$d/tmp "$WFS" --filter F129 --sca 1 --psf "$PSF" -o out.fits - < in 2> err & } &&
	pid=$! && exec 3> in && head -c 2880 cat.fits >&3 &&
	{ wait_sigterm Cgt $pid; i=0; while [ $i -lt 300 ] && ! ls tmp | grep -q "^wfiscene-fits-"; do
		sleep 0.1; i=$((i + 1)); done; ls tmp > during; kill -INT $pid; }; wait $pid; rc=$?
	exec 3>&-
	test $rc -eq 4 && test_grep "^wfiscene-fits-" during && test -z "$(ls -A tmp)" &&
	test -z "$(ls -A | grep -v "^err$\|^in$\|^during$\|^tmp$\|^cat.fits$")"
'

# signal_writing SIG: 6 SCAs with noise take long enough to write that the
# signal arrives once the temporary file exists.
signal_writing() {
	sig=$1
	d=$TRASH/write-$sig && mkdir "$d" && cd "$d" || return 1
	"$WFS" --filter F129 --sca 1-6 --psf "$PSF" --noise all --threads 1 \
		-o out.fits --placed placed.csv ../two.csv 2> err &
	pid=$!
	seen=
	i=0
	while [ $i -lt 3000 ] && kill -0 $pid 2>/dev/null; do
		if ls -A | grep -q '^\.out\.fits\.'; then kill -s "$sig" $pid && seen=1; break; fi
		sleep 0.01
		i=$((i + 1))
	done
	wait $pid
	rc=$?
	# Six SCAs with every noise stage on one thread take seconds to
	# write: not seeing the temporary file means something else is wrong.
	if [ -z "$seen" ]; then echo "no temporary file seen while writing (exit $rc)" >&2; return 1; fi
	test $rc -eq 4 || { echo "exit $rc, want 4" >&2; cat err >&2; return 1; }
	test_grep "interrupted" err && nothing_left
}
for sig in INT TERM; do
	test_expect_success "SIG$sig while writing: exit 4, nothing left" "signal_writing $sig"
done

test_expect_success 'output in a directory that does not exist: exit 2, named' '
	test_must_fail --status 2 "$WFS" --filter F129 --psf "$PSF" -o no/such/out.fits two.csv 2> err &&
	test_grep "no/such/out.fits" err && ! test -e no
'
test_expect_success 'output name is a directory: refused up front (1), untouched' '
	d=$TRASH/isdir && mkdir "$d" && cd "$d" && mkdir out.fits &&
	test_must_fail --status 1 "$WFS" --filter F129 --psf "$PSF" -o out.fits ../two.csv 2> err &&
	test_grep "out.fits: is a directory" err && test -d out.fits && test -z "$(ls -A out.fits)" &&
	test "$(ls -A | sort | tr "\n" " ")" = "err out.fits "
'
test_expect_success '--placed in an unwritable place: exit 2, no image either' '
	d=$TRASH/placed && mkdir "$d" && cd "$d" &&
	test_must_fail --status 2 "$WFS" --filter F129 --psf "$PSF" -o out.fits \
		--placed no/such/placed.csv ../two.csv 2> err &&
	test_grep "placed.csv" err && nothing_left out.fits
'
test_expect_success '--placed and --report name new files with the usual mode' '
	d=$TRASH/mode && mkdir "$d" && cd "$d" && umask 022 &&
	"$WFS" --filter F129 --psf "$PSF" -o out.fits --placed placed.csv \
		--report report.json ../two.csv &&
	test "$(stat -c %a placed.csv)" = 644 && test "$(stat -c %a report.json)" = 644
'
# A large file an output replaces (on a local file system, with no other
# link) is held across the rename and freed on a thread of its own
# (tempfile_commit): the new file whole under the name, nothing left
# beside; with another link, or as the target of a symbolic link, the old
# file stays intact.
test_expect_success 'an output over a large file: replaced whole, nothing left beside' '
	d=$TRASH/replace && mkdir "$d" && cd "$d" &&
	head -c 3000000 /dev/urandom > out.fits &&
	"$WFS" --filter F129 --psf "$PSF" -o out.fits ../two.csv &&
	test "$(head -c 6 out.fits)" = SIMPLE && cp out.fits first.fits &&
	"$WFS" --filter F129 --psf "$PSF" -o out.fits ../two.csv &&
	cmp out.fits first.fits && test -z "$(ls -A | grep "^\.")"
'
test_expect_success 'an output over a large file with another link: the old one intact there' '
	d=$TRASH/replace-hard && mkdir "$d" && cd "$d" &&
	head -c 3000000 /dev/urandom > old.bin && cp old.bin out.fits && ln out.fits keep.bin &&
	"$WFS" --filter F129 --psf "$PSF" -o out.fits ../two.csv &&
	test "$(head -c 6 out.fits)" = SIMPLE && test "$(stat -c %h keep.bin)" = 1 &&
	cmp keep.bin old.bin && test -z "$(ls -A | grep "^\.")"
'
test_expect_success 'an output over a link to a large file: the link replaced, the file untouched' '
	d=$TRASH/replace-link && mkdir "$d" && cd "$d" &&
	head -c 3000000 /dev/urandom > target.bin && cp target.bin want.bin &&
	ln -s target.bin out.fits &&
	"$WFS" --filter F129 --psf "$PSF" -o out.fits ../two.csv &&
	! test -L out.fits && test "$(head -c 6 out.fits)" = SIMPLE && cmp target.bin want.bin
'
# A FIFO reached through a symbolic link stands for /dev/stdout (a link to
# /proc/self/fd/1) and /dev/null, which a rename would replace (as root).
test_expect_success '--placed and --report to a FIFO through a link: written in place' '
	d=$TRASH/fifo && mkdir "$d" && cd "$d" && mkfifo p1 p2 &&
	ln -s p1 placed-link && ln -s p2 report-link &&
	{ timeout 600 cat placed-link > got.csv & } && { timeout 600 cat report-link > got.json & } &&
	"$WFS" --filter F129 --psf "$PSF" -o out.fits --placed placed-link \
		--report report-link ../two.csv && wait &&
	test -p p1 && test -p p2 && test -L placed-link && test -L report-link &&
	test "$(grep -c ",point$" got.csv)" = 2 && test_grep "\"flux\"" got.json &&
	test -z "$(ls -A | grep "^\.")"
'
test_expect_success '--placed or --report naming a directory: refused (1), nothing left' '
	d=$TRASH/sidedir && mkdir "$d" && cd "$d" && mkdir pl &&
	test_must_fail --status 1 "$WFS" --filter F129 --psf "$PSF" -o out.fits \
		--placed pl ../two.csv 2> err &&
	test_grep "pl: is a directory" err && nothing_left out.fits &&
	test_must_fail --status 1 "$WFS" --filter F129 --psf "$PSF" -o out.fits \
		--report pl ../two.csv 2> err &&
	test_grep "pl: is a directory" err && nothing_left out.fits && test -z "$(ls -A pl)"
'
test_expect_success 'wfiscene psf -o naming a FIFO or a directory: refused (1), untouched' '
	d=$TRASH/psffifo && mkdir "$d" && cd "$d" && mkfifo f && mkdir dir &&
	test_must_fail --status 1 "$WFS" psf --filter F129 --sca 1 -o f 2> err &&
	test_grep "f: not a regular file" err && test -p f &&
	test_must_fail --status 1 "$WFS" psf --filter F129 --sca 1 -o dir 2> err &&
	test -d dir && test -z "$(ls -A dir)" && test -z "$(ls -A | grep "^\.")"
'
test_expect_success '--report in a directory that does not exist: exit 2 up front, no image' '
	d=$TRASH/report && mkdir "$d" && cd "$d" &&
	test_must_fail --status 2 "$WFS" --filter F129 --psf "$PSF" -o out.fits \
		--report no/such/report.json ../two.csv 2> err &&
	test_grep "report.json: cannot write in .no/such/." err && nothing_left out.fits
'
test_expect_success 'a broken pipe on stdout: exit 2 and a message' '
	{ "$WFS" --filter F129 --psf "$PSF" --sca 1-3 -o - two.csv 2> err; echo $? > rc; } |
		head -c 100 > /dev/null &&
	test "$(cat rc)" = 2 && test_grep "<stdout>: write error: Broken pipe" err
'

# Permissions do not stop root; run those cases as nobody when we are root.
# nobody runs a copy of the program and its plugins in the scratch directory:
# the checkout may lie under a directory only its owner can enter (root's
# home is one), where nobody reaches neither.
as_user=
wfs_user=$WFS
why_not='root without setpriv (Debian package util-linux)'
if [ "$(id -u)" = 0 ] && command -v setpriv > /dev/null; then
	mkdir -p "$TRASH/nobody" && cp "$WFS" "$TRASH/nobody/" &&
		cp -R "$BUILD/plugins" "$TRASH/nobody/" && chmod -R a+rX "$TRASH/nobody" &&
		chmod 755 "$TRASH"
	# Through sh: setpriv's own exec of a program nobody cannot reach
	# was seen to succeed; what matters is what nobody can open.
	if setpriv --reuid=nobody --regid=nogroup --clear-groups sh -c \
		'test -r "$1/plugins/point.so" && "$1/wfiscene" --version' sh "$TRASH/nobody" \
		> /dev/null 2>&1; then
		as_user="setpriv --reuid=nobody --regid=nogroup --clear-groups env WFISCENE_PLUGIN_PATH=$TRASH/nobody/plugins"
		wfs_user=$TRASH/nobody/wfiscene
	else
		why_not="nobody cannot reach the scratch directory $TRASH (is TMPDIR private?)"
	fi
fi
if [ "$(id -u)" != 0 ] || [ -n "$as_user" ]; then
	test_expect_success 'unwritable output directory: exit 2, the cause, nothing left' '
		d=$TRASH/ro && mkdir "$d" && cp two.csv "$d" && chmod 555 "$d" && cd "$d" &&
		test_must_fail --status 2 $as_user "$wfs_user" --filter F129 --psf "$PSF" \
			-o out.fits two.csv 2> "$TRASH/err" &&
		test_grep "out.fits: cannot create temporary file .*Permission denied" "$TRASH/err" &&
		test "$(ls -A)" = two.csv
	'
	# The cache tests run `wfiscene psf` with cheap settings (t2100's):
	# same cache code, seconds instead of minutes.
	cheap='--filter F158 --sca 3 --nwave 2 --pupil-n 128'
	test_expect_success 'PSF cache directory unreadable and unwritable: still works' '
		c=$TRASH/cache-000 && mkdir -p "$c" && chmod 755 "$TRASH" &&
		WFISCENE_CACHE=$c "$WFS" psf $cheap -o "$TRASH/ref.fits" && chmod 000 "$c" &&
		chmod 777 "$TRASH" &&
		WFISCENE_CACHE=$c $as_user "$wfs_user" psf $cheap -o "$TRASH/u1.fits" 2> err &&
		samedata "$TRASH/ref.fits" "$TRASH/u1.fits"
	'
	test_expect_success 'a PSF cache file that cannot be read: rebuilt, same grid' '
		c=$TRASH/cache-file && mkdir -p "$c" && chmod 777 "$c" &&
		WFISCENE_CACHE=$c "$WFS" psf $cheap -o "$TRASH/r2.fits" &&
		chmod 000 "$c"/*.fits && chmod 777 "$TRASH" &&
		WFISCENE_CACHE=$c $as_user "$wfs_user" psf $cheap -v -o "$TRASH/u2.fits" 2> err &&
		test_grep "built" err && samedata "$TRASH/r2.fits" "$TRASH/u2.fits"
	'
else
	test_skip 'unwritable output directory and unreadable cache' "$why_not"
fi

test_expect_success 'PSF cache path is a regular file: still works, same grid' '
	cheap="--filter F158 --sca 3 --nwave 2 --pupil-n 128" &&
	: > notadir && WFISCENE_CACHE=$TRASH/notadir "$WFS" psf $cheap -o a.fits &&
	WFISCENE_CACHE=$TRASH/notadir/sub "$WFS" psf $cheap -o b.fits &&
	"$WFS" psf $cheap --no-cache -o c.fits && samedata a.fits c.fits && samedata b.fits c.fits &&
	test ! -s notadir
'
test_expect_success 'a PSF cache file replaced by a directory: rebuilt, same grid' '
	cheap="--filter F158 --sca 3 --nwave 2 --pupil-n 128" && c=$TRASH/cache-dir &&
	WFISCENE_CACHE=$c "$WFS" psf $cheap -o a.fits &&
	f=$(ls "$c"/*.fits) && rm "$f" && mkdir "$f" &&
	WFISCENE_CACHE=$c "$WFS" psf $cheap -v -o b.fits 2> err &&
	test_grep "built" err && samedata a.fits b.fits
'
test_expect_success 'a scene with an unusable PSF cache still renders' '
	d=$TRASH/scene-cache && mkdir "$d" && cd "$d" && : > cachefile &&
	"$WFS" --filter F129 --sca 1 --psf-cache "$d/cachefile/x" -o out.fits ../two.csv &&
	test -s out.fits && test ! -s cachefile
'

test_expect_success '--psf naming a missing file: exit 2, the system error, no output' '
	d=$TRASH/psf-missing && mkdir "$d" && cd "$d" &&
	test_must_fail --status 2 "$WFS" --filter F129 --psf nosuch.fits -o out.fits ../two.csv 2> err &&
	test_grep "nosuch.fits: No such file or directory" err && nothing_left &&
	test_must_fail --status 2 "$WFS" --filter F129 --psf nosuch_%d.fits -o out.fits ../two.csv 2> err &&
	test_grep "^wfiscene: nosuch_1.fits: No such file or directory" err && nothing_left
'
test_expect_success '--psf naming a file that is not a PSF grid: an error, no output' '
	d=$TRASH/psf-bad && mkdir "$d" && cd "$d" &&
	printf "SIMPLE  = garbage\n" > bad.fits && cp ../two.csv notfits.fits &&
	test_must_fail "$WFS" --filter F129 --psf bad.fits -o out.fits ../two.csv 2> err &&
	test_grep "bad.fits" err && nothing_left &&
	test_must_fail "$WFS" --filter F129 --psf notfits.fits -o out.fits ../two.csv 2> err &&
	test_grep "notfits.fits" err && nothing_left
'
if have_python; then
	test_expect_success '--psf naming an image without its sampling keywords: exit 1, no output' '
		d=$TRASH/psf-nokeys && mkdir "$d" && cd "$d" &&
		"$PY" -c "
import numpy as np; from astropy.io import fits
fits.PrimaryHDU(np.ones((9, 17, 17), dtype=np.float32)).writeto(\"plain.fits\")" &&
		test_must_fail --status 1 "$WFS" --filter F129 --psf plain.fits -o out.fits ../two.csv 2> err &&
		test_grep "plain.fits" err && nothing_left
	'
fi

test_done
