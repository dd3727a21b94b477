"""The PSF on each SCA's own pixels, for t4103-psf-siaf.sh.

The SIAF's local Jacobian J = d(x_idl, y_idl) / d(x, y) (arcsec per pixel)
is computed here from the SIAF XML by siaf_check.py's own Sci2Idl (central
differences), not from wfiscene.  A PSF seen through pixels of that shape is
the square-pixel PSF under the linear map A = J / 0.11", so a shape measured
as a covariance S (pixels^2) becomes A^-1 S A^-T.  The shape is that of the
least-squares elliptical Gaussian, which is affine-covariant.

    psfgrid_check.py optical SIAF.xml SCA SIAF.fits STIPS.fits
        the corner plane of two `wfiscene psf --kind psf` grids: the
        keywords JXX0..JYY0 match the SIAF's J at that node to 1e-9 "/px, and
        the SIAF plane's Gaussian covariance is A^-1 S A^-T of the STIPS
        plane's to 2e-3 (relative, per entry of the widths).
    psfgrid_check.py star SIAF.xml SCA X Y OPT_SIAF OPT_STIPS IMG_SIAF IMG_STIPS
        a star drawn at 1-based (X, Y) in both geometries: the widths along
        x and y of its pixel-integrated Gaussian fit change as predicted: the
        optical part by A (measured on the grids' corner planes), the pixel,
        IPC and sampling part K = S_star - S_optical unchanged; to 4e-3.
"""
import sys

import numpy as np
from astropy.io import fits
from scipy.optimize import least_squares

sys.path.insert(0, __file__.rsplit("/", 1)[0])
from siaf_check import read_siaf, sci2idl  # noqa: E402


def jacobian(aps, sca, x, y):
    ap = aps["WFI%02d_FULL" % sca]
    h = 0.5
    xp = sci2idl(ap, np.array([x + h, x - h, x, x]), np.array([y, y, y + h, y - h]))
    return np.array([[(xp[0][0] - xp[0][1]) / (2 * h), (xp[0][2] - xp[0][3]) / (2 * h)],
                     [(xp[1][0] - xp[1][1]) / (2 * h), (xp[1][2] - xp[1][3]) / (2 * h)]])


def gauss(p, n, sub):
    f, cx, cy, a, b, c = p
    L = np.array([[a, 0], [b, c]])
    S = L @ L.T
    Si = np.linalg.inv(S)
    o = (np.arange(sub) + 0.5) / sub - 0.5
    y, x = np.mgrid[:n, :n].astype(float)
    img = np.zeros((n, n))
    for oy in o:
        for ox in o:
            dx, dy = x + ox - cx, y + oy - cy
            img += np.exp(-0.5 * (Si[0, 0] * dx * dx + 2 * Si[0, 1] * dx * dy +
                                  Si[1, 1] * dy * dy))
    return f * img / (sub * sub * 2 * np.pi * np.sqrt(np.linalg.det(S)))


def fit(cut, sub, w0):
    """The covariance of the least-squares elliptical Gaussian (integrated
    over sub x sub points of each sample)."""
    n = cut.shape[0]
    c = (n - 1) / 2
    r = least_squares(lambda p: (gauss(p, n, sub) - cut).ravel(),
                      [cut.sum(), c, c, w0, 0, w0])
    L = np.array([[r.x[3], 0], [r.x[4], r.x[5]]])
    return L @ L.T


def corner_plane(path):
    """The plane at node (x, y) = (-4, -4) (STPSF's 0 of the 4096 frame),
    its Gaussian covariance in pixels^2, and its header."""
    with fits.open(path) as h:
        hdr = h[0].header
        for k in range(h[0].data.shape[0]):
            if hdr["DET_YX%d" % k].replace(" ", "") == "(0.0,0.0)":
                d = h[0].data[k].astype(float)
                break
    over = hdr["OVERSAMP"]
    c = d.shape[0] // 2
    cut = d[c - 24:c + 25, c - 24:c + 25]
    return fit(cut, 1, 2.0) / over ** 2, hdr, k


def widths(S):
    return np.sqrt(np.diag(S))


def optical(args):
    aps = read_siaf(args[0])
    sca = int(args[1])
    Ssi, hdr, k = corner_plane(args[2])
    Sst, hst, _ = corner_plane(args[3])
    J = jacobian(aps, sca, -3.0, -3.0)          # 0-based -4 is 1-based -3
    assert hdr["PIXGRID"] == "SIAF" and hst["PIXGRID"] == "SQUARE", (hdr["PIXGRID"],
                                                                     hst["PIXGRID"])
    Jf = np.array([[hdr["JXX%d" % k], hdr["JXY%d" % k]], [hdr["JYX%d" % k], hdr["JYY%d" % k]]])
    assert np.abs(Jf - J).max() < 1e-9, (Jf, J)
    assert abs(hdr["SCLY%d" % k] - np.hypot(J[0, 1], J[1, 1])) < 1e-8
    A = J / 0.11
    Ai = np.linalg.inv(A)
    pred = Ai @ Sst @ Ai.T
    err = np.abs(widths(Ssi) / widths(pred) - 1).max()
    moved = np.abs(widths(Sst) / widths(pred) - 1).max()
    print("# corner: scales %.5f x %.5f\"; widths siaf %s, predicted %s, stips %s; "
          "error %.2e (square pixels would be %.2e off)" %
          (np.hypot(J[0, 0], J[1, 0]), np.hypot(J[0, 1], J[1, 1]), widths(Ssi),
           widths(pred), widths(Sst), err, moved))
    assert err < 2e-3 and moved > 5 * err, (err, moved)
    skew = abs(Ssi[0, 1] - pred[0, 1]) / np.sqrt(Ssi[0, 0] * Ssi[1, 1])
    assert skew < 2e-3, skew


def star(args):
    aps = read_siaf(args[0])
    sca, x, y = int(args[1]), float(args[2]), float(args[3])
    So_si = corner_plane(args[4])[0]
    So_st = corner_plane(args[5])[0]
    J = jacobian(aps, sca, x, y)
    Ai = np.linalg.inv(J / 0.11)
    S = []
    for path in args[6:8]:
        d = fits.getdata(path, 1).astype(float)
        ix, iy = int(round(x - 1)), int(round(y - 1))
        cut = d[iy - 8:iy + 9, ix - 8:ix + 9]
        S.append(fit(cut, 8, 0.6))
    K = S[1] - So_st
    pred = Ai @ So_st @ Ai.T + K
    ratio = widths(S[0]) / widths(S[1])
    pratio = widths(pred) / widths(S[1])
    err = np.abs(ratio / pratio - 1).max()
    print("# star at (%g, %g): scales %.5f x %.5f\"; widths siaf/stips %s, "
          "predicted %s; error %.2e; grids' optical part siaf %s" %
          (x, y, np.hypot(J[0, 0], J[1, 0]), np.hypot(J[0, 1], J[1, 1]), ratio, pratio,
           err, widths(So_si)))
    # the x/y ratio moves by ~1.5% at this corner; square pixels would keep it
    assert err < 4e-3, err
    assert abs(ratio[1] / ratio[0] - 1) > 3 * err, ratio


if __name__ == "__main__":
    {"optical": optical, "star": star}[sys.argv[1]](sys.argv[2:])
