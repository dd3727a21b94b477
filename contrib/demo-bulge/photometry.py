#!/usr/bin/python3
"""Forced photometry of the microlensing event of make demo-bulge, and its plot.

Usage: photometry.py DIR FIRST_ROW (the first FITS row the images hold)
Reads DIR/season.txt, the images DIR/bulge_NAME.fits (their first image: the
rate at level 2), the event star's placements DIR/event_NAME.csv, and
DIR/event_base.fits (the event star alone at its baseline, without noise).
At each exposure the event star's position is taken from its placement
(forced: it is not searched for); its light is summed in
a 3-pixel-radius aperture, less the median of an annulus 8-12 pixels out.
The aperture holds a fraction of the star's light, measured on
event_base.fits; the baseline (neighbours' light included) is the median over
exposures more than 3 te from t0.  The magnification observed is then
1 + (F - F_base) / (fs * F_event), against the catalog's PSPL curve.
Writes DIR/lightcurve.csv and, where matplotlib is installed,
DIR/lightcurve.png: the field around the event, the afterglow the bright
stars leave for the next visit (DIR/afterglow.fits, when there) and the light
curve side by side.  Prints the rms deviation.
"""
import os
import sys
import numpy as np
from astropy.io import fits
try:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    plt = None

d = sys.argv[1]
ev = np.genfromtxt(d + "/event.csv", delimiter=",", names=True, dtype=None, encoding=None)
t0, te, u0, fs = float(ev["t0"]), float(ev["te"]), float(ev["u0"]), float(ev["fs"])


def aperture(img, x, y, ylo):
    """Aperture sum less annulus median at 1-based FITS pixel (x, y)."""
    i0, j0 = int(round(y - ylo)) - 14, int(round(x - 1)) - 14
    img = img[max(i0, 0):i0 + 29, max(j0, 0):j0 + 29]
    yy, xx = np.mgrid[0:img.shape[0], 0:img.shape[1]]
    r = np.hypot(xx + max(j0, 0) + 1 - x, yy + max(i0, 0) + ylo - y)
    sky = np.median(img[(r >= 8) & (r < 12)])
    ap = r < 3
    return img[ap].sum() - sky * ap.sum()


def load(name):
    """The SCA's image (the rows drawn, from FITS row ylo)."""
    return fits.getdata(name, 1).astype(float)


def event_xy(placed):
    p = np.genfromtxt(placed, delimiter=",", names=True, dtype=None, encoding=None)
    r = p[p["id"] == 1][0]
    return r["x"], r["y"], r["flux"]


rows = [l.split() for l in open(d + "/season.txt") if not l.startswith("name")]
img = load(d + "/event_base.fits")
ylo = int(sys.argv[2]) if len(sys.argv) > 2 else 1
x, y, f_event = event_xy(d + "/event_base.csv")
frac = aperture(img, x, y, ylo) / f_event
t, flux = [], []
for name, mjd, *_ in rows:
    img = load(d + "/bulge_%s.fits" % name)
    x, y, _ = event_xy(d + "/event_%s.csv" % name)
    t.append(float(mjd))
    flux.append(aperture(img, x, y, ylo))
t, flux = np.array(t), np.array(flux)
base = np.median(flux[np.abs(t - t0) > 3 * te])
a_obs = 1 + (flux - base) / (fs * frac * f_event)
A = lambda u: (u * u + 2) / (u * np.sqrt(u * u + 4))
a_true = A(np.hypot(u0, (t - t0) / te))
rms = np.sqrt(np.mean((a_obs - a_true) ** 2))
np.savetxt(d + "/lightcurve.csv", np.c_[t, flux, a_obs, a_true], delimiter=",",
           header="mjd,aperture_flux,magnification_measured,magnification_true", comments="")
tt = np.linspace(t.min(), t.max(), 2000)
if plt is None:
    print("demo-bulge: no matplotlib (Debian python3-matplotlib): the light curve is "
          "in lightcurve.csv, the images in the PNG previews")
else:
    last = load(d + "/bulge_%s.fits" % rows[-1][0])
    glow = d + "/afterglow.fits"
    panels = 3 if os.path.exists(glow) else 2
    fig, ax = plt.subplots(1, panels, figsize=(5 * panels, 4.6),
                           gridspec_kw={"width_ratios": [1] * (panels - 1) + [1.4]})
    # the field: a 400-pixel square about the event, asinh-stretched
    cx, cy = int(round(x)) - 1, int(round(y)) - ylo
    cut = (slice(max(cy - 200, 0), cy + 200), slice(max(cx - 200, 0), cx + 200))
    sky = np.median(last[cut])
    ax[0].imshow(np.arcsinh((last[cut] - sky) / 5), origin="lower", cmap="gray",
                 vmin=-1, vmax=np.arcsinh(3000 / 5))
    ax[0].set_title("the field (rate, last exposure)")
    if panels == 3:
        g = fits.getdata(glow, 1)[cut]
        ax[1].imshow(np.arcsinh(g / 0.02), origin="lower", cmap="magma",
                     vmin=0, vmax=np.arcsinh(max(g.max(), 0.1) / 0.02))
        ax[1].set_title("afterglow at the next visit (e-/s)")
    for a_ in ax[:-1]:
        a_.set_xticks([])
        a_.set_yticks([])
    ax[-1].plot(tt, A(np.hypot(u0, (tt - t0) / te)), "-", color="0.5",
                label="PSPL: te %.2f d, u0 %.2f" % (te, u0))
    ax[-1].plot(t, a_obs, "o", ms=4, label="forced photometry (3 px aperture)")
    ax[-1].set_xlabel("MJD")
    ax[-1].set_ylabel("magnification of the source")
    ax[-1].legend()
    fig.suptitle("make demo-bulge: SCA 4 of a Roman bulge field (F146, level 2, 15-minute cadence)")
    fig.tight_layout()
    fig.savefig(d + "/lightcurve.png", dpi=100)
print("demo-bulge: %d exposures; peak magnification measured %.2f (true %.2f); "
      "rms deviation %.3f" % (len(t), a_obs.max(), a_true.max(), rms))
