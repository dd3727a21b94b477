#!/bin/sh
# make bench: wfiscene's benchmark suite.  Generates its scenes on the fly,
# prints markdown tables on stdout (paste them into BENCHMARKS.md), keeps its
# scratch files in build/bench/.  Never part of make check.
#
#   BENCH_QUICK=1 make bench     smaller catalogs, for a quick look
#   make bench-render            the render stage against the float floor alone
set -e
B=${WFS_BUILD:-build}
W=$B/bench
mkdir -p "$W"
WFS="$B/wfiscene"
GEN="$B/contrib/starfield"
export WFISCENE_PLUGIN_PATH="$B/plugins"
quick=${BENCH_QUICK:-0}
big=1000000
huge=10000000
goals=5         # runs of each goal row, the median taken
[ "$quick" = 1 ] && big=200000 && huge=1000000 && goals=3

# seconds and peak KiB of a shell command, as "SECONDS KIB"
measure() {
	/usr/bin/time -f '%e %M' -o "$W/time" sh -c "$1" > /dev/null 2> "$W/err" ||
		{ cat "$W/err" >&2; exit 1; }
	cat "$W/time"
}

# seconds, CPU seconds (user + system, the whole pipeline) and peak KiB
measure3() {
	/usr/bin/time -f '%e %U %S %M' -o "$W/time" sh -c "$1" > /dev/null 2> "$W/err" ||
		{ cat "$W/err" >&2; exit 1; }
	awk '{ print $1, $2 + $3, $4 }' "$W/time"
}

# one number from a --report file: json KEY... (python only reads the report)
json() {
	/usr/bin/python3 -c "
import json, sys
r = json.load(open(sys.argv[1]))
for k in sys.argv[2:]:
    r = r[k]
print(r)" "$@"
}

# one row of the level-2 table: level2_row LABEL WALL CPU KIB REPORT
level2_row() {
	/usr/bin/python3 -c "
import json, sys
l, t, c, k, f = sys.argv[1:6]
a = json.load(open(f)); r = a['seconds']
print('| %s | %.1f | %.1f | %.0f | %.1f | %.1f | %.1f | %.1f | %.1f | %d |' % (l, float(t), float(c),
      float(k) / 1024, r['read_parse'], r['project_place'], r['render_busy'], r['noise'],
      r['write'], a['psf_grids']['built']))" "$@"
}

cpu=$(sed -n 's/^model name[[:space:]]*: *//p' /proc/cpuinfo 2>/dev/null | head -n 1)
flags=$(grep -m 1 '^flags' /proc/cpuinfo 2>/dev/null | grep -o -w -e avx2 -e fma -e avx512f | tr '\n' ' ')
# A virtual machine's name string may say only "Intel(R) Xeon(R) Processor":
# the family and model numbers tell the part (6/85 Skylake-SP or Cascade
# Lake, 6/106 Ice Lake, 6/143 Sapphire Rapids, 6/207 Emerald Rapids), and
# the L1d and L2 sizes what the engine's working sets meet.
family=$(sed -n 's/^cpu family[[:space:]]*: *//p' /proc/cpuinfo 2>/dev/null | head -n 1)
model=$(sed -n 's/^model[[:space:]]*: *//p' /proc/cpuinfo 2>/dev/null | head -n 1)
cache() { cat "/sys/devices/system/cpu/cpu0/cache/index$1/size" 2>/dev/null || echo '?'; }
echo "# wfiscene benchmarks, $(date -u +%Y-%m-%d), $(nproc) cores, $(uname -m)"
echo
echo "CPU: ${cpu:-unknown}, family ${family:-?} model ${model:-?} (${flags% }); L1d $(cache 0), L2 $(cache 2) per core;"
echo "load at the start: $(cut -d ' ' -f 1-3 /proc/loadavg 2>/dev/null).  Absolute figures hold for this"
echo "machine only; the ratios are taken in one run, interleaved."
echo
echo "Commands are shown with each table; catalogs come from build/contrib/starfield."

# Warm the PSF cache so that PSF building is not timed here: a scene
# without sources loads no PSF, so a few faint stars on every SCA.
: > "$W/empty.csv"
"$GEN" -n 3000 -r 10 -d 20 -w 0.8 -s 5 > "$W/warm.csv"
"$WFS" --filter F129 --sca 1-18 --ra 10 --dec 20 --pointing-ref boresight \
	--flux-unit abmag --compress gzip -o "$W/warm.fits" "$W/warm.csv"

