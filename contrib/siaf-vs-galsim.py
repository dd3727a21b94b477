#!/usr/bin/python3
"""siaf-vs-galsim.py - how far apart the two public Roman distortion models
put sources: the SIAF (data/siaf.tsv, wfiscene's default geometry) and
GalSim's sip_20210204.txt with sca_positions_20210204.txt.

    /usr/bin/python3 contrib/siaf-vs-galsim.py [SHARED_ROMAN_DIR]

Both models are taken to a focal-plane tangent frame in arcsec over a grid
of pixels on every SCA:

  SIAF:   science pixel -> ideal (Sci2Idl) -> V2/V3 (tangent plane at
          V2Ref/V3Ref) -> the ideal frame of WFI_CEN (tangent plane at the
          boresight), as wfiscene does.
  GalSim: pixel offsets (x - 2044, y - 2044) -> degrees through the SIP
          polynomials of sip_20210204.txt (linear terms included), plus the
          SCA centre (crval_u, crval_v) of sca_positions_20210204.txt, in
          the WFI local frame (GalSim's own reading of the files).

GalSim's pixel axes and focal-plane axes need not be the SIAF's, and a user
points each model its own way, so the comparison first fits, over all
SCAs at once, the best similarity transform (offset, rotation, scale,
with either parity) from GalSim's focal plane to the SIAF's; what is left is
how far apart the two models put the same source after the best common
pointing, roll and plate scale.  A second fit per SCA (its own offset,
rotation and scale) shows the part that is the shape of each SCA's
distortion.  Per-SCA pixel flips between the models (GalSim's detector
versus the SIAF's science frame) are found by trying the four.
"""
import math
import os
import re
import sys

import numpy as np

roman = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
    os.path.dirname(__file__), "..", "..", "shared", "roman")
data = os.path.join(os.path.dirname(__file__), "..", "data")
AS = math.pi / 180 / 3600


def read_tsv(path):
    rows = [l.rstrip("\n").split("\t") for l in open(path) if not l.startswith("#")]
    head = rows[0]
    return [dict(zip(head, r)) for r in rows[1:]]


def siaf_focal(tab, sca, x, y):
    """wfiscene's table: 1-based science pixels -> WFI_CEN ideal arcsec."""
    a = tab[sca]
    u, v = x - float(a["xsciref"]), y - float(a["ysciref"])
    xi = sum(float(a["sx_%d_%d" % (i, j)]) * u ** (i - j) * v ** j
             for i in range(1, 6) for j in range(i + 1))
    yi = sum(float(a["sy_%d_%d" % (i, j)]) * u ** (i - j) * v ** j
             for i in range(1, 6) for j in range(i + 1))

    def frame(r):
        v2, v3 = float(r["v2ref"]) * AS, float(r["v3ref"]) * AS
        th, p = math.radians(float(r["v3idlyangle"])), float(r["vidlparity"])
        ut = np.array([math.cos(v3) * math.cos(v2), math.cos(v3) * math.sin(v2), math.sin(v3)])
        e2 = np.array([-math.sin(v2), math.cos(v2), 0])
        e3 = np.array([-math.sin(v3) * math.cos(v2), -math.sin(v3) * math.sin(v2), math.cos(v3)])
        return ut, p * (math.cos(th) * e2 - math.sin(th) * e3), math.sin(th) * e2 + math.cos(th) * e3

    ut, xt, yt = frame(a)
    w = ut[:, None] + np.outer(xt, xi * AS) + np.outer(yt, yi * AS)
    uc, xc, yc = frame(tab[0])
    d = uc @ w
    return (xc @ w) / d / AS, (yc @ w) / d / AS


def galsim_model(root):
    a = np.zeros((19, 5, 5))
    b = np.zeros((19, 5, 5))
    for line in open(os.path.join(root, "sip_20210204.txt")):
        f = line.split()
        if len(f) != 8:
            continue
        s, which, k = int(f[0]) + 1, f[1], int(f[2])
        (a if which == "a" else b)[s, k, :] = [float(t) for t in f[3:]]
    cen = {}
    for line in open(os.path.join(root, "sca_positions_20210204.txt")):
        f = line.split()
        if len(f) == 7 and not line.startswith("#"):
            cen[int(f[0])] = (float(f[5]), float(f[6]))
    return a, b, cen


def galsim_focal(model, sca, x, y):
    """GalSim: pixel offsets from 2044 -> WFI local frame, arcsec.  As
    GalSim reads the file, the terms of degree >= 2 are SIP A/B in pixels
    and the linear ones the CD matrix in degrees per pixel."""
    a, b, cen = model
    u, v = x - 2044.0, y - 2044.0
    du = sum(a[sca, i, j] * u ** i * v ** j for i in range(5) for j in range(5) if i + j >= 2)
    dv = sum(b[sca, i, j] * u ** i * v ** j for i in range(5) for j in range(5) if i + j >= 2)
    u, v = u + du, v + dv
    U = a[sca, 1, 0] * u + a[sca, 0, 1] * v
    V = b[sca, 1, 0] * u + b[sca, 0, 1] * v
    return (-cen[sca][0] + U) * 3600, (cen[sca][1] + V) * 3600


