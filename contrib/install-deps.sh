#!/bin/sh
# Install the Debian packages wfiscene needs to build, test and run its demo,
# when some are missing.  Called by `make deps`, `make check` and `make demo`;
# `make validate` calls it with the argument `validate`, which adds what the
# validation's plot needs, and `make bench` with `bench`: gnuplot, for the
# error-against-time plot.
#
# As root it runs apt-get.  As anyone else it says what is missing and the
# command to run as root, and then: without a package the build needs (or,
# for validate and bench, the package that mode adds) it exits 1; without
# packages only some tests need it exits 0, so that `make check` builds and
# runs the rest (those tests skip, naming the package that enables them).
#
# The tests need clang with the libFuzzer runtime (t9003: a short `make
# fuzz`; Debian's clang only recommends libclang-rt-dev, which apt-get
# --no-install-recommends leaves out, so it is named here), valgrind (t9002),
# GNU time (the memory checks of t3001, t4100, t4300 and tests/validate),
# mandoc (the man pages' lint), bsdutils' script(1) (t3003's terminal),
# util-linux's setpriv (t9001 drops to nobody as root), and GNU parallel,
# Slurm and munge (t7100 runs contrib/parallel and contrib/slurm for real,
# on a private one-node cluster it starts and stops); python3-asdf,
# python3-asdf-astropy and python3-gwcs open the ASDF products (t4400:
# the Roman schemas' validation, the gwcs against the FITS WCS), and
# python3-lz4 lets python3-asdf compress blocks with lz4 (t4403).  liblz4
# reads (and writes) the lz4-compressed blocks of Roman ASDF files.
set -e
build="gcc make pkg-config libcfitsio-dev wcslib-dev libfftw3-dev libltdl-dev libzstd-dev zlib1g-dev libpng-dev libchealpix-dev libfyaml-dev libmd-dev liblz4-dev zstd perl"
tests="gzip time python3 python3-numpy python3-astropy python3-scipy python3-photutils python3-sep mandoc
	bsdutils util-linux parallel slurmctld slurmd slurm-client munge clang libclang-rt-dev valgrind
	python3-asdf python3-asdf-astropy python3-gwcs python3-lz4"
extra=
case ${1:-} in
validate) extra="python3-matplotlib" ;;
bench) extra="gnuplot-nox" ;;
'') ;;
*) echo "usage: install-deps.sh [validate|bench]" >&2; exit 1 ;;
esac
if ! command -v dpkg-query > /dev/null 2>&1; then
	echo "wfiscene: not a Debian system; packages not checked (the build needs" \
		"cc, make, pkg-config and cfitsio, wcslib, fftw3, libltdl, zstd, zlib, libpng, libfyaml, libmd, liblz4)" >&2
	exit 0
fi
missing() {
	m=
	for p in "$@"; do
		dpkg-query -W -f='${Status}\n' "$p" 2>/dev/null | grep -q '^install ok installed' ||
			m="$m $p"
	done
	echo "$m"
}
need=$(missing $build $extra)
want=$(missing $tests)
[ -z "$need$want" ] && exit 0
cmd="apt-get install -y --no-install-recommends$need$want"
if [ "$(id -u)" = 0 ]; then
	echo "wfiscene: installing$need$want" >&2
	export DEBIAN_FRONTEND=noninteractive
	{ apt-get update -qq >/dev/null || apt-get update; } &&
		{ $cmd >/dev/null || $cmd; } && exit 0
	need=$(missing $build $extra)
	want=$(missing $tests)
	[ -z "$need$want" ] && exit 0
	echo "wfiscene: apt-get failed; still missing:$need$want" >&2
	[ -z "$need" ] || exit 1
	echo "wfiscene: the tests that need them will be skipped" >&2
	exit 0
fi
if [ -n "$need" ]; then
	echo "wfiscene: cannot go on without:$need; as root run:" >&2
	echo "  $cmd" >&2
	exit 1
fi
echo "wfiscene: not installed:$want" >&2
echo "  the tests that need them will be skipped; to run them too, as root run:" >&2
echo "  $cmd" >&2