echo
echo "## The render stage in the engine against a float stamp-add floor"
echo
echo "Faint stars (AB 20-27) on SCA 1, one worker; the engine's render CPU from"
echo "--report (render_cpu: the worker's thread CPU time in render(), tile"
echo "handling and first touch of the tiles included), per star:"
echo "\`starfield -n N -x -s 1 > one.csv; wfiscene --filter F129 --flux-unit abmag --threads 1 --report r.json -o out.fits one.csv\`,"
echo "against contrib/bench/floor.c's stamp-float loop (a 44x44 float stamp added"
echo "into a float image, binned by 256-pixel tile, thread CPU, best of 3) run"
echo "between the engine's runs: floor, engine, floor, engine, floor, engine."
echo "Main thread: read+parse and project+place (prepare() and footprint() run"
echo "there) CPU per star is the process's user+system less render_cpu."
echo
echo "| pair | floor ns/star | engine render ns/star | × float floor | main thread + rest ns/star | engine system s |"
echo "|---|---|---|---|---|---|"
${CC:-cc} -O3 -march=native -std=c11 -Iinclude -o "$W/floor" contrib/bench/floor.c -lm -ldl
"$GEN" -n $big -x -s 1 > "$W/one.csv"
"$WFS" --filter F129 --flux-unit abmag --threads 1 -o "$W/o.fits" "$W/one.csv"   # warm
ratios=
for pair in 1 2 3; do
	fl=$("$W/floor" - $big | awk '$1 == "stamp-float" { print $2 }')
	"$WFS" --filter F129 --flux-unit abmag --threads 1 --report "$W/rf.json" -o "$W/o.fits" "$W/one.csv" ||
		exit 1
	set -- $(json "$W/rf.json" seconds render_cpu) $(json "$W/rf.json" seconds cpu_user) \
		$(json "$W/rf.json" seconds cpu_system)
	r=$(awk -v n=$big -v fl=$fl -v rc=$1 -v u=$2 -v sy=$3 -v p=$pair 'BEGIN {
		printf "| %d | %.0f | %.0f | %.2f | %.0f | %.2f |\n", p, fl, 1e9 * rc / n, 1e9 * rc / n / fl,
			1e9 * (u + sy - rc) / n, sy }')
	echo "$r"
	ratios="$ratios $(echo "$r" | cut -d '|' -f 5)"
done
echo
echo "Median ratio, engine render / float floor: $(printf '%s\n' $ratios | sort -n | sed -n 2p)"
rm -f "$W/one.csv"
[ "${BENCH_RENDER_ONLY:-0}" = 1 ] && exit 0

# firsttouch 600, before a timed run: this virtual machine's freed memory
# may have gone back to its host, and the first process to take it again
# pays (see the figures after the goals' table)
${CC:-cc} -O2 -o "$W/firsttouch" contrib/bench/firsttouch.c

echo
echo "## Faint stars end to end from a file: the goal of 2x10^6 stars/s"
echo
echo "Faint stars (AB 20-27) on SCA 1, two threads (the defaults), from a CSV file"
echo "and from the same rows as a FITS table (\`build/contrib/csv2fits\`):"
echo "\`starfield -n N -x -s 1 > one.csv; wfiscene --filter F129 --flux-unit abmag --report r.json -o out.fits one.csv\`."
echo "Median of $goals runs by wall time (the whole process; CPU is its user +"
echo "system), each right after a process touched 600 MB (\`firsttouch 600\`);"
echo "the stage seconds are that run's --report (main thread: read and"
echo "parse, then project and place, waiting for the threads that prepare)."
echo
echo "| catalog | stars | wall s | CPU s | stars/s | read+parse s | project+place s | render CPU s | write s |"
echo "|---|---|---|---|---|---|---|---|---|"
for n in $big $huge; do
	"$GEN" -n $n -x -s 1 > "$W/goal.csv"
	"$B/contrib/csv2fits" "$W/goal.fits" < "$W/goal.csv"
	sync    # the catalogs written back first, not during the runs
	for cat in goal.csv goal.fits; do
		# in this shell, not a pipeline's, so that a failed run stops
		# the suite
		for k in $(seq $goals); do
			"$W/firsttouch" 600 > /dev/null
			r=$(measure3 "'$WFS' --filter F129 --flux-unit abmag --report '$W/goal$k.json' -o '$W/o.fits' '$W/$cat'") ||
				exit 1
			echo "$r $k"
		done > "$W/goal.runs"
		sort -n "$W/goal.runs" | sed -n "$(( (goals + 1) / 2 ))p" > "$W/goal.med"
		set -- $(cat "$W/goal.med")
		r="$W/goal$4.json"
		awk -v c="${cat#goal.}" -v n=$n -v t=$1 -v cpu=$2 \
			-v rp=$(json "$r" seconds read_parse) -v pp=$(json "$r" seconds project_place) \
			-v rc=$(json "$r" seconds render_cpu) -v wr=$(json "$r" seconds write) 'BEGIN {
			printf "| %s file | %d | %.2f | %.2f | %.0f | %.2f | %.2f | %.2f | %.3f |\n",
				toupper(c), n, t, cpu, n / t, rp, pp, rc, wr }'
	done
done
rm -f "$W/goal.csv" "$W/goal.fits"
echo
echo "What a fresh process pays for zeroed memory: the first write to one SCA's"
echo "accumulation tiles (134 MB of doubles), then twice more in the same process"
echo "(\`cc -O2 contrib/bench/firsttouch.c -o firsttouch && firsttouch\`), right"
echo "after the runs above and again after 10 s idle (a virtual machine may give"
echo "freed memory back to its host, and then pays to get it again):"
echo
"$W/firsttouch" | sed 's/^/    /'
sleep 10
"$W/firsttouch" | sed 's/^/    /'

echo
echo "## Faint stars (AB 20-27), end to end"
echo
echo "\`zstd -dc stars.csv.zst | wfiscene --filter F129 --sca S --flux-unit abmag -o out.fits\`"
echo
echo "| stars | SCAs | wall s | empty scene s | stars/s (all) | stars/s (less empty scene) | peak MiB |"
echo "|---|---|---|---|---|---|---|"
for n in 100000 $big; do
	"$GEN" -n $n -x -s 1 | zstd -q -c > "$W/one.csv.zst"
	"$GEN" -n $n -r 10 -d 20 -w 0.8 -s 2 | zstd -q -c > "$W/all.csv.zst"
	for scas in 1 1-18; do
		if [ $scas = 1 ]; then cat=one; opt=""; else
			cat=all; opt="--ra 10 --dec 20 --pointing-ref boresight"; fi
		set -- $(measure "'$WFS' --filter F129 --sca $scas $opt -o '$W/e.fits' '$W/empty.csv'")
		e=$1
		set -- $(measure "zstd -dc '$W/$cat.csv.zst' | '$WFS' --filter F129 --sca $scas $opt --flux-unit abmag -o '$W/o.fits' -")
		awk -v n=$n -v s=$scas -v t=$1 -v e=$e -v m=$2 'BEGIN {
			printf "| %d | %s | %.2f | %.2f | %.0f | %.0f | %.0f |\n", n, s, t, e, n / t,
				(t > e ? n / (t - e) : 0), m / 1024 }'
	done
