#!/bin/sh
# The man pages are part of the interface: mandoc -Tlint finds nothing in
# them at any level, style included (what `make lint-man` checks).
. "$(dirname "$0")/lib.sh"

command -v mandoc > /dev/null || skip_all "mandoc is absent (Debian package mandoc)"

for page in "$TOP"/man/*.[157]; do
	test_expect_success "$(basename "$page") is mandoc -Tlint clean" '
		mandoc -Tlint -W style "$page" > lint 2>&1 &&
		test ! -s lint || { cat lint; false; }
	'
done
test_expect_success 'make lint-man passes, and fails on a page with a lint message' '
	make -s -C "$TOP" lint-man > out 2>&1 || { cat out; false; } &&
	mkdir -p man && cp "$TOP/man/wfiscene.1" man/ && echo ".B trailing " >> man/wfiscene.1 &&
	cp "$TOP/Makefile" . &&
	test_must_fail make -s lint-man > out 2>&1 && test_grep "whitespace at end" out
'
test_done
