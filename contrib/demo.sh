#!/bin/sh
# make demo: a crowded globular cluster like the STIPS paper's M13 figure.
#
# contrib/king writes 200,000 stars (King profile, old metal-poor luminosity
# function) as CSV, zstd compresses them, and wfiscene reads the stream from
# stdin and renders the six central SCAs in F129 with the built-in PSF, the
# paper's background and full noise, then makes a PNG preview of the focal
# plane.  The same stars in F106 and F158 (king draws them alike for any
# filter) make the colour composite of the paper's Figure 1 (F158, F129 and
# F106 as red, green and blue).  Results go to build/demo/.
set -e
B=${WFS_BUILD:-build}
out=$B/demo
mkdir -p "$out"
n=${DEMO_STARS:-200000}

start=$(date +%s.%N)
"$B/contrib/king" -n "$n" -f F129 -s 13 | zstd -q -c > "$out/m13.csv.zst"
echo "demo: generated $n stars of an M13-like cluster: $out/m13.csv.zst"

t0=$(date +%s.%N)
zstd -d -c "$out/m13.csv.zst" |
	"$B/wfiscene" --filter F129 --sca 1,2,4,10,11,13 --ra 250.4235 --dec 36.4613 \
		--pa 30 --pointing-ref boresight --exptime 139.8 --background avg \
		--noise all --seed 13 --placed "$out/m13-placed.csv" -o "$out/m13.fits" -v
t1=$(date +%s.%N)

"$B/wfiscene" preview "$out/m13.fits" -o "$out/m13.png"
for f in F106 F158; do
	"$B/contrib/king" -n "$n" -f "$f" -s 13 |
		"$B/wfiscene" --filter "$f" --sca 1,2,4,10,11,13 --ra 250.4235 --dec 36.4613 \
			--pa 30 --pointing-ref boresight --exptime 139.8 --background avg \
			--noise all --seed 13 -q -o "$out/m13-$f.fits"
done
"$B/wfiscene" preview --rgb "$out/m13-F158.fits" "$out/m13.fits" "$out/m13-F106.fits" \
	-o "$out/m13-rgb.png"
t2=$(date +%s.%N)
placed=$(($(wc -l < "$out/m13-placed.csv") - 1))
cat <<EOT

demo: summary
  catalog           $n stars, zstd-compressed, read from stdin
  sources placed    $placed placements on SCAs 1,2,4,10,11,13 (the rest miss them)
  simulation time   $(awk "BEGIN { printf \"%.1f\", $t1 - $t0 }") s (including PSF grids built or loaded)
  image             $out/m13.fits (F129, 139.8 s, counts/s, noise and background)
  placed catalog    $out/m13-placed.csv
  preview           $out/m13.png
  colour composite  $out/m13-rgb.png (F158, F129, F106 as red, green, blue;
                    $out/m13-F106.fits and m13-F158.fits, $(awk "BEGIN { printf \"%.1f\", $t2 - $t1 }") s)
  total             $(awk "BEGIN { printf \"%.1f\", $(date +%s.%N) - $start }") s
EOT
