#!/usr/bin/python3
"""An artificial-star test with wfiscene --into, end to end.

1. The field: a simulated crowded exposure of one SCA (wfiscene, with
   background and all noise), or an image you give (--image, one HDU
   WFInn, counts/s).
2. Artificial stars on a jittered grid (no two closer than --spacing
   pixels, so they do not crowd each other), magnitudes uniform in
   [--mag-min, --mag-max], added with wfiscene --into and the photon noise
   of the light added.
3. Detection with sep (background map, threshold --thresh sigma, 5 pixels)
   on the image before and after; an artificial star is recovered when a new
   detection (none in the image before within --radius pixels) lies within
   --radius pixels of it and its flux is within 0.75 mag of the input.
4. Completeness against magnitude: a table on stdout, the magnitude of 50 %
   completeness, and a plot (completeness.png).

    contrib/injection/artificial-stars.py --wfiscene build/wfiscene \\
        --stars 2000 --out ast

It prints the seconds wfiscene took to inject the stars and the cost per
injected star (BENCHMARKS.md).
"""
import argparse
import math
import os
import subprocess
import sys
import time

import numpy as np
from astropy.io import fits
import sep


def run(cmd, **kw):
    print("+", " ".join(cmd), file=sys.stderr)
    subprocess.run(cmd, check=True, **kw)


def make_field(a, out):
    """A crowded field: a power law of stars over the SCA, with noise."""
    rng = np.random.default_rng(a.seed)
    n = a.field_stars
    # dN/dm ~ 10^(0.3 m) between 18 and 27
    u = rng.random(n)
    k = 0.3 * math.log(10)
    m = np.log(np.exp(k * 18) + u * (np.exp(k * 27) - np.exp(k * 18))) / k
    cat = os.path.join(out, "field.csv")
    with open(cat, "w") as f:
        f.write("x,y,mag\n")
        for x, y, mm in zip(rng.uniform(-10, 4098, n), rng.uniform(-10, 4098, n), m):
            f.write("%.3f,%.3f,%.3f\n" % (x, y, mm))
    img = os.path.join(out, "field.fits")
    run([a.wfiscene, "--filter", a.filter, "--sca", str(a.sca), "--exptime", str(a.exptime),
         "--background", "avg", "--noise", "all", "--seed", str(a.seed), "-q",
         "-o", img, cat])
    return img


