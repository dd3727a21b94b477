#!/bin/sh
# README's first scene runs as written: its sample catalog and the command
# that draws it, both taken from README.md, give SCA 1 with its two stars
# and two galaxies placed; and both stand within the first screen.
. "$(dirname "$0")/lib.sh"

# The indented blocks of the "A first scene" section, each to a file
# blockN in order: the catalog, then the command.
sed -n '/^## A first scene/,/^## [^A]/p' "$TOP/README.md" |
	awk '/^    / { if (!inb) { n++; inb = 1 } sub(/^    /, ""); print > ("block" n); next }
	     { inb = 0 }'
blocks=$(ls block* 2> /dev/null)

test_expect_success 'README has a sample catalog of five lines and one command' '
	set -- $blocks && test $# -ge 2 &&
	test "$(wc -l < "$1")" = 5 &&
	name=$(sed -n "s/.*(\`\([a-z]*\.csv\)\`).*/\1/p" "$TOP/README.md" | head -n 1) &&
	test -n "$name" && cp "$1" "$name" &&
	test "$(wc -l < "$2")" = 1 && test_grep "^build/wfiscene .*$name\$" "$2"
'

test_expect_success '... within the first 40 lines' '
	n=$(grep -n "^    build/wfiscene .*\.csv\$" "$TOP/README.md" | head -n 1 | cut -d: -f1) &&
	test -n "$n" && test "$n" -le 40
'

test_expect_success 'no paragraph of prose is over 600 characters' '
	awk "BEGIN { RS = \"\" } !/^    / && length(\$0) > 600 { print length(\$0) \": \" substr(\$0, 1, 60) }" \
		"$TOP/README.md" > long &&
	test ! -s long || { cat long; false; }
'

test_expect_success 'the command draws the catalog: SCA 1, four sources placed' '
	set -- $blocks &&
	cmd=$(sed "s|^build/wfiscene|\"\$WFS\" --psf $PSF --placed placed.csv|" "$2") &&
	eval "$cmd" &&
	out=$(sed -n "s/.* -o \([^ ]*\) .*/\1/p" "$2") && test -s "$out" &&
	test "$(tail -n +2 placed.csv | wc -l)" = 4 &&
	test "$(cut -d, -f2 placed.csv | sort -u | tr "\n" " ")" = "1 sca "
'
test_done