done

echo
echo "## Catalog parse rate, zstd CSV on stdin and a FITS table"
echo
echo "Rows far from the pointing are read, parsed, projected and culled, so this"
echo "is the reading side alone: \`zstd -dc far.csv.zst | wfiscene --filter F129 --ra 180 --dec -20 -o out.fits -\`;"
echo "the same rows as a FITS binary table (\`build/contrib/csv2fits\`: id as K, the"
echo "rest as D columns), read from the file: \`wfiscene ... far.fits\`.  MB are"
echo "the bytes wfiscene reads (CSV after decompression; the FITS file)."
echo
echo "| catalog | rows | MB | wall s | CPU s | rows/s | MB/s | peak MiB |"
echo "|---|---|---|---|---|---|---|---|"
"$GEN" -n $big -r 10 -d 20 -s 3 | zstd -q -c > "$W/far.csv.zst"
zstd -dc "$W/far.csv.zst" | "$B/contrib/csv2fits" "$W/far.fits"
mb=$(zstd -dc "$W/far.csv.zst" | wc -c)
set -- $(measure3 "zstd -dc '$W/far.csv.zst' | '$WFS' --filter F129 --ra 180 --dec -20 --flux-unit abmag -o '$W/o.fits' -")
awk -v n=$big -v b=$mb -v t=$1 -v c=$2 -v m=$3 'BEGIN {
	printf "| zstd CSV, stdin | %d | %.1f | %.2f | %.2f | %.0f | %.1f | %.0f |\n", n, b / 1e6, t, c, n / t, b / 1e6 / t, m / 1024 }'
mb=$(wc -c < "$W/far.fits")
set -- $(measure3 "'$WFS' --filter F129 --ra 180 --dec -20 --flux-unit abmag -o '$W/o.fits' '$W/far.fits'")
awk -v n=$big -v b=$mb -v t=$1 -v c=$2 -v m=$3 'BEGIN {
	printf "| FITS binary table, file | %d | %.1f | %.2f | %.2f | %.0f | %.1f | %.0f |\n", n, b / 1e6, t, c, n / t, b / 1e6 / t, m / 1024 }'
rm -f "$W/far.fits"
echo
echo "## Peak memory against catalog length"
echo
echo "Faint stars on SCA 1, generated on the fly and piped in (nothing stored):"
echo "\`starfield -n N -x | wfiscene --filter F129 --flux-unit abmag -o out.fits\`"
echo
echo "| rows | wall s | stars/s | peak MiB |"
echo "|---|---|---|---|"
for n in 100000 $big $huge; do
	set -- $(measure "'$GEN' -n $n -x -s 4 | '$WFS' --filter F129 --flux-unit abmag -o '$W/o.fits' -")
	awk -v n=$n -v t=$1 -v m=$2 'BEGIN { printf "| %d | %.1f | %.0f | %.0f |\n", n, t, n / t, m / 1024 }'
done

echo
echo "## Render stage against the floor, and error against time"
echo
echo "\`cc -O3 -march=native contrib/bench/floor.c -o floor && floor [--epsf GRID] build/plugins/point.so N SETTINGS...\`:"
echo "point.so's prepare() and render() through a mock host, and in the same run the"
echo "floor loops of issue 8; thread CPU ns per star (faint stars, AB 20-27, one SCA,"
echo "256-pixel tiles as the engine's default; render, and prepare() + footprint() on"
echo "the main thread)."
echo "Errors over 2000 stars (worst star), twice: on a synthetic ePSF grid whose"
echo "exact value is known, and on the built-in F129 grid of SCA 1 against the"
echo "plugin's best evaluation (psf-blend=source, psf-interp=bicubic); σ is 0.1 counts/s:"
echo
${CC:-cc} -O3 -march=native -std=c11 -Iinclude -o "$W/floor" contrib/bench/floor.c -lm -ldl
${CC:-cc} -O3 -march=native -std=c11 -Iinclude -DTILE=512 -o "$W/floor512" contrib/bench/floor.c -lm -ldl
"$WFS" psf --filter F129 --sca 1 -o "$W/epsf.fits"
fn=200000
[ "$quick" = 1 ] && fn=50000
configs="psf-blend=source psf-interp=bilinear psf-interp=bicubic psf-core=2 psf-core=3 psf-core=8
	psf-wing=4 psf-wing=6 psf-wing=44 psf-cell=256 psf-cell=1024
	psf-blend=cell,psf-cell=256 psf-blend=cell psf-blend=cell,psf-interp=bilinear
	psf-box=adaptive,psf-box-sigma=0.1 psf-box=adaptive,psf-box-sigma=0.1,psf-box-noise=0.01
	psf-blend=cell,psf-box=adaptive,psf-box-sigma=0.1"