def artificial(a, out):
    """Stars on a jittered grid, magnitudes uniform."""
    rng = np.random.default_rng(a.seed + 1)
    side = max(1, int(math.ceil(math.sqrt(a.stars))))
    step = 4000.0 / side
    if step < a.spacing:
        sys.exit("artificial-stars: %d stars do not fit %g pixels apart; "
                 "run several passes" % (a.stars, a.spacing))
    cells = rng.permutation(side * side)[:a.stars]
    x = 44 + (cells % side + 0.5) * step + rng.uniform(-0.25, 0.25, a.stars) * (step - a.spacing)
    y = 44 + (cells // side + 0.5) * step + rng.uniform(-0.25, 0.25, a.stars) * (step - a.spacing)
    m = rng.uniform(a.mag_min, a.mag_max, a.stars)
    cat = os.path.join(out, "artificial.csv")
    with open(cat, "w") as f:
        f.write("id,x,y,sca,mag\n")
        for i in range(a.stars):
            f.write("%d,%.3f,%.3f,%d,%.4f\n" % (i + 1, x[i], y[i], a.sca, m[i]))
    return cat, x, y, m


def detect(data, thresh):
    d = data.astype(np.float64)
    bkg = sep.Background(d, bw=64, bh=64)
    sub = d - bkg.back()
    sep.set_extract_pixstack(5000000)
    sep.set_sub_object_limit(4096)
    obj = sep.extract(sub, thresh, err=bkg.globalrms, minarea=5)
    flux, _, _ = sep.sum_circle(sub, obj["x"], obj["y"], 3.0, err=bkg.globalrms)
    return obj["x"], obj["y"], flux


def nearest(xa, ya, xb, yb):
    """For each (xa, ya): distance to and index of the nearest (xb, yb)."""
    order = np.argsort(yb)
    ys = yb[order]
    dist = np.full(len(xa), np.inf)
    idx = np.full(len(xa), -1)
    for i, (x, y) in enumerate(zip(xa, ya)):
        lo, hi = np.searchsorted(ys, [y - 3, y + 3])
        if hi > lo:
            j = order[lo:hi]
            d = np.hypot(xb[j] - x, yb[j] - y)
            k = np.argmin(d)
            dist[i], idx[i] = d[k], j[k]
    return dist, idx


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--wfiscene", default="wfiscene")
    p.add_argument("--image", help="the field (default: simulate one)")
    p.add_argument("--out", default="ast")
    p.add_argument("--filter", default="F158")
    p.add_argument("--sca", type=int, default=1)
    p.add_argument("--exptime", type=float, default=139.8)
    p.add_argument("--field-stars", type=int, default=100000)
    p.add_argument("--stars", type=int, default=2000)
    p.add_argument("--mag-min", type=float, default=21.0)
    p.add_argument("--mag-max", type=float, default=28.0)
    p.add_argument("--spacing", type=float, default=30.0)
    p.add_argument("--thresh", type=float, default=1.5)
    p.add_argument("--radius", type=float, default=1.0)
    p.add_argument("--seed", type=int, default=42)
    p.add_argument("--zeropoint", type=float,
                   help="AB mag of 1 count/s (default: the image's PHOTZPAB)")
    a = p.parse_args()
    os.makedirs(a.out, exist_ok=True)

    img = a.image or make_field(a, a.out)
    cat, x, y, m = artificial(a, a.out)
    inj = os.path.join(a.out, "injected.fits")
    report = os.path.join(a.out, "report.json")
    t0 = time.monotonic()
    run([a.wfiscene, "--filter", a.filter, "--sca", str(a.sca), "--into", img,
         "--exptime", str(a.exptime), "--noise", "poisson", "--seed", str(a.seed + 2),
         "--placed", os.path.join(a.out, "placed.csv"), "--report", report, "-q",
         "-o", inj, cat])
    t_inject = time.monotonic() - t0

    ext = "WFI%02d" % a.sca
    with fits.open(img) as f:
        before = f[ext].data if ext in f else f[0].data
        zp = f[ext].header.get("PHOTZPAB") if ext in f else None
    with fits.open(inj) as f:
        after = f[ext].data if ext in f else f[0].data
    t0 = time.monotonic()
    bx, by, _ = detect(before, a.thresh)
    ax, ay, af = detect(after, a.thresh)
    t_detect = time.monotonic() - t0
    zp = a.zeropoint if a.zeropoint is not None else zp
    if zp is None:
        sys.exit("artificial-stars: the image has no PHOTZPAB: give --zeropoint")

    # wfiscene's x, y are 1-based; sep's are 0-based
    d_new, j = nearest(x - 1, y - 1, ax, ay)
    d_old, _ = nearest(x - 1, y - 1, bx, by)
    mag_meas = np.where(j >= 0, zp - 2.5 * np.log10(np.clip(af[j], 1e-30, None)), np.inf)
    # the 3-pixel aperture holds about 80 % of a point source's light
    ok = (d_new < a.radius) & ~(d_old < a.radius) & (np.abs(mag_meas - m - 0.25) < 0.75)

    edges = np.arange(a.mag_min, a.mag_max + 0.25, 0.5)
    centre = 0.5 * (edges[1:] + edges[:-1])
    comp = []
    print("# mag   injected recovered completeness")
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (m >= lo) & (m < hi)
        c = ok[sel].mean() if sel.any() else float("nan")
        comp.append(c)
        print("%6.2f %9d %9d %8.3f" % (0.5 * (lo + hi), sel.sum(), ok[sel].sum(), c))
    comp = np.array(comp)
    half = float("nan")
    for k in range(1, len(comp)):
        if comp[k - 1] >= 0.5 > comp[k]:
            half = centre[k - 1] + (comp[k - 1] - 0.5) / (comp[k - 1] - comp[k]) * (centre[k] - centre[k - 1])
            break
    print("# 50%% completeness at %s = %.2f AB" % (a.filter, half))
    print("# injecting %d stars took %.3f s (%.1f us a star, all included); detection %.2f s"
          % (a.stars, t_inject, 1e6 * t_inject / a.stars, t_detect))

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(centre, comp, "o-")
    ax.axhline(0.5, color="grey", lw=0.5)
    ax.set_xlabel("%s AB magnitude (input)" % a.filter)
    ax.set_ylabel("completeness")
    ax.set_title("artificial stars: %d into SCA %d, %g s" % (a.stars, a.sca, a.exptime))
    ax.set_ylim(-0.02, 1.02)
    fig.tight_layout()
    fig.savefig(os.path.join(a.out, "completeness.png"), dpi=100)


if __name__ == "__main__":
    main()
