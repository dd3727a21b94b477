#!/usr/bin/python3
"""distortion-figure.py - how far each pixel of the SIAF geometry moves from
a square grid, drawn over the WFI focal plane (contrib/bench/distortion.png,
referred to by wfiscene(1) GEOMETRY and BENCHMARKS.md).

    /usr/bin/python3 contrib/distortion-figure.py -o contrib/bench/distortion.png

Reads only data/siaf.tsv.  Left: the distance, in pixels, between where the
SIAF geometry puts each pixel and where --geometry stips puts it (0.11"
square pixels aligned with the focal plane about the same SCA centre): the
different scales, rotations and distortion together.  Right: the
non-linear part alone, what is left after the best affine map of each SCA
(its own scales, skew and rotation), i.e. how far the optical distortion
bends each SCA's pixel grid.  Both over the ideal frame of WFI_CEN
(boresight at the origin, +y_idl up, arcsec).
"""
import argparse
import math
import os

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

AS = math.pi / 180 / 3600
DATA = os.path.join(os.path.dirname(__file__), "..", "data", "siaf.tsv")


def table():
    rows = [l.rstrip("\n").split("\t") for l in open(DATA) if not l.startswith("#")]
    return {int(r[1]): dict(zip(rows[0], r)) for r in rows[1:]}


def frame(r):
    v2, v3 = float(r["v2ref"]) * AS, float(r["v3ref"]) * AS
    th, p = math.radians(float(r["v3idlyangle"])), float(r["vidlparity"])
    ut = np.array([math.cos(v3) * math.cos(v2), math.cos(v3) * math.sin(v2), math.sin(v3)])
    e2 = np.array([-math.sin(v2), math.cos(v2), 0])
    e3 = np.array([-math.sin(v3) * math.cos(v2), -math.sin(v3) * math.sin(v2), math.cos(v3)])
    return ut, p * (math.cos(th) * e2 - math.sin(th) * e3), math.sin(th) * e2 + math.cos(th) * e3


def to_cen(tab, sca, xi, yi):
    """SCA ideal arcsec -> WFI_CEN ideal arcsec."""
    ut, xt, yt = frame(tab[sca])
    w = ut[:, None] + np.outer(xt, np.ravel(xi) * AS) + np.outer(yt, np.ravel(yi) * AS)
    uc, xc, yc = frame(tab[0])
    d = uc @ w
    return ((xc @ w) / d / AS).reshape(np.shape(xi)), ((yc @ w) / d / AS).reshape(np.shape(xi))


def sci2idl(r, u, v):
    xi = sum(float(r["sx_%d_%d" % (i, j)]) * u ** (i - j) * v ** j
             for i in range(1, 6) for j in range(i + 1))
    yi = sum(float(r["sy_%d_%d" % (i, j)]) * u ** (i - j) * v ** j
             for i in range(1, 6) for j in range(i + 1))
    return xi, yi


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("-o", default="distortion.png")
    a = ap.parse_args()
    tab = table()
    n = 41
    g = np.linspace(-2043.5, 2043.5, n)
    u, v = np.meshgrid(g, g)
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.6), constrained_layout=True)
    total, nonlin = [], []
    for sca in range(1, 19):
        r = tab[sca]
        xi, yi = sci2idl(r, u, v)
        fx, fy = to_cen(tab, sca, xi, yi)
        cx, cy = to_cen(tab, sca, np.zeros(1), np.zeros(1))
        # stips: 0.11" square pixels along the focal-plane axes
        d_total = np.hypot(fx - (cx + 0.11 * u), fy - (cy + 0.11 * v)) / 0.11
        # the best affine map of this SCA, removed
        M = np.stack([u.ravel(), v.ravel(), np.ones(u.size)], 1)
        cxf, *_ = np.linalg.lstsq(M, fx.ravel(), rcond=None)
        cyf, *_ = np.linalg.lstsq(M, fy.ravel(), rcond=None)
        scale = math.sqrt(abs(np.linalg.det(np.array([cxf[:2], cyf[:2]]))))
        d_nl = np.hypot(fx.ravel() - M @ cxf, fy.ravel() - M @ cyf).reshape(u.shape) / scale
        total.append((fx, fy, d_total, sca))
        nonlin.append((fx, fy, d_nl, sca))
    for ax, sets, title in ((axes[0], total, "SIAF against 0.11\" square aligned pixels"),
                            (axes[1], nonlin, "non-linear part (each SCA's affine map removed)")):
        vmax = max(s[2].max() for s in sets)
        for fx, fy, d, sca in sets:
            m = ax.pcolormesh(fx, fy, d, vmin=0, vmax=vmax, cmap="viridis", shading="gouraud")
            ax.text(fx.mean(), fy.mean(), "%d" % sca, ha="center", va="center", color="w",
                    fontsize=9)
        ax.set_aspect("equal")
        ax.set_title(title)
        ax.set_xlabel("x_idl of WFI_CEN (arcsec)")
        ax.set_ylabel("y_idl of WFI_CEN (arcsec)")
        fig.colorbar(m, ax=ax, label="pixels moved (max %.1f)" % vmax, shrink=0.85)
    fig.savefig(a.o, dpi=90)
    print("total: max %.1f px; non-linear: max %.2f px"
          % (max(s[2].max() for s in total), max(s[2].max() for s in nonlin)))


if __name__ == "__main__":
    main()
