#!/bin/sh
# model.h tells the whole truth about settings: every key a built-in model
# reads through host->setting() is one of the scene's keys model.h lists, or
# one the model declares in its own wfs_model.settings (what --report
# lists); the scene's keys model.h lists are the ones the host answers, no
# more and no fewer, and wfiscene-model(7) lists them too.  The keys are
# read from the sources: a call whose function's name holds "setting" with
# a key in quotes, as host->setting(host->ctx, "mjd") or
# setting_number(host, "psf-core", ...).
. "$(dirname "$0")/lib.sh"

command -v perl > /dev/null || skip_all "perl is absent (Debian package perl)"

# The scene's keys in model.h's Settings block (" *   KEY  what it is"),
# and those of older hosts listed after it.
model_h_keys() {
	sed -n '/^ \* Settings\./,/^ \* and every KEY/p' "$1" |
		sed -n 's/^ \*   \([a-z][a-z0-9-]*\)  .*/\1/p' | sort -u
}
model_h_old_keys() {
	sed -n '/^ \* The list above is the whole/,/^ \* The host itself reads/p' "$1" |
		sed -n 's/^ \*   \([a-z][a-z0-9-]*\)  .*/\1/p' | sort -u
}

# The keys the host answers: the strcmp(key, "KEY") of host_setting().
host_keys() {
	f=$(grep -l '^const char \*host_setting(void \*ctx' "$TOP"/src/*.c) &&
	sed -n '/^const char \*host_setting(void \*ctx/,/^}/p' "$f" |
		sed -n 's/.*strcmp(key, "\([^"]*\)").*/\1/p' | sort -u
}

# The keys the files read, and the keys they declare: a wfs_setting
# entry is { "key", "fallback" or MACRO(...), ... }, which a column
# entry ({ "name", number, ...) is not.
read_keys() {
	perl -0777 -ne 'print "$1\n" while /\b\w*setting\w*\s*\(\s*[^,;()]*,\s*"([a-z][a-z0-9-]*)"/g' "$@" |
		sort -u
}
declared_keys() {
	perl -0777 -ne 'print "$1\n" while /\{\s*"([a-z][a-z0-9-]*)",\s*(?:"|[A-Z_]+\()/g' "$@" |
		sort -u
}

# The files of the plugin whose main file is $1 (plugins/foo.c): its units
# plugins/foo_*.c and shared units (as the Makefile links them) and the
# headers of the directory they include.
plugin_files() {
	dir=$(dirname "$1") base=$(basename "$1" .c)
	set -- "$1" $(ls "$dir/${base}"_*.c 2> /dev/null)
	# the units both Sersic plugins link in (the Makefile's SERSIC_UNITS)
	case $base in sersic_quick|sersic_precise)
		set -- "$@" "$dir/sersic_core.c" "$dir/sersic_render.c" ;;
	esac
	${CC:-cc} -MM -I"$TOP/include" "$@" | tr ' \\' '\n\n' |
		grep "^$dir/.*\.[ch]\$" | sort -u
}