"$W/floor" "$B/plugins/point.so" $fn - $configs grid=5 > "$W/floor.txt"
"$W/floor" --epsf "$W/epsf.fits" "$B/plugins/point.so" 20000 - $configs > "$W/floor-real.txt"
"$W/floor512" "$B/plugins/point.so" $fn - psf-blend=source > "$W/floor512.txt"
echo "| loop or settings | ns/star | × stamp floor | pixels/star | main thread ns/star | error / peak | flux error | error / σ | F129: error / peak | F129: error / σ |"
echo "|---|---|---|---|---|---|---|---|---|---|"
awk 'FNR == 1 { file++ } /^#/ { next }
	file == 1 && NF == 8 { real[$1] = $5 " " $7; next }
	file == 2 && NF == 3 { printf "| floor: %s | %.0f | %.2f | 1936 | | | | | | |\n", $1, $2, $3 }
	file == 2 && NF == 8 { split(($1 in real) ? real[$1] : "- -", r, " "); n = $1;
		sub(/^point:/, "", n); gsub(/,/, ", ", n);
		printf "| %s | %.0f | %.2f | %d | %.0f | %s | %s | %s | %s | %s |\n", n, $2, $3, $4, $8,
			$5, $6, $7, r[1], r[2] }' "$W/floor-real.txt" "$W/floor.txt"
echo
echo "The same with 512-pixel tiles (\`-DTILE=512\`; a tile of doubles is then twice the"
echo "1 MiB L2 cache, the floor slower):"
echo
echo "| loop or settings | ns/star | × stamp floor |"
echo "|---|---|---|"
awk '/^#/ { next } NF >= 3 { n = $1; sub(/^point:/, "", n); if ((n != $1 && n !~ /^exact/) || $1 ~ /^(stamp|polyphase|random)$/)
	printf "| %s%s | %.0f | %.2f |\n", (n == $1 ? "floor: " : ""), n, $2, $3 }' "$W/floor512.txt"
awk '$1 ~ /^point:/ { sub(/^point:/, "", $1); gsub(/psf-/, "", $1); sub(/,box-sigma=0.1/, "", $1)
	print $2, $5, $1 }' "$W/floor.txt" > "$W/errtime.dat"
awk 'FNR == 1 { file++ } file == 1 && $1 ~ /^point:/ { real[$1] = $5; next }
	file == 2 && ($1 in real) { n = $1; sub(/^point:/, "", n); gsub(/psf-/, "", n);
		sub(/,box-sigma=0.1/, "", n); print $2, real[$1], n }' \
	"$W/floor-real.txt" "$W/floor.txt" > "$W/errtime-real.dat"
stamp=$(awk '$1 == "stamp" { print $2 }' "$W/floor.txt")
poly=$(awk '$1 == "polyphase" { print $2 }' "$W/floor.txt")
if command -v gnuplot > /dev/null; then
	gnuplot <<EOF
set terminal pngcairo size 1000,650
set output "$W/error-time.png"
set logscale xy
set xlabel "render CPU time per faint star (ns)"
set ylabel "largest pixel error / peak (worst of 2000 stars)"
set title "point sources: error against time (contrib/bench/floor.c)"
set key top right
set grid
set yrange [1e-5:1]
set xrange [200:100000]
set arrow from $stamp, graph 0 to $stamp, graph 1 nohead dt 2 lc rgb "gray40"
set label "stamp-add floor" at $stamp, graph 0.05 rotate by 90 offset char -0.8,0 font ",8"
set arrow from $poly, graph 0 to $poly, graph 1 nohead dt 3 lc rgb "gray40"
set label "polyphase floor" at $poly, graph 0.05 rotate by 90 offset char -0.8,0 font ",8"
set arrow from 2 * $stamp, graph 0 to 2 * $stamp, graph 1 nohead lc rgb "red"
set label "2x floor" at 2 * $stamp, graph 0.05 rotate by 90 offset char -0.8,0 font ",8" tc rgb "red"
plot "$W/errtime.dat" using 1:2 with points pt 7 ps 1.2 lc rgb "#1f77b4" title "synthetic ePSF, against the exact value", \
     "$W/errtime.dat" using 1:2:3 with labels rotate by 35 offset char 0.8,0.5 left font ",7" notitle, \
     "$W/errtime-real.dat" using 1:2 with points pt 5 ps 1.0 lc rgb "#d62728" title "built-in F129, against the best evaluation", \
     "< grep ' defaults\$' $W/errtime.dat $W/errtime-real.dat | cut -d: -f2" using 1:2 with points pt 6 ps 3 lw 2 lc rgb "black" title "the defaults"
EOF
	echo
	echo "Plot: $W/error-time.png (the one BENCHMARKS.md shows is contrib/bench/error-time.png;"
	echo "copy it there with the tables it goes with)"
fi

echo
echo "## Thread scaling and stage split"
echo
echo "\`zstd -dc one.csv.zst | wfiscene --filter F129 --flux-unit abmag --threads T --report r.json -o out.fits -\`"
echo "($big faint stars on SCA 1; one run each, right after \`firsttouch 600\`; seconds from"
echo "--report; render is the workers' busy time summed)"
echo
echo "fast: \`--set psf-extent=stips --set psf-box=adaptive --set psf-box-sigma=0.1 --set psf-blend=cell\`"
echo
echo "| settings | threads | wall s | CPU s | stars/s | read+parse s | project+place s | render busy s | render wait s | write s |"
echo "|---|---|---|---|---|---|---|---|---|---|"
"$GEN" -n $big -x -s 1 | zstd -q -c > "$W/one.csv.zst"
for set in defaults fast; do
	opt=""
	[ $set = fast ] && opt="--set psf-extent=stips --set psf-box=adaptive --set psf-box-sigma=0.1 --set psf-blend=cell"
	for t in 1 2; do
		"$W/firsttouch" 600 > /dev/null
		/usr/bin/time -f '%e %U %S' -o "$W/time" sh -c "zstd -dc '$W/one.csv.zst' | '$WFS' --filter F129 --flux-unit abmag --threads $t $opt --report '$W/r$t.json' -o '$W/o.fits' -" ||
			exit 1
		set -- $(cat "$W/time")
		/usr/bin/python3 -c "
