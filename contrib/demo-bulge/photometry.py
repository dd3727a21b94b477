#!/usr/bin/python3
"""Forced photometry of the microlensing event of make demo-bulge, and its plot.

Usage: photometry.py DIR FIRST_ROW (the first FITS row the images hold)
Reads DIR/season.txt, the images DIR/bulge_NAME.fits with their placed lists
DIR/placed_NAME.csv, and DIR/event_base.fits (the event star alone at its
baseline, without noise).  At each exposure the event star's position is taken
from the placed list (forced: it is not searched for); its light is summed in
a 3-pixel-radius aperture, less the median of an annulus 8-12 pixels out.
The aperture holds a fraction of the star's light, measured on
event_base.fits; the baseline (neighbours' light included) is the median over
exposures more than 3 te from t0.  The magnification observed is then
1 + (F - F_base) / (fs * F_event), against the catalog's PSPL curve.
Writes DIR/lightcurve.csv and DIR/lightcurve.png; prints the rms deviation.
"""
import sys
import numpy as np
from astropy.io import fits
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt

d = sys.argv[1]
ev = np.genfromtxt(d + "/event.csv", delimiter=",", names=True, dtype=None, encoding=None)
t0, te, u0, fs = float(ev["t0"]), float(ev["te"]), float(ev["u0"]), float(ev["fs"])


def aperture(img, x, y, ylo):
    """Aperture sum less annulus median at 1-based FITS pixel (x, y)."""
    yy, xx = np.mgrid[0:img.shape[0], 0:img.shape[1]]
    r = np.hypot(xx + 1 - x, yy + ylo - y)
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
    x, y, _ = event_xy(d + "/placed_%s.csv" % name)
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
plt.figure(figsize=(7, 4))
plt.plot(tt, A(np.hypot(u0, (tt - t0) / te)), "-", color="0.5",
         label="PSPL: t0 %.0f, te %.0f d, u0 %.2f" % (t0, te, u0))
plt.plot(t, a_obs, "o", ms=4, label="forced photometry (3 px aperture)")
plt.xlabel("MJD")
plt.ylabel("magnification of the source")
plt.title("make demo-bulge: a microlensing event in a Roman bulge field (F146)")
plt.legend()
plt.tight_layout()
plt.savefig(d + "/lightcurve.png", dpi=110)
print("demo-bulge: %d exposures; peak magnification measured %.2f (true %.2f); "
      "rms deviation %.3f" % (len(t), a_obs.max(), a_true.max(), rms))
