#!/bin/sh
# wfiscene preview: FITS images to PNG, one SCA, the focal plane by WCS, and
# a three-filter colour composite.
. "$(dirname "$0")/lib.sh"
require_python

# mkfp.py OUT.fits [options]: an 18-SCA focal plane of small images, each
# with its own TAN WCS, laid out like the WFI (6 columns x 3 rows, the outer
# columns lower) and turned by --pa.  A bright star sits at the centre of
# SCA --star, and SCA --bright has three times the sky.  Prints, for the
# star, where a north-up, east-left canvas of --width pixels built as
# wfiscene(1) describes must show it.
cat >mkfp.py <<'EOF'
import sys, math, argparse
import numpy as np
from astropy.io import fits
ap = argparse.ArgumentParser()
ap.add_argument('out')
ap.add_argument('--n', type=int, default=256)
ap.add_argument('--pa', type=float, default=30.0)
ap.add_argument('--ra', type=float, default=270.0)
ap.add_argument('--dec', type=float, default=-30.0)
ap.add_argument('--sky', type=float, default=1.0)
ap.add_argument('--noise', type=float, default=0.05)
ap.add_argument('--star', type=int, default=1)
ap.add_argument('--starflux', type=float, default=500.0)
ap.add_argument('--bright', type=int, default=5)
ap.add_argument('--nsca', type=int, default=18)
ap.add_argument('--width', type=int, default=600)
ap.add_argument('--seed', type=int, default=1)
ap.add_argument('--zp', type=float, default=None)
a = ap.parse_args()
rng = np.random.default_rng(a.seed)
n = a.n
scale = 0.11 / 3600.0
size = n * scale
pa = math.radians(a.pa)
ra0, dec0 = math.radians(a.ra), math.radians(a.dec)
def deproj(xi, eta, ra0, dec0):
    x = math.cos(dec0) - eta * math.sin(dec0); y = xi
    z = eta * math.cos(dec0) + math.sin(dec0)
    return (math.degrees(ra0 + math.atan2(y, x)) % 360,
            math.degrees(math.atan2(z, math.hypot(x, y))))
def proj(ra, dec, ra0, dec0):
    a_, d = math.radians(ra) - ra0, math.radians(dec)
    c = math.sin(dec0) * math.sin(d) + math.cos(dec0) * math.cos(d) * math.cos(a_)
    return (math.cos(d) * math.sin(a_) / c,
            (math.cos(dec0) * math.sin(d) - math.sin(dec0) * math.cos(d) * math.cos(a_)) / c)
hdus, wcss = [fits.PrimaryHDU()], []
for k in range(a.nsca):
    col, row = k // 3, k % 3
    fx = (col - 2.5) * 1.15 * size
    fy = (row - 1) * 1.1 * size - 0.12 * size * (col - 2.5) ** 2
    xi = math.radians(fx * math.cos(pa) - fy * math.sin(pa))
    eta = math.radians(fx * math.sin(pa) + fy * math.cos(pa))
    ra, dec = deproj(xi, eta, ra0, dec0)
    img = np.full((n, n), a.sky * (3.0 if k + 1 == a.bright else 1.0), np.float32)
    img += rng.normal(0, a.noise, (n, n)).astype(np.float32)
    if k + 1 == a.star:
        yy, xx = np.mgrid[0:n, 0:n]
        c = (n - 1) / 2.0
        img += (a.starflux / (2 * math.pi * 4.0) *
                np.exp(-((xx - c) ** 2 + (yy - c) ** 2) / 8.0)).astype(np.float32)
    h = fits.ImageHDU(img, name='WFI%02d' % (k + 1))
    hd = h.header
    hd['CTYPE1'] = 'RA---TAN'; hd['CTYPE2'] = 'DEC--TAN'
    hd['CRPIX1'] = (n + 1) / 2.0; hd['CRPIX2'] = (n + 1) / 2.0
    hd['CRVAL1'] = ra; hd['CRVAL2'] = dec
    hd['CD1_1'] = -scale * math.cos(pa); hd['CD1_2'] = scale * math.sin(pa)
    hd['CD2_1'] = scale * math.sin(pa);  hd['CD2_2'] = scale * math.cos(pa)
    hd['BUNIT'] = 'counts/s'
    if a.zp is not None:
        hd['PHOTZPAB'] = a.zp
    hdus.append(h)
    wcss.append((ra, dec))