import json
r = json.load(open('$W/r$t.json'))['seconds']
print('| $set | $t | %.2f | %.2f | %.0f | %.2f | %.2f | %.2f | %.2f | %.2f |' % ($1, $2 + $3, $big / $1,
      r['read_parse'], r['project_place'], r['render_busy'], r['render_wait'], r['write']))"
	done
done
echo
echo "## Bright stars: the 88- and 176-pixel boxes, and drawn to the noise"
echo
echo "Stars on SCA 1 in three magnitude ranges, one run each, one worker thread"
echo "(\`--threads 1\`); render is the worker's busy time from --report, per star."
echo "\`--bright-limit 14\` (88 px) and \`--xbright-limit 3\` (176 px) pick the box;"
echo "extent stips is STIPS's box alone (\`--set psf-extent=stips\`), noise the"
echo "default (box, halo and tail out to 0.1 σ; fewer stars, as each costs more)."
echo "\`starfield -n N -x -m MIN -M MAX | wfiscene --filter F129 --flux-unit abmag --threads 1 [--set psf-extent=stips] --report r.json -o out.fits\`"
echo
echo "| stars | AB mag | box px | extent | wall s | render s | µs/star (render) | × faint, same extent |"
echo "|---|---|---|---|---|---|---|---|"
nf=200000; nb=50000; nx=10000
[ "$quick" = 1 ] && nf=50000 && nb=12000 && nx=2500
# build (or load) the three PSF grids first: one star of each class
printf 'x,y,mag\n100,100,25\n200,200,12\n300,300,2\n' > "$W/warm.csv"
"$WFS" --filter F129 --flux-unit abmag -o "$W/warm.fits" "$W/warm.csv"
for ext in stips noise; do
	faint=
	opt=; [ $ext = stips ] && opt="--set psf-extent=stips"
	for cls in "$nf 20 27 44 1" "$nb 10 14 88 10" "$nx 0 3 176 100"; do
		set -- $cls
		n=$1 lo=$2 hi=$3 box=$4
		[ $ext = noise ] && n=$((n / $5))
		"$GEN" -n $n -x -s 11 -m $lo -M $hi > "$W/bright.csv"
		set -- $(measure "'$WFS' --filter F129 --flux-unit abmag --threads 1 $opt --report '$W/rb.json' -o '$W/o.fits' '$W/bright.csv'")
		r=$(json "$W/rb.json" seconds render_busy)
		us=$(awk -v r=$r -v n=$n 'BEGIN { printf "%.2f", 1e6 * r / n }')
		[ -z "$faint" ] && faint=$us
		awk -v n=$n -v lo=$lo -v hi=$hi -v b=$box -v e=$ext -v t=$1 -v r=$r -v us=$us -v f=$faint 'BEGIN {
			printf "| %d | %s-%s | %d | %s | %.2f | %.2f | %.1f | %.1f |\n", n, lo, hi, b, e, t, r, us, us / f }'
	done
done
rm -f "$W/bright.csv"

echo
echo "## Two goals' ratios: bright stars against STIPS's boxes, spectra against none"
echo
echo "Each ratio from paired rounds: in every round each run of the pair in"
echo "turn, each right after a process touched 600 MB (a virtual machine slow to"
echo "give back freed memory makes the first run of a round pay for it"
echo "otherwise); the median of the rounds' ratios.  CPU is --report's"
echo "cpu_user + cpu_system, render + set-up its render_cpu + project_place."
echo "The AB 15-26 mix (issue 34's goal: CPU at most 1.5x STIPS's boxes): 10^5"
echo "stars uniform on SCA 1 and uniform in AB 15-26 (the magnitudes by awk,"
echo "\`srand(11)\`; mawk's numbers), \`wfiscene --filter F158 --flux-unit abmag"
echo "--noise all --exptime 139.8 [--set psf-extent=stips]\`.  Spectra (issue"
echo "30's goal: render + set-up at most 1.2x): 10^6 faint stars on SCA 1"
echo "(\`starfield -n 1000000 -x -s 1\`), and the same rows with a \`teff\`"
echo "column log-uniform in 2500-50 000 K (awk, \`srand(7)\`)."
echo
echo "| pair | filter | rounds | run A CPU s (median) | run B CPU s (median) | CPU B / A | render + set-up B / A |"
echo "|---|---|---|---|---|---|---|"
nr=5; nmix=100000; ncol=$big
[ "$quick" = 1 ] && nr=3 && nmix=20000
"$GEN" -n $nmix -x -s 11 -m 15 -M 26 |
	awk -F, 'BEGIN { OFS = ","; srand(11) } NR > 1 { $4 = sprintf("%.3f", 15 + 11 * rand()) } { print }' \
	> "$W/mix.csv"
"$GEN" -n $ncol -x -s 1 > "$W/plain.csv"
awk -F, 'BEGIN { srand(7) } NR == 1 { print $0 ",teff"; next }
	{ printf "%s,%.1f\n", $0, 2500 * exp(rand() * log(20)) }' "$W/plain.csv" > "$W/teff.csv"
