# tests/lib.sh - a small TAP test library in the manner of git's t/test-lib.sh.
#
#   . "$(dirname "$0")/lib.sh"
#   test_expect_success 'title' 'commands && more commands'
#   test_must_fail [--status N] wfiscene ...   fails in a controlled way
#   test_done
#
# Each test runs in a fresh scratch directory ($TRASH); $WFS is the built
# program, $SHARED the shared reference data (may be absent: use
# require_shared to skip).  PY is Debian's python3 (with astropy etc.).

TOP=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${WFS_BUILD:-build}
case $BUILD in /*) ;; *) BUILD=$TOP/$BUILD ;; esac
WFS=$BUILD/wfiscene
WFISCENE_PLUGIN_PATH=$BUILD/plugins
export WFISCENE_PLUGIN_PATH
SHARED=${WFS_SHARED:-$TOP/../shared}
PY=/usr/bin/python3
TRASH=$(mktemp -d "${TMPDIR:-/tmp}/wfs-test.XXXXXX")
WFISCENE_CACHE=$TRASH/cache
export WFISCENE_CACHE
# A shared PSF cache between test scripts keeps the suite fast; tests that
# exercise the cache itself set WFISCENE_CACHE to a private directory.
if [ -n "${WFS_TEST_CACHE:-}" ]; then WFISCENE_CACHE=$WFS_TEST_CACHE; else
	WFISCENE_CACHE=$BUILD/test-cache; fi
export WFISCENE_CACHE
# the cache's bound is the default's unless a test sets it
unset WFISCENE_CACHE_MAX
# Pin the DATE card so that runs can be compared byte for byte.
SOURCE_DATE_EPOCH=1700000000
export SOURCE_DATE_EPOCH
# Tests that LD_PRELOAD a shim (tests/shim/enospc.c) would stop an ASan
# build (make check SANITIZE=1) at start-up: the shim comes before the ASan
# runtime in the library list.  The check is harmless to skip here.
ASAN_OPTIONS=${ASAN_OPTIONS:+$ASAN_OPTIONS:}verify_asan_link_order=0
export ASAN_OPTIONS
test_count=0
test_fail=0
trap 'rm -rf "$TRASH"' EXIT
cd "$TRASH" || exit 1

say() { printf '# %s\n' "$*"; }

test_expect_success() {
	test_count=$((test_count + 1))
	if (eval "$2") >"$TRASH/.out" 2>&1; then
		echo "ok $test_count - $1"
	else
		echo "not ok $test_count - $1"
		# The diagnostics on stderr, as Test::More prints them, so that a
		# failure explains itself in prove's summary output too: every
		# line ends in a newline (a file without one would swallow the
		# plan) and control characters are shown, not obeyed.
		tail -n 30 "$TRASH/.out" | cat -v | awk '{ print "#   " $0 }' >&2
		test_fail=$((test_fail + 1))
	fi
}

# wait_sigterm Cgt|Blk PID: wait, up to ten seconds, until process PID
# catches (Cgt) or blocks (Blk) SIGTERM, that is, until wfiscene has set up
# its signal handling; a signal sent earlier would take the default action.
# Without /proc it waits a second.
wait_sigterm() {
	[ -r "/proc/$2/status" ] || { sleep 1; return 0; }
	i=0
	while [ $i -lt 1000 ]; do
		m=$(sed -n "s/^Sig$1:[[:space:]]*//p" "/proc/$2/status" 2>/dev/null)
		m=${m#"${m%????}"}
		[ -n "$m" ] && [ $((0x$m & 0x4000)) -ne 0 ] && return 0
		sleep 0.01
		i=$((i + 1))
	done
	echo "wait_sigterm: process $2 never had SIGTERM in Sig$1" >&2
	return 1
}

# test_skip 'title' 'why'
test_skip() {
	test_count=$((test_count + 1))
	echo "ok $test_count # skip $1: $2"
}