def fit_similarity(p, q, parity):
    """q ~ s R (parity p) + t; complex least squares.  Returns the fitted p
    and the parameters."""
    zp = p[:, 0] + (1j if parity > 0 else -1j) * p[:, 1]
    zq = q[:, 0] + 1j * q[:, 1]
    M = np.stack([zp, np.ones_like(zp)], axis=1)
    c, *_ = np.linalg.lstsq(M, zq, rcond=None)
    z = M @ c
    return np.stack([z.real, z.imag], axis=1), c


def main():
    tab = {int(r["sca"]): r for r in read_tsv(os.path.join(data, "siaf.tsv"))}
    model = galsim_model(roman)
    g = np.linspace(1, 4088, 21)
    gx, gy = [t.ravel() for t in np.meshgrid(g, g)]
    # the parity of GalSim's focal frame against the SIAF's, from the SCA
    # centres alone
    sc = np.array([siaf_focal(tab, k, np.array([2044.5]), np.array([2044.5])) for k in
                   range(1, 19)])[:, :, 0]
    gc = np.array([[-model[2][k][0] * 3600, model[2][k][1] * 3600] for k in range(1, 19)])
    res = {}
    for par in (1, -1):
        fit, _ = fit_similarity(gc, sc, par)
        res[par] = np.max(np.hypot(*(fit - sc).T))
    par = min(res, key=res.get)
    S, G, who = [], [], []
    flips = {}
    for sca in range(1, 19):
        sx, sy = siaf_focal(tab, sca, gx, gy)
        best = None
        # which of GalSim's pixel orientations matches the SIAF's frame
        for fx in (False, True):
            for fy in (False, True):
                px = 4089 - gx if fx else gx
                py = 4089 - gy if fy else gy
                ux, uy = galsim_focal(model, sca, px, py)
                fit, _ = fit_similarity(np.stack([ux, uy], 1), np.stack([sx, sy], 1), par)
                r = np.max(np.hypot(fit[:, 0] - sx, fit[:, 1] - sy))
                if best is None or r < best[0]:
                    best = (r, fx, fy, ux, uy)
        flips[sca] = best[1:3]
        S.append(np.stack([sx, sy], 1))
        G.append(np.stack([best[3], best[4]], 1))
        who += [sca] * len(gx)
    S, G, who = np.concatenate(S), np.concatenate(G), np.array(who)
    fit, c = fit_similarity(G, S, par)
    d = np.hypot(fit[:, 0] - S[:, 0], fit[:, 1] - S[:, 1])
    scale = abs(c[0])
    rot = math.degrees(np.angle(c[0]))
    px = 0.11
    print("GalSim pixel flips to match the SIAF science frame (x, y): " +
          ", ".join("%d:%s%s" % (s, "x" if f[0] else "-", "y" if f[1] else "-")
                    for s, f in flips.items()))
    print("SCA centres alone: residual %.2f px with parity %+d, %.2f px with %+d"
          % (res[par] / 0.11, par, res[-par] / 0.11, -par))
    print("one fit over the focal plane: parity %+d, rotation %.4f deg, scale %.6f"
          % (par, rot, scale))
    print("| SCA | common fit: median | max (px) | own fit per SCA: max (px) |")
    print("|---|---|---|---|")
    allown = []
    for sca in range(1, 19):
        k = who == sca
        fit, _ = fit_similarity(G[k], S[k], par)
        own = np.hypot(fit[:, 0] - S[k, 0], fit[:, 1] - S[k, 1])
        allown.append(own.max())
        print("| %d | %.2f | %.2f | %.3f |" % (sca, np.median(d[k]) / px, d[k].max() / px,
                                             own.max() / px))
    # the non-linear part of each model alone, in pixels at the corners
    nl_g, nl_s = 0.0, 0.0
    a, b, _ = model
    for sca in range(1, 19):
        u, v = gx - 2044.0, gy - 2044.0
        du = sum(a[sca, i, j] * u ** i * v ** j for i in range(5) for j in range(5) if i + j >= 2)
        dv = sum(b[sca, i, j] * u ** i * v ** j for i in range(5) for j in range(5) if i + j >= 2)
        nl_g = max(nl_g, np.max(np.hypot(du, dv)))
        r = tab[sca]
        u, v = gx - 2044.5, gy - 2044.5
        L = np.array([[float(r["sx_1_0"]), float(r["sx_1_1"])], [float(r["sy_1_0"]), float(r["sy_1_1"])]])
        nx = sum(float(r["sx_%d_%d" % (i, j)]) * u ** (i - j) * v ** j
                 for i in range(2, 6) for j in range(i + 1))
        ny = sum(float(r["sy_%d_%d" % (i, j)]) * u ** (i - j) * v ** j
                 for i in range(2, 6) for j in range(i + 1))
        q = np.linalg.solve(L, np.stack([nx, ny]))
        nl_s = max(nl_s, np.max(np.hypot(q[0], q[1])))
    print("non-linear terms alone move a pixel by at most: SIAF %.2f px, GalSim %.4f px"
          % (nl_s, nl_g))
    print("all SCAs: common fit median %.2f px, max %.2f px; per-SCA fit max %.3f px"
          % (np.median(d) / px, d.max() / px, max(allown) / px))


if __name__ == "__main__":
    main()
