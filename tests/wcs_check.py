"""WCS round trip for t4101-wcs.sh.

    wcs_check.py make HEADERS.fits N SEED > cat.csv
        N random pixel positions per image HDU, turned into RA/Dec through
        astropy's reading of each HDU's header.
    wcs_check.py compare cat.csv placed.csv TOL
        every catalog row must be placed on its SCA within TOL pixels.
"""
import csv
import sys


def make(path, n, seed):
    # imported here: compare needs neither, and they are most of a call
    import numpy as np
    from astropy.io import fits
    from astropy.wcs import WCS

    rng = np.random.default_rng(seed)
    print("id,ra,dec,flux,sca,xtrue,ytrue")
    k = 0
    with fits.open(path) as h:
        for hdu in h:
            if not hdu.name.startswith("WFI"):
                continue
            sca = int(hdu.name[3:])
            w = WCS(hdu.header)
            # 1-based pixels well inside the detector
            x = rng.uniform(50, 4039, n)
            y = rng.uniform(50, 4039, n)
            ra, dec = w.all_pix2world(x, y, 1)
            for i in range(n):
                k += 1
                print("%d,%.12f,%.12f,100,%d,%.6f,%.6f" % (k, ra[i], dec[i], sca, x[i], y[i]))


def compare(catpath, placedpath, tol):
    want = {}
    for r in csv.DictReader(open(catpath)):
        want[int(r["id"])] = (int(r["sca"]), float(r["xtrue"]), float(r["ytrue"]))
    worst, seen = 0.0, set()
    for r in csv.DictReader(open(placedpath)):
        i = int(r["id"])
        sca, x, y = want[i]
        if int(r["sca"]) != sca:
            continue            # also lands on a neighbour: fine
        d = max(abs(float(r["x"]) - x), abs(float(r["y"]) - y))
        worst = max(worst, d)
        seen.add(i)
    missing = set(want) - seen
    print("worst %.6f px over %d sources, %d missing" % (worst, len(seen), len(missing)))
    return 0 if worst <= tol and not missing else 1


if sys.argv[1] == "make":
    make(sys.argv[2], int(sys.argv[3]), int(sys.argv[4]))
else:
    sys.exit(compare(sys.argv[2], sys.argv[3], float(sys.argv[4])))
