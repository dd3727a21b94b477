"""Compare the gwcs of a level-2 ASDF product with the FITS TAN-SIP WCS
of the same SCA and pointing, and its inverse with the forward map.

    asdf_gwcs_check.py L2.asdf SCENE.fits SCA

Prints the largest distances in pixels over a 65 x 65 grid that covers
the SCA to its edges: "fits MAX inverse MAX v2v3 MAX".  Debian's asdf
2.14 lacks the float16 datatype of the level-2 arrays; it is added here as
newer asdf has it.
"""
import sys
import warnings

import numpy as np
import asdf
import asdf.tags.core.ndarray as nd
from astropy.io import fits
from astropy.wcs import WCS

warnings.simplefilter("ignore")
nd._datatype_names.setdefault("float16", "f2")

path, fitsfile, sca = sys.argv[1], sys.argv[2], int(sys.argv[3])
with asdf.open(path) as af:
    meta = af.tree["roman"]["meta"]
    w = meta["wcs"]
    info = meta["wcsinfo"]
    assert type(w).__name__ == "WCS", type(w)
    assert [f for f in w.available_frames] == ["detector", "v2v3", "world"], w.available_frames
    g = np.linspace(0, 4087, 65)
    x, y = np.meshgrid(g, g)
    ra, dec = w(x, y)
    fw = WCS(fits.open(fitsfile)["WFI%02d" % sca].header)
    px, py = fw.all_world2pix(ra, dec, 0, tolerance=1e-6, maxiter=50)
    dfits = np.hypot(px - x, py - y).max()
    ix, iy = w.invert(ra, dec)
    dinv = np.hypot(ix - x, iy - y).max()
    # the reference pixel is at wcsinfo's V2Ref, V3Ref and RA/Dec Ref
    d2v = w.get_transform("detector", "v2v3")
    ref = w.get_transform("v2v3", "world")
    r0, d0 = ref(info["v2_ref"], info["v3_ref"])
    dref = np.hypot((r0 - info["ra_ref"]) * np.cos(np.radians(d0)), d0 - info["dec_ref"]) * 3600
    v2, v3 = d2v(x, y)
    assert np.all(np.abs(v2) < 3600) and np.all(np.abs(v3 + 1800) < 3600), (v2.min(), v2.max())
print("fits %.2e inverse %.2e refpoint_arcsec %.2e" % (dfits, dinv, dref))
