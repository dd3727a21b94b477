"""Compare the gwcs of a level-2 ASDF product with the FITS TAN-SIP WCS
of the same SCA and pointing, and its inverse with the forward map.

    asdf_gwcs_check.py L2.asdf SCENE.fits SCA [L2.asdf SCENE.fits SCA]...

Prints, for each L2.asdf in turn, the largest distances in pixels over a
65 x 65 grid that covers the SCA to its edges: "fits MAX inverse MAX
refpoint_arcsec MAX romancal MAX" (several files in one call spare the
start-up of python3-asdf and gwcs, seconds, per file; a failed assertion
names its file).  romancal is the distance to the WCS romancal's
assign_wcs builds from the file's meta (wcsinfo,
velocity_aberration.scale_factor) and the file's own detector -> v2v3
distortion, rebuilt here with the same astropy models (DVA scale and
shift about V2Ref/V3Ref, RotationSequence3D).  Debian's asdf 2.14 lacks
the float16 datatype of the level-2 arrays; it is added here as newer
asdf has it.
"""
import sys
import traceback
import warnings

import numpy as np
import asdf
import asdf.tags.core.ndarray as nd
from astropy.io import fits
from astropy.wcs import WCS

warnings.simplefilter("ignore")
nd._datatype_names.setdefault("float16", "f2")


def check(path, fitsfile, sca):
    with asdf.open(path) as af:
        meta = af.tree["roman"]["meta"]
        w = meta["wcs"]
        info = meta["wcsinfo"]
        assert type(w).__name__ == "WCS", type(w)
        frames = list(w.available_frames)
        va = meta["velocity_aberration"]["scale_factor"]
        want = ["detector", "v2v3", "world"]
        if va != 1:
            want[2:2] = ["v2v3vacorr"]
        assert frames == want, (frames, va)
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
        ref = w.get_transform(frames[-2], "world")
        r0, d0 = ref(info["v2_ref"], info["v3_ref"])
        dref = np.hypot((r0 - info["ra_ref"]) * np.cos(np.radians(d0)), d0 - info["dec_ref"]) * 3600
        v2, v3 = d2v(x, y)
        assert np.all(np.abs(v2) < 3600) and np.all(np.abs(v3 + 1800) < 3600), (v2.min(), v2.max())
        # romancal's WCS (romancal/assign_wcs/assign_wcs.py): the same models
        from astropy.modeling.models import RotationSequence3D, Scale, Shift, Identity
        from gwcs.geometry import CartesianToSpherical, SphericalToCartesian
        if va == 1:
            dva = Identity(2)
        else:
            dva = (Scale(va) & Scale(va)) | (Shift((1 - va) * info["v2_ref"]) &
                                             Shift((1 - va) * info["v3_ref"]))
        rot = RotationSequence3D([info["v2_ref"] / 3600, -info["v3_ref"] / 3600, info["roll_ref"],
                                  info["dec_ref"], -info["ra_ref"]], axes_order="zyxyz")
        tel2sky = ((Scale(1 / 3600) & Scale(1 / 3600)) | SphericalToCartesian(wrap_lon_at=180) |
                   rot | CartesianToSpherical(wrap_lon_at=360))
        rra, rdec = (d2v | dva | tel2sky)(x, y)
        qx, qy = fw.all_world2pix(rra, rdec, 0, tolerance=1e-6, maxiter=50)
        drc = np.hypot(qx - px, qy - py).max()
    return "fits %.2e inverse %.2e refpoint_arcsec %.2e romancal %.2e" % (dfits, dinv, dref, drc)


args = sys.argv[1:]
if not args or len(args) % 3:
    sys.exit("usage: " + __doc__.splitlines()[3].strip())
for i in range(0, len(args), 3):
    try:
        line = check(args[i], args[i + 1], int(args[i + 2]))
    except Exception as e:  # an assertion, or astropy or gwcs failing
        traceback.print_exc()
        sys.exit("asdf_gwcs_check.py: %s: %s: %s" % (args[i], type(e).__name__, e))
    print(line, flush=True)
