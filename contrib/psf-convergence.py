#!/usr/bin/python3
"""psf-convergence.py - error against cost of the built-in PSF's knobs.

    WFS=build/wfiscene contrib/psf-convergence.py [waves|pupil|grid|all]

waves: wavelengths per filter (1..24) against 41, at the default pupil
sampling; pupil: pupil samples across the mask array (96..384) against 512;
grid: a 3x3 grid interpolated bilinearly against PSFs computed directly at
the midpoints (from a 5x5 grid).  Errors are of the optical PSF at the
SCA centre (4x sampled, normalised to 1 in the 177-sample box): the largest
per-sample difference over the peak, and the change of the encircled
energy within 0.2".  Times are CPU seconds (user + system) of one
`wfiscene psf` run on the centre node, --no-cache, one thread.
"""
import os
import resource
import subprocess
import sys
import tempfile

import numpy as np
from astropy.io import fits

WFS = os.environ.get('WFS', 'build/wfiscene')
TMP = tempfile.mkdtemp(prefix='wfs-conv.')


def run(filt, sca=1, nwave=None, pupil=None, grid=1, kind='psf', threads=1):
    out = os.path.join(TMP, 'p.fits')
    cmd = [WFS, 'psf', '--filter', filt, '--sca', str(sca), '--kind', kind,
           '--grid', str(grid), '--no-cache', '-j', str(threads), '-o', out]
    if nwave:
        cmd += ['--nwave', str(nwave)]
    if pupil:
        cmd += ['--pupil-n', str(pupil)]
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(cmd, check=True)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    h = fits.open(out)
    d = h[0].data.astype(float)
    pos = []
    for k in range(d.shape[0]):
        y, x = map(float, h[0].header['DET_YX%d' % k].strip('()').split(','))
        pos.append((x, y))
    return d, pos, cpu


def ee02(img):
    n = img.shape[-1]
    y, x = np.mgrid[0:n, 0:n]
    c = (n - 1) / 2
    return img[..., np.hypot(x - c, y - c) * 0.0275 <= 0.2].sum(axis=-1)


def err(a, b):
    return np.abs(a - b).max() / b.max(), np.abs(ee02(a) - ee02(b)).max()


def waves():
    print('| filter | wavelengths | max error / peak | EE(0.2") error | CPU s |')
    print('|---|---|---|---|---|')
    for filt in ('F062', 'F087', 'F106', 'F129', 'F158', 'F184', 'F213',
                 'F146'):
        ref, _, _ = run(filt, nwave=41)
        for nw in (1, 2, 3, 4, 6, 8, 12, 16, 24):
            d, _, cpu = run(filt, nwave=nw)
            e, ee = err(d, ref)
            print('| %s | %d | %.1e | %.1e | %.2f |' % (filt, nw, e, ee, cpu))
            if e < 2e-4:
                break
        sys.stdout.flush()


def pupil():
    print('| filter | pupil samples | max error / peak | EE(0.2") error | CPU s |')
    print('|---|---|---|---|---|')
    for filt in ('F062', 'F129', 'F213'):
        ref, _, _ = run(filt, pupil=512)
        for pn in (96, 128, 192, 256, 384):
            d, _, cpu = run(filt, pupil=pn)
            e, ee = err(d, ref)
            print('| %s | %d | %.1e | %.1e | %.2f |' % (filt, pn, e, ee, cpu))
        sys.stdout.flush()


def grid():
    print('| filter | SCA | position (x, y), 4096 frame | 3x3 interpolation error / peak | EE(0.2") error |')
    print('|---|---|---|---|---|')
    for filt, sca in (('F062', 1), ('F129', 1), ('F213', 1), ('F129', 9)):
        g3, p3, c3 = run(filt, sca=sca, grid=3, threads=2)
        g5, p5, c5 = run(filt, sca=sca, grid=5, threads=2)
        xs3 = sorted({p[0] for p in p3})
        node3 = {p: g3[k] for k, p in enumerate(p3)}
        worst = 0
        for k, (x, y) in enumerate(p5):
            if (x, y) in node3:
                continue
            # bilinear in the 3x3 grid
            def br(v):
                i = 0 if v <= xs3[1] else 1
                return i, (v - xs3[i]) / (xs3[i + 1] - xs3[i])
            ix, tx = br(x)
            iy, ty = br(y)
            f = lambda a, b: node3[(xs3[a], xs3[b])]
            interp = ((1 - tx) * (1 - ty) * f(ix, iy) + tx * (1 - ty) * f(ix + 1, iy)
                      + (1 - tx) * ty * f(ix, iy + 1) + tx * ty * f(ix + 1, iy + 1))
            e, ee = err(interp, g5[k])
            if e > worst:
                worst = e
                wpos = (x, y, e, ee)
            if (x, y) in ((1024, 1024), (3071, 3071), (2048, 1024)):
                print('| %s | %d | (%g, %g) | %.1e | %.1e |' % (filt, sca, x, y, e, ee))
        print('| %s | %d | worst: (%g, %g) | %.1e | %.1e |' % (filt, sca, *wpos))
        print('|  |  | CPU s, 3x3 / 5x5 grid (2 threads) | %.2f / %.2f | |' % (c3, c5))
        sys.stdout.flush()


if __name__ == '__main__':
    what = sys.argv[1] if len(sys.argv) > 1 else 'all'
    for name, fn in (('waves', waves), ('pupil', pupil), ('grid', grid)):
        if what in (name, 'all'):
            fn()
            print()
