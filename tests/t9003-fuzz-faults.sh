#!/bin/sh
# A short libFuzzer run over the catalog parser and the decompression layer
# (tests/fuzz/catalog_fuzz.c): `make fuzz FUZZ_SECONDS=20`, when clang can
# build with -fsanitize=fuzzer here.  A crash, leak or sanitizer report
# fails the test (the input is left in the build directory as crash-*).
# WFS_FUZZ_SECONDS changes the time (0 skips).
. "$(dirname "$0")/lib.sh"

secs=${WFS_FUZZ_SECONDS:-20}
[ "$secs" != 0 ] || skip_all "WFS_FUZZ_SECONDS=0"
command -v clang > /dev/null || skip_all "clang is absent (Debian packages clang, libclang-rt-dev)"
printf '#include <stdint.h>\n#include <stddef.h>\nint LLVMFuzzerTestOneInput(const uint8_t *d, size_t n) { (void)d; (void)n; return 0; }\n' > probe.c
clang -fsanitize=fuzzer,address,undefined -o probe probe.c > /dev/null 2>&1 &&
	./probe -runs=1 > /dev/null 2>&1 || skip_all "clang cannot build libFuzzer programs here (Debian package libclang-rt-dev)"

# cfitsio sizes allocations from header values and checks for NULL; on
# damaged headers it can ask for petabytes (see t8001's
# cfitsio-garbage-header.fits).  libc returns NULL there, and so must ASan,
# or the fuzzer stops on cfitsio's request instead of on our bugs.
ASAN_OPTIONS=${ASAN_OPTIONS:+$ASAN_OPTIONS:}allocator_may_return_null=1
export ASAN_OPTIONS

test_expect_success "make fuzz FUZZ_SECONDS=$secs finds nothing" '
	make -C "$TOP" --no-print-directory fuzz FUZZ_SECONDS=$secs > log 2>&1 ||
		{ grep -E -A8 "ERROR|SUMMARY|crash-|Test unit written|error:|undefined reference" log | head -n 40; false; }
'
test_done
