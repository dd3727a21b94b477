#!/usr/bin/python3
"""derive_sky.py - derive wfiscene's sky background tables from the public
Roman files in ../shared/roman/ (see ../shared/reference/roman-data.md 1.6).

    contrib/tables/derive_sky.py [SHARED_ROMAN_DIR] [DATA_DIR]

writes DATA_DIR/zodi.tsv (the zodiacal light of the eight imaging filters on
the ETC's grid of ecliptic latitude and longitude from the Sun) and
DATA_DIR/background.tsv (per filter: the Roman Project's minimum zodiacal
rate and internal thermal rate, the ETC table's minimum, and each SCA's
response to zodiacal light relative to the mean of the 18).  It prints how
much the zodiacal light varies across an SCA and across the field, and how
well the grid's bilinear interpolation does (the numbers in BENCHMARKS.md
and wfiscene(1)).  Development-time only: the product embeds the tables.
"""
import hashlib
import os
import sys

import numpy as np

ROMAN = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
    os.path.dirname(__file__), '..', '..', '..', 'shared', 'roman')
DATA = sys.argv[2] if len(sys.argv) > 2 else os.path.join(
    os.path.dirname(__file__), '..', '..', 'data')

FILTERS = ['F062', 'F087', 'F106', 'F129', 'F158', 'F184', 'F213', 'F146']
# The ETC table's (GalSim's) names of the same filters.
ETC_NAME = {'F062': 'R062', 'F087': 'Z087', 'F106': 'Y106', 'F129': 'J129',
            'F158': 'H158', 'F184': 'F184', 'F213': 'K213', 'F146': 'W146'}
NLAT, NLON = 42, 46         # sin(beta) = k/41, dlon = 4 j degrees
NSCA = 18
T_SUN = 5778.0              # K: the solar spectrum as a black body


def sha(path):
    with open(path, 'rb') as f:
        return hashlib.sha256(f.read()).hexdigest()[:16]


def manifest(name):
    """(repository, commit) of a public file from MANIFEST.tsv."""
    for line in open(os.path.join(ROMAN, 'MANIFEST.tsv')):
        f = line.rstrip('\n').split('\t')
        if f[0] == name:
            return f[3], f[5][:8]
    return '?', '?'


def ecsv_rates(name):
    """filter -> rate of a two-column RTI ECSV (filter, rate)."""
    out = {}
    for line in open(os.path.join(ROMAN, name)):
        if line.startswith('#') or line.startswith('filter'):
            continue
        f = [x.strip() for x in line.split(',')]
        if len(f) == 2 and f[0]:
            out[f[0]] = float(f[1])
    return out


def read_etc():
    path = os.path.join(ROMAN, 'roman_sky_backgrounds.txt')
    cols = None
    rows = []
    for line in open(path):
        if line.startswith('#'):
            cols = line[1:].split()
            continue
        rows.append([float(x) for x in line.split()])
    t = np.array(rows)
    assert t.shape[0] == NLAT * NLON, t.shape
    lat = t[:, 0].reshape(NLON, NLAT)
    lon = t[:, 1].reshape(NLON, NLAT)
    # The grid is what the runtime's index arithmetic assumes.
    assert np.allclose(np.sin(np.radians(lat[0])), np.arange(NLAT) / (NLAT - 1), atol=2e-5)
    assert np.allclose(lon[:, 0], 4.0 * np.arange(NLON))
    grid = {f: t[:, cols.index(ETC_NAME[f])].reshape(NLON, NLAT) for f in FILTERS}
    return t, cols, grid


def bilinear(v, beta, dlon):
    """The runtime's interpolation: bilinear in (41 sin|beta|, |dlon|/4)."""
    x = (NLAT - 1) * np.sin(np.radians(np.abs(beta)))
    y = np.abs(dlon) / 4.0
    i = np.clip(np.floor(x).astype(int), 0, NLAT - 2)
    j = np.clip(np.floor(y).astype(int), 0, NLON - 2)
    fx, fy = x - i, y - j
    return (v[j, i] * (1 - fx) * (1 - fy) + v[j, i + 1] * fx * (1 - fy) +
            v[j + 1, i] * (1 - fx) * fy + v[j + 1, i + 1] * fx * fy)


