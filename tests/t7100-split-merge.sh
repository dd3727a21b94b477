#!/bin/sh
# Split runs and `wfiscene merge`: an exposure rendered in SCA groups and
# in bands of rows (--rows, with every noise stage on) and merged is byte
# for byte the single run, also tile-compressed (by SCA); merge refuses inputs of different exposures, a duplicate
# SCA, files wfiscene did not write and truncated ones, and leaves nothing
# behind when it fails or is interrupted.  The Slurm job-array script runs
# its task body through SLURM_ARRAY_TASK_ID every time, and through sbatch
# on a real cluster: one that answers, or a private one-node cluster this
# script starts when it can (see below); the GNU parallel recipe runs when
# parallel is installed (contrib/install-deps.sh installs it and Slurm).
# WFS_TEST_FULL=1 adds the whole 1-9 / 10-18 case (slow).
. "$(dirname "$0")/lib.sh"

SLURM=$TOP/contrib/slurm
PARALLEL=$TOP/contrib/parallel/wfiscene-parallel.sh
export WFISCENE="$WFS"
OPTS="--filter F158 --psf $PSF --noise all --background avg --seed 5 -q"
# What every Slurm task adds to its task line (wfiscene-array.sh).
WFISCENE_OPTS="--psf $PSF --noise all --background avg -q"
export WFISCENE_OPTS
# Cheaper noise for the compressed runs; read noise still dithers Rice.
RBASE="--filter F158 --psf $PSF --background avg --noise readnoise --seed 5 -q"

# Stars on SCAs 1-4 (and 10 and 18, for the full case).
printf 'ra,dec,flux\n0.01,0.01,1000\n0.2,0.1,500\n-0.1,0.3,800\n0.3,-0.2,700\n' > cat.csv
printf 'ra,dec,flux\n' > empty.csv

# no_output NAME: neither NAME nor a temporary .NAME.* is left.
no_output() { ! test -e "$1" && test -z "$(ls -A | grep "^\.$1\.")"; }

# mkfits FILE CARD...: a primary header of the given cards, no data.
mkfits() {
	f=$1
	shift
	for c in "SIMPLE  =                    T" "BITPIX  =                    8" \
		"NAXIS   =                    0" "$@" END; do printf '%-80s' "$c"; done > "$f"
	n=$(wc -c < "$f")
	head -c $(((2880 - n % 2880) % 2880)) /dev/zero | tr '\0' ' ' >> "$f"
}

test_expect_success 'a single run over SCAs 1-4' '
	"$WFS" $OPTS --sca 1-4 -o full.fits cat.csv 2>/dev/null
'

# The split runs come from the Slurm task script itself, run as array
# tasks 1 and 2 would be.
cat > tasks.txt <<\EOF
# name  ra  dec  pa  filter  scas  catalog  options
expA    0   0    0   F158    1-2   cat.csv  --seed 5

expA    0   0    0   F158    3-4   cat.csv  --seed 5
EOF
test_expect_success 'Slurm task body: SLURM_ARRAY_TASK_ID 1 and 2 write the parts' '
	SLURM_ARRAY_TASK_ID=2 SLURM_CPUS_PER_TASK=1 "$SLURM/wfiscene-array.sh" tasks.txt parts 2>log &&
	test_grep "task 2: expA F158 SCAs 3-4" log &&
	SLURM_ARRAY_TASK_ID=1 "$SLURM/wfiscene-array.sh" tasks.txt parts 2>/dev/null &&
	test -f parts/expA/sca-1-2.fits && test -f parts/expA/sca-3-4.fits
'
test_expect_success 'Slurm merge step: the parts merge into the single run, byte for byte' '
	KEEP_PARTS=1 "$SLURM/wfiscene-merge.sh" tasks.txt parts out 2>log &&
	test_grep "expA: parts/expA/sca-1-2.fits parts/expA/sca-3-4.fits -> out/expA.fits" log &&
	cmp full.fits out/expA.fits