# check DIR MODEL_H: every plugin of DIR reads only keys MODEL_H lists or
# it declares; prints the offending "plugin: key" lines.
check() {
	{ model_h_keys "$2" && model_h_old_keys "$2"; } > scene.keys
	for c in "$1"/*.c; do
		b=$(basename "$c" .c)
		case $b in *_*) [ -f "$1/${b%%_*}.c" ] && continue ;; esac
		files=$(plugin_files "$c") || return 1
		read_keys $files > read.keys
		declared_keys $files | sort -u - scene.keys > known.keys
		comm -23 read.keys known.keys | sed "s/^/$b: /"
	done
}

test_expect_success 'the scene keys model.h lists are the ones the host answers' '
	model_h_keys "$TOP/include/wfiscene/model.h" > listed &&
	host_keys > answered &&
	test "$(wc -l < answered)" -ge 8 &&
	test_cmp answered listed
'

test_expect_success 'wfiscene-model(7) lists each of them under SETTINGS' '
	sed -n "/^\.SH SETTINGS/,/^\.SH /p" "$TOP/man/wfiscene-model.7" |
		sed -n "s/^\.B \([a-z\\\\-]*\)\$/\1/p" | sed "s/\\\\-/-/g" | sort -u > man.keys &&
	comm -23 listed man.keys > missing &&
	test ! -s missing || { cat missing; false; }
'

test_expect_success 'each built-in model reads only keys model.h lists or it declares' '
	check "$TOP/plugins" "$TOP/include/wfiscene/model.h" > bad &&
	test ! -s bad || { cat bad; false; }
'

test_expect_success '... which the scan does see: point, the Sérsic models, variable' '
	read_keys $(plugin_files "$TOP/plugins/point.c") > point.keys &&
	test_grep "^pixel-sigma\$" point.keys && test_grep "^psf-core\$" point.keys &&
	test_grep "^psf-halo-far\$" point.keys &&
	read_keys $(plugin_files "$TOP/plugins/sersic_quick.c") > quick.keys &&
	test_grep "^pixel-sigma\$" quick.keys && test_grep "^sersic-flux\$" quick.keys &&
	read_keys $(plugin_files "$TOP/plugins/variable.c") > variable.keys &&
	test_grep "^variable-curve\$" variable.keys && test_grep "^mjd\$" variable.keys
'

test_expect_success 'a model reading a key it neither declares nor model.h lists fails' '
	mkdir p && cp "$TOP/plugins/variable.c" p/ &&
	printf "%s\n" "static const char *extra(const struct wfs_host *h)" \
		"{ return h->setting(h->ctx, \"undeclared-key\"); }" >> p/variable.c &&
	check p "$TOP/include/wfiscene/model.h" > bad &&
	test_grep "^variable: undeclared-key\$" bad &&
	grep -v "^ \*   pixel-sigma " "$TOP/include/wfiscene/model.h" > model.h &&
	check "$TOP/plugins" model.h > bad &&
	test_grep "^point: pixel-sigma\$" bad && test_grep "^sersic_quick: pixel-sigma\$" bad
'
# A --set key that nothing in the run reads (a misspelt key, or a model's
# setting in a run that does not use the model) changes nothing: the run
# says so on standard error, and still succeeds.  A key within two edits
# of one the run knows (the host's or a model's) is suggested; a setting of
# a model the run did not load, or a key like no other, is not.  plaecd is
# one swap from placed but two plain edits, which its six letters would
# not allow; pnt is two edits from point, too many for three letters.
test_expect_success 'a --set nothing in the run reads is named in a warning' '
	printf "x,y,mag\n100.5,100.5,20\n" > one.csv &&
	printf "x,y,mag,type,n,re,phi,ratio\n100.5,100.5,20,sersic,1,3,0,0.5\n" > gal.csv &&
	"$WFS" --filter F158 --flux-unit abmag --rows 90-110 --set psf-halo-radus=64 \
		--set psf-core=3 --set sersic-trunc=0.01 --set psf-cor=2 --set pfs-wing=4 \
		--set xyz=1 -o a.fits one.csv 2> err &&
	test_grep "warning: --set psf-halo-radus: nothing in this run reads it" err &&
	test_grep "psf-halo-radus: .*misspelt key; did you mean psf-halo-radius?)\$" err &&
	test_grep "psf-cor: .*misspelt key; did you mean psf-core?)\$" err &&
	test_grep "pfs-wing: .*misspelt key; did you mean psf-wing?)\$" err &&
	test_grep "warning: --set sersic-trunc: nothing in this run reads it" err &&
	test_grep "sersic-trunc: .*misspelt key)\$" err &&
	test_grep "xyz: .*misspelt key)\$" err &&
	! grep -q "psf-core:" err &&
	"$WFS" --filter F158 --flux-unit abmag --rows 90-110 --placed p2.csv \
		--set plaecd=1 --set pnt=1 -o d.fits one.csv 2> err &&
	test_grep "plaecd: .*misspelt key; did you mean placed?)\$" err &&
	test_grep "pnt: .*misspelt key)\$" err &&
	"$WFS" --filter F158 --flux-unit abmag --rows 90-110 --set sersic-trunc=0.01 \
		-o b.fits gal.csv 2> err &&
	! grep -q "warning" err &&
	"$WFS" --filter F158 --flux-unit abmag --rows 90-110 --set placed=romanisim \
		--placed p.ecsv --set poisson-normal=50 --noise poisson --set psf-core=3 \
		-o c.fits one.csv 2> err &&
	! grep -q "warning" err
'
# A value a model refuses as it is set up is the user's bad input: exit 1,
# named by its key, not a plugin failure (3) at the row that loaded it.
test_expect_success 'a --set value a model refuses: exit 1, named by its key' '
	printf "x,y,mag,type,n,re,phi,ratio\n100.5,100.5,20,sersic,1,3,0,0.5\n" > gal.csv &&
	for kv in psf-core=x sersic-trunc=2 sersic-noise-cut=abc; do
		case $kv in psf-*) cat=one.csv ;; *) cat=gal.csv ;; esac &&
		test_must_fail --status 1 "$WFS" --filter F158 --flux-unit abmag --rows 90-110 \
			--set $kv -o bad.fits $cat 2> err &&
		test_grep "^wfiscene: --set ${kv%%=*}: model .* refuses it: .*${kv%%=*}" err &&
		! grep -q "csv:2" err && ! test -e bad.fits || return 1
	done
'
# The same when the model that refuses it draws another's sources: a
# variable star loads the point model as its drawer.
test_expect_success '... and when the model refusing it draws a variable star' '
	printf "x,y,mag,type,period,amplitude\n100.5,100.5,20,variable,1,0.5\n" > var.csv &&
	test_must_fail --status 1 "$WFS" --filter F158 --flux-unit abmag --rows 90-110 \
		--date 61000 --set psf-core=x -o bad.fits var.csv 2> err &&
	test_grep "^wfiscene: --set psf-core: model .point. refuses it: psf-core" err &&
	! grep -q "csv:2\|drawn by" err && ! test -e bad.fits
'
test_done
