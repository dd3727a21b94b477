#!/usr/bin/python3
"""Photometry and astrometry of injected stars, as the STIPS paper's section 3.

    photometry.py [--n 1000] [--seed 1] [--wfs build/wfiscene] [--dir DIR]
                  [--methods sep,gauss,epsf] [--table RESULTS.md] [--plot out.png]
                  [--json summary.json]

Draws N point sources, magnitudes uniform in [15, 26] AB, at uniform random
1-based pixel positions on SCA01 (kept 30 pixels from the edges so that
every fit box is whole) in F129, with the paper's background and noise:

    wfiscene --filter F129 --sca 1 --geometry stips --set psf-extent=E
        --background avg --noise all
        --exptime 139.8 --seed S --placed placed.csv

(E is noise, the default, or stips with --extent stips; --noiseless draws
no background and no noise, for the ePSF fit alone)

and recovers them three ways, as the paper does:

  sep     Source Extractor's library: sep.Background, then sep.extract on
          the background-subtracted image (threshold 1.5 sigma); the
          isophotal flux and the first-moment centroid of the detection
          nearest each star (within 1.5 px).
  gauss   astropy.modeling: Gaussian2D plus a constant, fitted by
          LevMarLSQFitter to the 11 x 11 pixels about each star.  Flux is
          2 pi A sigma_x sigma_y.
  epsf    photutils' GriddedPSFModel made from the grid `wfiscene psf --kind
          epsf` writes (grid_xypos from DET_YX less the 4 reference pixels,
          oversampling from OVERSAMP), i.e. the very ePSF that drew the
          stars; flux and position fitted by LevMarLSQFitter to the 11 x 11
          background-subtracted pixels about each star, weighted by the
          pixel noise.  photutils 1.6 uses the local ePSF's samples as they
          are (not renormalised), and a sample of wfiscene's ePSF is the
          fraction of the flux in a pixel centred there, so the fitted flux
          is the catalog flux, the light outside the box included.  The local
          ePSF (bilinear between the four grid nodes, as wfiscene does) is
          built once per star, at its catalog position: it changes by far
          less than the noise over the fraction of a pixel the fit moves.
          The grid is normalised within its box, as STIPS's; drawn to the
          noise (psf-extent=noise), a star's box holds the optics' light
          there and the rest lies beyond it, so the fitted fluxes are
          divided by the fit's reading of noiseless bright stars
          (calibrate(): 0.978 in F129, the aperture correction photometry
          takes from bright stars); 1 with --extent stips.

Truth is the --placed list: 1-based (x, y) and the flux in counts/s of each
star on SCA01.  Residuals are recovered minus true: magnitudes
-2.5 log10(F_rec / F_true), positions in pixels.  Stars that a method does
not recover (not detected, fit failed) are counted, not hidden.

Prints a summary (JSON with --json) and writes a Markdown table and a plot
when asked.  Exit status 0, or 1 if a step fails.
"""
import argparse
import json
import os
import subprocess
import sys
import time
import warnings

import numpy as np
from astropy.io import fits

FILTER = "F129"
EXPTIME = 139.8
BOX = 11                       # fit box side, pixels
HALF = BOX // 2
EDGE = 30                      # stars this far from the edges
NPIX = 4088
BINS = [(15, 17), (17, 19), (19, 21), (21, 23), (23, 24.5), (24.5, 26)]

# The STIPS paper's figures (section 3.1-3.2), for the side-by-side table.
PAPER = {
    "sep": "centroid offset ~0.1 px (asymmetric PSF); magnitudes fine when "
           "bright, increasingly off when faint",
    "gauss": "~0.5 mag offset, nearly independent of magnitude; no position "
             "offset, pixel-phase structure, ~0.009 px after removing it",
    "epsf": "~0.06 mag mean deviation; ~0.004 px position accuracy "
            "(stars brighter than 21)",
}

# The same figures drawn on the plot, dashed: magnitude levels (lines at
# each value) and position radii (a circle of that radius about the
# origin; for sep the size of the centroid offset, else the scatter).
PAPER_MAG = {"sep": [], "gauss": [0.5], "epsf": [-0.06, 0.06]}
PAPER_POS = {"sep": 0.1, "gauss": 0.009, "epsf": 0.004}