# Run a command that must fail with a normal non-zero exit (not a crash).
# With --status N, the exit status must be exactly N.
test_must_fail() {
	want=
	if [ "$1" = --status ]; then want=$2; shift 2; fi
	"$@"
	rc=$?
	if [ $rc -eq 0 ]; then echo "test_must_fail: command succeeded: $*" >&2; return 1; fi
	if [ $rc -gt 128 ]; then echo "test_must_fail: killed by signal $((rc - 128)): $*" >&2; return 1; fi
	if [ -n "$want" ] && [ $rc -ne "$want" ]; then
		echo "test_must_fail: exit $rc, want $want: $*" >&2; return 1; fi
	return 0
}

test_cmp() { cmp "$1" "$2" || { diff -u "$1" "$2" | head -n 40; return 1; }; }

# test_grep PATTERN FILE: like grep, but shows the file on failure.
test_grep() {
	grep -q -e "$1" "$2" && return 0
	echo "test_grep: no '$1' in $2:" >&2; sed 's/^/| /' "$2" >&2; return 1
}

# The PSF that scene tests draw with: the built-in one unless a test run
# chooses another grid file.
PSF=${WFS_TEST_PSF:-builtin}

# fitsinfo FILE: one line per image HDU: name sum max x y (0-based argmax).
fitsinfo() { "$PY" "$TOP/tests/fitsinfo.py" "$@"; }

# wfs_install PREFIX [make variables...]: `make install PREFIX=...` of this
# build, done from a private copy of the build directory: an install compiles
# its plugin directory into the program it installs, and the program the
# other tests are running must not be rebuilt under them.
wfs_install() {
	_prefix=$1
	shift
	_copy=$TRASH/.build-copy
	rm -rf "$_copy" && mkdir -p "$_copy" || return 1
	for _f in obj plugins contrib libwfs.a wfiscene data_tables.c psf_src.h \
		plugindir.stamp; do
		[ ! -e "$BUILD/$_f" ] || cp -pR "$BUILD/$_f" "$_copy/" || return 1
	done
	case $BUILD in
	*/build-san) set -- SANITIZE=1 "$@" ;;
	*/build-tsan) set -- SANITIZE=thread "$@" ;;
	esac
	make -s -C "$TOP" B="$_copy" PREFIX="$_prefix" "$@" install
}

have_shared() { [ -d "$SHARED/roman" ]; }
# have_modules MODULE...: each is installed (found, not imported: importing
# numpy and astropy took 0.25 s of every test, gwcs a second); prints the
# first that is not.
have_modules() {
	"$PY" -c 'import importlib.util, sys
for m in sys.argv[1:]:
    try:
        found = importlib.util.find_spec(m) is not None
    except ImportError:
        found = False
    if not found:
        print(m)
        sys.exit(1)' "$@" 2>/dev/null
}
have_python() { have_modules numpy astropy >/dev/null; }

# Skip the whole script cleanly.
skip_all() { echo "1..0 # SKIP $*"; exit 0; }
require_shared() { have_shared || skip_all "../shared is absent"; }
require_python() { have_python || skip_all "python3 with numpy and astropy is absent (Debian packages python3-numpy, python3-astropy)"; }
# require_modules "DEBIAN PACKAGES" MODULE...: python3 with numpy, astropy
# and these modules, or skip naming the packages that bring them.
require_modules() {
	_pkgs=$1
	shift
	require_python
	_m=$(have_modules "$@") ||
		skip_all "python3 module ${_m:-$*} is absent (Debian packages $_pkgs)"
}
# A ThreadSanitizer build (make check SANITIZE=thread) runs several times
# slower in several times the memory: tests of memory bounds skip there.
tsan_build() { grep -qa __tsan_init "$WFS" 2>/dev/null; }
# So does an AddressSanitizer build (make check SANITIZE=1), whose shadow
# memory and quarantine of freed blocks are not the program's: sanitizer
# names which of the two, or fails.
sanitizer() {
	if tsan_build; then echo ThreadSanitizer
	elif grep -qa __asan_init "$WFS" 2>/dev/null; then echo AddressSanitizer
	else return 1
	fi
}

test_done() {
	echo "1..$test_count"
	[ $test_fail -eq 0 ]
}
