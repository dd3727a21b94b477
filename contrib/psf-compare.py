#!/usr/bin/python3
"""psf-compare.py - compare two gridded PSF files (e.g. wfiscene's built-in
optical PSF with the STPSF grid STIPS ships) node by node.

    contrib/psf-compare.py OURS.fits REF.fits

Both must be optical PSFs at 0.0275"/sample with DET_YX keywords.  Prints,
per node: FWHM (from the 4x sampled image, by the area above half maximum),
encircled energy at 0.1, 0.2, 0.5 and 1 arcsec, centroid, and the largest
per-pixel difference after integrating over 0.11" pixels centred on the
PSF (as a fraction of the peak pixel, and in absolute flux).
"""
import sys

import numpy as np
from astropy.io import fits


def planes(path):
    h = fits.open(path)
    d = h[0].data.astype(float)
    hd = h[0].header
    out = {}
    for k in range(d.shape[0]):
        yx = hd['DET_YX%d' % k].strip('()').split(',')
        out[(float(yx[0]), float(yx[1]))] = d[k] / d[k].sum()
    return out, hd


def fwhm(img, scale):
    # area above half maximum, on a 4x finer bilinear resampling of the core
    from scipy.ndimage import zoom
    n = img.shape[0]
    c = n // 2
    core = img[c - 12:c + 13, c - 12:c + 13]
    fine = zoom(core, 8, order=3)
    area = (fine >= fine.max() / 2).sum() * (scale / 8) ** 2
    return 2 * np.sqrt(area / np.pi)


def ee(img, scale, radii):
    n = img.shape[0]
    y, x = np.mgrid[0:n, 0:n]
    c = (n - 1) / 2
    # sub-sample each sample 5x5 for the aperture edge
    sub = (np.arange(5) - 2) / 5
    out = []
    for r in radii:
        frac = np.zeros_like(img)
        for dy in sub:
            for dx in sub:
                frac += (np.hypot(x + dx - c, y + dy - c) * scale <= r)
        out.append((img * frac / 25).sum())
    return out


def centroid(img, scale):
    n = img.shape[0]
    y, x = np.mgrid[0:n, 0:n]
    c = (n - 1) / 2
    m = np.hypot(x - c, y - c) <= 12
    s = img[m].sum()
    return ((img * (x - c))[m].sum() / s * scale,
            (img * (y - c))[m].sum() / s * scale)


def binned(img):
    """Integrate over 0.11" pixels on the lattice centred on the central
    sample: each pixel is a 4x4-sample box, trapezoid weights 1/2, 1, 1, 1,
    1/2 along each axis (the EPSF4 kernel, without IPC)."""
    from scipy.ndimage import convolve1d
    k1 = np.array([0.5, 1, 1, 1, 0.5])
    p = convolve1d(convolve1d(img, k1, axis=0, mode='constant'), k1, axis=1,
                   mode='constant')
    c = (img.shape[0] - 1) // 2
    return p[c % 4::4, c % 4::4]


def main():
    ours, ho = planes(sys.argv[1])
    ref, hr = planes(sys.argv[2])
    scale = 0.0275
    print('%-14s %-6s %7s %7s %7s %7s %7s %15s %9s %9s' % (
        'node (y, x)', 'who', 'FWHM"', 'EE0.1', 'EE0.2', 'EE0.5', 'EE1.0',
        'centroid mas', 'peakpix', 'maxdiff'))
    for key in sorted(ref):
        a, b = ours[key], ref[key]
        ba, bb = binned(a), binned(b)
        for who, img, bi in (('ours', a, ba), ('STPSF', b, bb)):
            cx, cy = centroid(img, scale)
            e = ee(img, scale, (0.1, 0.2, 0.5, 1.0))
            extra = ''
            if who == 'ours':
                d = np.abs(ba - bb).max()
                extra = '%9.5f %9.2e' % (d / bb.max(), d)
            print('%-14s %-6s %7.4f %7.4f %7.4f %7.4f %7.4f %7.2f,%6.2f %9.5f %s'
                  % ('(%g, %g)' % key, who, fwhm(img, scale), *e,
                     1e3 * cx, 1e3 * cy, bi.max(), extra))


if __name__ == '__main__':
    main()