def run(cmd, **kw):
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, **kw)
    if r.returncode != 0:
        sys.exit("photometry.py: %s: exit %d: %s" % (cmd[0], r.returncode,
                                                    r.stderr.decode().strip()))
    return r


def noise_opts(args):
    if args.noiseless:
        return ["--background", "none", "--noise", "none"]
    return ["--background", "avg", "--noise", "all"]


def calibrate(args, psf):
    """The ePSF's light within its box as the point model draws it: the
    fitted over the true flux of 25 noiseless 16 mag stars spread over the
    SCA, the median.  The grids `wfiscene psf` writes are normalised within
    their boxes (STIPS's convention); under psf-extent=noise the box holds
    the optics' light there and the rest lies beyond, as on the sky, so an
    ePSF fit reads every star by this factor, which photometry calibrates
    on bright stars (an aperture correction).  1 with psf-extent=stips."""
    if args.extent == "stips":
        return 1.0
    cat = os.path.join(args.dir, "cal.csv")
    img = os.path.join(args.dir, "cal.fits")
    placed = os.path.join(args.dir, "cal-placed.csv")
    g = np.linspace(400, NPIX - 400, 5)
    with open(cat, "w") as f:
        f.write("id,x,y,mag\n")
        k = 0
        for yy in g:
            for xx in g:
                k += 1
                f.write("%d,%.4f,%.4f,16\n" % (k, xx + 0.13 * k % 1, yy + 0.29 * k % 1))
    run([args.wfs, "--filter", FILTER, "--sca", "1", "--geometry", "stips",
         "--set", "psf-extent=" + args.extent, "--background", "none", "--noise", "none",
         "--exptime", str(EXPTIME), "--placed", placed, "-o", img, cat])
    t = np.genfromtxt(placed, delimiter=",", names=True, dtype=None, encoding="ascii")
    data = load(img)[0]
    f = method_epsf(data, np.ones_like(data), t, psf)[0]
    return float(np.median(f / t["flux"]))


def make_scene(args):
    rng = np.random.default_rng(args.seed)
    n = args.n
    x = rng.uniform(1 + EDGE, NPIX - EDGE, n)
    y = rng.uniform(1 + EDGE, NPIX - EDGE, n)
    mag = rng.uniform(15.0, 26.0, n)
    cat = os.path.join(args.dir, "stars.csv")
    with open(cat, "w") as f:
        f.write("id,x,y,mag\n")
        for i in range(n):
            f.write("%d,%.4f,%.4f,%.4f\n" % (i + 1, x[i], y[i], mag[i]))
    img = os.path.join(args.dir, "scene.fits")
    placed = os.path.join(args.dir, "placed.csv")
    psf = os.path.join(args.dir, "epsf.fits")
    t0 = time.time()
    # the paper's setting: STIPS's geometry (a flat background per pixel),
    # with the point model's default extent (each star drawn to the noise,
    # the light beyond spread as diffuse light) or STIPS's PSF boxes
    run([args.wfs, "--filter", FILTER, "--sca", "1", "--geometry", "stips",
         "--set", "psf-extent=" + args.extent] + noise_opts(args) +
        ["--exptime", str(EXPTIME), "--seed", str(args.seed),
         "--placed", placed, "-o", img, cat])
    t1 = time.time()
    run([args.wfs, "psf", "--filter", FILTER, "--sca", "1", "--kind", "epsf",
         "-o", psf])
    t = np.genfromtxt(placed, delimiter=",", names=True, dtype=None,
                      encoding="ascii")
    order = np.argsort(t["id"])
    t = t[order]
    return img, psf, t, t1 - t0


def load(img):
    with fits.open(img) as h:
        data = h[1].data.astype(np.float64)
        hdr = h[1].header
    return data, hdr


def method_sep(sub, rms, truth):
    import sep
    from scipy.spatial import cKDTree
    sep.set_extract_pixstack(5000000)
    obj = sep.extract(np.ascontiguousarray(sub.astype(np.float32)), 1.5, err=rms,
                      minarea=5)
    tree = cKDTree(np.column_stack([obj["x"] + 1, obj["y"] + 1]))
    d, k = tree.query(np.column_stack([truth["x"], truth["y"]]))
    ok = (d < 1.5) & (obj["flux"][np.minimum(k, len(obj) - 1)] > 0)
    n = len(truth)
    flux = np.full(n, np.nan)
    xr = np.full(n, np.nan)
    yr = np.full(n, np.nan)
    flux[ok] = obj["flux"][k[ok]]
    xr[ok] = obj["x"][k[ok]] + 1
    yr[ok] = obj["y"][k[ok]] + 1
    return flux, xr, yr


