#!/bin/sh
# Files follow the data flow: no file of src/ calls back into one that calls
# it, directly or through others (a file A "calls" B when A's object uses a
# symbol B's defines, as nm shows them), no source file is over 1,200
# lines, no function of src/ or plugins/ is over 120, and vector code
# sits under simd.h's one switch (and compiles out with it).  A plugin's own
# units may call each other; they are not in build/obj.
. "$(dirname "$0")/lib.sh"

command -v nm > /dev/null || skip_all "nm is absent (Debian package binutils)"
command -v perl > /dev/null || skip_all "perl is absent (Debian package perl)"
ls "$BUILD"/obj/*.o > /dev/null 2>&1 || skip_all "no objects in $BUILD/obj (make all)"

# circles DIR [SRC]: each circle among DIR's objects (with SRC, only those
# of a SRC/NAME.c that exists: a stale object is no file), one line
# "a -> b -> a".
circles() {
	for o in "$1"/*.o; do
		[ -z "${2:-}" ] || [ -f "$2/$(basename "$o" .o).c" ] || continue
		nm "$o" | sed "s|^|$(basename "$o" .o) |"
	done | perl -e '
		my (%def, %use, %g);
		while (<>) {
			my @f = split;
			if (@f == 4 && $f[2] =~ /^[TDBR]$/) { $def{$f[3]} = $f[0] }
			elsif (@f == 3 && $f[1] eq "U") { $use{$f[0]}{$f[2]} = 1 }
		}
		for my $a (keys %use) {
			for my $s (keys %{$use{$a}}) {
				my $b = $def{$s};
				$g{$a}{$b} = 1 if defined $b && $b ne $a;
			}
		}
		my (%state, @path);
		sub visit {
			my $v = shift;
			$state{$v} = 1;
			push @path, $v;
			for my $w (sort keys %{$g{$v}}) {
				if (($state{$w} // 0) == 1) {
					my @p = @path;
					shift @p while $p[0] ne $w;
					print join(" -> ", @p, $w), "\n";
				} elsif (!$state{$w}) {
					visit($w);
				}
			}
			pop @path;
			$state{$v} = 2;
		}
		visit($_) for grep { !$state{$_} } sort keys %g;
	'
}

test_expect_success 'no file of src/ calls back into a file that calls it' '
	circles "$BUILD/obj" "$TOP/src" > found &&
	test ! -s found || { cat found; false; }
'

test_expect_success '... which the check does see: two objects that call each other' '
	mkdir o &&
	printf "int b(void);\nint a(void) { return b(); }\n" > a.c &&
	printf "int a(void);\nint b(void) { return 1; }\nint c(void) { return a(); }\n" > b.c &&
	${CC:-cc} -c a.c -o o/a.o && ${CC:-cc} -c b.c -o o/b.o &&
	circles o > found && test_grep "a -> b -> a" found
'

test_expect_success 'no source file is over 1,200 lines' '
	wc -l "$TOP"/src/*.[ch] "$TOP"/plugins/*.[ch] "$TOP"/include/wfiscene/*.h |
		awk "\$2 != \"total\" && \$1 > 1200" > long &&
	test ! -s long || { cat long; false; }
'
# long FILE...: "file function lines" for each function over 120 lines.  A
# definition's body opens with "{" at the start of a line (or its
# signature's last line ends in "{") and closes with "}" at the start of a
# line, as STYLE's code does; the name is the last identifier before "("
# on the lines above that start in column 0.  Its lines are the body's,
# between the braces.
long() {
	awk '
		FNR == 1 { start = 0 }
		/^}/ && start { n = FNR - start - 1; if (n > 120) print FILENAME, name, n; start = 0; next }
		start { next }
		/^[A-Za-z_].*\(/ { s = $0; sub(/\(.*/, "", s); k = split(s, w, /[^A-Za-z0-9_]+/); name = w[k] }
		/^\{/ || (/^[A-Za-z_].*\) *\{ *$/ && !/=/) { start = FNR }
	' "$@"
}

test_expect_success 'no function of src/ or plugins/ is over 120 lines' '
	(cd "$TOP" && long src/*.[ch] plugins/*.[ch]) > over &&
	test ! -s over || { cat over; false; }
'

test_expect_success '... which the check does see: a function of 121 lines, in both styles' '
	{ printf "static int f(int a)\n{\n"; i=0; while [ $i -lt 120 ]; do
		echo "	a++;"; i=$((i + 1)); done; printf "	return a;\n}\n"; } > f.c &&
	{ echo "int g(int a) {"; sed 1,2d f.c; } > g.c &&
	long f.c g.c > found &&
	printf "f.c f 121\ng.c g 121\n" > want && test_cmp want found
'
# One SIMD switch (simd.h): vector code elsewhere sits under SIMD_X86, never
# under a guard of its own, which a rename leaves silently undefined.
test_expect_success 'vector code is guarded by simd.h alone' '
	(cd "$TOP" && grep -n -E "__x86_64__|#if(def|ndef)? [A-Z_0-9]*AVX|defined\([A-Z_0-9]*AVX" \
		src/*.[ch] plugins/*.[ch] | grep -v "^src/simd.h:") > ad_hoc ;
	test ! -s ad_hoc || { cat ad_hoc; false; }
'
# ... and every source still compiles where that switch is off
# (-DWFS_NO_SIMD, or a processor other than x86-64): a vector loop left
# outside it broke that build once, unseen.
test_expect_success 'every source compiles without the vector loops (make lint-nosimd)' '
	make -s -C "$TOP" lint-nosimd > out 2>&1 || { cat out; false; }
'
test_done
