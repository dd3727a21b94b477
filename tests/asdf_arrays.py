"""Compare an ASDF product of wfiscene with the FITS product of the same
level, seed and SCA.

    asdf_arrays.py 1|2 PRODUCT.asdf PRODUCT.fits SCA

Level 1: data is the FITS cube; amp33 (n, 4096, 128) has the reference
pixels' level and read noise (with the correlated read noise, RNCORR =
T: those of the left border's channel, within what its own pedestal and
pink series allow); reference_read is the reset level the border's
resultants start from (with RNCORR, its own read's channel offsets
apart).  Level 2: data x gain is the FITS rate, dq
the FITS DQ, err and the variances the FITS planes over the gain (squared)
as float16; chisq, dumo, amp33 and the border arrays have their RAD
shapes.  Debian's asdf 2.14 lacks float16: it is added as newer asdf has
it.  Prints "ok" and a few figures, or fails with an assertion.
"""
import sys
import warnings

import numpy as np
import asdf
import asdf.tags.core.ndarray as nd
from astropy.io import fits

warnings.simplefilter("ignore")
nd._datatype_names.setdefault("float16", "f2")

level, apath, fpath, sca = int(sys.argv[1]), sys.argv[2], sys.argv[3], int(sys.argv[4])
name = "WFI%02d" % sca
h = fits.open(fpath)
corr = bool(h[name].header.get("RNCORR", False))
# memory-mapped (its blocks are uncompressed), not copied: all is read
# inside the with
with asdf.open(apath, copy_arrays=False) as af:
    r = af.tree["roman"]
    meta = r["meta"]
    assert meta["instrument"]["detector"] == name, meta["instrument"]
    nres = meta["exposure"]["nresultants"]
    amp = np.asarray(r["amp33"])
    assert amp.dtype == np.uint16 and amp.shape == (nres, 4096, 128), (amp.dtype, amp.shape)
    if level == 1:
        d = np.asarray(r["data"])
        assert d.dtype == np.uint16 and d.shape == (nres, 4096, 4096), (d.dtype, d.shape)
        assert np.array_equal(d, h[name].data), "data differs from the FITS cube"
        ref = d[:, :4, :].astype(float)
        left = d[:, :, :4].astype(float)
        # the reference read is the reset level the resultants start from:
        # the border's first resultant less it is read noise about zero
        rr = np.asarray(r["reference_read"])
        assert rr.dtype == np.uint16 and rr.shape == (4096, 4096), (rr.dtype, rr.shape)
        diff = ref[0] - rr[:4].astype(float)
        print("data[0] - reference_read on the border: %.3f +- %.3f DN" % (diff.mean(), diff.std()))
        # the correlated noise: read 0 and read 1 have channel offsets
        # of their own (pedestal 5.6 DN per channel on WFI01, over 32)
        assert abs(diff.mean()) < (6 if corr else 0.5) and diff.std() < 1.5 * ref[0].std()
    else:
        g = float(h[name].header["GAIN"])
        d = np.asarray(r["data"])
        assert d.dtype == np.float32 and d.shape == (4088, 4088), (d.dtype, d.shape)
        assert np.array_equal(d * np.float32(g), h[name].data), "data x gain is not the FITS rate"
        assert np.array_equal(np.asarray(r["dq"]), h[name + "_DQ"].data), "dq"
        for k, ext, s in (("err", "_ERR", g), ("var_poisson", "_VAR_POISSON", g * g),
                          ("var_rnoise", "_VAR_RNOISE", g * g)):
            x = np.asarray(r[k])
            assert x.dtype == np.float16 and x.shape == (4088, 4088), (k, x.dtype)
            want = (h[name + ext].data.astype(np.float64) / s).astype(np.float32).astype(np.float16)
            assert np.array_equal(x, want, equal_nan=True), k
        for k in ("chisq", "dumo"):
            x = np.asarray(r[k])
            assert x.dtype == np.float16 and x.shape == (4088, 4088), (k, x.dtype)
        shapes = {"left": (nres, 4096, 4), "right": (nres, 4096, 4),
                  "top": (nres, 4, 4096), "bottom": (nres, 4, 4096)}
        for k, s in shapes.items():
            b = np.asarray(r["border_ref_pix_" + k])
            q = np.asarray(r["dq_border_ref_pix_" + k])
            assert b.dtype == np.float32 and b.shape == s, (k, b.dtype, b.shape)
            assert q.dtype == np.uint32 and q.shape == s[1:], (k, q.dtype, q.shape)
        ref = np.asarray(r["border_ref_pix_bottom"]).astype(float)
        left = np.asarray(r["border_ref_pix_left"]).astype(float)
        chisq = np.nanmedian(np.asarray(r["chisq"], dtype=float))
        print("chisq_median %.3f" % chisq)
    # amp33 sees what a reference pixel sees: the same level and noise;
    # with the correlated noise, what a channel's reference pixels see
    # over the frame's rows (the left border's channel 0), its own
    # pedestal apart
    a = amp.astype(float)
    if corr:
        ref = left
    print("amp33 %.2f %.3f ref %.2f %.3f" % (a.mean(), a[-1].std(), ref.mean(), ref[-1].std()))
    assert abs(a.mean() - ref.mean()) < (20 if corr else 1)
    assert abs(a[-1].std() / ref[-1].std() - 1) < (0.25 if corr else 0.1)
print("ok")