# pair LABEL FILTER "ARGS A" "ARGS B": one table row from nr paired rounds
pair() {
	: > "$W/pair.txt"
	for k in $(seq $nr); do
		for ab in A B; do
			[ $ab = A ] && args=$3 || args=$4
			"$W/firsttouch" 600 > /dev/null
			"$WFS" --filter $2 --flux-unit abmag $args --report "$W/rp.json" -o /dev/null ||
				exit 1
			echo "$k $ab $(json "$W/rp.json" seconds cpu_user) $(json "$W/rp.json" seconds cpu_system)" \
				"$(json "$W/rp.json" seconds render_cpu) $(json "$W/rp.json" seconds project_place)" \
				>> "$W/pair.txt"
		done
	done
	awk -v l="$1" -v f=$2 -v n=$nr '
	function median(a, m,   i, j, t) {
		for (i = 1; i <= m; i++) for (j = i + 1; j <= m; j++) if (a[j] < a[i]) { t = a[i]; a[i] = a[j]; a[j] = t }
		return m % 2 ? a[(m + 1) / 2] : (a[m / 2] + a[m / 2 + 1]) / 2 }
	$2 == "A" { ca[$1] = $3 + $4; ra[$1] = $5 + $6 }
	$2 == "B" { cb[$1] = $3 + $4; rb[$1] = $5 + $6 }
	END {
		for (k = 1; k <= n; k++) { x[k] = ca[k]; y[k] = cb[k]; c[k] = cb[k] / ca[k]; r[k] = rb[k] / ra[k] }
		printf "| %s | %s | %d | %.3f | %.3f | %.3f | %.3f |\n", l, f, n, median(x, n), median(y, n), median(c, n), median(r, n) }' "$W/pair.txt"
}
mixargs="--noise all --exptime 139.8"
pair "AB 15-26 mix, $nmix stars: STIPS's boxes (A), the default (B)" F158 \
	"$mixargs --set psf-extent=stips $W/mix.csv" "$mixargs $W/mix.csv"
for f in F146 F158; do
	pair "$ncol faint stars: no spectrum (A), teff (B)" $f "$W/plain.csv" "$W/teff.csv"
done
rm -f "$W/mix.csv" "$W/plain.csv" "$W/teff.csv" "$W/pair.txt"

echo
echo "## 10^7 sky rows on 18 SCAs, end to end"
echo
echo "Stars given by RA/Dec over a 0.9 degree square about the boresight (AB"
echo "20-27, counts rising 0.3 dex/mag), read from a file; F158, SCAs 1-18,"
echo "2 threads, no noise (issue goal: 2x10^6 rows/s, 5 s for 10^7 rows):"
echo "\`starfield -n N -r 10 -d 20 -w 0.9 -s 12 > sky.csv; wfiscene --filter F158 --ra 10 --dec 20 --pointing-ref boresight --sca 1-18 --flux-unit abmag --threads 2 --report r.json -o out.fits sky.csv\`"
echo "(median of 3 by wall time; stage seconds from that run's --report; each run"
echo "writes a new file, the last run's output removed and flushed first:"
echo "truncating 1.2 GB of it cost a run some 0.35 s, and on a virtual machine"
echo "that is slow to hand out memory its freed pages also warm the next run's)"
echo
echo "| rows | placed | wall s | CPU s | rows/s | peak MiB | read+parse s | project+place s | render busy s | render wait s | write s |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
"$GEN" -n $huge -r 10 -d 20 -w 0.9 -s 12 > "$W/sky.csv"
sync
for k in 1 2 3; do
	rm -f "$W/o.fits"
	sync
	echo "$(measure3 "'$WFS' --filter F158 --ra 10 --dec 20 --pointing-ref boresight --sca 1-18 --flux-unit abmag --threads 2 --report '$W/r18_$k.json' -o '$W/o.fits' '$W/sky.csv'") $k"
done | sort -n | sed -n 2p > "$W/r18.med"
set -- $(cat "$W/r18.med")
/usr/bin/python3 -c "
import json
j = json.load(open('$W/r18_$4.json'))
r = j['seconds']
print('| %d | %d | %.1f | %.1f | %.0f | %.0f | %.1f | %.1f | %.1f | %.1f | %.1f |' % ($huge,
      j['rows']['placements'], $1, $2, $huge / $1, $3 / 1024, r['read_parse'],
      r['project_place'], r['render_busy'], r['render_wait'], r['write']))"
rm -f "$W/o.fits"

echo
nbulge=1000000
[ "$quick" = 1 ] && nbulge=200000
echo "A bulge-like field with spectra: $nbulge sky rows over the same square, AB"
echo "14-28 (\`starfield -n N -r 10 -d 20 -w 0.9 -m 14 -M 28 -s 5\`; some 1 000"
echo "stars brighter than 18, drawn with halos), with a \`teff\` column"
echo "log-uniform in 2 500-50 000 K (awk, \`srand(7)\`) and without; F146 (four"
echo "spectral classes, each bright star drawn with its class and colour step's"
echo "halo), SCAs 1-18, 2 threads, \`-o /dev/null\`; median of 3 by wall time,"
echo "after one run that builds any grid the PSF cache lacks."
echo
echo "| catalog | rows | wall s | CPU s | peak MiB | project+place s | render busy s |"
echo "|---|---|---|---|---|---|---|"
"$GEN" -n $nbulge -r 10 -d 20 -w 0.9 -m 14 -M 28 -s 5 > "$W/bulge.csv"
awk -F, 'BEGIN { srand(7) } NR == 1 { print $0 ",teff"; next }
	{ printf "%s,%.1f\n", $0, 2500 * exp(rand() * log(20)) }' "$W/bulge.csv" > "$W/bulget.csv"
