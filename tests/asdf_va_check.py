"""Where a level-2 ASDF file's WCS puts sources against where wfiscene
placed them, for velocity aberration (--set velocity-aberration).

    asdf_va_check.py grid L2.asdf > CATALOG.csv
        stars at 5 x 5 pixels from corner to corner of the SCA, their RA
        and Dec by the file's gwcs
    asdf_va_check.py placed L2.asdf PLACED.csv
        prints "gwcs MAX romancal MAX" pixels: the largest distance from
        wfiscene's placed positions (--placed, 1-based) to those the
        file's gwcs gives, and to those of the WCS romancal's assign_wcs
        builds from the file's meta (asdf_gwcs_check.py's rebuild)
"""
import csv
import sys
import warnings

import numpy as np
import asdf
import asdf.tags.core.ndarray as nd
from astropy.modeling.models import Identity, RotationSequence3D, Scale, Shift
from gwcs.geometry import CartesianToSpherical, SphericalToCartesian

warnings.simplefilter("ignore")
nd._datatype_names.setdefault("float16", "f2")


def romancal(meta):
    w, info = meta["wcs"], meta["wcsinfo"]
    va = meta["velocity_aberration"]["scale_factor"]
    d2v = w.get_transform("detector", "v2v3")
    dva = Identity(2) if va == 1 else ((Scale(va) & Scale(va)) |
                                       (Shift((1 - va) * info["v2_ref"]) &
                                        Shift((1 - va) * info["v3_ref"])))
    rot = RotationSequence3D([info["v2_ref"] / 3600, -info["v3_ref"] / 3600, info["roll_ref"],
                              info["dec_ref"], -info["ra_ref"]], axes_order="zyxyz")
    return d2v | dva | ((Scale(1 / 3600) & Scale(1 / 3600)) |
                        SphericalToCartesian(wrap_lon_at=180) | rot |
                        CartesianToSpherical(wrap_lon_at=360))


with asdf.open(sys.argv[2]) as af:
    meta = af.tree["roman"]["meta"]
    w = meta["wcs"]
    if sys.argv[1] == "grid":
        g = np.linspace(20, 4067, 5)
        x, y = np.meshgrid(g, g)
        ra, dec = w(x.ravel(), y.ravel())
        print("ra,dec,flux")
        for r, d in zip(ra, dec):
            print("%.12f,%.12f,1e5" % (r, d))
        sys.exit(0)
    rows = list(csv.DictReader(open(sys.argv[3])))
    assert len(rows) == 25, len(rows)
    px = np.array([float(r["x"]) - 1 for r in rows])
    py = np.array([float(r["y"]) - 1 for r in rows])
    g = np.linspace(20, 4067, 5)
    x, y = (v.ravel() for v in np.meshgrid(g, g))
    # the placed list's order is the catalogue's
    dg = np.hypot(px - x, py - y).max()
    # romancal's sky against the gwcs's, over the nominal 0.11" pixel
    ra, dec = romancal(meta)(px, py)
    ga, gd = w(px, py)
    drc = (np.hypot((ra - ga) * np.cos(np.radians(gd)), dec - gd) * 3600 / 0.11).max()
print("gwcs %.2e romancal %.2e" % (dg, drc))
