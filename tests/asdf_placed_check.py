"""Where wfiscene placed a catalogue's sources against where a level-2
ASDF file's gwcs puts them.

    asdf_placed_check.py FILE.asdf PLACED.csv CATALOG.csv [wcsinfo]
                         [FILE.asdf PLACED.csv CATALOG.csv [wcsinfo]]...

Prints "max DISTANCE" in pixels over the rows, in catalogue order, a line
for each FILE in turn (several in one call spare the start-up of
python3-asdf and gwcs, seconds, per file; a failure names its file): the
sky position the gwcs's forward transform gives for the placed position
(--placed, 1-based) against the row's RA and Dec, over the pixel's scale
there (the gwcs's own, by differences of a pixel).  The forward
transform, as every gwcs has one (python3-gwcs 0.18's numerical inverse
does not converge on a gwcs without a bounding box).  With "wcsinfo",
the WCS romancal's assign_wcs builds from the file's meta instead: the
gwcs's detector -> v2v3 step, V2/V3 scaled by
meta.velocity_aberration.scale_factor about (v2_ref, v3_ref), then
meta.wcsinfo's rotation.
"""
import csv
import sys
import traceback
import warnings

import numpy as np
import asdf
import asdf.tags.core.ndarray as nd

warnings.simplefilter("ignore")
nd._datatype_names.setdefault("float16", "f2")


def sep(r1, d1, r2, d2):
    c = np.cos(np.radians(d1))
    return np.hypot((r2 - r1) * c, d2 - d1)


def check(path, placed_csv, cat_csv, wcsinfo):
    placed = list(csv.DictReader(open(placed_csv)))
    cat = list(csv.DictReader(open(cat_csv)))
    assert len(placed) == len(cat), (len(placed), len(cat))
    with asdf.open(path) as af:
        meta = af.tree["roman"]["meta"]
        w = meta["wcs"]
        if wcsinfo:
            from astropy.modeling.models import Identity, RotationSequence3D, Scale, Shift
            from gwcs.geometry import CartesianToSpherical, SphericalToCartesian
            info = meta["wcsinfo"]
            va = meta["velocity_aberration"]["scale_factor"]
            dva = Identity(2) if va == 1 else ((Scale(va) & Scale(va)) |
                                               (Shift((1 - va) * info["v2_ref"]) &
                                                Shift((1 - va) * info["v3_ref"])))
            rot = RotationSequence3D([info["v2_ref"] / 3600, -info["v3_ref"] / 3600,
                                      info["roll_ref"], info["dec_ref"], -info["ra_ref"]],
                                     axes_order="zyxyz")
            w = (w.get_transform("detector", "v2v3") | dva |
                 ((Scale(1 / 3600) & Scale(1 / 3600)) | SphericalToCartesian(wrap_lon_at=180) |
                  rot | CartesianToSpherical(wrap_lon_at=360)))
        ra = np.array([float(r["ra"]) for r in cat])
        dec = np.array([float(r["dec"]) for r in cat])
        px = np.array([float(r["x"]) - 1 for r in placed])
        py = np.array([float(r["y"]) - 1 for r in placed])
        pr, pd = w(px, py)
        qr, qd = w(px + 1, py)
        rr, rd = w(px, py + 1)
    scale = np.sqrt(sep(pr, pd, qr, qd) * sep(pr, pd, rr, rd))
    return "max %.2e" % (sep(pr, pd, ra, dec) / scale).max()


args, groups = sys.argv[1:], []
while len(args) >= 3:
    wcsinfo = len(args) > 3 and args[3] == "wcsinfo"
    groups.append(args[:3] + [wcsinfo])
    args = args[4 if wcsinfo else 3:]
if args or not groups:
    sys.exit("usage: " + __doc__.splitlines()[3].strip())
for path, placed_csv, cat_csv, wcsinfo in groups:
    try:
        line = check(path, placed_csv, cat_csv, wcsinfo)
    except Exception as e:  # an assertion, or astropy or gwcs failing
        traceback.print_exc()
        sys.exit("asdf_placed_check.py: %s, %s: %s: %s" % (path, placed_csv, type(e).__name__, e))
    print(line, flush=True)