for cat in bulge bulget; do
	"$WFS" --filter F146 --ra 10 --dec 20 --pointing-ref boresight --sca 1-18 --flux-unit abmag \
		--threads 2 -o /dev/null "$W/$cat.csv" > /dev/null 2>&1 || exit 1
	for k in 1 2 3; do
		echo "$(measure3 "'$WFS' --filter F146 --ra 10 --dec 20 --pointing-ref boresight --sca 1-18 --flux-unit abmag --threads 2 --report '$W/rb_$k.json' -o /dev/null '$W/$cat.csv'") $k"
	done | sort -n | sed -n 2p > "$W/rb.med"
	set -- $(cat "$W/rb.med")
	/usr/bin/python3 -c "
import json
r = json.load(open('$W/rb_$4.json'))['seconds']
print('| %s | %d | %.2f | %.2f | %.0f | %.2f | %.2f |' % ('$cat' == 'bulge' and 'no spectra' or 'teff',
      $nbulge, $1, $2, $3 / 1024, r['project_place'], r['render_busy']))"
done
rm -f "$W/bulge.csv" "$W/bulget.csv"

echo
echo "## The same sky rows at level 2, and an empty exposure with all noise"
echo
echo "Level 2 of the 18 SCAs (MA table 4, the filter's average background; one"
echo "run: it writes 6 GB; issue goal: 60 s wall, 2 GB peak), by default (at"
echo "most 2000 MB at levels 1 and 2: two passes over the catalog, nine SCAs"
echo "each) and in one pass (--memory 100000):"
echo "\`wfiscene --filter F158 --ra 10 --dec 20 --pointing-ref boresight --sca 1-18 --flux-unit abmag --level 2 --background avg --report r.json -o out.fits sky.csv\`."
echo "An empty catalog on the 18 SCAs with every noise stage (median of 3; goal"
echo "10 s wall): \`wfiscene --filter F129 --sca 1-18 --noise all --background avg --report r.json -o out.fits empty.csv\`."
echo "Level 2 of one SCA (F158, MA table 4), empty and with 185 000 stars (\`starfield -n 185000 -x -s 1\`)."
echo "Noise is the --report's noise stage (the ramps and fits at level 2, wall"
echo "time less the writing it overlaps), write its writing.  Levels 1 and 2"
echo "draw the ePSF without IPC, which no row before these needs: its grids are"
echo "built ahead (\`wfiscene psf --kind epsf-noipc\`, box and halo, SCAs 1-18),"
echo "as a first run on a cache without them would build all 36 (some 9 s"
echo "here); grids built counts any a row built all the same."
echo
"$WFS" psf --filter F158 --sca 1-18 --kind epsf-noipc -o "$W/nb.fits" &&
	"$WFS" psf --filter F158 --sca 1-18 --kind epsf-noipc --halo 256 -o "$W/nh.fits" || exit 1
rm -f "$W"/nb_wfi*.fits "$W"/nh_wfi*.fits
echo "| run | wall s | CPU s | peak MiB | read+parse s | project+place s | render busy s | noise s | write s | grids built |"
echo "|---|---|---|---|---|---|---|---|---|---|"
set -- $(measure3 "'$WFS' --filter F158 --ra 10 --dec 20 --pointing-ref boresight --sca 1-18 --flux-unit abmag --level 2 --background avg --report '$W/rl2.json' -o '$W/o.fits' '$W/sky.csv'")
level2_row "level 2, 10^7 sky rows (two passes)" "$1" "$2" "$3" "$W/rl2.json"
rm -f "$W/o.fits"
# the same in one pass, all 18 SCAs' tiles at once
set -- $(measure3 "'$WFS' --filter F158 --ra 10 --dec 20 --pointing-ref boresight --sca 1-18 --flux-unit abmag --level 2 --background avg --memory 100000 --report '$W/rl2m.json' -o '$W/o.fits' '$W/sky.csv'")
level2_row "the same in one pass, --memory 100000" "$1" "$2" "$3" "$W/rl2m.json"
rm -f "$W/o.fits" "$W/sky.csv"
for k in 1 2 3; do
	echo "$(measure3 "'$WFS' --filter F129 --sca 1-18 --noise all --background avg --report '$W/rn_$k.json' -o '$W/o.fits' '$W/empty.csv'") $k"
done | sort -n | sed -n 2p > "$W/rn.med"
set -- $(cat "$W/rn.med")
/usr/bin/python3 -c "
import json
r = json.load(open('$W/rn_$4.json'))['seconds']
print('| empty, --noise all | %.1f | %.1f | %.0f | | | | %.1f | %.1f | |' % ($1, $2, $3 / 1024,
      r['noise'], r['write']))"
rm -f "$W/o.fits"
# level 2 of one SCA, empty and crowded (issue 34: the crowded one cost
# 2.6x the empty one when the Poisson tables were rebuilt per pixel)
"$GEN" -n 185000 -x -s 1 > "$W/c185.csv"
"$WFS" --filter F158 --flux-unit abmag --level 2 --background avg -o "$W/o.fits" "$W/c185.csv"
for c in empty c185; do
	set -- $(measure3 "'$WFS' --filter F158 --flux-unit abmag --level 2 --background avg --report '$W/r1_$c.json' -o '$W/o.fits' '$W/$c.csv'")
	[ $c = empty ] && l=empty || l="185 000 stars"
	level2_row "level 2, one SCA, $l" "$1" "$2" "$3" "$W/r1_$c.json"
done
rm -f "$W/o.fits" "$W/c185.csv"

