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
    psfgrid_check.py galaxy IMG STAR RA DEC PA BA HLR
        a galaxy of a romanisim catalog (n = 1) drawn in the SIAF geometry,
        and a star at the same place: see galaxy().
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


def local_jacobian(w, x, y):
    """Pixel -> sky (east, north arcsec) at 0-based (x, y), from an astropy
    WCS by central differences of a tenth of a pixel, in the plane tangent
    to the sky at (x, y)."""
    ra0, dec0 = w.all_pix2world([[x, y]], 0)[0]
    a0, d0 = np.radians(ra0), np.radians(dec0)
    east = np.array([-np.sin(a0), np.cos(a0), 0])
    north = np.array([-np.sin(d0) * np.cos(a0), -np.sin(d0) * np.sin(a0), np.cos(d0)])
    c = np.array([np.cos(d0) * np.cos(a0), np.cos(d0) * np.sin(a0), np.sin(d0)])
    h = 0.1
    pts = w.all_pix2world([[x + h, y], [x - h, y], [x, y + h], [x, y - h]], 0)
    t = []
    for ra, dec in np.radians(pts):
        v = np.array([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)])
        t.append(np.array([v @ east, v @ north]) / (v @ c) * 180 / np.pi * 3600)
    return np.column_stack([(t[0] - t[1]) / (2 * h), (t[2] - t[3]) / (2 * h)])


def moments(d, cx, cy, r):
    y, x = np.mgrid[:d.shape[0], :d.shape[1]].astype(float)
    m = (x - cx) ** 2 + (y - cy) ** 2 <= r * r
    f = np.where(m, d, 0)
    s = f.sum()
    mx, my = (f * x).sum() / s, (f * y).sum() / s
    dx, dy = x - mx, y - my
    return np.array([[(f * dx * dx).sum(), (f * dx * dy).sum()],
                     [(f * dx * dy).sum(), (f * dy * dy).sum()]]) / s


def shape(M):
    """Axis ratio and orientation (degrees from +x toward +y) of a
    symmetric 2 x 2 matrix's ellipse."""
    l, v = np.linalg.eigh(M)
    return np.sqrt(l[0] / l[1]), np.degrees(np.arctan2(v[1, 1], v[0, 1])) % 180


def galaxy(args):
    """A galaxy given on the sky (a romanisim catalog: pa, ba) drawn in
    the SIAF geometry: the covariance of its image less that of a star at
    the same place (unweighted moments add under convolution) has the axis
    ratio and orientation of the sky ellipse mapped into pixels through the
    local Jacobian of the image's own WCS (astropy, SIP)."""
    from astropy.wcs import WCS
    img, star, ra, dec, pa, ba, hlr = args[0], args[1], *map(float, args[2:7])
    w = WCS(fits.getheader(img, 1))
    x, y = w.all_world2pix([[ra, dec]], 0)[0]
    K = jacobian_sky = local_jacobian(w, x, y)
    v = np.array([np.sin(np.radians(pa)), np.cos(np.radians(pa))])
    u = np.array([-v[1], v[0]])
    S = np.outer(v, v) + ba * ba * np.outer(u, u)
    Ki = np.linalg.inv(jacobian_sky)
    P = Ki @ S @ Ki.T
    q_want, th_want = shape(P)
    dg = fits.getdata(img, 1).astype(float)
    ds = fits.getdata(star, 1).astype(float)
    ix, iy = int(round(x)), int(round(y))
    cut = (slice(iy - 150, iy + 151), slice(ix - 150, ix + 151))
    M = moments(dg[cut], 150 + x - ix, 150 + y - iy, 150) - \
        moments(ds[cut], 150 + x - ix, 150 + y - iy, 150)
    q, th = shape(M)
    # an exponential disc (n = 1, b_1 = 1.67835) of half-light semi-axis a
    # has <x^2> = 3 (a / b_1)^2 along it: the size in pixels
    a_pix = np.sqrt(np.linalg.eigvalsh(M)[1] / 3) * 1.67835
    # romanisim's half_light_radius is the circularised sqrt(a b)
    a_want = np.sqrt(np.linalg.eigvalsh(P)[1]) * hlr / np.sqrt(ba)
    skew = np.degrees(np.arccos(K[:, 0] @ K[:, 1] / np.linalg.norm(K[:, 0]) /
                                np.linalg.norm(K[:, 1])))
    dth = (th - th_want + 90) % 180 - 90
    print("# galaxy at (%.1f, %.1f), pixel axes %.3f deg apart: axis ratio %.5f "
          "(want %.5f), orientation %.4f deg (want %.4f, off %.4f)" %
          (x, y, skew, q, q_want, th, th_want, dth))
    print("# major half-light semi-axis %.4f px (want %.4f)" % (a_pix, a_want))
    # square 0.11" pixels turned by the position angle of +y alone would be
    # 5 % off in axis ratio and size and 0.09 deg in orientation here; the
    # residual size is the profile's truncation and the moments' aperture
    assert abs(q / q_want - 1) < 3e-3, (q, q_want)
    assert abs(a_pix / a_want - 1) < 1.5e-2, (a_pix, a_want)
    assert abs(dth) < 0.02, dth


if __name__ == "__main__":
    {"optical": optical, "star": star, "galaxy": galaxy}[sys.argv[1]](sys.argv[2:])
