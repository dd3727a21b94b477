#!/usr/bin/python3
"""A Galactic-bulge field for make demo-bulge, and a few hours of its
15-minute cadence.

Writes, into the directory given:
  field.csv      NSTARS stars (default 1.6 million) in a circle of radius
                 0.0885 deg about the centre of SCA 4 when WFI01's centre is
                 at (RA, Dec) = (268.5, -28.9), PA 0 (which that circle
                 covers, so ~1 million of them fall on it: the density of
                 the bulge near Baade's window to F146 ~ 26).  SCA 4: its
                 measured persistence (SCU 4) is the strongest of the 18,
                 so the afterglow shows at a 15-minute cadence.  Magnitudes from a power-law luminosity function
                 dN/dm ~ 10^(0.3 m) between 12 and 26 (F146, AB): the ~1000
                 giants brighter than 15.5 saturate in an exposure, and
                 leave an afterglow in the next.  Bulge proper motions (3
                 mas/yr about -6 mas/yr in RA), a few foreground disc stars
                 with parallaxes; one star near the middle is a short
                 microlensing event (type microlens: te 0.08 d, peaking in
                 the middle of the hours simulated), a few are variables.
  event.csv      the same event star alone, for the aperture calibration;
  season.txt     the --pointings file: N exposures (default 12: three hours)
                 15 minutes apart from 2027-03-20 00:00 UTC, each moved by a
                 small dither of 1 to 3 arcsec, as the survey's visits are,
                 so that a bright star's afterglow falls beside it; and one
                 more, "ref", a day later, for the event's baseline.
Usage: make-field.py DIR [N [NSTARS]]
"""
import sys
import numpy as np

out = sys.argv[1]
nexp = int(sys.argv[2]) if len(sys.argv) > 2 else 12
n = int(sys.argv[3]) if len(sys.argv) > 3 else 1600000
rng = np.random.default_rng(2027)
ra0, dec0 = 268.5, -28.9     # the pointing: WFI01's centre
# SCA 4's centre from there (found by placing a grid of stars, to ~1")
fra, fdec = ra0 - 0.1355 / np.cos(np.radians(dec0)), dec0 + 0.027
radius = 0.0885               # deg: the circle about SCA 1's square
# dN/dm ~ 10^(0.3 m), between 12 and 26
u = rng.uniform(size=n)
a, lo, hi = 0.3 * np.log(10), 12.0, 26.0
mag = np.log(np.exp(a * lo) + u * (np.exp(a * hi) - np.exp(a * lo))) / a
r = radius * np.sqrt(rng.uniform(size=n))
phi = rng.uniform(0, 2 * np.pi, n)
ra = fra + r * np.cos(phi) / np.cos(np.radians(dec0))
dec = fdec + r * np.sin(phi)
disc = rng.uniform(size=n) < 0.1
pmra = np.where(disc, rng.normal(0, 3, n), rng.normal(-6, 3, n))
pmdec = np.where(disc, rng.normal(0, 3, n), rng.normal(-0.2, 3, n))
plx = np.where(disc, rng.uniform(0.5, 2.0, n), 1 / 8.2)
mjd0 = 61484.0                # 2027-03-20 00:00 UTC
cadence = 15.0 / 1440         # days
t0, te, u0, fs = mjd0 + cadence * (nexp - 1) / 2, 0.08, 0.1, 0.8
event = "%.9f,%.9f,%.3f,microlens,%.3f,%.3f,%.5f,%.5f,%.4f,%.3f,%.4f,,,,"
head = "id,ra,dec,mag,type,pmra,pmdec,parallax,t0,te,u0,fs,period,amplitude,phase,shape\n"
ev_ra, ev_dec = fra + 0.01, fdec + 0.01

with open(out + "/field.csv", "w") as f:
    f.write(head)
    f.write(("1," + event + "\n") % (ev_ra, ev_dec, 19.5, -5.0, -0.5, 1 / 8.2, t0, te, u0, fs))
    var = np.zeros(n, dtype=bool)
    var[7::4000] = True
    lines = []
    for k in range(n):
        if var[k]:
            typ, extra = "variable", "%.4f,%.2f,%.3f,%d" % (
                rng.uniform(0.45, 0.7), 0.8, rng.uniform(), 1 if k % 8000 == 7 else 0)
        else:
            typ, extra = "point", ",,,"
        lines.append("%d,%.9f,%.9f,%.3f,%s,%.3f,%.3f,%.4f,,,,,%s\n"
                     % (k + 2, ra[k], dec[k], mag[k], typ, pmra[k], pmdec[k], plx[k], extra))
        if len(lines) == 100000:
            f.writelines(lines)
            lines = []
    f.writelines(lines)
with open(out + "/event.csv", "w") as f:
    f.write(head)
    f.write(("1," + event + "\n") % (ev_ra, ev_dec, 19.5, -5.0, -0.5, 1 / 8.2, t0, te, u0, fs))
# 15 minutes apart, each visit dithered by 1 to 3 arcsec
with open(out + "/season.txt", "w") as f:
    f.write("name date ra dec pa\n")
    for k in range(nexp):
        d = rng.uniform(1, 3) / 3600
        ang = rng.uniform(0, 2 * np.pi)
        f.write("e%03d %.9f %.9f %.9f 0\n" % (k, mjd0 + k * cadence,
                                             ra0 + d * np.cos(ang) / np.cos(np.radians(dec0)),
                                             dec0 + d * np.sin(ang)))
    f.write("ref %.9f %.9f %.9f 0\n" % (mjd0 + 1, ra0, dec0))