echo
echo "## Noise, per stage"
echo
echo "\`WFS_BENCH=1 build/tests/noise_bench\`: Mpixel/s of each stage on one full SCA (4088², 512-pixel"
echo "tiles, one thread, CPU seconds, best of 3), against writing the same SCA as float32 FITS:"
echo
echo "| stage | Mpixel/s | s per SCA | × write |"
echo "|---|---|---|---|"
WFS_BENCH=1 "$B/tests/noise_bench" 2>&1 | sed -n 's/^# //p' | awk '
	/Mpixel\/s/ { s = $0; sub(/ *[0-9.]+ Mpixel\/s.*/, "", s);
		match($0, /[0-9.]+ Mpixel\/s/); mp = substr($0, RSTART, RLENGTH - 9);
		match($0, /\([0-9.]+ s per SCA/); sec = substr($0, RSTART + 1, RLENGTH - 11);
		x = "1"; if (match($0, /[0-9.]+ x write/)) x = substr($0, RSTART, RLENGTH - 8);
		printf "| %s | %s | %s | %s |\n", s, mp, sec, x }'

echo
echo "## Sersic galaxies, end to end"
echo
echo "A deep-field mix on SCA 1 (\`starfield -g\`: n 0.8-1.4 for 60%, 1.5-4 for the"
echo "rest; r_e log-normal about 3 px, 0.3-60; axis ratio 0.2-1; AB 20-28 from a"
echo "power-law count), 2 threads:"
echo "\`starfield -n N -x -g -m 20 -M 28 | wfiscene --filter F129 --flux-unit abmag --sersic METHOD [--exptime S] -o out.fits\`"
echo "(the default exposure is 1 s, where the pixel noise is 12 counts/s and most"
echo "of these galaxies are below it; at 1000 s it is 0.026)"
echo
echo "The bright and large mix: the same rows with AB uniform in 20-27 and r_e"
echo "log-uniform in 1-15 px (awk, \`srand(17)\`; mawk's numbers).  The last row"
echo "gives the deep-field rows by RA/Dec over a 0.3 degree square about SCA 1"
echo "(\`starfield -r 10 -d 20 -w 0.3 -g\`, \`--ra 10 --dec 20 --sca 1\`): each row's"
echo "reach is measured before it is placed; galaxies/s counts the rows read."
echo
echo "| model | exposure s | galaxies | wall s | CPU s | galaxies/s | CPU ms/galaxy | peak MiB |"
echo "|---|---|---|---|---|---|---|---|"
for m in "quick 1 1000" "quick 1 10000" "quick 1 100000" "quick 1000 10000" "precise 1 300" \
	 "quick 1 3000 bright" "quick 1 100000 sky"; do
	set -- $m
	meth=$1 exp=$2 n=$3 mix=${4:-deep} where=
	[ "$quick" = 1 ] && n=$((n / 5))
	if [ "$mix" = sky ]; then
		"$GEN" -n $n -r 10 -d 20 -w 0.3 -g -m 20 -M 28 -s 13 > "$W/gal.csv"
		where="--ra 10 --dec 20 --sca 1"
	else
		"$GEN" -n $n -x -g -m 20 -M 28 -s 13 > "$W/gal.csv"
	fi
	if [ "$mix" = bright ]; then
		awk -F, 'BEGIN { OFS = ","; srand(17) } NR == 1 { print; next }
			{ $4 = sprintf("%.3f", 20 + 7 * rand()); $7 = sprintf("%.3f", exp(log(15) * rand())); print }' \
			"$W/gal.csv" > "$W/galb.csv" && mv "$W/galb.csv" "$W/gal.csv"
	fi
	set -- $(measure3 "'$WFS' --filter F129 --flux-unit abmag --sersic $meth --exptime $exp $where -o '$W/o.fits' '$W/gal.csv'")
	awk -v m=$meth -v e=$exp -v n=$n -v t=$1 -v c=$2 -v k=$3 -v x=$mix 'BEGIN {
		printf "| sersic-%s%s | %s | %d | %.1f | %.1f | %.0f | %.2f | %.0f |\n", m,
			x == "bright" ? ", bright and large" : x == "sky" ? \
			", by RA/Dec over 0.3 degrees (rows, most off the SCA)" : "",
			e, n, t, c, n / t, 1e3 * c / n, k / 1024 }'
done
rm -f "$W/gal.csv"

echo
echo "## Building the PSF: a new user's first run"
echo
echo "The built-in grids of one SCA, computed without the cache (\`wfiscene psf"
echo "--filter F158 --sca 1 --no-cache -o g.fits\`, the box's 177 samples at 9"
echo "nodes, and the same with \`--halo 256\`, 1025 samples at one node); median"
echo "of 3 by wall time, the whole process.  A run on an empty cache builds both"
echo "for each SCA and filter it draws (and at levels 1 and 2 their kind without"
echo "IPC)."
echo
echo "| grid | wall s | CPU s |"
echo "|---|---|---|"
for g in "box" "halo --halo 256"; do
	set -- $g
	name=$1
	shift
	# in this shell, not a pipeline's, so that a failed build stops the suite
	for k in 1 2 3; do
		measure3 "'$WFS' psf --filter F158 --sca 1 $* --no-cache -o '$W/g.fits'" || exit 1
	done > "$W/g.runs"
	sort -n "$W/g.runs" | sed -n 2p > "$W/g.med"
	set -- $(cat "$W/g.med")
	printf '| %s | %.2f | %.2f |\n' "$name" "$1" "$2"
done
rm -f "$W"/*.fits