'
cp parts/expA/sca-1-2.fits p12.fits 2>/dev/null
cp parts/expA/sca-3-4.fits p34.fits 2>/dev/null

test_expect_success 'Slurm task id past the task lines is an error' '
	test_must_fail --status 1 env SLURM_ARRAY_TASK_ID=3 "$SLURM/wfiscene-array.sh" tasks.txt parts 2>err &&
	test_grep "tasks.txt: no task 3" err &&
	test_must_fail env -u SLURM_ARRAY_TASK_ID "$SLURM/wfiscene-array.sh" tasks.txt parts 2>err &&
	test_grep "not an array task" err
'
test_expect_success 'Slurm merge step: a missing part is named' '
	mkdir -p gone/expA && cp p12.fits gone/expA/sca-1-2.fits &&
	test_must_fail "$SLURM/wfiscene-merge.sh" tasks.txt gone out2 2>err &&
	test_grep "part gone/expA/sca-3-4.fits is missing" err && ! test -e out2/expA.fits
'
test_expect_success 'Slurm merge step removes the parts unless KEEP_PARTS=1' '
	"$SLURM/wfiscene-merge.sh" tasks.txt parts out 2>/dev/null &&
	cmp full.fits out/expA.fits && ! test -e parts/expA
'

test_expect_success 'merge: any input order gives the single run' '
	"$WFS" merge -o m.fits p34.fits p12.fits && cmp full.fits m.fits &&
	"$WFS" merge -o m2.fits p12.fits p34.fits && cmp full.fits m2.fits
'
test_expect_success 'merge -o - streams the same bytes' '
	"$WFS" merge -o - p34.fits p12.fits | cat > piped.fits && cmp full.fits piped.fits
'
test_expect_success 'merge may write over one of its inputs' '
	cp p12.fits over.fits && "$WFS" merge -o over.fits over.fits p34.fits &&
	cmp full.fits over.fits
'
test_expect_success 'merge -v says where each SCA comes from' '
	"$WFS" merge -v -o m.fits p34.fits p12.fits 2>log &&
	test_grep "WFI01 from p12.fits (HDU 2, not compressed)" log &&
	test_grep "WFI04 from p34.fits (HDU 3, not compressed)" log
'
test_expect_success 'a part that is itself a merge merges again' '
	"$WFS" merge -o m3.fits m.fits && cmp full.fits m3.fits
'

# Splitting by rows (--rows A-B): each part draws and writes a band of rows
# of its SCAs, with a WCS for its own pixels, and merge joins the bands.
# The first boundary runs through the brightest star on SCA 1, and none is
# on a tile edge.
"$WFS" $OPTS --sca 1 --placed placed1.csv -o /dev/null cat.csv 2>/dev/null
cut=$(awk -F, 'NR > 1 && $2 == 1 { if ($5 > f) { f = $5; y = int($4) } } END { print y + 0 }' \
	placed1.csv 2>/dev/null)
test_expect_success 'row parts (--rows), cut through a star, merge into the single run' '
	test "$cut" -gt 100 && test "$cut" -lt 3000 &&
	"$WFS" $OPTS --sca 1-2 --rows 1-$cut -o ra.fits cat.csv 2>/dev/null &&
	"$WFS" $OPTS --sca 1-2 --rows $((cut + 1))-3000 -o rb.fits cat.csv 2>/dev/null &&
	"$WFS" $OPTS --sca 1-2 --rows 3001-4088 -o rc.fits cat.csv 2>/dev/null &&
	"$WFS" merge -v -o rm.fits rc.fits p34.fits rb.fits ra.fits 2>log &&
	cmp full.fits rm.fits &&
	test_grep "WFI02 rows $((cut + 1))-3000 from rb.fits (HDU 3)" log &&
	test_grep "rm.fits: 4 SCA images from 4 files" log
'
test_expect_success 'a row part is a proper FITS image of its rows, WCS and all' '
	"$PY" -c "
