"""Flux conservation of point sources, checked against an independent
implementation of the evaluation wfiscene(1) documents.

    flux_check.py grid OUT.fits         a synthetic 3x3 ePSF grid (WFSKIND EPSF)
                                        whose shape changes with position
    flux_check.py stars SCAS SEED       a catalog (x, y, sca, flux) with stars
                                        at all 64 eighth-pixel phases on each
                                        SCA, on tile boundaries, corners and
                                        edges (partly off the detector)
    flux_check.py check GRID CAT IMAGE TOL
                                        per SCA of IMAGE, the image sum must
                                        equal sum(flux * enclosed fraction)
                                        to TOL (drawn with psf-blend=source)
    flux_check.py check-default GRID CAT IMAGE TOL
                                        the same for the default evaluation
"""
import csv
import math
import sys

import numpy as np
from astropy.io import fits

N, OVER, NPIX = 177, 4, 4088
C = (N - 1) // 2
NODES = [0.0, 2048.0, 4095.0]            # STPSF's, in the 4096-pixel frame


def make_grid(path):
    planes, cards = [], []
    k = 0
    yy, xx = np.mgrid[0:N, 0:N].astype(float)
    for ix, nx in enumerate(NODES):
        for iy, ny in enumerate(NODES):
            # an off-centre core and wings that change from node to node
            sx, sy = 4.0 + 0.5 * ix, 4.5 + 0.4 * iy
            dx, dy = xx - C - 0.3 * ix, yy - C + 0.2 * iy
            core = np.exp(-0.5 * ((dx / sx) ** 2 + (dy / sy) ** 2))
            wing = (1 + (dx * dx + dy * dy) / 30.0 ** 2) ** -2.5
            img = core + 0.02 * wing
            img *= 16.0 * 0.99 / img.sum()       # pixel-spaced samples sum ~0.99
            planes.append(img)
            cards.append(("DET_YX%d" % k, "(%.1f, %.1f)" % (ny, nx)))
            k += 1
    h = fits.PrimaryHDU(np.array(planes, dtype=np.float32))
    for key, val in cards:
        h.header[key] = val
    h.header["NUM_PSFS"] = 9
    h.header["OVERSAMP"] = OVER
    h.header["PIXELSCL"] = 0.11 / OVER
    h.header["FILTER"] = "F129"
    h.header["DETECTOR"] = "SCA01"
    h.header["WFSKIND"] = "EPSF"
    h.writeto(path, overwrite=True)


def stars(scas, seed):
    rng = np.random.default_rng(seed)
    print("id,x,y,sca,flux")
    k = 0
    for sca in scas:
        pts = []
        for a in range(8):
            for b in range(8):
                # 1-based positions at eighth-pixel phases, anywhere
                pts.append((rng.integers(30, 4060) + a / 8, rng.integers(30, 4060) + b / 8))
        # on tile boundaries (256), in the corners, partly off every edge
        pts += [(256.5, 300.25), (512.5, 512.5), (1024.9, 768.1), (1.0, 1.0),
                (4088.0, 4088.0), (-10.3, 2000.0), (4100.7, 100.0), (2000, -15.2),
                (3000.0, 4099.9), (-21.0, -21.0)]
        for x, y in pts:
            k += 1
            print("%d,%.6f,%.6f,%d,%.6g" % (k, x, y, sca, 10 ** rng.uniform(0, 4)))


def read_grid(path):
    with fits.open(path) as h:
        data = h[0].data.astype(np.float64)
        hdr = h[0].header
        pos = []
        for k in range(data.shape[0]):
            y, x = [float(v) for v in hdr["DET_YX%d" % k].strip("() ").split(",")]
            pos.append((x - 4, y - 4))          # to the 0-based 4088 frame
    xs, ys = sorted({p[0] for p in pos}), sorted({p[1] for p in pos})
    nodes = {}
    for k, (x, y) in enumerate(pos):
        nodes[(xs.index(x), ys.index(y))] = data[k]
    return xs, ys, nodes


def bracket(a, v):
    if v <= a[0]:
        return 0, 0.0
    if v >= a[-1]:
        return len(a) - 2, 1.0
    i = max(j for j in range(len(a) - 1) if a[j] < v) if v > a[0] else 0
    return i, (v - a[i]) / (a[i + 1] - a[i])


def keys_np(t):
    return np.stack([-0.5 * t ** 3 + t * t - 0.5 * t, 1.5 * t ** 3 - 2.5 * t * t + 1,
                     -1.5 * t ** 3 + 2 * t * t + 0.5 * t, 0.5 * t ** 3 - 0.5 * t * t])


def blend_at(grid, x, y):
    """The ePSF bilinear in position between the four nodes about (x, y)."""
    xs, ys, nodes = grid
    ix, tx = bracket(xs, x)
    iy, ty = bracket(ys, y)
    return ((1 - tx) * (1 - ty) * nodes[(ix, iy)] + tx * (1 - ty) * nodes[(ix + 1, iy)] +
            (1 - tx) * ty * nodes[(ix, iy + 1)] + tx * ty * nodes[(ix + 1, iy + 1)])


