#!/bin/sh
# Install the Debian packages wfiscene needs to build, test and run its demo,
# when some are missing.  As root it runs apt-get; otherwise it prints the
# command to run.  Called by `make deps`, `make check` and `make demo`;
# `make validate` calls it with the argument `validate`, which adds what the
# validation's plot needs, and `make bench` with `bench`: gnuplot, for the
# error-against-time plot.
#
# The tests need clang with the libFuzzer runtime (t9003: a short `make
# fuzz`; Debian's clang only recommends libclang-rt-dev, which apt-get
# --no-install-recommends leaves out, so it is named here), valgrind (t9002),
# GNU time (the memory checks of t4100, t4300 and tests/validate), and GNU
# parallel, Slurm and munge (t7100 runs contrib/parallel and contrib/slurm
# for real, on a private one-node cluster it starts and stops).
set -e
build="gcc make pkg-config libcfitsio-dev wcslib-dev libfftw3-dev libltdl-dev libzstd-dev zlib1g-dev libpng-dev libchealpix-dev zstd"
tests="perl gzip time python3 python3-numpy python3-astropy python3-scipy python3-photutils python3-sep mandoc
	parallel slurmctld slurmd slurm-client munge clang libclang-rt-dev valgrind"
extra=
case ${1:-} in
validate) extra="python3-matplotlib" ;;
bench) extra="gnuplot-nox" ;;
'') ;;
*) echo "usage: install-deps.sh [validate|bench]" >&2; exit 1 ;;
esac
missing=
for p in $build $tests $extra; do
	dpkg-query -W -f='${Status}\n' "$p" 2>/dev/null | grep -q '^install ok installed' ||
		missing="$missing $p"
done
[ -z "$missing" ] && exit 0
cmd="apt-get install -y --no-install-recommends$missing"
if [ "$(id -u)" = 0 ]; then
	echo "wfiscene: installing$missing" >&2
	export DEBIAN_FRONTEND=noninteractive
	apt-get update -qq >/dev/null || apt-get update
	$cmd >/dev/null || $cmd
else
	echo "wfiscene: missing packages; run as root:" >&2
	echo "  $cmd" >&2
	exit 1
fi