def sca_response():
    """filter -> 18 relative responses of the SCAs to zodiacal light (a
    solar spectrum), and the same for a flat f_nu source for comparison."""
    rel, flat = {}, {}
    lam = None
    area = {f: [] for f in FILTERS}
    for s in range(1, NSCA + 1):
        path = os.path.join(ROMAN, 'Roman_effarea_v8_SCA%02d_20240301.ecsv' % s)
        names, rows = None, []
        for line in open(path):
            if line.startswith('#'):
                continue
            f = [x.strip() for x in line.split(',')]
            if names is None:
                names = f
                continue
            rows.append([float(x) for x in f])
        t = np.array(rows)
        lam = t[:, 0]
        for f in FILTERS:
            area[f].append(t[:, names.index(f)])
    # Photon rate per unit wavelength of a black body: B_lambda lambda / hc
    # is proportional to lambda^-4 / (exp(hc / lambda k T) - 1).
    hc_k = 14387.77     # micron K
    sun = lam ** -4 / np.expm1(hc_k / (lam * T_SUN))
    fnu = 1 / lam       # photons per d lambda of a flat f_nu source
    for f in FILTERS:
        a = np.array(area[f])
        r = (a * sun).sum(axis=1)
        q = (a * fnu).sum(axis=1)
        rel[f] = r / r.mean()
        flat[f] = q / q.mean()
    return rel, flat


def variation(grid):
    """Largest and median relative change of F129's zodiacal light across
    an SCA (0.125 deg) and across the field (0.8 deg), from the gradient of
    the interpolated table, over the pointable sky (Sun angle 54-126)."""
    v = grid['F129']
    b = np.linspace(-89.5, 89.5, 359)
    d = np.linspace(0.5, 179.5, 359)
    B, D = np.meshgrid(b, d)
    elong = np.degrees(np.arccos(np.cos(np.radians(B)) * np.cos(np.radians(D))))
    ok = (elong >= 54) & (elong <= 126)
    h = 0.05
    z = bilinear(v, B, D)
    # d/dbeta and, along the sky, d/(cos beta dlon)
    gb = (bilinear(v, B + h, D) - bilinear(v, B - h, D)) / (2 * h)
    gl = (bilinear(v, B, D + h) - bilinear(v, B, D - h)) / (2 * h) / np.cos(np.radians(B))
    g = np.hypot(gb, gl)[ok] / z[ok]
    return {'sca_max': g.max() * 0.125 * np.sqrt(2), 'sca_median': np.median(g) * 0.125,
            'field_max': g.max() * 0.8, 'field_median': np.median(g) * 0.8}


def interp_error(grid):
    """Bilinear interpolation's error: every other node left out and
    interpolated from its neighbours on the half-density grid, against the
    tabulated value, over the pointable nodes.  The error on the full grid
    is about a quarter of this (the error of linear interpolation goes as
    the square of the spacing)."""
    out = {}
    for f in ('F129', 'F213'):
        v = grid[f]
        errs = []
        lat = np.degrees(np.arcsin(np.arange(NLAT) / (NLAT - 1)))
        for j in range(1, NLON - 1, 2):
            for i in range(1, NLAT - 1, 2):
                e = np.degrees(np.arccos(np.cos(np.radians(lat[i])) *
                                         np.cos(np.radians(4 * j))))
                if not (54 <= e <= 126):
                    continue
                c = [v[j - 1, i - 1], v[j - 1, i + 1], v[j + 1, i - 1], v[j + 1, i + 1]]
                if min(c) <= 0:
                    continue
                errs.append(abs(sum(c) / 4 / v[j, i] - 1))
        errs = np.array(errs)
        out[f] = (errs.max() / 4, np.median(errs) / 4, errs.max(), len(errs))
    return out


