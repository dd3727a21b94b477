#!/bin/sh
# --into IMAGE.asdf given broken or foreign files beyond t4400's: each
# refused with exit 1 and the file named, nothing written; FITS tile
# compression asked of an ASDF output refused the same way.
. "$(dirname "$0")/lib.sh"
require_python

run() { "$WFS" --filter F129 --ra 90 --dec 0 --date 2027-03-20T06:30 "$@"; }
inj() { "$WFS" --filter F129 --into "$1" -o out.asdf inj.csv; }
printf 'ra,dec,flux\n90.02,0.02,1e4\n' > inj.csv

test_expect_success 'an empty file or a FITS file named .asdf: not ASDF' '
	: > empty.asdf &&
	test_must_fail --status 1 inj empty.asdf 2> err &&
	test_grep "empty.asdf: not an ASDF file" err &&
	run -o scene.fits inj.csv && cp scene.fits fits.asdf &&
	test_must_fail --status 1 inj fits.asdf 2> err &&
	test_grep "fits.asdf: not an ASDF file" err &&
	! ls -a | grep -q "out\.asdf"
'

test_expect_success 'a tree that is not YAML: its line and column in the file, no noise' '
	printf "#ASDF 1.0.0\n#ASDF_STANDARD 1.6.0\n%%YAML 1.1\n--- !core/asdf-1.1.0\nroman: [\n...\n" \
		> yaml.asdf &&
	test_must_fail --status 1 inj yaml.asdf 2> err &&
	test_grep "^wfiscene: yaml.asdf:6:1: the ASDF tree is not valid YAML: " err &&
	test "$(wc -l < err)" -eq 1 &&
	! ls -a | grep -q "out\.asdf"
'

test_expect_success 'a block whose sizes wrap around 2^64: beyond the end, no allocation' '
	run --level 2 -o l2.asdf inj.csv &&
	"$PY" "$TOP/tests/asdf_break.py" l2.asdf wrap.asdf wrap 3 &&
	test_must_fail --status 1 inj wrap.asdf 2> err &&
	test_grep "wrap.asdf: block 3: .* beyond the file.s end" err &&
	! ls -a | grep -q "out\.asdf"
'

test_expect_success 'an array whose source is another array.s block, or not a block' '
	grep -n -a -A1 "^  err: !core/ndarray" l2.asdf | grep -q "source: 2" &&
	LC_ALL=C sed "/^  err: !core\/ndarray/,/source:/s/source: 2/source: 3/" l2.asdf > share.asdf &&
	test_must_fail --status 1 inj share.asdf 2> err &&
	test_grep "share.asdf: roman.err: block 3 is another array.s too" err &&
	LC_ALL=C sed "/^  data: !core\/ndarray/,/source:/s/source: 0/source: \"x.asdf\"/" \
		l2.asdf > ext.asdf &&
	test_must_fail --status 1 inj ext.asdf 2> err &&
	test_grep "ext.asdf: roman.data: source .x.asdf. is not one of the file.s" err &&
	! ls -a | grep -q "out\.asdf"
'

test_expect_success '--compress with ASDF output: refused, naming the ASDF setting' '
	test_must_fail --status 1 run --level 2 --compress gzip -o c.asdf inj.csv 2> err &&
	test_grep "compress gzip with ASDF: .*asdf-compression" err &&
	! ls -a | grep -q "c\.asdf"
'

# An ASDF file is made beside its name and renamed over it: a named pipe or
# a device given as -o would be replaced (as root, /dev/null itself).
test_expect_success 'ASDF to a named pipe or a device: refused, the node kept' '
	mkfifo pipe &&
	test_must_fail --status 1 run --level 2 --format asdf -o pipe inj.csv 2> err &&
	test_grep "pipe: not a regular file; an ASDF file" err && test -p pipe &&
	if test "$(id -u)" = 0 && mknod -m 666 null c 1 3; then
		test_must_fail --status 1 run --level 1 --format asdf -o null inj.csv 2> err &&
		test_grep "null: not a regular file" err && test -c null &&
		mknod -m 666 null2 c 1 3 &&
		test_must_fail --status 1 run --level 2 --format asdf --sca 1,2 -o "null%d" \
			inj.csv 2> err &&
		test_grep "^wfiscene: null2: not a regular file" err && test -c null2 &&
		! test -e null1 &&
		printf "90 0 0 ea\n90.01 0 0 eb\n" > two.txt &&
		mknod -m 666 s_eb_1 c 1 3 &&
		test_must_fail --status 1 run --level 2 --format asdf --pointings two.txt \
			-o "s_%s_%d" inj.csv 2> err &&
		test_grep "^wfiscene: s_eb_1: not a regular file" err && test -c s_eb_1 &&
		! test -e s_ea_1
	fi
'

test_done
