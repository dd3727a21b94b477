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
	first_error bad1.csv "^wfiscene: bad1.csv:1801: column .flux.: 1e40 (counts/s) gives"
'
test_expect_success 'a bad row in the threads before one refused on the main thread' '
	bad 1101 3855 > bad2.csv && first_error bad2.csv "^wfiscene: bad2.csv:1101: column .flux.: 1e40 (counts/s) gives"
'
test_expect_success 'a row refused on the main thread before a bad one in the threads' '
	bad 3901 1195 > bad3.csv &&
	first_error bad3.csv "^wfiscene: bad3.csv:1195: model .variable.: column .amplitude."
'
test_expect_success 'and so in chunks of 2000 rows, where they fall in later chunks' '
	chunk="--chunk 2000" &&
	first_error bad1.csv "^wfiscene: bad1.csv:1801: column .flux." &&
	first_error bad2.csv "^wfiscene: bad2.csv:1101: column .flux." &&
	first_error bad3.csv "^wfiscene: bad3.csv:1195: model .variable."
'
# The threads take 512 placements at a time (place.c, PLACE_PART): two
# bad rows in neighbouring parts, one each side of the boundary, failing
# at once, again and again.  Placements go SCA by SCA, so the rank of a
# row among those of SCA 1 is its placement.
test_expect_success 'bad rows either side of a boundary between the threads'"'"' parts' '
	"$PY" -c "
rows = [l.rstrip().split(\",\") for l in open(\"mix.csv\")][1:]
sca1 = [i for i, r in enumerate(rows) if r[4] == \"1\"]
pts = [i for i in sca1[505:520] if rows[i][5] == \"point\"]
print(pts[0] + 2, pts[-1] + 2)
" > lines && read a z < lines &&
	awk -F, -v OFS=, -v a=$a -v z=$z "NR == a || NR == z { \$4 = \"1e40\" } { print }" \
		mix.csv > edge.csv &&
	for k in 1 2 3 4 5; do
		first_error edge.csv "^wfiscene: edge.csv:$a: column .flux.: 1e40" || return 1
	done
'
# A model without the flag (tests/plugins/counts.c, a square) is prepared on
# the main thread while the threads prepare the point rows: its refusal and
# theirs still come in catalog order.  And a model drawn by counts (drawn.c)
# hands counts its own state in footprint(), not the deciding model's.
mkdir plugins
test_expect_success 'test plugins counts (no flag) and drawnc (drawn by counts) build' '
	${CC:-cc} -std=c11 -Wall -Wextra -Wno-unused-parameter -shared -fPIC \
		-fvisibility=hidden -I"$TOP/include" -Wl,-z,defs -o plugins/counts.so \
		"$TOP/tests/plugins/counts.c" -lm &&
	${CC:-cc} -std=c11 -Wall -Wextra -Wno-unused-parameter -shared -fPIC \
		-fvisibility=hidden -I"$TOP/include" -Wl,-z,defs -DDRAWN_NAME="\"drawnc\"" \
		-DDRAWN_BY="\"counts\"" -o plugins/drawnc.so "$TOP/tests/plugins/drawn.c" -lm &&
	"$PY" -c "
import random
random.seed(9)
print(\"id,x,y,flux,type,side,dx\")
for i in range(3000):
    t = \"counts\" if i % 40 == 5 else \"drawnc\" if i % 40 == 25 else \"point\"
    print(\"%d,%.2f,%.2f,%.2f,%s,%s,%s\" % (i + 1, random.uniform(10, 4070), random.uniform(10, 4070),
          random.uniform(1, 100), t, 5 if t != \"point\" else \"\", 1.5 if t == \"drawnc\" else \"\"))
" > sq.csv
'
sq() { "$WFS" --filter F129 --sca 1 --plugin-path "$TRASH/plugins" "$@"; }
test_expect_success 'a model without the flag: the same image, and footprint() its own state' '
	sq --threads 1 -o q1.fits sq.csv 2> log1 && sq --threads 2 -o q2.fits sq.csv 2> log2 &&
	cmp q1.fits q2.fits &&
	test_grep "counts: prepare 150 footprint 150" log1 &&
	test_grep "counts: prepare 150 footprint 150" log2
'
test_expect_success 'its refusal and a thread'"'"'s failure, in either order' '
	awk -F, -v OFS=, "NR == 1007 { \$6 = 4 } NR == 2500 { \$4 = \"1e40\" } { print }" \
		sq.csv > sq1.csv &&
	awk -F, -v OFS=, "NR == 1000 { \$4 = \"1e40\" } NR == 2487 { \$6 = 4 } { print }" \
		sq.csv > sq2.csv &&
	sed -n "1007p;2487p" sq.csv | cut -d, -f5 > types && test "$(sort -u types)" = counts &&
	for t in 1 2 3; do
		test_must_fail --status 1 sq --threads $t -o b.fits sq1.csv 2> err &&
		test_grep "^wfiscene: sq1.csv:1007: model .counts.: column .side." err &&
		test_must_fail --status 1 sq --threads $t -o b.fits sq2.csv 2> err &&
		test_grep "^wfiscene: sq2.csv:1000: column .flux.: 1e40" err && ! test -e b.fits || return 1
	done
'
test_done