def main():
    t, cols, grid = read_etc()
    zodi_min = ecsv_rates('zodiacal_light.ecsv')
    thermal = ecsv_rates('internal_thermal_backgrounds.ecsv')
    rel, flat = sca_response()
    var = variation(grid)
    ierr = interp_error(grid)

    src = 'roman_sky_backgrounds.txt'
    repo, commit = manifest(src)
    lines = [
        '# zodi.tsv - zodiacal light seen by Roman in each imaging filter, in',
        '# e-/s per m^2 of collecting area per arcsec^2, on a grid of ecliptic',
        '# latitude (lat: 42 values with sin(lat) = k/41, the fastest index) and',
        '# ecliptic longitude from the Sun (dlon: 0 to 180 in steps of 4); -10',
        '# marks directions too close to the Sun, which Roman cannot take.',
        '# Derived by contrib/tables/derive_sky.py from %s' % src,
        '# (%s @ %s, sha256 %s), C. Hirata\'s Roman exposure' % (repo, commit, sha(os.path.join(ROMAN, src))),
        '# time calculator: its columns %s renamed' % ' '.join(ETC_NAME[f] for f in FILTERS),
        '# %s; values as published (4 decimals).' % ' '.join(FILTERS),
        '# src/background.c interpolates it bilinearly in (41 sin|lat|, |dlon|/4)',
        '# and normalises it (see background.tsv and wfiscene(1)).',
        '\t'.join(['lat', 'dlon'] + FILTERS),
    ]
    for k in range(t.shape[0]):
        j, i = divmod(k, NLAT)
        vals = ['%.4f' % grid[f][j, i] for f in FILTERS]
        lines.append('\t'.join(['%.4f' % t[k, 0], '%.1f' % t[k, 1]] + vals))
    open(os.path.join(DATA, 'zodi.tsv'), 'w').write('\n'.join(lines) + '\n')

    zr, zc = manifest('zodiacal_light.ecsv')
    tr, tc = manifest('internal_thermal_backgrounds.ecsv')
    maxdiff = max(np.abs(rel[f] / flat[f] - 1).max() for f in FILTERS)
    lines = [
        '# background.tsv - the parts of the sky background per filter.',
        '# Derived by contrib/tables/derive_sky.py.',
        '# zodi_min: the Roman Project\'s count rate at minimum zodiacal light,',
        '#   e-/s/pixel (zodiacal_light.ecsv, %s @ %s, 2024-06-03).' % (zr, zc),
        '# thermal: the Project\'s internal thermal background, e-/s/pixel',
        '#   (internal_thermal_backgrounds.ecsv, %s @ %s, 2024-06-03).' % (tr, tc),
        '# etc_min: the smallest value of the filter\'s column in zodi.tsv over',
        '#   the whole sky (e-/s/m^2/arcsec^2), the minimum zodi_min refers to.',
        '# r_NN: SCA NN\'s response to zodiacal light relative to the mean of the',
        '#   18 SCAs: the per-SCA effective areas Roman_effarea_v8_SCANN_20240301.ecsv',
        '#   (%s @ %s, 1 nm steps) weighted by the photon spectrum'
        % manifest('Roman_effarea_v8_SCA01_20240301.ecsv'),
    ]
    lines += [
        '#   of a %.0f K black body (the Sun, whose light the dust scatters); a' % T_SUN,
        '#   flat f_nu spectrum instead changes no r_NN by more than %.2f%%.' % (100 * maxdiff),
        '\t'.join(['filter', 'zodi_min', 'thermal', 'etc_min'] +
                  ['r_%02d' % s for s in range(1, NSCA + 1)]),
    ]
    for f in FILTERS:
        v = grid[f]
        lines.append('\t'.join([f, '%.4g' % zodi_min[f], '%.4g' % thermal[f],
                                '%.4f' % v[v > 0].min()] +
                               ['%.5f' % x for x in rel[f]]))
    open(os.path.join(DATA, 'background.tsv'), 'w').write('\n'.join(lines) + '\n')

    sys.stderr.write('F129 zodiacal light across an SCA: at most %.2f%%, median %.2f%%; '
                     'across the field: at most %.1f%%, median %.1f%%\n'
                     % (100 * var['sca_max'], 100 * var['sca_median'],
                        100 * var['field_max'], 100 * var['field_median']))
    for f, (mx, med, mx2, n) in ierr.items():
        sys.stderr.write('%s bilinear interpolation: left-out nodes at half density '
                         'off by at most %.2f%% (%d nodes); full grid est. max %.2f%%, '
                         'median %.3f%%\n' % (f, 100 * mx2, n, 100 * mx, 100 * med))
    for f in FILTERS:
        sys.stderr.write('%s SCA response %.4f-%.4f; ETC minimum x 3.960 m^2 x 0.0121 '
                         'arcsec^2 = %.3f e-/s/pix vs Project %.3f\n'
                         % (f, rel[f].min(), rel[f].max(),
                            grid[f][grid[f] > 0].min() * 3.960 * 0.0121, zodi_min[f]))


if __name__ == '__main__':
    main()