fits.HDUList(hdus).writeto(a.out, overwrite=True)
# The canvas as wfiscene(1) lays it out: tangent point at the mean direction
# of the SCA centres; corners, edge midpoints and centre of every SCA plus a
# 2 % margin; east left, north up.
from astropy.wcs import WCS
hl = fits.open(a.out)
v = np.zeros(3); pts = []
for h in hl[1:]:
    w = WCS(h.header)
    f = [(0, 0), (1, 0), (1, 1), (0, 1), (.5, 0), (1, .5), (.5, 1), (0, .5), (.5, .5)]
    p = [w.all_pix2world(0.5 + fx * n, 0.5 + fy * n, 1) for fx, fy in f]
    pts += p
    r, d = map(math.radians, p[-1])
    v += [math.cos(d) * math.cos(r), math.cos(d) * math.sin(r), math.sin(d)]
tra, tdec = math.atan2(v[1], v[0]), math.asin(v[2] / np.linalg.norm(v))
xy = [proj(float(r), float(d), tra, tdec) for r, d in pts]
xs, ys = [q[0] for q in xy], [q[1] for q in xy]
span = max(max(xs) - min(xs), max(ys) - min(ys)); m = 0.02 * span
xmax, ymax = max(xs) + m, max(ys) + m
step = (max(xs) + m - (min(xs) - m)) / a.width
sra, sdec = wcss[a.star - 1]
sx, sy = proj(sra, sdec, tra, tdec)
print('%d %d %d' % ((xmax - sx) / step, (ymax - sy) / step,
                    math.ceil((ymax - (min(ys) - m)) / step)))
EOF

# png.py: a PNG reader without third-party modules (8-bit, not interlaced).
cat >png.py <<'EOF'
import struct, zlib
def read(path):
    d = open(path, 'rb').read()
    assert d[:8] == b'\x89PNG\r\n\x1a\n', 'not a PNG'
    pos, idat, text = 8, b'', {}
    while pos < len(d):
        n, t = struct.unpack('>I4s', d[pos:pos + 8])
        body = d[pos + 8:pos + 8 + n]
        assert zlib.crc32(t + body) == struct.unpack('>I', d[pos + 8 + n:pos + 12 + n])[0], 'bad CRC'
        if t == b'IHDR':
            w, h, depth, ctype, _, _, inter = struct.unpack('>IIBBBBB', body)
            assert depth == 8 and inter == 0
            ch = {0: 1, 4: 2, 2: 3, 6: 4}[ctype]
        elif t == b'IDAT':
            idat += body
        elif t == b'tEXt':
            k, v = body.split(b'\0', 1); text[k.decode()] = v.decode('latin-1')
        elif t == b'IEND':
            break
        pos += 12 + n
    raw = zlib.decompress(idat)
    stride = w * ch
    rows, prev, p = [], [0] * stride, 0
    for y in range(h):
        f = raw[p]; line = list(raw[p + 1:p + 1 + stride]); p += 1 + stride
        for i in range(stride):
            a = line[i - ch] if i >= ch else 0
            b = prev[i]; c = prev[i - ch] if i >= ch else 0
            if f == 1: line[i] = (line[i] + a) & 255
            elif f == 2: line[i] = (line[i] + b) & 255
            elif f == 3: line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                pr = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                line[i] = (line[i] + pr) & 255
        rows.append(line); prev = line
    class P: pass
    r = P(); r.w, r.h, r.ch, r.rows, r.text = w, h, ch, rows, text
    r.px = lambda x, y: r.rows[y][x * ch:(x + 1) * ch]
    return r
