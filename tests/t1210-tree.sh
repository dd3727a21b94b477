#!/bin/sh
# Catalog trees: a directory of catalog files split by HEALPix pixel is read
# as one catalog, but only the files whose pixels reach the requested SCAs
# are opened; the image is the one big file's, byte for byte.
. "$(dirname "$0")/lib.sh"
require_python

# ang2pix in the ring and nested schemes, written from the HEALPix paper
# (Gorski et al. 2005), independent of the C library wfiscene uses.
cat > hp.py <<'PY'
import math

def ang2pix_ring(nside, ra, dec):
    z = math.sin(math.radians(dec)); za = abs(z)
    tt = (math.radians(ra) % (2 * math.pi)) / (math.pi / 2)
    if za <= 2 / 3:
        t1 = nside * (0.5 + tt); t2 = nside * z * 0.75
        jp = int(t1 - t2); jm = int(t1 + t2)
        ir = nside + 1 + jp - jm
        kshift = 1 - (ir & 1)
        ip = ((jp + jm - nside + kshift + 1) // 2) % (4 * nside)
        return 2 * nside * (nside - 1) + (ir - 1) * 4 * nside + ip
    tp = tt - int(tt)
    tmp = nside * math.sqrt(3 * (1 - za))
    jp = int(tp * tmp); jm = int((1 - tp) * tmp)
    ir = jp + jm + 1
    ip = int(tt * ir) % (4 * ir)
    if z > 0:
        return 2 * ir * (ir - 1) + ip
    return 12 * nside * nside - 2 * ir * (ir + 1) + ip

def ang2pix_nest(nside, ra, dec):
    z = math.sin(math.radians(dec)); za = abs(z)
    tt = (math.radians(ra) % (2 * math.pi)) / (math.pi / 2)
    if za <= 2 / 3:
        t1 = nside * (0.5 + tt); t2 = nside * z * 0.75
        jp = int(t1 - t2); jm = int(t1 + t2)
        ifp = jp // nside; ifm = jm // nside
        face = (ifp % 4 + 4) if ifp == ifm else ((ifp % 4) if ifp < ifm else (ifm % 4 + 8))
        ix = jm % nside; iy = nside - (jp % nside) - 1
    else:
        ntt = min(int(tt), 3); tp = tt - ntt
        tmp = nside * math.sqrt(3 * (1 - za))
        jp = min(int(tp * tmp), nside - 1); jm = min(int((1 - tp) * tmp), nside - 1)
        if z >= 0:
            face = ntt; ix = nside - jm - 1; iy = nside - jp - 1
        else:
            face = ntt + 8; ix = jp; iy = jm
    ipf = 0
    for b in range(30):
        ipf |= ((ix >> b) & 1) << (2 * b) | ((iy >> b) & 1) << (2 * b + 1)
    return face * nside * nside + ipf
PY

# 48 files at NSIDE 2 (ring): a uniform sky of faint stars plus a cluster
# about the pointing; every format and compression wfiscene reads, by pixel
# number.  big.csv is the same rows in the tree's reading order.
cat > make.py <<'PY'
import math, os, random, subprocess, sys
import numpy as np
from astropy.table import Table
sys.path.insert(0, ".")
import hp
out, scheme, ra0, dec0 = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
rng = random.Random(7)
rows = []
for i in range(6000):
    ra = rng.uniform(0, 360); dec = math.degrees(math.asin(rng.uniform(-1, 1)))
    rows.append((ra, dec, rng.uniform(18, 24)))
for i in range(400):
    d = 0.25 * math.sqrt(rng.random()); a = rng.uniform(0, 2 * math.pi)
    dec = dec0 + d * math.sin(a)
    rows.append(((ra0 + d * math.cos(a) / math.cos(math.radians(dec))) % 360, dec,
                 rng.uniform(16, 24)))
nside = 2
pix = {}
for k, (ra, dec, mag) in enumerate(rows):
    p = hp.ang2pix_nest(nside, ra, dec) if scheme in ("nested", "hats") else hp.ang2pix_ring(nside, ra, dec)
    pix.setdefault(p, []).append((k + 1, ra, dec, mag))
os.makedirs(out, exist_ok=True)
kinds = ["csv", "csv.gz", "csv.zst", "fits", "fits.gz", "ecsv", "txt"]
big = open(out + ".big.csv", "w")
big.write("id,ra,dec,mag\n")
rows_in = {}
for p in range(12 * nside * nside):
    r = pix.get(p, [])
    kind = kinds[p % len(kinds)]
    if scheme == "hats":
        d = os.path.join(out, "Norder=1", "Dir=0"); os.makedirs(d, exist_ok=True)
        name = os.path.join(d, "Npix=%d.%s" % (p, kind))
    else:
        name = os.path.join(out, "stars_%d.%s" % (p, kind))
    t = Table(rows=r if r else None, names=("id", "ra", "dec", "mag"),
              dtype=("i8", "f8", "f8", "f8"))
    base = kind.split(".")[0]
    if base == "fits":
        t.write(name.replace(".gz", ""), format="fits", overwrite=True)
    elif base == "ecsv":
        t.write(name, format="ascii.ecsv", overwrite=True)
    elif base == "txt":
        with open(name, "w") as f:
            f.write("id ra dec mag\n")
            for row in r:
                f.write("%d %.17g %.17g %.17g\n" % row)
    else:
        with open(name.replace(".gz", "").replace(".zst", ""), "w") as f:
            f.write("id,ra,dec,mag\n")
            for row in r:
                f.write("%d,%.17g,%.17g,%.17g\n" % row)
    if kind.endswith(".gz"):
        subprocess.check_call(["gzip", "-n", name[:-3]])
    if kind.endswith(".zst"):
        subprocess.check_call(["zstd", "-q", "--rm", name[:-4]])
    for row in r:
        big.write("%d,%.17g,%.17g,%.17g\n" % row)
    rows_in[p] = (len(r), kind)
with open(out + ".rows", "w") as f:
    for p in sorted(rows_in):
        f.write("%d %d %s\n" % (p, rows_in[p][0], rows_in[p][1]))
PY

# The report's catalog_trees entry as "files read skipped rows unknown".
cat > counts.py <<'PY'
import json, sys
t = json.load(open(sys.argv[1]))["catalog_trees"]
print(t["files"], t["files_read"], t["files_skipped"], t["rows_skipped"],
      t["files_skipped_rows_unknown"])
PY

# What the skipped files hold, from the maker's list: files other than
# those named on the command line; rows of the plain FITS ones; the others.
expect() {
	"$PY" -c "
import sys
keep = set(int(p) for p in sys.argv[2:])
rows = unknown = 0
for line in open(sys.argv[1]):
    p, n, kind = line.split()
    if int(p) in keep:
        continue
    if kind == 'fits':
        rows += int(n)
    else:
        unknown += 1
print(48, len(keep), 48 - len(keep), rows, unknown)" "$@"
}

RA=100 DEC=-30
POINT="--filter F129 --ra $RA --dec $DEC --sca 1,2"

test_expect_success 'setup: a 48-file tree of the whole sky at NSIDE 2, ring order' '
	"$PY" make.py ring ring $RA $DEC &&
	test $(ls ring | wc -l) = 48 && test -s ring.big.csv
'
test_expect_success 'it opens only the file under the pointing and gives the big file'"'"'s bytes' '
	"$WFS" $POINT --report rep.json -o tree.fits ring &&
	"$WFS" $POINT -o big.fits ring.big.csv &&
	cmp tree.fits big.fits &&
	"$PY" counts.py rep.json > got &&
	expect ring.rows $("$PY" -c "import hp; print(hp.ang2pix_ring(2, $RA, $DEC))") > want &&
	test_cmp want got
'
test_expect_success '-v says what the tree skipped' '
	"$WFS" $POINT -v -o /dev/null ring 2> err &&
	test_grep "ring: catalog tree: 1 of 48 files read; 47 skipped unread" err
'
test_expect_success 'the rows the tree skipped were far from the SCAs' '
	"$WFS" $POINT --report repb.json -o /dev/null ring.big.csv &&
	"$PY" -c "
import json
a = json.load(open(\"rep.json\"))[\"rows\"]; b = json.load(open(\"repb.json\"))[\"rows\"]
assert a[\"placements\"] == b[\"placements\"] > 20, (a, b)
assert a[\"read\"] < b[\"read\"] / 10, (a, b)"
'
test_expect_success 'at the pole, where four pixels meet, it opens those four' '
	"$WFS" --filter F129 --ra 45 --dec 89.95 --report pole.json -o pole.fits ring &&
	"$WFS" --filter F129 --ra 45 --dec 89.95 -o poleb.fits ring.big.csv &&
	cmp pole.fits poleb.fits &&
	"$PY" counts.py pole.json > got && expect ring.rows 0 1 2 3 > want && test_cmp want got
'
test_expect_success 'several exposures read the files every one of them needs' '
	printf "%s %s 0 a\n150 20 0 b\n" $RA $DEC > pts &&
	"$WFS" --filter F129 --sca 1 --pointings pts --report "r_%s.json" -o "e_%s.fits" ring &&
	"$PY" counts.py r_a.json > got &&
	expect ring.rows $("$PY" -c "import hp; print(hp.ang2pix_ring(2, $RA, $DEC), hp.ang2pix_ring(2, 150, 20))") > want &&
	test_cmp want got &&
	"$WFS" --filter F129 --sca 1 --ra $RA --dec $DEC -o a1.fits ring.big.csv &&
	"$WFS" --filter F129 --sca 1 --ra 150 --dec 20 -o b1.fits ring.big.csv &&
	"$PY" -c "
import sys
import numpy as np
from astropy.io import fits
same = lambda x, y: np.array_equal(fits.getdata(x, 1), fits.getdata(y, 1))
sys.exit(not (same(\"e_a.fits\", \"a1.fits\") and same(\"e_b.fits\", \"b1.fits\") and
              fits.getdata(\"a1.fits\", 1).max() > 0))"
'
test_expect_success 'nested order: from a HEALPIX file, or --set tree-ordering' '
	"$PY" make.py nest nested $RA $DEC &&
	"$WFS" $POINT -o big2.fits nest.big.csv &&
	printf "nside=2\nordering=nested\n" > nest/HEALPIX &&
	"$WFS" $POINT --report n.json -o n.fits nest && cmp n.fits big2.fits &&
	"$PY" counts.py n.json > got &&
	expect nest.rows $("$PY" -c "import hp; print(hp.ang2pix_nest(2, $RA, $DEC))") > want &&
	test_cmp want got &&
	rm nest/HEALPIX &&
	"$WFS" $POINT --set tree-ordering=nested -o n2.fits nest && cmp n2.fits big2.fits
'
test_expect_success 'a survey simulation'"'"'s skyCatalog.yaml gives NSIDE and ordering' '
	mkdir part && cp ring/stars_3[0-9].* part/ &&
	test_must_fail --status 1 "$WFS" $POINT -o p.fits part 2> err &&
	test_grep "part: HEALPix NSIDE unknown: give --set tree-nside=N" err && test ! -e p.fits &&
	printf "area_partition:\n  type: healpix\n  ordering: ring\n  nside: 2\n" > part/skyCatalog.yaml &&
	"$WFS" $POINT -o p.fits part && cmp p.fits big.fits &&
	rm part/skyCatalog.yaml &&
	"$WFS" $POINT --set tree-nside=2 -o p2.fits part && cmp p2.fits big.fits
'
test_expect_success 'HATS layout: Norder=K/Dir=D/Npix=N files' '
	"$PY" make.py hats hats $RA $DEC &&
	"$WFS" $POINT --report h.json -o h.fits hats && cmp h.fits big2.fits &&
	"$PY" counts.py h.json > got &&
	expect hats.rows $("$PY" -c "import hp; print(hp.ang2pix_nest(2, $RA, $DEC))") > want &&
	test_cmp want got
'
test_expect_success 'tree-glob chooses among the files; files without a pixel number are not read' '
	echo "not a catalog" > ring/README &&
	"$WFS" $POINT --set "tree-glob=stars_*" -o g.fits ring && cmp g.fits big.fits &&
	test_must_fail --status 1 "$WFS" $POINT --set "tree-glob=galaxies_*" -o g2.fits ring 2> err &&
	test_grep "ring: a directory (a catalog tree) without catalog files: .* and matches tree-glob" err &&
	test ! -e g2.fits
'
test_expect_success 'bad trees are refused with the file or setting at fault' '
	mkdir bad && printf "id,ra,dec,mag\n1,100,-30,20\n" > bad/s_1.csv &&
	printf "id,ra,dec,flux\n2,100,-30,20\n" > bad/s_2.csv &&
	test_must_fail --status 1 "$WFS" $POINT --set tree-nside=1 --set tree-margin=648000 \
		-o x.fits bad 2> err &&
	test_grep "its columns differ from those of the tree.s first file" err &&
	printf "id,ra,dec,mag\n2,100,-30,20\n" > bad/s_99.csv &&
	test_must_fail --status 1 "$WFS" $POINT --set tree-nside=2 -o x.fits bad 2> err &&
	test_grep "bad/s_99.csv: pixel 99 does not exist at NSIDE 2" err &&
	test_must_fail --status 1 "$WFS" $POINT --set tree-nside=3 --set tree-ordering=nested \
		-o x.fits bad 2> err &&
	test_grep "nested ordering needs NSIDE a power of 2" err &&
	test_must_fail --status 1 "$WFS" $POINT --set tree-nside=two -o x.fits bad 2> err &&
	test_grep "tree-nside: NSIDE .two.: want an integer" err &&
	test_must_fail --status 1 "$WFS" $POINT --set tree-margin=-1 -o x.fits bad 2> err &&
	test_grep "tree-margin=-1: want arcseconds" err &&
	test ! -e x.fits &&
	# a pixel number too long for any pixel: refused, not passed over
	# with its rows (it once was)
	mkdir huge && cp bad/s_1.csv huge/s_1.csv &&
	cp bad/s_1.csv huge/s_9223372036854775807.csv &&
	test_must_fail --status 1 "$WFS" $POINT --set tree-nside=1 -o x.fits huge 2> err &&
	test_grep "huge/s_9223372036854775807.csv: a pixel number of more than 18 digits" err &&
	test ! -e x.fits
'
test_done
