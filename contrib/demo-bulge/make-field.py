#!/usr/bin/python3
"""A small Galactic-bulge field for make demo-bulge, and its season.

Writes, into the directory given:
  field.csv      ~4000 stars in a 40" square about (RA, Dec) = (268.5, -28.9),
                 magnitudes from a power-law luminosity function (F146, AB,
                 18 to 25.5), bulge proper motions (3 mas/yr dispersion about
                 the bulge's mean, -6 mas/yr in RA relative to the disc) and
                 a few foreground disc stars with parallaxes of 0.5-2 mas;
                 one of them, near the middle, is a microlensing event
                 (type microlens: t0, te, u0, fs), and a few are RR Lyrae
                 and sinusoidal variables (type variable);
  event.csv      the same event star alone, for the aperture calibration;
  season.txt     the --pointings file: N exposures over a spring season
                 (2027-02-22 to 2027-04-20), one every (season / N) days.
Usage: make-field.py DIR [N]
"""
import sys
import numpy as np

out = sys.argv[1]
nexp = int(sys.argv[2]) if len(sys.argv) > 2 else 30
rng = np.random.default_rng(2027)
ra0, dec0 = 268.5, -28.9
half = 20.0 / 3600.0          # a 40" square, 364 pixels
n = 4000
# dN/dm ~ 10^(0.3 m), between 18 and 25.5
u = rng.uniform(size=n)
a, lo, hi = 0.3 * np.log(10), 18.0, 25.5
mag = np.log(np.exp(a * lo) + u * (np.exp(a * hi) - np.exp(a * lo))) / a
ra = ra0 + rng.uniform(-half, half, n) / np.cos(np.radians(dec0))
dec = dec0 + rng.uniform(-half, half, n)
disc = rng.uniform(size=n) < 0.1
pmra = np.where(disc, rng.normal(0, 3, n), rng.normal(-6, 3, n))
pmdec = np.where(disc, rng.normal(0, 3, n), rng.normal(-0.2, 3, n))
plx = np.where(disc, rng.uniform(0.5, 2.0, n), 1 / 8.2)
t0, te, u0, fs = 61488.0, 6.0, 0.15, 0.8
event = "%.9f,%.9f,%.3f,microlens,%.3f,%.3f,%.5f,%.4f,%.3f,%.4f,%.3f,,,,"

with open(out + "/field.csv", "w") as f:
    f.write("id,ra,dec,mag,type,pmra,pmdec,parallax,t0,te,u0,fs,period,amplitude,phase,shape\n")
    f.write(("1," + event + "\n") % (ra0, dec0, 19.5, -5.0, -0.5, 1 / 8.2, t0, te, u0, fs))
    for k in range(n):
        typ, var = "point", ",,,"
        if k % 400 == 7:
            typ, var = "variable", "%.4f,%.2f,%.3f,%d" % (rng.uniform(0.45, 0.7), 0.8,
                                                         rng.uniform(), 1 if k % 800 == 7 else 0)
        f.write("%d,%.9f,%.9f,%.3f,%s,%.3f,%.3f,%.4f,,,,,%s\n"
                % (k + 2, ra[k], dec[k], mag[k], typ, pmra[k], pmdec[k], plx[k], var))
with open(out + "/event.csv", "w") as f:
    f.write("id,ra,dec,mag,type,pmra,pmdec,parallax,t0,te,u0,fs,period,amplitude,phase,shape\n")
    f.write(("1," + event + "\n") % (ra0, dec0, 19.5, -5.0, -0.5, 1 / 8.2, t0, te, u0, fs))
# 2027-02-22 to 2027-04-20 (MJD 61458 to 61515), evenly
with open(out + "/season.txt", "w") as f:
    f.write("name date ra dec pa\n")
    for k, t in enumerate(np.linspace(61458.0, 61515.0, nexp)):
        f.write("e%03d %.4f %.6f %.6f 0\n" % (k, t, ra0, dec0))