def cutout(img, x1, y1):
    """The BOX x BOX pixels about 1-based (x1, y1): data, 0-based x, y grids."""
    ix = int(round(x1 - 1))
    iy = int(round(y1 - 1))
    sl = (slice(iy - HALF, iy + HALF + 1), slice(ix - HALF, ix + HALF + 1))
    yy, xx = np.mgrid[sl]
    return img[sl], xx.astype(float), yy.astype(float)


def method_gauss(sub, truth):
    from astropy.modeling import fitting, models
    fitter = fitting.LevMarLSQFitter()
    n = len(truth)
    flux = np.full(n, np.nan)
    xr = np.full(n, np.nan)
    yr = np.full(n, np.nan)
    for i in range(n):
        d, xx, yy = cutout(sub, truth["x"][i], truth["y"][i])
        x0, y0 = truth["x"][i] - 1, truth["y"][i] - 1
        amp = max(d[HALF, HALF], 1e-3)
        g = models.Gaussian2D(amplitude=amp, x_mean=x0, y_mean=y0,
                              x_stddev=0.7, y_stddev=0.7,
                              bounds={"x_stddev": (0.2, 4.0), "y_stddev": (0.2, 4.0)}
                              ) + models.Const2D(0.0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                f = fitter(g, xx, yy, d, maxiter=200)
            except Exception:
                continue
        a, sx, sy = f.amplitude_0.value, f.x_stddev_0.value, f.y_stddev_0.value
        if not (np.isfinite(a) and a > 0 and abs(f.x_mean_0.value - x0) < 2
                and abs(f.y_mean_0.value - y0) < 2):
            continue
        flux[i] = 2 * np.pi * a * abs(sx * sy)
        xr[i] = f.x_mean_0.value + 1
        yr[i] = f.y_mean_0.value + 1
    return flux, xr, yr


def gridded_model(psf):
    from astropy.nddata import NDData
    from photutils.psf import GriddedPSFModel
    with fits.open(psf) as h:
        data = h[0].data.astype(np.float64)
        hdr = h[0].header
    xy = []
    for k in range(hdr["NUM_PSFS"]):
        yd, xd = (float(v) for v in hdr["DET_YX%d" % k].strip("()").split(","))
        xy.append((xd - 4.0, yd - 4.0))      # 4096-pixel frame -> science, 0-based
    nd = NDData(data, meta={"grid_xypos": xy, "oversampling": hdr["OVERSAMP"]})
    return GriddedPSFModel(nd)


def method_epsf(sub, sigma, truth, psf):
    from astropy.modeling import fitting
    gm = gridded_model(psf)
    fitter = fitting.LevMarLSQFitter()
    n = len(truth)
    flux = np.full(n, np.nan)
    xr = np.full(n, np.nan)
    yr = np.full(n, np.nan)
    for i in range(n):
        x0, y0 = truth["x"][i] - 1, truth["y"][i] - 1
        d, xx, yy = cutout(sub, truth["x"][i], truth["y"][i])
        s = cutout(sigma, truth["x"][i], truth["y"][i])[0]
        # The local ePSF at the star, as GriddedPSFModel.evaluate builds it
        # on every call; built once here (see the module comment).
        local = gm._compute_local_model(x0, y0)
        local.flux = max(float(np.sum(d)), 1e-3)
        local.x_0 = x0
        local.y_0 = y0
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                f = fitter(local, xx, yy, d, weights=1.0 / s, maxiter=200)
            except Exception:
                continue
        if not (np.isfinite(f.flux.value) and f.flux.value > 0
                and abs(f.x_0.value - x0) < 2 and abs(f.y_0.value - y0) < 2):
            continue
        flux[i] = f.flux.value
        xr[i] = f.x_0.value + 1
        yr[i] = f.y_0.value + 1
    return flux, xr, yr


def robust_sigma(v):
    v = v[np.isfinite(v)]
    if len(v) < 2:
        return float("nan")
    return float(1.4826 * np.median(np.abs(v - np.median(v))))


def stats(truth, flux, xr, yr):
    dm = -2.5 * np.log10(flux / truth["flux"])
    dx = xr - truth["x"]
    dy = yr - truth["y"]
    out = {"n": int(len(truth)), "recovered": int(np.sum(np.isfinite(dm))),
           "bins": []}
    for lo, hi in BINS + [(15, 21), (15, 26)]:
        sel = (truth["mag"] >= lo) & (truth["mag"] < hi) & np.isfinite(dm)
        nsel = int(np.sum((truth["mag"] >= lo) & (truth["mag"] < hi)))
        b = {"lo": lo, "hi": hi, "n": nsel, "rec": int(np.sum(sel))}
        if np.sum(sel) >= 2:
            b.update(
                dm_mean=float(np.mean(dm[sel])), dm_median=float(np.median(dm[sel])),
                dm_std=float(np.std(dm[sel])), dm_abs=float(np.mean(np.abs(dm[sel]))),
                dx_mean=float(np.mean(dx[sel])), dy_mean=float(np.mean(dy[sel])),
                dx_rsig=robust_sigma(dx[sel]), dy_rsig=robust_sigma(dy[sel]),
                dx_std=float(np.std(dx[sel])), dy_std=float(np.std(dy[sel])))
        out["bins"].append(b)
    # The paper removes the pixel-phase structure of the Gaussian fit's
    # positions before quoting its scatter: subtract the median residual in
    # ten bins of pixel phase (per axis), stars brighter than 21.
    sel = (truth["mag"] < 21) & np.isfinite(dx)
    rs = []
    for d, p in ((dx, truth["x"]), (dy, truth["y"])):
        ph = np.floor(((p[sel] - 0.5) % 1.0) * 10).astype(int)
        r = d[sel].copy()
        for k in range(10):
            if np.any(ph == k):
                r[ph == k] -= np.median(r[ph == k])
        rs.append(robust_sigma(r))
    out["phase_corrected_sigma"] = rs
    return out, dm, dx, dy


NAMES = {"sep": "sep (isophotal flux, centroid)",
         "gauss": "Gaussian2D fit (astropy)",
         "epsf": "ePSF fit (photutils GriddedPSFModel)"}


def table(summary):
    lines = []
    for m, s in summary["methods"].items():
        lines.append("### %s\n" % NAMES[m])
        lines.append("Recovered %d of %d.  Paper: %s.\n" % (s["recovered"], s["n"],
                                                          PAPER[m]))
        lines.append("Position scatter of stars brighter than 21 after removing "
                     "the pixel-phase structure: %.4f px (x), %.4f px (y).\n"
                     % tuple(s["phase_corrected_sigma"]))
        lines.append("| mag | N | rec | mean dm | median dm | std dm | mean abs dm "
                     "| mean dx | mean dy | sigma dx | sigma dy |")
        lines.append("|---|---|---|---|---|---|---|---|---|---|---|")
        for b in s["bins"]:
            if "dm_mean" not in b:
                lines.append("| %g-%g | %d | %d | | | | | | | | |" % (
                    b["lo"], b["hi"], b["n"], b["rec"]))
                continue
            lines.append(
                "| %g-%g | %d | %d | %+.4f | %+.4f | %.4f | %.4f | %+.4f | %+.4f "
                "| %.4f | %.4f |" % (b["lo"], b["hi"], b["n"], b["rec"], b["dm_mean"],
                                     b["dm_median"], b["dm_std"], b["dm_abs"],
                                     b["dx_mean"], b["dy_mean"], b["dx_rsig"],
                                     b["dy_rsig"]))
        lines.append("")
    return "\n".join(lines)


def plot(path, truth, res):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ms = list(res)
    fig, ax = plt.subplots(2, len(ms), figsize=(4.6 * len(ms), 8), squeeze=False)
    bright = truth["mag"] < 21
    for j, m in enumerate(ms):
        dm, dx, dy = res[m]
        a = ax[0][j]
        a.scatter(truth["mag"], dm, s=4, c="k")
        a.axhline(0, color="r", lw=0.8)
        for k, v in enumerate(PAPER_MAG[m]):
            a.axhline(v, color="g", lw=1.0, ls="--",
                      label="STIPS paper" if k == 0 else None)
        if PAPER_MAG[m]:
            a.legend(fontsize=7, loc="lower left")
        a.set_ylim(-1.0, 1.0)
        a.set_xlabel("input magnitude (AB, F129)")
        a.set_ylabel("recovered - input (mag)")
        a.set_title(NAMES[m], fontsize=10)
        a = ax[1][j]
        a.scatter(dx[~bright], dy[~bright], s=6, marker="x", c="0.6",
                  label=">= 21 mag", lw=0.6)
        a.scatter(dx[bright], dy[bright], s=6, marker="o", facecolors="none",
                  edgecolors="b", label="< 21 mag")
        a.add_patch(plt.Circle((0, 0), PAPER_POS[m], fill=False, color="g",
                               ls="--", lw=1.0,
                               label="STIPS paper, %g px" % PAPER_POS[m]))
        lim = 0.3
        a.set_xlim(-lim, lim)
        a.set_ylim(-lim, lim)
        a.axhline(0, color="r", lw=0.5)
        a.axvline(0, color="r", lw=0.5)
        a.set_aspect("equal")
        a.set_xlabel("recovered - input x (px)")
        a.set_ylabel("recovered - input y (px)")
        a.legend(fontsize=7, loc="upper right")
    fig.suptitle("wfiscene: %d stars, F129, SCA01, background avg, noise all, "
                 "139.8 s (dashed green: the STIPS paper's figures)" % len(truth),
                 fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--n", type=int, default=1000)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--wfs", default="build/wfiscene")
    p.add_argument("--dir", default=None)
    p.add_argument("--methods", default="sep,gauss,epsf")
    p.add_argument("--table", default=None)
    p.add_argument("--plot", default=None)
    p.add_argument("--json", default=None)
    p.add_argument("--extent", choices=("noise", "stips"), default="noise",
                   help="the point model's psf-extent (default noise)")
    p.add_argument("--noiseless", action="store_true",
                   help="no background and no noise (sep and gauss need them)")
    args = p.parse_args()
    if args.dir is None:
        import tempfile
        args.dir = tempfile.mkdtemp(prefix="wfs-validate.")
    os.makedirs(args.dir, exist_ok=True)

    img, psf, truth, t_sim = make_scene(args)
    data, hdr = load(img)
    if args.noiseless:
        # nothing to subtract, every pixel weighed alike
        sub = data
        sigma = np.ones_like(data)
        bkg = None
    else:
        import sep
        bkg = sep.Background(data.astype(np.float32), bw=64, bh=64)
        sub = data - bkg.back()
        # Per-pixel noise for the fit weights: background rms, plus the
        # star's own Poisson noise from the image itself (counts/s over t).
        sigma = np.sqrt(bkg.rms().astype(np.float64) ** 2
                        + np.clip(sub, 0, None) / EXPTIME)
    scale = calibrate(args, psf) if "epsf" in args.methods.split(",") else 1.0

    summary = {"n": args.n, "seed": args.seed, "filter": FILTER, "exptime": EXPTIME,
               "extent": args.extent, "noiseless": bool(args.noiseless),
               "epsf_scale": scale, "sim_seconds": round(t_sim, 2), "methods": {}}
    res = {}
    for m in args.methods.split(","):
        t0 = time.process_time()
        if m == "sep":
            f, x, y = method_sep(sub, bkg.globalrms, truth)
        elif m == "gauss":
            f, x, y = method_gauss(sub, truth)
        elif m == "epsf":
            f, x, y = method_epsf(sub, sigma, truth, psf)
            f = f / scale
        else:
            sys.exit("photometry.py: unknown method '%s'" % m)
        s, dm, dx, dy = stats(truth, f, x, y)
        s["cpu_seconds"] = round(time.process_time() - t0, 2)
        summary["methods"][m] = s
        res[m] = (dm, dx, dy)

    if args.table:
        with open(args.table, "w") as fh:
            fh.write(table(summary) + "\n")
    if args.plot:
        plot(args.plot, truth, res)
    text = json.dumps(summary, indent=1)
    if args.json:
        with open(args.json, "w") as fh:
            fh.write(text + "\n")
    else:
        print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
