"""Where a level-2 ASDF file's WCS puts sources against where wfiscene
placed them, for velocity aberration (--set velocity-aberration).

    asdf_va_check.py grid L2.asdf > CATALOG.csv
    asdf_va_check.py grid L2.asdf CATALOG.csv [L2.asdf CATALOG.csv]...
        stars at 5 x 5 pixels from corner to corner of the SCA, their RA
        and Dec by the file's gwcs
    asdf_va_check.py placed L2.asdf PLACED.csv [L2.asdf PLACED.csv]...
        prints "gwcs MAX romancal MAX" pixels, a line for each pair in
        turn: the largest distance from wfiscene's placed positions
        (--placed, 1-based) to those the file's gwcs gives, and to those
        of the WCS romancal's assign_wcs builds from the file's meta
        (asdf_gwcs_check.py's rebuild)

Several files in one call spare the start-up of python3-asdf and gwcs
(seconds) per file; a failed assertion names its files.
"""
import csv
import sys
import traceback
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


def grid(path, out):
    with asdf.open(path) as af:
        w = af.tree["roman"]["meta"]["wcs"]
        g = np.linspace(20, 4067, 5)
        x, y = np.meshgrid(g, g)
        ra, dec = w(x.ravel(), y.ravel())
    out.write("ra,dec,flux\n")
    for r, d in zip(ra, dec):
        out.write("%.12f,%.12f,1e5\n" % (r, d))


def placed(path, placed_csv):
    with asdf.open(path) as af:
        meta = af.tree["roman"]["meta"]
        w = meta["wcs"]
        rows = list(csv.DictReader(open(placed_csv)))
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
    return "gwcs %.2e romancal %.2e" % (dg, drc)


mode, args = (sys.argv[1:2] or [""])[0], sys.argv[2:]
if mode == "grid" and len(args) == 1:
    grid(args[0], sys.stdout)
    sys.exit(0)
if mode not in ("grid", "placed") or not args or len(args) % 2:
    sys.exit("usage: " + __doc__.splitlines()[3].strip() + ", or " +
             __doc__.splitlines()[4].strip()[len("asdf_va_check.py "):] + ", or " +
             __doc__.splitlines()[7].strip()[len("asdf_va_check.py "):])
for i in range(0, len(args), 2):
    try:
        if mode == "grid":
            with open(args[i + 1], "w") as out:
                grid(args[i], out)
            continue
        line = placed(args[i], args[i + 1])
    except Exception as e:  # an assertion, or astropy or gwcs failing
        traceback.print_exc()
        sys.exit("asdf_va_check.py: %s, %s: %s: %s" % (args[i], args[i + 1], type(e).__name__, e))
    print(line, flush=True)
