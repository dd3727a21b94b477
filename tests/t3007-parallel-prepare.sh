#!/bin/sh
# prepare() on several threads (model.h, WFS_PARALLEL_PREPARE; the point
# model declares it): the image, the --placed list and the first error
# reported are those of one thread going through the rows in order, for
# any number of threads and any chunk size.  The catalog mixes point rows
# (prepared in parallel), galaxies (prepared on the main thread) and
# variable stars (decided on the main thread, then drawn as points), on two
# SCAs, with enough rows that the threads take part.
. "$(dirname "$0")/lib.sh"
require_python

run() { "$WFS" --filter F129 --sca 1,2 "$@"; }
chunk=

test_expect_success 'a catalog of 5000 mixed rows on two SCAs' '
	"$PY" -c "
import random
random.seed(7)
print(\"id,x,y,flux,sca,type,n,re,ratio,phi,period,amplitude,shape\")
for i in range(5000):
    x, y, sca = random.uniform(-20, 4100), random.uniform(-20, 4100), 1 + (i % 3 == 0)
    if i % 50 == 7:
        print(\"%d,%.3f,%.3f,%.2f,%d,sersic,%.2f,%.2f,%.2f,%.1f,,,\" % (i + 1, x, y,
              random.uniform(200, 5000), sca, random.uniform(0.5, 4), random.uniform(1, 8),
              random.uniform(0.3, 1), random.uniform(0, 180)))
    elif i % 70 == 3:
        print(\"%d,%.3f,%.3f,%.2f,%d,variable,,,,,%.3f,%.2f,0\" % (i + 1, x, y,
              random.uniform(50, 500), sca, random.uniform(0.3, 2), random.uniform(0.1, 1)))
    else:
        print(\"%d,%.3f,%.3f,%.3f,%d,point,,,,,,,\" % (i + 1, x, y, 10 ** random.uniform(0, 3), sca))
" > mix.csv && test "$(wc -l < mix.csv)" = 5001
'
# (The --placed list goes chunk by chunk, SCA by SCA: its order depends on
# the chunk size, not on the threads.)
test_expect_success 'the image and the placed list do not depend on the threads' '
	run --threads 1 -o t1.fits --placed p1.csv --report r1.json mix.csv &&
	for c in 65536 1500 700; do
		run --threads 1 --chunk $c -o c1.fits --placed c1.csv mix.csv &&
		cmp t1.fits c1.fits &&
		for t in 2 3; do
			run --threads $t --chunk $c -o c$t.fits --placed c$t.csv mix.csv &&
			cmp t1.fits c$t.fits && cmp c1.csv c$t.csv || return 1
		done || return 1
	done
'
test_expect_success 'every row is placed: off-detector rows counted, none lost' '
	"$PY" -c "
import json
r = json.load(open(\"r1.json\"))[\"rows\"]
assert r[\"read\"] == 5000, r
assert r[\"placements\"] + r[\"off_detector\"] == 5000, r
assert r[\"placements\"] == sum(1 for _ in open(\"p1.csv\")) - 1, r
m = r[\"by_model\"]
assert sorted(m) == [\"point\", \"sersic-quick\", \"variable\"], r
assert sum(m.values()) == r[\"placements\"], r
"
'
# A row whose flux is too large fails in the threads' step (its flux is
# worked out there); a variable star with an impossible amplitude fails
# when its model decides it, on the main thread, before the threads run.
# Rows 1100 and 3854 (lines 1101 and 3855) are on SCA 1, a point and a
# variable star; rows 1800 and 3900 are points on SCA 1.
bad() {
	awk -F, -v OFS=, -v f="$1" -v a="$2" \
		'NR == f { $4 = "1e40" } NR == a { $12 = 50 } { print }' mix.csv
}
first_error() {
	for t in 1 2 3; do
		test_must_fail --status 1 run --threads $t $chunk -o b.fits "$1" 2> err &&
		test_grep "$2" err && ! test -e b.fits || return 1
	done
}
test_expect_success 'two bad rows in the threads: the first is named, for any threads' '
	awk -F, -v OFS=, "NR == 1801 || NR == 3901 { \$4 = \"1e40\" } { print }" mix.csv > bad1.csv &&
	first_error bad1.csv "^wfiscene: bad1.csv:1801: flux 1e+40 gives"
'
test_expect_success 'a bad row in the threads before one refused on the main thread' '
	bad 1101 3855 > bad2.csv && first_error bad2.csv "^wfiscene: bad2.csv:1101: flux 1e+40 gives"
'
test_expect_success 'a row refused on the main thread before a bad one in the threads' '
	bad 3901 1195 > bad3.csv &&
	first_error bad3.csv "^wfiscene: bad3.csv:1195: model .variable.: column .amplitude."
'
test_expect_success 'and so in chunks of 1000 rows, where they fall in later chunks' '
	chunk="--chunk 1000" &&
	first_error bad1.csv "^wfiscene: bad1.csv:1801: flux" &&
	first_error bad2.csv "^wfiscene: bad2.csv:1101: flux" &&
	first_error bad3.csv "^wfiscene: bad3.csv:1195: model .variable."
'
test_done