EOF
# pycheck 'python code with P = png.read' : run a check against a PNG
pycheck() { PYTHONPATH=$TRASH "$PY" -c "import png, sys
$1"; }

# A plain FITS file: one primary image, no WCS, a bright square near
# FITS pixel (1, 1), the bottom left as ds9 shows it.
"$PY" - <<'EOF'
import numpy as np
from astropy.io import fits
img = np.ones((300, 400), np.float32)
img[10:40, 10:40] = 100
img[150, 200] = np.nan
fits.PrimaryHDU(img).writeto('plain.fits')
EOF

test_expect_success 'a single image is drawn bottom row last, never enlarged' '
	"$WFS" preview plain.fits -o plain.png &&
	pycheck "
P = png.read(\"plain.png\")
assert (P.w, P.h, P.ch) == (400, 300, 1), (P.w, P.h, P.ch)
assert P.px(25, 299 - 25)[0] == 255, P.px(25, 274)
assert P.px(25, 25)[0] < 80, P.px(25, 25)
"'

test_expect_success 'the default output name is the input with .png' '
	cp plain.fits named.fits.fz 2>/dev/null; cp plain.fits named.fits &&
	"$WFS" preview named.fits && test -f named.png
'

test_expect_success '--width averages down and keeps the aspect ratio' '
	"$WFS" preview plain.fits --width 100 -o small.png &&
	pycheck "
P = png.read(\"small.png\")
assert (P.w, P.h) == (100, 75), (P.w, P.h)
# the 30-pixel square is 7.5 output pixels; its middle stays white
assert P.px(6, 74 - 6)[0] > 200, P.px(6, 68)
"'

"$PY" mkfp.py fp.fits --bright 0 --width 600 >star.xy

test_expect_success '--sca N draws that detector' '
	"$WFS" preview fp.fits --sca 1 -o one.png &&
	pycheck "
P = png.read(\"one.png\")
assert (P.w, P.h, P.ch) == (256, 256, 1)
c = P.px(127, 128)[0]; edge = max(P.px(5, 5)[0], P.px(250, 250)[0])
assert c == 255 and edge < 120, (c, edge)
" &&
	"$WFS" preview fp.fits --sca WFI05 -o five.png &&
	"$WFS" preview fp.fits --sca=wfi5 -o five2.png && cmp five.png five2.png
'

test_expect_success 'the focal plane is laid out on the sky, north up, east left' '
	"$WFS" preview fp.fits --width 600 -o fp.png &&
	read sx sy h <star.xy &&
	pycheck "
P = png.read(\"fp.png\")
assert (P.w, P.ch) == (600, 2), (P.w, P.ch)
assert abs(P.h - $h) <= 1, (P.h, $h)
# the white pixels are the star in SCA 1
w = [(x, y) for y in range(P.h) for x in range(P.w) if P.px(x, y)[0] > 250]
cx, cy = sum(q[0] for q in w) / len(w), sum(q[1] for q in w) / len(w)
assert len(w) < 30 and abs(cx - $sx) <= 2 and abs(cy - $sy) <= 2, (len(w), cx, cy, $sx, $sy)
# gaps between detectors are transparent, and there are 18 detectors'"'"' worth of data
covered = sum(1 for y in range(P.h) for x in range(P.w) if P.px(x, y)[1])
frac = covered / float(P.w * P.h)
assert 0.2 < frac < 0.9, frac
"'

test_expect_success 'brighter sky is drawn brighter' '
	"$PY" mkfp.py fp2.fits --star 7 --bright 5 --pa 0 --width 400 >/dev/null &&
	"$WFS" preview fp2.fits --sca all --width 400 -o fp2.png &&
	"$WFS" preview fp2.fits --sca 5 -o b5.png &&
	"$WFS" preview fp2.fits --sca 6 -o b6.png --min 0.8 --max 4 &&
	"$WFS" preview fp2.fits --sca 5 -o b5f.png --min 0.8 --max 4 &&
	pycheck "
a = png.read(\"b5f.png\"); b = png.read(\"b6.png\")
m = lambda P: sum(sum(r) for r in P.rows) / float(P.w * P.h)
assert m(a) > m(b) + 50, (m(a), m(b))
"'

test_expect_success 'a rotated layout (PA 123) still puts the star in place' '
	"$PY" mkfp.py fp3.fits --bright 0 --pa 123 --dec 60 --width 500 >star3.xy &&
	"$WFS" preview fp3.fits --width 500 -o fp3.png &&
	read sx sy h <star3.xy &&
	pycheck "
P = png.read(\"fp3.png\")
w = [(x, y) for y in range(P.h) for x in range(P.w) if P.px(x, y)[0] > 250]
cx, cy = sum(q[0] for q in w) / len(w), sum(q[1] for q in w) / len(w)
assert len(w) < 30 and abs(cx - $sx) <= 2 and abs(cy - $sy) <= 2, (len(w), cx, cy, $sx, $sy)
"'

# wfiscene's own output: a star at the centre of SCAs 1, 3, 7 and 16 (the
# two ends and the middle of the focal plane).  On the PNG, north up and
# east left, the stars must sit where data/sca.tsv puts the SCA centres in
# the WFI's ideal frame (+x west and +y north at PA 0; +y east and +x north
# at PA 90), up to one scale factor, within 2 pixels (the
# SCAs are 54 pixels apart).
printf 'x,y,sca,flux\n' >fpstars.csv
for s in 1 3 7 16; do printf '2044.5,2044.5,%d,100000\n' $s >>fpstars.csv; done
cat >layout.py <<'EOF'
import sys, png
P = png.read(sys.argv[1]); pa = float(sys.argv[2])
tsv = {}
for line in open(sys.argv[3]):
    f = line.split()
    if f and f[0].isdigit():
        tsv[int(f[0])] = (float(f[1]), float(f[2]))
# the stars: white pixels in clusters, each cluster's centre
white = [(x, y) for y in range(P.h) for x in range(P.w) if P.px(x, y)[0] > 250]
blobs = []
for x, y in white:
    for b in blobs:
        if abs(b[0][0] - x) < 8 and abs(b[0][1] - y) < 8:
            b.append((x, y)); break
    else:
        blobs.append([(x, y)])
assert len(blobs) == 4, [b[0] for b in blobs]
c = [(sum(p[0] for p in b) / len(b), sum(p[1] for p in b) / len(b)) for b in blobs]
# where each SCA should be on the PNG, up to offset and scale
want = {}
for s in (1, 3, 7, 16):
    fx, fy = tsv[s]
    want[s] = (fx, -fy) if pa == 0 else (-fy, -fx)
# pair each blob with its SCA from a rough fit (offset and scale from the
# extremes along PNG x), then fit offset and scale by least squares
sx = sorted(want, key=lambda s: want[s][0])
cx = sorted(c)
k = (cx[-1][0] - cx[0][0]) / (want[sx[-1]][0] - want[sx[0]][0])
ox, oy = cx[0][0] - k * want[sx[0]][0], sum(q[1] for q in c) / 4 - k * sum(w[1] for w in want.values()) / 4
pair = {s: min(c, key=lambda q: (q[0] - ox - k * want[s][0]) ** 2 + (q[1] - oy - k * want[s][1]) ** 2)
        for s in want}
assert len(set(pair.values())) == 4, pair
mw = [sum(want[s][i] for s in want) / 4 for i in (0, 1)]
mc = [sum(pair[s][i] for s in want) / 4 for i in (0, 1)]
k = (sum((pair[s][i] - mc[i]) * (want[s][i] - mw[i]) for s in want for i in (0, 1)) /
     sum((want[s][i] - mw[i]) ** 2 for s in want for i in (0, 1)))
for s in want:
    px, py = mc[0] + k * (want[s][0] - mw[0]), mc[1] + k * (want[s][1] - mw[1])
    d = ((pair[s][0] - px) ** 2 + (pair[s][1] - py) ** 2) ** 0.5
    assert d < 2, ('WFI%02d' % s, px, py, pair[s])
print('ok', k)
EOF
test_expect_success 'wfiscene'"'"'s focal plane at PA 0 is laid out as the WFI on the sky' '
	"$WFS" --filter F158 --sca 1,3,7,16 --psf "$PSF" -q -o wfp0.fits fpstars.csv &&
	"$WFS" preview wfp0.fits --width 400 -o wfp0.png &&
	PYTHONPATH=$TRASH "$PY" layout.py wfp0.png 0 "$TOP/data/sca.tsv"
'
test_expect_success 'and at PA 90 it turns with the position angle (+y east)' '
	"$WFS" --filter F158 --sca 1,3,7,16 --psf "$PSF" --pa 90 -q -o wfp90.fits fpstars.csv &&
	"$WFS" preview wfp90.fits --width 400 -o wfp90.png &&
	PYTHONPATH=$TRASH "$PY" layout.py wfp90.png 90 "$TOP/data/sca.tsv"
'

test_expect_success 'a colour composite from three filters' '
	"$PY" mkfp.py r.fits --star 2 --bright 0 --seed 1 --width 500 >/dev/null &&
	"$PY" mkfp.py g.fits --star 0 --bright 0 --seed 2 >/dev/null &&
	"$PY" mkfp.py b.fits --star 0 --bright 0 --seed 3 >/dev/null &&
	"$WFS" preview --rgb r.fits g.fits b.fits -o rgb.png --width 500 &&
	"$WFS" preview --rgb r.fits g.fits b.fits --sca 2 -o rgb2.png &&
	pycheck "
P = png.read(\"rgb.png\")
assert (P.w, P.ch) == (500, 4), (P.w, P.ch)
best = max((P.px(x, y)[0], x, y) for y in range(P.h) for x in range(P.w) if P.px(x, y)[3])
r, g, b, a = P.px(best[1], best[2])
assert r > 200 and g < r / 2 and b < r / 2, (r, g, b)
Q = png.read(\"rgb2.png\")
assert (Q.w, Q.h, Q.ch) == (256, 256, 3)
r, g, b = Q.px(127, 128)
assert r == 255 and g < 128 and b < 128, (r, g, b)
assert \"Lupton\" in Q.text[\"Comment\"], Q.text
"'

# A star of flat f_nu gives fewer counts/s through a filter of lower
# zeropoint: 500 in G and B (PHOTZPAB 26.3) is 500 x 10^(-0.2) = 315.5 in R
# (25.8).  Balanced by PHOTZPAB it is white; by counts it would be cyan.
test_expect_success 'a colour composite is balanced by PHOTZPAB: a flat spectrum is white' '
	"$PY" mkfp.py zr.fits --star 2 --starflux 315.479 --zp 25.8 --bright 0 --seed 1 >/dev/null &&
	"$PY" mkfp.py zg.fits --star 2 --starflux 500 --zp 26.3 --bright 0 --seed 2 >/dev/null &&
	"$PY" mkfp.py zb.fits --star 2 --starflux 500 --zp 26.3 --bright 0 --seed 3 >/dev/null &&
	"$WFS" preview --rgb zr.fits zg.fits zb.fits --sca 2 -v -o z.png 2>err &&
	test_grep "zr.fits: balanced by PHOTZPAB" err &&
	pycheck "
P = png.read(\"z.png\")
# the star: every pixel within 3 of the centre that is not black
px = [P.px(x, y) for y in range(124, 132) for x in range(124, 132)]
px = [p for p in px if max(p) > 60]
assert len(px) > 4, px
r, g, b = [sum(p[c] for p in px) for c in range(3)]
assert abs(r / g - 1) < 0.05 and abs(b / g - 1) < 0.05, (r, g, b, px)
assert \"PHOTZPAB\" in P.text[\"Comment\"], P.text
" &&
	"$PY" mkfp.py zn.fits --star 2 --starflux 500 --bright 0 --seed 2 >/dev/null &&
	"$WFS" preview --rgb zr.fits zn.fits zb.fits --sca 2 -v -o zn.png 2>err &&
	test_grep "not every image has PHOTZPAB" err
'

test_expect_success 'levels and stretch are recorded and can be set' '
	"$WFS" preview fp.fits --sca 1 --min 0 --max 10 --stretch linear -o lin.png &&
	pycheck "
P = png.read(\"lin.png\")
assert \"linear\" in P.text[\"Comment\"] and \"white 10\" in P.text[\"Comment\"], P.text
assert P.px(5, 5)[0] in range(20, 32), P.px(5, 5)
" &&
	"$WFS" preview fp.fits --sca 1 --scale 50 -v -o q.png 2>err &&
	test_grep "fp.fits: sky 0.99[0-9]*, noise 0.0[45]" err
'

test_expect_success 'writing to stdout' '
	"$WFS" preview plain.fits -o - >out.png &&
	pycheck "assert png.read(\"out.png\").w == 400"
'
test_expect_success 'a FIFO (like /dev/stdout) is written in place, not renamed over' '
	mkfifo fifo.png &&
	{ timeout 30 cat fifo.png >fromfifo.png & } &&
	"$WFS" preview plain.fits -o fifo.png &&
	wait &&
	test -p fifo.png &&
	pycheck "assert png.read(\"fromfifo.png\").w == 400" &&
	rm -f fifo.png fromfifo.png
'

# Refusals: a message naming the subject, exit 1 (bad input) or 2 (I/O),
# and no PNG left behind.
no_png() { ! ls ./*.png ./.*.png 2>/dev/null | grep -q . ; }

test_expect_success 'bad arguments are refused with exit 1' '
	mkdir bad && cd bad &&
	test_must_fail --status 1 "$WFS" preview ../fp.fits --sca 19 -o x.png 2>err &&
	test_grep "sca.*19" err &&
	test_must_fail --status 1 "$WFS" preview ../fp.fits --width 0 -o x.png 2>err &&
	test_grep "width" err &&
	test_must_fail --status 1 "$WFS" preview ../fp.fits --frobnicate 2>err &&
	test_grep "unknown option .--frobnicate." err &&
	test_must_fail --status 1 "$WFS" preview ../fp.fits --min 5 --max 1 -o x.png 2>err &&
	test_grep "max" err &&
	test_must_fail --status 1 "$WFS" preview --rgb ../r.fits ../g.fits 2>err &&
	test_grep "three" err &&
	test_must_fail --status 1 "$WFS" preview 2>err &&
	test_grep "no input" err &&
	no_png
'

test_expect_success 'bad input is refused with exit 1, a missing file with 2' '
	mkdir bad2 && cd bad2 &&
	echo "not a FITS file" >junk.fits &&
	test_must_fail --status 1 "$WFS" preview junk.fits -o x.png 2>err &&
	test_grep "junk.fits" err &&
	test_must_fail --status 2 "$WFS" preview nosuch.fits -o x.png 2>err &&
	test_grep "nosuch.fits.*No such file" err &&
	"$PY" ../mkfp.py six.fits --nsca 6 >/dev/null &&
	test_must_fail --status 1 "$WFS" preview six.fits --sca 7 -o x.png 2>err &&
	test_grep "six.fits: no image HDU with EXTNAME .WFI07." err &&
	test_must_fail --status 1 "$WFS" preview ../plain.fits --sca all -o x.png 2>err &&
	test_grep "plain.fits.*WCS" err &&
	test_must_fail --status 1 "$WFS" preview --rgb ../plain.fits ../plain.fits ../fp.fits --sca 1 -o x.png 2>err &&
	test_grep "EXTNAME" err &&
	no_png
'

test_expect_success 'an unwritable output is exit 2 and leaves nothing' '
	mkdir ro && chmod 555 ro &&
	if [ "$(id -u)" = 0 ]; then
		test_must_fail --status 2 "$WFS" preview plain.fits -o nodir/x.png 2>err &&
		test_grep "nodir/x.png" err
	else
		test_must_fail --status 2 "$WFS" preview plain.fits -o ro/x.png 2>err &&
		test_grep "ro/x.png" err
	fi &&
	! ls -A ro | grep -q .
'

test_expect_success 'a full disk is reported, not a truncated PNG' '
	if [ -w /dev/full ] && [ -d /proc/self/fd ]; then
		test_must_fail --status 2 "$WFS" preview plain.fits -o - >/dev/full 2>err &&
		test_grep "stdout\|PNG" err
	fi
'

test_done
