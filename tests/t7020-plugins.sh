#!/bin/sh
# Model plugins that break the contract of wfiscene/model.h are refused
# with a message that names the model, its file and what is wrong, exit
# status 3, and no output file; never a crash.  The plugins are built here
# from tests/plugins/*.c the way an outside author builds one.
. "$(dirname "$0")/lib.sh"

mkdir plugins
build() {
	${CC:-cc} -std=c11 -Wall -Wextra -Wno-unused-parameter -shared -fPIC \
		-fvisibility=hidden -I"$TOP/include" -o "plugins/$1.so" \
		"$TOP/tests/plugins/$1.c"
}

# catalog TYPE: one source of that type in the middle of SCA 1
catalog() {
	printf 'x,y,flux,type\n1000,1000,100,%s\n1010,1012,50,%s\n' "$1" "$1" >cat.csv
}

# refused TYPE PATTERN: the run fails with status 3, says PATTERN, names the
# model, and leaves neither out.fits nor its temporary file.
refused() {
	catalog "$1" &&
	test_must_fail --status 3 "$WFS" --filter F129 --sca 1 \
		--plugin-path "$TRASH/plugins" -o out.fits cat.csv 2>err &&
	test_grep "$1" err &&
	test_grep "$2" err &&
	! ls -A | grep -q "out\.fits"
}

for p in abi_wrong desc_small init_fails render_fails no_entry declines col_noname draws_bad; do
	test_expect_success "test plugin $p builds" "build $p"
done
for c in prepare footprint render; do
	test_expect_success "test plugin silent_$c builds" "
		\${CC:-cc} -std=c11 -Wall -Wextra -Wno-unused-parameter -shared -fPIC \
			-fvisibility=hidden -I\"\$TOP/include\" -DSILENT_$(echo $c | tr a-z A-Z) \
			-DSILENT_NAME='\"silent_$c\"' -o plugins/silent_$c.so \
			\"\$TOP/tests/plugins/silent.c\""
done

test_expect_success 'wrong ABI version: refused, and told to rebuild' '
	refused abi_wrong "ABI version 2.*version 1" &&
	test_grep "rebuild" err
'

test_expect_success 'descriptor smaller than the host needs: refused' '
	refused desc_small "descriptor of [0-9]* bytes is too small"
'

test_expect_success 'init() that fails: its own message, exit 3' '
	refused init_fails "set-up failed" &&
	test_grep "cannot open its table ./nonexistent/init_fails.tab." err
'

test_expect_success 'render() that returns an error: its message, exit 3' '
	refused render_fails "deliberate failure while rendering"
'

test_expect_success 'render() failing on several threads at once is reported once' '
	awk "BEGIN { print \"x,y,flux,type\"; for (k = 0; k < 200; k++)
		printf \"%d,%d,50,render_fails\\n\", 100 + 19 * k, 100 + 19 * k }" >many.csv &&
	test_must_fail --status 3 "$WFS" --filter F129 --sca 1 --threads 4 \
		--plugin-path "$TRASH/plugins" -o out.fits many.csv 2>err &&
	test "$(grep -c "deliberate failure" err)" = 1 &&
	! ls -A | grep -q "out\.fits"
'

test_expect_success 'a column without a name: refused when loaded' '
	refused col_noname "column 2 of the descriptor has no name"
'

for c in prepare footprint render; do
	test_expect_success "$c() failing without a message: exit 3, named, no output" "
		refused silent_$c '$c() failed, with no message' &&
		test_grep 'cat.csv:2: model .silent_$c.\\|model .silent_$c.: source' err
	"
done

test_expect_success 'a shared object without the entry symbol: not a model' '
	refused no_entry "no symbol .wfs_model_entry."
'

test_expect_success 'a plugin whose entry declines this host: refused' '
	refused declines "declined"
'

test_expect_success 'a file that is not a shared object: refused' '
	echo "not ELF" >plugins/garbage.so &&
	refused garbage "cannot load"
'

test_expect_success 'a type with no plugin is bad input (exit 1), not a plugin error' '
	catalog nosuchmodel &&
	test_must_fail --status 1 "$WFS" --filter F129 --sca 1 \
		--plugin-path "$TRASH/plugins" -o out.fits cat.csv 2>err &&
	test_grep "unknown source type .nosuchmodel." err &&
	! ls -A | grep -q "out\.fits"
'

# draws_bad: flux 42 draws NaN, flux 100 draws 1e39 (beyond float32) in
# the source's pixel.  The host bounds each source's flux, not what a model
# draws, so the image itself is checked before it is written.
test_expect_success 'a model that draws NaN: exit 3, SCA and pixel named, no output' '
	printf "x,y,flux,type\n1000,1200,42,draws_bad\n" > nan.csv &&
	test_must_fail --status 3 "$WFS" --filter F129 --sca 1 --placed placed.csv \
		--plugin-path "$TRASH/plugins" -o out.fits nan.csv 2>err &&
	test_grep "^wfiscene: WFI01: pixel x=1000, y=1200 (1-based) is NaN: a source model drew" err &&
	! ls -A | grep -q "out\.fits\|placed\.csv"
'
test_expect_success 'a value beyond float32 in the image: exit 1, named, no output' '
	printf "x,y,flux,type\n10,20,1,draws_bad\n300,4000,100,draws_bad\n" > inf.csv &&
	test_must_fail --status 1 "$WFS" --filter F129 --sca 1-2 --placed placed.csv \
		--plugin-path "$TRASH/plugins" -o out.fits inf.csv 2>err &&
	test_grep "^wfiscene: WFI01: pixel x=300, y=4000 (1-based) is beyond the largest 32-bit float" err &&
	! ls -A | grep -q "out\.fits\|placed\.csv"
'
test_expect_success '... and 1e37, within float32, is written' '
	printf "x,y,flux,type\n10,20,1,draws_bad\n" > big.csv &&
	"$WFS" --filter F129 --sca 1 --plugin-path "$TRASH/plugins" -o big.fits big.csv &&
	test -s big.fits
'

test_expect_success 'WFISCENE_PLUGIN_PATH finds plugins too' '
	catalog abi_wrong &&
	test_must_fail --status 3 env WFISCENE_PLUGIN_PATH="$TRASH/plugins" \
		"$WFS" --filter F129 --sca 1 -o out.fits cat.csv 2>err &&
	test_grep "$TRASH/plugins/abi_wrong.so" err
'

test_done
