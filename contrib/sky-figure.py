#!/usr/bin/python3
"""sky-figure.py - the F129 sky background Roman sees over the whole sky on
one date, as wfiscene --background sky computes it (the mean SCA: zodiacal
light normalised to the Roman Project's minimum, plus internal thermal), in
a Mollweide map of equatorial coordinates; the sky Roman cannot point at
(less than 54 or more than 126 degrees from the Sun) is grey.

    contrib/sky-figure.py [--date 2027-05-15] [--filter F129] [--norm project|etc] [-o sky.png]

Reads wfiscene's own tables (data/zodi.tsv, data/background.tsv) and
computes the Sun's position with astropy, independently of the C code.
Needs python3-matplotlib and python3-astropy.
"""
import argparse
import os
import warnings

import numpy as np

warnings.simplefilter('ignore')

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, '..', 'data')
EPS = np.radians(23.4392794)    # J2000 mean obliquity


def read_tsv(name):
    rows = [l.rstrip('\n').split('\t') for l in open(os.path.join(DATA, name))
            if not l.startswith('#') and l.strip()]
    return rows[0], rows[1:]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--date', default='2027-05-15T00:00')
    ap.add_argument('--filter', default='F129')
    ap.add_argument('--norm', default='project', choices=['project', 'etc'])
    ap.add_argument('-o', '--output', default='sky-background.png')
    a = ap.parse_args()

    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from astropy.coordinates import GeocentricMeanEcliptic, get_sun
    from astropy.time import Time

    head, rows = read_tsv('zodi.tsv')
    c = head.index(a.filter)
    grid = np.array([float(r[c]) for r in rows]).reshape(46, 42)
    head, rows = read_tsv('background.tsv')
    row = [r for r in rows if r[0] == a.filter][0]
    zmin, thermal, etcmin = (float(row[head.index(k)]) for k in ('zodi_min', 'thermal', 'etc_min'))
    scale = zmin / etcmin if a.norm == 'project' else 3.960 * 0.11 ** 2

    t = Time(a.date, scale='utc')
    sun = get_sun(t)
    lsun = sun.transform_to(GeocentricMeanEcliptic(equinox='J2000')).lon.rad
    sra, sdec = sun.ra.rad, sun.dec.rad

    ra = np.radians(np.linspace(0, 360, 721))
    dec = np.radians(np.linspace(-90, 90, 361))
    RA, DEC = np.meshgrid(ra, dec)
    x, y, z = np.cos(DEC) * np.cos(RA), np.cos(DEC) * np.sin(RA), np.sin(DEC)
    ye = np.cos(EPS) * y + np.sin(EPS) * z
    ze = -np.sin(EPS) * y + np.cos(EPS) * z
    beta = np.arctan2(ze, np.hypot(x, ye))
    dlon = np.degrees((np.arctan2(ye, x) - lsun + np.pi) % (2 * np.pi) - np.pi)
    sun_angle = np.degrees(np.arccos(np.clip(
        x * np.cos(sdec) * np.cos(sra) + y * np.cos(sdec) * np.sin(sra) + z * np.sin(sdec), -1, 1)))

    fx = 41 * np.sin(np.abs(beta))
    fy = np.abs(dlon) / 4
    i = np.clip(np.floor(fx).astype(int), 0, 40)
    j = np.clip(np.floor(fy).astype(int), 0, 44)
    fx -= i
    fy -= j
    v = (grid[j, i] * (1 - fx) * (1 - fy) + grid[j, i + 1] * fx * (1 - fy) +
         grid[j + 1, i] * (1 - fx) * fy + grid[j + 1, i + 1] * fx * fy)
    bkg = v * scale + thermal
    bkg = np.ma.masked_where((sun_angle < 54) | (sun_angle > 126), bkg)

    fig = plt.figure(figsize=(10, 5.6))
    axm = fig.add_subplot(111, projection='mollweide')
    axm.set_facecolor('0.8')
    # Mollweide axes run over longitude -pi..pi, east to the left as on the sky.
    lon_plot = -(RA - np.pi)
    m = axm.pcolormesh(lon_plot, DEC, bkg, shading='auto', cmap='viridis')
    axm.plot(-(sra - np.pi if sra <= np.pi else sra - 3 * np.pi), sdec, 'o', color='orange',
             ms=10, label='Sun')
    lam = np.linspace(0, 2 * np.pi, 361)
    eq_ra = np.arctan2(np.cos(EPS) * np.sin(lam), np.cos(lam)) % (2 * np.pi)
    eq_dec = np.arcsin(np.sin(EPS) * np.sin(lam))
    order = np.argsort(eq_ra)
    axm.plot(-(eq_ra[order] - np.pi), eq_dec[order], 'w--', lw=0.8, label='ecliptic')
    axm.set_xticks(np.radians([-150, -120, -90, -60, -30, 0, 30, 60, 90, 120, 150]))
    axm.set_xticklabels(['330', '300', '270', '240', '210', '180', '150', '120', '90',
                         '60', '30'])
    axm.grid(True, alpha=0.4)
    cb = fig.colorbar(m, orientation='horizontal', pad=0.07, fraction=0.05)
    cb.set_label('%s background, e-/s per 0.11" pixel (zodiacal, %s scale, + thermal %.3g)'
                 % (a.filter, a.norm, thermal))
    axm.set_title('Roman WFI sky background on %s (RA, Dec; grey: Sun angle outside 54-126 deg)'
                  % t.isot[:16], fontsize=10)
    axm.legend(loc='lower right', fontsize=8)
    fig.savefig(a.output, dpi=120, bbox_inches='tight')
    print('%s: min %.3f, max %.3f e-/s/pixel over the pointable sky'
          % (a.output, bkg.min(), bkg.max()))


if __name__ == '__main__':
    main()
