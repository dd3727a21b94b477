#!/usr/bin/python3
"""Open wfiscene's Roman ASDF products with Python's asdf and print what
the Roman pipeline would read: the datamodel, a few meta values, the
arrays, and (level 2) where the gwcs puts the SCA's centre and corners.

    wfiscene --filter F129 --ra 90 --dec 0 --date 2027-03-20 --level 2 \\
        -o l2.asdf stars.csv
    contrib/asdf/open.py l2.asdf

Needs Debian's python3-asdf, python3-asdf-astropy and python3-gwcs.
asdf 2.14 (Debian 12) reads ASDF Standard 1.6.0 files but lacks two of
its pieces that the Roman datamodels use: the float16 datatype (err,
var_poisson, var_rnoise, chisq, dumo) and the ndarray-1.1.0 schema (a
warning only).  Both are added below as newer asdf has them.  Without
the RAD package the `roman` node reads as a plain dictionary (a warning
says it is not recognised); with roman_datamodels installed,
roman_datamodels.open(path) gives the pipeline's model.
"""
import sys
import warnings

import numpy as np
import asdf
import asdf.tags.core.ndarray as ndarray

ndarray._datatype_names.setdefault("float16", "f2")
# asdf's notes on the unknown RAD tags and ERFA's on dates past its
# leap-second table are not for this example
warnings.simplefilter("ignore")

for path in sys.argv[1:]:
    with asdf.open(path) as af:
        roman = af.tree["roman"]
        meta = roman["meta"]
        x = meta["exposure"]
        print(f"{path}: {meta['model_type']} {meta['instrument']['detector']} "
              f"{meta['instrument']['optical_element']}, MA table {x['ma_table_number']}, "
              f"{x['nresultants']} resultants, {x['exposure_time']:.3f} s from {x['start_time']}")
        w = meta["wcsinfo"]
        print(f"  {w['aperture_name']}: V2/V3 ({w['v2_ref']:.3f}, {w['v3_ref']:.3f})\" "
              f"at RA {w['ra_ref']:.6f} Dec {w['dec_ref']:.6f}, roll {w['roll_ref']:.4f}")
        for name, a in roman.items():
            if name == "meta":
                continue
            a = np.asarray(a)
            f = a[np.isfinite(a)] if a.dtype.kind == "f" else a
            print(f"  {name:24s} {str(a.dtype):8s} {str(a.shape):20s} "
                  f"median {np.median(f.astype(np.float64)):.4g}")
        g = meta.get("wcs")
        if g is not None:
            xs = np.array([2043.5, 0, 4087, 4087, 0])
            ys = np.array([2043.5, 0, 0, 4087, 4087])
            ra, dec = g(xs, ys)
            for xi, yi, r, d in zip(xs, ys, ra, dec):
                print(f"  gwcs: pixel ({xi:6.1f}, {yi:6.1f}) -> RA {r:.6f} Dec {d:.6f}")
