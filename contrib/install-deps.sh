#!/bin/sh
# Install the Debian packages wfiscene needs to build, test and run its demo,
# when some are missing.  As root it runs apt-get; otherwise it prints the
# command to run.  Called by `make deps`, `make check` and `make demo`;
# `make bench` calls it with "bench" for what the benchmarks use besides
# (gnuplot for the error-against-time plot).
set -e
build="gcc make pkg-config libcfitsio-dev wcslib-dev libfftw3-dev libltdl-dev libzstd-dev zlib1g-dev libpng-dev zstd"
# parallel, slurm*, munge: tests/t7100 runs contrib/parallel and contrib/slurm
# for real (a private one-node Slurm cluster, started and stopped by the test).
tests="perl gzip time python3 python3-numpy python3-astropy python3-scipy python3-photutils python3-sep mandoc
	parallel slurmctld slurmd slurm-client munge"
bench=
[ "${1:-}" = bench ] && bench="gnuplot-nox"
missing=
for p in $build $tests $bench; do
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