class Box:
    """The pixels within C / OVER of a star at 0-based (x, y), the sample
    below each pixel centre (sx, sy) and its phase (fx, fy)."""

    def __init__(self, x, y):
        half = C / OVER
        i = np.arange(math.floor(x - half) + 1, math.ceil(x + half))
        j = np.arange(math.floor(y - half) + 1, math.ceil(y + half))
        self.I, self.J = np.meshgrid(i, j)
        rx, ry = C + OVER * (self.I - x), C + OVER * (self.J - y)
        self.sx, self.sy = np.floor(rx).astype(int), np.floor(ry).astype(int)
        self.fx, self.fy = rx - self.sx, ry - self.sy
        self.dx, self.dy = np.abs(self.I - x), np.abs(self.J - y)

    def bil(self, a):
        """Bilinear interpolation of a (padded by 2 zero samples)."""
        sx, sy, fx, fy = self.sx, self.sy, self.fx, self.fy
        return ((1 - fy) * ((1 - fx) * a[sy + 2, sx + 2] + fx * a[sy + 2, sx + 3]) +
                fy * ((1 - fx) * a[sy + 3, sx + 2] + fx * a[sy + 3, sx + 3]))

    def keys(self, a, m):
        """Keys' cubic of a (padded) at the pixels of mask m."""
        cx, cy = keys_np(self.fx[m]), keys_np(self.fy[m])
        sx, sy = self.sx[m], self.sy[m]
        return sum(cy[b] * cx[a_] * a[sy + 1 + b, sx + 1 + a_] for a_ in range(4) for b in range(4))

    def on_detector(self, v):
        I, J = self.I, self.J
        return float(v[(I >= 0) & (I < NPIX) & (J >= 0) & (J < NPIX)].sum())


def scaled(v, kv, core, t):
    """v with the core kv and everything else times the one factor that
    makes the box's total t."""
    u = v[~core].sum()
    f = (t - kv.sum()) / u if u > 0.01 * abs(t) else 1.0
    v = v * f
    v[core] = kv
    return v


def enclosed(grid, x, y):
    """Sum over the pixels a star at 0-based (x, y) lights on the detector,
    blended at the source (psf-blend=source): Keys' cubic within 4 pixels
    in x and y, bilinear beyond, scaled by the one factor that makes the
    box's total its bilinear sum."""
    ep = np.pad(blend_at(grid, x, y), 2)
    box = Box(x, y)
    r = 4.0 if 4 * OVER + 2 < C else 0.0
    v = box.bil(ep)
    core = (box.dx < r) & (box.dy < r)
    return box.on_detector(scaled(v, box.keys(ep, core), core, v.sum()))


def enclosed_default(grid, x, y, cell=512, core=4.0, wing=8.0):
    """The same for the default evaluation (psf-blend=core): the ePSF
    blended at the centre of the source's cell; in the core (within 4
    pixels in x and y) Keys' cubic of that plus the bilinear difference
    (blend at the source - the cell's); the cell's blend bilinear within 8
    pixels, its nearest sample beyond; all but the core scaled so that the
    box's total is the bilinear sum of the blend at the source."""
    cxy = [(math.floor(v / cell) + 0.5) * cell - 0.5 for v in (x, y)]
    ep = np.pad(blend_at(grid, x, y), 2)
    cp = np.pad(blend_at(grid, *cxy).astype(np.float32).astype(np.float64), 2)
    box = Box(x, y)
    incore = (box.dx < core) & (box.dy < core)
    inwing = (box.dx < wing) & (box.dy < wing)
    v = np.where(inwing, box.bil(cp),
                 cp[box.sy + 2 + (box.fy >= 0.5), box.sx + 2 + (box.fx >= 0.5)])
    kv = box.keys(cp, incore) + (box.bil(ep) - box.bil(cp))[incore]
    return box.on_detector(scaled(v, kv, incore, box.bil(ep).sum()))


def check(gridpath, catpath, imgpath, tol, default=False):
    grid = read_grid(gridpath)
    with fits.open(imgpath) as h:
        scas = {int(hdu.name[3:]) for hdu in h[1:]}
    # the expected sums of the image's SCAs (the catalog may have more)
    want = {}
    for r in csv.DictReader(open(catpath)):
        s = int(r["sca"])
        if s not in scas:
            continue
        want[s] = want.get(s, 0.0) + float(r["flux"]) * (enclosed_default if default else enclosed)(
            grid, float(r["x"]) - 1, float(r["y"]) - 1)
    worst = 0.0
    with fits.open(imgpath) as h:
        for hdu in h[1:]:
            s = int(hdu.name[3:])
            got = np.sum(hdu.data, dtype=np.float64)
            rel = abs(got / want[s] - 1)
            worst = max(worst, rel)
            if rel > tol:
                print("SCA %d: image %.10g, expected %.10g, relative %.3g" % (s, got, want[s], rel))
    print("worst relative difference %.3g over %d SCAs" % (worst, len(want)))
    return 0 if worst <= tol else 1


cmd = sys.argv[1]
if cmd == "grid":
    make_grid(sys.argv[2])
elif cmd == "stars":
    stars([int(s) for s in sys.argv[2].split(",")], int(sys.argv[3]))
elif cmd == "check-default":
    sys.exit(check(sys.argv[2], sys.argv[3], sys.argv[4], float(sys.argv[5]), default=True))
else:
    sys.exit(check(sys.argv[2], sys.argv[3], sys.argv[4], float(sys.argv[5])))
