#!/usr/bin/python3
"""The persistence left by the bright stars of make demo-bulge.

Usage: afterglow.py DIR STATE CADENCE_S SCA
Reads the persistence state wfiscene wrote after the last exposure
(--persistence-state STATE, its format in wfiscene(1) DETECTOR MODEL) and
the decay curve of the SCA from data/persistence.tsv, and writes
DIR/afterglow.fits: the current (e-/s) each pixel of the SCA would release
at the start of the next visit, CADENCE_S seconds after the last began.
Counts, in each level-2 file DIR/bulge_NAME.fits of DIR/season.txt, the
pixels whose DQ has romancal's PERSISTENCE bit (32), into
DIR/persistence.csv.
"""
import os
import sys
import numpy as np
from astropy.io import fits

d, state, cadence = sys.argv[1], sys.argv[2], float(sys.argv[3])
ext = "WFI%02d" % int(sys.argv[4])
here = os.path.dirname(os.path.abspath(__file__))
curve = None
for line in open(os.path.join(here, "..", "..", "data", "persistence.tsv")):
    f = line.rstrip("\n").split("\t")
    if f[0] == "const" and f[1] == "tmax":
        tmax = float(f[2])
    if f[0] == "decay" and f[1] == ext:
        curve = [float(v) for v in f[2:7]]
a, b, c, dd, e = curve
raw = open(state, "rb").read()
head, pos = {}, 0
for _ in range(5):
    end = raw.index(b"\n", pos)
    k, _, v = raw[pos:end].decode().partition(" ")
    head[k], pos = v, end + 1
end = raw.index(b"\n", pos)
_, sca, n = raw[pos:end].decode().split()
pos, n = end + 1, int(n)
pix = np.frombuffer(raw, "<u4", n, pos)
scale = np.frombuffer(raw, "<f4", n, pos + 4 * n).astype(np.float64)
tend = np.frombuffer(raw, "<f8", n, pos + 8 * n)
rows = [l.split() for l in open(d + "/season.txt") if not l.startswith("name")]
exptime = fits.getheader(d + "/bulge_%s.fits" % rows[-1][0], 1)["EXPTIME"]
t = float(head["end"]) - exptime + cadence - tend
cur = scale * (a * np.exp(-b * t) + dd * np.exp(-e * t) + c)
cur[(t > tmax) | (cur < 0)] = 0
img = np.zeros(4088 * 4088, np.float32)
img[pix] = cur
hdu = fits.ImageHDU(img.reshape(4088, 4088), name=ext)
hdu.header["BUNIT"] = "e-/s"
hdu.header["COMMENT"] = "afterglow current at the start of the next visit"
fits.HDUList([fits.PrimaryHDU(), hdu]).writeto(d + "/afterglow.fits", overwrite=True)
with open(d + "/persistence.csv", "w") as out:
    out.write("exposure,mjd,pixels_flagged_persistence\n")
    for name, mjd, *_ in rows:
        q = fits.getdata(d + "/bulge_%s.fits" % name, ext + "_DQ")
        out.write("%s,%s,%d\n" % (name, mjd, int(((q & 32) != 0).sum())))
flags = [l.strip().split(",")[2] for l in open(d + "/persistence.csv")][1:]
print("demo-bulge: %d pixels hold trapped charge after the last exposure; at the next "
      "visit %d release more than 0.1 e-/s (most %.2f e-/s); DQ PERSISTENCE per "
      "exposure: %s" % (n, int((cur > 0.1).sum()), cur.max(), " ".join(flags)))
