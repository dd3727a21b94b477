"""Check an injection into a level-2 ASDF file.

    asdf_into_check.py BEFORE.asdf AFTER.asdf PLACED.csv GAIN RA DEC [SAME.asdf]

The light added to data (DN/s) peaks at the placed position, which the
file's gwcs gives for the source's RA and Dec within 0.01 pixel;
var_poisson grows by the added rate over gain x effective exposure time
(within float16's rounding); every other array is unchanged.  With
SAME.asdf: AFTER's data, var_poisson, err, dq and amp33 equal SAME's (NaN
equal to NaN), checked after the rest, and "same" printed (AFTER read
once).
"""
import csv
import sys
import warnings

import numpy as np
import asdf
import asdf.tags.core.ndarray as nd

warnings.simplefilter("ignore")
nd._datatype_names.setdefault("float16", "f2")

before, after, placed = sys.argv[1:4]
gain, ra0, dec0 = (float(v) for v in sys.argv[4:7])
same = sys.argv[7] if len(sys.argv) > 7 else None
rows = list(csv.DictReader(open(placed)))
assert len(rows) == 1, rows
x0, y0 = float(rows[0]["x"]) - 1, float(rows[0]["y"]) - 1
# uncompressed blocks memory-mapped, not copied (python3-asdf's default); all is
# read inside the with
with asdf.open(before, copy_arrays=False) as a, asdf.open(after, copy_arrays=False) as b:
    ra, rb = a.tree["roman"], b.tree["roman"]
    d = np.asarray(rb["data"], float) - np.asarray(ra["data"], float)
    y, x = np.unravel_index(np.argmax(d), d.shape)
    assert abs(x - x0) <= 1 and abs(y - y0) <= 1, (x, y, x0, y0)
    gx, gy = rb["meta"]["wcs"].invert(ra0, dec0)
    assert np.hypot(gx - x0, gy - y0) < 0.01, (gx, gy, x0, y0)
    t = rb["meta"]["exposure"]["effective_exposure_time"]
    vp = np.asarray(rb["var_poisson"], float) - np.asarray(ra["var_poisson"], float)
    want = np.clip(d, 0, None).sum() / (gain * t)
    assert abs(vp.sum() / want - 1) < 0.01, (vp.sum(), want)
    for k in ra:
        if k in ("meta", "data", "var_poisson", "err"):
            continue
        u, v = np.asarray(ra[k]), np.asarray(rb[k])
        # the same bytes of one dtype and shape (sooner), or np.array_equal's
        assert (u.dtype == v.dtype and u.shape == v.shape and np.array_equal(
            np.ascontiguousarray(u).reshape(-1).view(np.uint8),
            np.ascontiguousarray(v).reshape(-1).view(np.uint8))) or \
            np.array_equal(u, v, equal_nan=True), k
    print("added %.1f DN/s at (%d, %d); var_poisson +%.3f" % (d.sum(), x, y, vp.sum()))
    print("ok")
    if same:
        with asdf.open(same) as c:
            for k in ("data", "var_poisson", "err", "dq", "amp33"):
                assert np.array_equal(np.asarray(rb[k]), np.asarray(c.tree["roman"][k]),
                                      equal_nan=True), k
        print("same")