import numpy as np
from astropy.io import fits
from astropy.wcs import WCS
full = fits.open(\"full.fits\")[\"WFI01\"]
part = fits.open(\"rb.fits\")[\"WFI01\"]
a, b = map(int, part.header[\"ROWS\"].split(\"-\"))
assert part.data.shape == (b - a + 1, 4088), part.data.shape
assert np.array_equal(part.data, full.data[a - 1:b])
assert part.header[\"NSOURCES\"] == full.header[\"NSOURCES\"]
wf, wp = WCS(full.header), WCS(part.header)
for x, y in ((1, a), (2000.5, a + 17.25), (4088, b)):
    sf = wf.all_pix2world(x, y, 1); sp = wp.all_pix2world(x, y - a + 1, 1)
    assert abs(sf[0] - sp[0]) < 1e-12 and abs(sf[1] - sp[1]) < 1e-12, (sf, sp)
"
'
test_expect_success 'merge refuses row parts that leave a gap, overlap, or join a whole image' '
	"$WFS" $OPTS --sca 1-2 --rows 2990-4088 -o rover.fits cat.csv 2>/dev/null &&
	test_must_fail --status 1 "$WFS" merge -o x.fits ra.fits rb.fits p34.fits 2>err &&
	test_grep "WFI01: rows 3001-4088 are in no input (the last part, in rb.fits, has rows $((cut + 1))-3000)" err &&
	test_must_fail --status 1 "$WFS" merge -o x.fits ra.fits rc.fits 2>err &&
	test_grep "WFI01: rows $((cut + 1))-3000 are in no input (ra.fits has rows 1-$cut, rc.fits rows 3001-4088)" err &&
	test_must_fail --status 1 "$WFS" merge -o x.fits rb.fits rc.fits 2>err &&
	test_grep "WFI01: rows 1-$cut are in no input" err &&
	test_must_fail --status 1 "$WFS" merge -o x.fits ra.fits rb.fits rover.fits 2>err &&
	test_grep "rover.fits: WFI01 rows 2990-4088 overlap rows $((cut + 1))-3000 in rb.fits" err &&
	test_must_fail --status 1 "$WFS" merge -o x.fits ra.fits rb.fits rc.fits p12.fits 2>err &&
	test_grep "WFI01 is also in" err &&
	no_output x.fits
'
test_expect_success 'merge refuses row parts of different images (another catalog)' '
	grep -v "^0.01,0.01," cat.csv >cat1.csv &&
	"$WFS" $OPTS --sca 1-2 --rows 3001-4088 -o rother.fits cat1.csv 2>/dev/null &&
	test_must_fail --status 1 "$WFS" merge -o x.fits ra.fits rb.fits rother.fits 2>err &&
	test_grep "rother.fits: WFI0[12] rows 3001-4088: its header has .NSOURCES=" err &&
	no_output x.fits
'
test_expect_success '--rows: bad ranges and tile compression are refused' '
	for r in 0-10 10-4089 20-10 10 a-b 1-2-3; do
		test_must_fail --status 1 "$WFS" $OPTS --rows $r -o x.fits cat.csv 2>err &&
		test_grep "^wfiscene: --rows" err || exit 1
	done &&
	test_must_fail --status 1 "$WFS" $OPTS --rows 1-10 --compress rice -o x.fits cat.csv 2>err &&
	test_grep "joined uncompressed" err && no_output x.fits
'
cat > tasks-rows.txt <<\EOF
expR    0   0    0   F158    1-2    cat.csv  --seed 5 --rows 1-1500
expR    0   0    0   F158    1-2    cat.csv  --seed 5 --rows=1501-4088
expR    0   0    0   F158    3,4    cat.csv  --seed 5
EOF
test_expect_success 'Slurm scripts with --rows in the task lines: parts named by rows, merged' '
	for k in 1 2 3; do
		SLURM_ARRAY_TASK_ID=$k "$SLURM/wfiscene-array.sh" tasks-rows.txt rparts 2>>log ||
			exit 1
	done &&
	test_grep "task 2: expR F158 SCAs 1-2 rows 1501-4088 -> rparts/expR/sca-1-2.rows-1501-4088.fits" log &&
	test -f rparts/expR/sca-1-2.rows-1-1500.fits && test -f rparts/expR/sca-3+4.fits &&
	"$SLURM/wfiscene-merge.sh" tasks-rows.txt rparts rout 2>/dev/null &&
	cmp full.fits rout/expR.fits && ! test -e rparts/expR
'

test_expect_success 'tile-compressed (rice, with dither) parts merge into the compressed single run' '
	"$WFS" $RBASE --compress rice --sca 1-2 -o r12.fits cat.csv 2>/dev/null &&
	"$WFS" $RBASE --compress rice --sca 2 -o r2.fits cat.csv 2>/dev/null &&
	"$WFS" $RBASE --compress rice --sca 1 -o r1.fits cat.csv 2>/dev/null &&
	"$WFS" merge -v -o rm.fits r2.fits r1.fits 2>log && cmp r12.fits rm.fits &&
	test_grep "WFI02 from r2.fits (HDU 2, RICE_ONE)" log
'
test_expect_success 'compressed and plain parts are not mixed' '
	"$WFS" $RBASE --sca 3 -o n3.fits empty.csv &&
	test_must_fail --status 1 "$WFS" merge -o x.fits r1.fits n3.fits 2>err &&
	test_grep "n3.fits: WFI03 is not compressed, but WFI01 in r1.fits is RICE_ONE" err &&
	no_output x.fits
'

test_expect_success 'merge refuses a part of another filter, naming file and keyword' '
	"$WFS" --filter F087 --sca 5 -q -o f087.fits empty.csv &&
	test_must_fail --status 1 "$WFS" merge -o x.fits p12.fits f087.fits 2>err &&
	test_grep "^wfiscene merge: f087.fits: FILTER is .F087., but .F158. in p12.fits" err &&
	no_output x.fits
'
test_expect_success 'merge refuses another seed' '
	"$WFS" --filter F158 --psf $PSF --sca 5 --seed 6 -q -o s6.fits empty.csv &&
	test_must_fail --status 1 "$WFS" merge -o x.fits p12.fits s6.fits 2>err &&
	test_grep "s6.fits: SEED is .6., but .5. in p12.fits" err && no_output x.fits
'
test_expect_success 'merge refuses a keyword that only one primary header has' '
	mkfits a.fits "ORIGIN  = '"'"'wfiscene'"'"'" &&
	mkfits b.fits "ORIGIN  = '"'"'wfiscene'"'"'" "EXTRA   =                    1" &&
	test_must_fail --status 1 "$WFS" merge -o x.fits a.fits b.fits 2>err &&
	test_grep "b.fits: keyword EXTRA (= .1.) is in b.fits.s primary header but not in a.fits.s" err &&
	test_must_fail --status 1 "$WFS" merge -o x.fits b.fits a.fits 2>err &&
	test_grep "a.fits: keyword EXTRA (= .1.) is in b.fits.s primary header but not in a.fits.s" err &&
	no_output x.fits
'
test_expect_success 'a different DATE is no mismatch: the first input'"'"'s is kept' '
	cp p34.fits late.fits &&
	at=$(grep -boa "DATE    = " late.fits | head -n 1 | cut -d: -f1) &&
	printf "%-80s" "DATE    = '"'"'2027-01-15T08:00:00'"'"' / file creation date (UTC)" |
		dd of=late.fits bs=1 seek="$at" conv=notrunc 2>/dev/null &&
	! cmp -s p34.fits late.fits &&
	"$WFS" merge -o d.fits p12.fits late.fits && cmp full.fits d.fits &&
	"$WFS" merge -o d.fits late.fits p12.fits && ! cmp -s full.fits d.fits &&
	head -c 2880 d.fits > d.hdr && head -c 2880 late.fits > l.hdr && cmp l.hdr d.hdr
'
test_expect_success 'merge refuses a duplicate SCA' '
	test_must_fail --status 1 "$WFS" merge -o x.fits p12.fits full.fits 2>err &&
	test_grep "full.fits: WFI01 is also in p12.fits" err &&
	test_must_fail --status 1 "$WFS" merge -o x.fits p12.fits p12.fits 2>err &&
	test_grep "p12.fits: WFI01 is also in p12.fits" err && no_output x.fits
'
test_expect_success 'merge refuses files that are not wfiscene output' '
	echo "ra,dec,flux" > text.fits &&
	test_must_fail --status 1 "$WFS" merge -o x.fits p12.fits text.fits 2>err &&
	test_grep "text.fits: not a FITS file" err &&
	mkfits other.fits "ORIGIN  = '"'"'astropy '"'"'" &&
	test_must_fail --status 1 "$WFS" merge -o x.fits other.fits 2>err &&
	test_grep "other.fits: not a wfiscene file" err &&
	mkfits fake.fits "ORIGIN  = '"'"'wfiscene'"'"'" && cp fake.fits ext.fits &&
	for c in "XTENSION= '"'"'IMAGE   '"'"'" "BITPIX  =                  -32" \
		"NAXIS   =                    0" "PCOUNT  =                    0" \
		"GCOUNT  =                    1" "EXTNAME = '"'"'SCI     '"'"'" END; do
		printf "%-80s" "$c"; done >> ext.fits &&
	head -c 2320 /dev/zero | tr "\0" " " >> ext.fits &&
	test_must_fail --status 1 "$WFS" merge -o x.fits ext.fits 2>err &&
	test_grep "ext.fits: HDU 2: EXTNAME .SCI. is not an SCA image" err &&
	no_output x.fits
'
test_expect_success 'merge refuses a truncated part' '
	head -c 70000000 p12.fits > trunc.fits &&
	test_must_fail --status 1 "$WFS" merge -o x.fits trunc.fits 2>err &&
	test_grep "trunc.fits: WFI02: truncated" err && no_output x.fits &&
	cp p34.fits tail.fits && echo garbage >> tail.fits &&
	test_must_fail --status 1 "$WFS" merge -o x.fits tail.fits 2>err &&
	test_grep "tail.fits: 8 bytes after HDU 3 are not a FITS extension" err &&
	head -c 1000 p12.fits > short.fits &&
	test_must_fail --status 1 "$WFS" merge -o x.fits short.fits 2>err &&
	test_grep "short.fits: not a FITS file" err
'
test_expect_success 'merge with no inputs, a bad option, a missing input, a directory as output' '
	test_must_fail --status 1 "$WFS" merge -o x.fits 2>err &&
	test_grep "no input files" err &&
	test_must_fail --status 1 "$WFS" merge --bogus -o x.fits p12.fits 2>err &&
	test_grep "^wfiscene merge: unknown option .--bogus." err &&
	test_must_fail --status 2 "$WFS" merge -o x.fits nosuch.fits 2>err &&
	test_grep "nosuch.fits: cannot open: No such file" err &&
	mkdir -p adir && test_must_fail --status 1 "$WFS" merge -o adir p12.fits 2>err &&
	test_grep "adir: is a directory" err && no_output x.fits
'
test_expect_success 'merge into an unwritable place: exit 2, nothing left' '
	test_must_fail --status 2 "$WFS" merge -o nodir/x.fits p12.fits 2>err &&
	test_grep "nodir/x.fits: cannot create temporary file .*No such file" err &&
	! test -e nodir
'

SHIM=$TRASH/enospc.so
if cc -shared -fPIC -o "$SHIM" "$TOP/tests/shim/enospc.c" -ldl 2>/dev/null; then
	test_expect_success 'disk full in the middle of a merge: exit 2, old file kept' '
		mkdir full && echo old > full/x.fits &&
		test_must_fail --status 2 env WFS_ENOSPC_MATCH=/full/ WFS_ENOSPC_AFTER=5000000 \
			ASAN_OPTIONS=verify_asan_link_order=0 \
			LD_PRELOAD="$SHIM" "$WFS" merge -o full/x.fits p12.fits p34.fits 2>err &&
		test_grep "full/x.fits: write error: No space left on device" err &&
		test "$(cat full/x.fits)" = old && test "$(ls -A full)" = x.fits
	'
else
	test_skip 'disk full in the middle of a merge' 'cannot build tests/shim/enospc.c'
fi

# SIGTERM is caught by the one signal policy: wait until the handler is
# set (else the default action would kill it first), then signal it while
# it waits for a reader of its FIFO.  Nothing reads the FIFO afterwards: a
# merge stopped before it opened the FIFO never writes to it, and a reader
# would wait for ever.
if [ -r /proc/self/status ]; then
	test_expect_success 'SIGTERM stops a merge with status 4' '
		mkfifo pipe &&
		{ "$WFS" merge -o pipe p12.fits p34.fits 2>err & } && pid=$! &&
		{ wait_sigterm Cgt $pid; kill -TERM $pid; } && { wait $pid; rc=$?; } ; test $rc = 4 &&
		test_grep "wfiscene merge: interrupted; partial output removed" err
	'
else
	test_skip 'SIGTERM stops a merge' 'no /proc'
fi

if command -v parallel >/dev/null 2>&1; then
	test_expect_success 'GNU parallel recipe: SCAs 3 and 4 as two jobs give the single run' '
		"$PARALLEL" -j 2 -g "3 4" -o par.fits $OPTS cat.csv 2>/dev/null &&
		cmp p34.fits par.fits && test -z "$(ls -A | grep "^\.wfiscene-parallel")"
	'
	test_expect_success 'GNU parallel recipe: a failed run fails the whole, nothing left' '
		test_must_fail "$PARALLEL" -g "3 4" -o bad.fits --filter F999 cat.csv 2>err &&
		test_grep "unknown filter" err && no_output bad.fits &&
		test -z "$(ls -A | grep "^\.wfiscene-parallel")" &&
		test_must_fail "$PARALLEL" -o bad.fits --sca 3 $OPTS cat.csv 2>err &&
		test_grep "give SCAs with -g" err
	'
else
	test_skip 'GNU parallel recipe' 'parallel is not installed (Debian package parallel)'
fi

# Slurm for real: a cluster that answers sinfo already, or else (as root,
# with Debian's slurmctld, slurmd and munge installed) a private one-node
# cluster started here: its own munge key and socket, configuration, spool
# and ports under $TRASH, stopped when the script ends.  Without either,
# the task body above has still run, through SLURM_ARRAY_TASK_ID set by
# hand, and this test says so when it skips.
slurm_pids=
stop_slurm() {
	for p in $slurm_pids; do kill "$p" 2>/dev/null; done
	for p in $slurm_pids; do wait "$p" 2>/dev/null; done
	slurm_pids=
}
trap 'stop_slurm; rm -rf "$TRASH"' EXIT

start_slurm() {
	d=$TRASH/slurm
	command -v slurmctld >/dev/null && command -v slurmd >/dev/null &&
		command -v munged >/dev/null && [ "$(id -u)" = 0 ] || return 1
	mkdir -p "$d/ctld" "$d/spool" "$d/munge" && chmod 711 "$d/munge" &&
		head -c 1024 /dev/urandom >"$d/munge/key" && chmod 400 "$d/munge/key" ||
		return 1
	munged -F --force --key-file="$d/munge/key" --socket="$d/munge/socket" \
		--pid-file="$d/munge/pid" --log-file="$d/munge/log" \
		--seed-file="$d/munge/seed" 2>"$d/munged.err" &
	slurm_pids="$slurm_pids $!"
	port=$((20000 + $$ % 20000))
	host=$(hostname -s)
	# This machine's CPUs and memory, as slurmd sees them.
	node=$(slurmd -C | sed -n 's/.*\(CPUs=[0-9]*\).*\(RealMemory=[0-9]*\).*/\1 \2/p')
	cat >"$d/slurm.conf" <<EOT
ClusterName=wfiscenetest
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$port
SlurmdPort=$((port + 1))
SlurmUser=root
AuthType=auth/munge
AuthInfo=socket=$d/munge/socket
CredType=cred/munge
StateSaveLocation=$d/ctld
SlurmdSpoolDir=$d/spool
SlurmctldPidFile=$d/slurmctld.pid
SlurmdPidFile=$d/slurmd.pid
SlurmctldLogFile=$d/slurmctld.log
SlurmdLogFile=$d/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
ReturnToService=2
NodeName=wfsnode NodeHostname=$host NodeAddr=127.0.0.1 $node State=UNKNOWN
PartitionName=wfs Nodes=wfsnode Default=YES MaxTime=INFINITE State=UP
EOT
	SLURM_CONF=$d/slurm.conf
	export SLURM_CONF
	i=0
	until [ -S "$d/munge/socket" ] || [ $i -ge 100 ]; do sleep 0.1; i=$((i + 1)); done
	slurmctld -D -i >"$d/slurmctld.out" 2>&1 &
	slurm_pids="$slurm_pids $!"
	slurmd -D -N wfsnode >"$d/slurmd.out" 2>&1 &
	slurm_pids="$slurm_pids $!"
	i=0
	until timeout 5 sinfo -h -o %t 2>/dev/null | grep -q idle || [ $i -ge 30 ]; do
		sleep 1; i=$((i + 1)); done
	timeout 5 sinfo -h -o %t 2>/dev/null | grep -q idle && return 0
	echo "# the private Slurm cluster did not start:" && tail -n 5 "$d"/*.log
	stop_slurm
	unset SLURM_CONF
	return 1
}

slurm=
if command -v sbatch >/dev/null 2>&1 && timeout 10 sinfo -h >/dev/null 2>&1; then
	slurm="the cluster that answers sinfo"
elif start_slurm; then
	slurm="a private one-node cluster ($(sinfo -V))"
fi
if [ -n "$slurm" ]; then
	say "Slurm for real on $slurm"
	test_expect_success 'Slurm for real: array job (by SCA and by rows) and dependent merge job' '
		"$SLURM/wfiscene-submit.sh" tasks-rows.txt sparts sout --cpus-per-task=1 \
			--mem=1G >jobs &&
		test_grep "array job .* (3 tasks), merge job" jobs &&
		i=0 && while ! test -f sout/expR.fits && [ $i -lt 300 ]; do
			sleep 1; i=$((i + 1)); done &&
		{ test -f sout/expR.fits ||
		  { scancel $(awk "{ print \$3, \$NF }" jobs); cat wfiscene-*.log; false; }; } &&
		cmp full.fits sout/expR.fits && ! test -e sparts/expR &&
		test_grep "task 1: expR F158 SCAs 1-2 rows 1-1500" wfiscene-*_1.log &&
		test_grep "task 2: expR F158 SCAs 1-2 rows 1501-4088" wfiscene-*_2.log &&
		test_grep "task 3: expR F158 SCAs 3,4" wfiscene-*_3.log
	'
else
	test_skip 'Slurm for real' 'no Slurm cluster here and none could be started (as root, with slurmctld, slurmd and munge: Debian packages slurmctld, slurmd, slurm-client, munge); the array task body ran with SLURM_ARRAY_TASK_ID set by the test instead'
fi
stop_slurm

if [ "${WFS_TEST_FULL:-0}" = 1 ]; then
	test_expect_success 'full exposure: --sca 1-9 and 10-18 merge into --sca 1-18' '
		"$WFS" $OPTS --sca 1-18 -o all.fits cat.csv 2>/dev/null &&
		"$WFS" $OPTS --sca 10-18 -o b.fits cat.csv 2>/dev/null &&
		"$WFS" $OPTS --sca 1-9 -o a.fits cat.csv 2>/dev/null &&
		"$WFS" merge -o ab.fits b.fits a.fits && cmp all.fits ab.fits
	'
else
	test_skip 'full exposure 1-9 / 10-18' 'set WFS_TEST_FULL=1'
fi

test_done
