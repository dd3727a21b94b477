#!/usr/bin/python3
"""derive_optics.py - derive wfiscene's compact optics tables from the public
Roman WFI files in ../shared/roman/ (see ../shared/reference/roman-data.md).

    contrib/tables/derive_optics.py [SHARED_ROMAN_DIR] [DATA_DIR]

writes DATA_DIR/pupil_edge.tsv, pupil_strut.tsv, zernike.tsv and
throughput.tsv.  The public files themselves are not copied: each pupil mask
becomes a handful of numbers (its rim and central obscuration as radii at
720 angles, delta coded, and six or seven straight, slightly tapered
struts) that src/optics.c rasterises at any sampling; the
Zernike table keeps what the PSF needs at reduced precision; the effective
areas are resampled to 5 nm inside each band.  Run it again when the
public files change; the tables carry the checksums of their inputs.
"""
import gzip
import hashlib
import io
import os
import sys

import numpy as np
from astropy.io import fits
from astropy.table import Table
from scipy import ndimage

ROMAN = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
    os.path.dirname(__file__), '..', '..', '..', 'shared', 'roman')
DATA = sys.argv[2] if len(sys.argv) > 2 else os.path.join(
    os.path.dirname(__file__), '..', '..', 'data')
NSCA = 18
NPIX = 2048
DX = 0.00117978731902147     # PIXELSCL of every mask, m per pixel


def sha(path):
    with open(path, 'rb') as f:
        return hashlib.sha256(f.read()).hexdigest()[:16]


NANG = 720                   # edge radii per turn (0.5 degree)
UNIT = 1e-4                  # edge radii are stored in 0.1 mm


def ray_profiles(lit, radii):
    """The mask bilinearly interpolated along NANG rays from the array
    centre: where it crosses 0.5 is the edge to a fraction of a pixel."""
    from scipy.ndimage import map_coordinates
    th = -np.pi + 2 * np.pi * np.arange(NANG) / NANG
    rr, tt = np.meshgrid(radii, th)
    i = rr * np.cos(tt) / DX + (NPIX - 1) / 2
    j = rr * np.sin(tt) / DX + (NPIX - 1) / 2
    v = map_coordinates(lit.astype(np.float32), [j.ravel(), i.ravel()],
                        order=1, mode='constant', cval=0)
    return th, v.reshape(rr.shape)


def crossing(radii, prof, outward):
    """First 0.5 crossing of each profile walking outward (inner edge) or
    inward (outer edge), linearly interpolated between samples."""
    out = np.empty(prof.shape[0])
    for k, p in enumerate(prof):
        idx = np.nonzero(p >= 0.5)[0]
        if outward:
            q = idx[0]
            a, b = q - 1, q
        else:
            q = idx[-1]
            a, b = q + 1, q
        f = (0.5 - p[a]) / (p[b] - p[a])
        out[k] = radii[a] + f * (radii[b] - radii[a])
    return out


def heal(r, bad):
    """Replace the flagged angles by periodic linear interpolation from
    the clean ones."""
    k = np.arange(NANG)
    good = ~bad
    return np.interp(k, k[good], r[good], period=NANG)


def strut_inside(struts, x, y, grow=0.0):
    inside = np.zeros(np.shape(x), bool)
    for x0, y0, phi, la, lb, ha, hb, smin, smax in struts:
        c, s_ = np.cos(phi), np.sin(phi)
        s = (x - x0) * c + (y - y0) * s_
        t = -(x - x0) * s_ + (y - y0) * c
        inside |= ((s >= smin) & (s <= smax) & (t >= la + lb * s - grow) &
                   (t <= ha + hb * s + grow))
    return inside


def describe(mask):
    """Fit the geometry of one 0/255 mask.  Coordinates are metres from the
    array centre, x along NAXIS1, y along NAXIS2 (as the file is stored)."""
    lit = mask > 0
    j, i = np.mgrid[0:NPIX, 0:NPIX]
    x = (i - (NPIX - 1) / 2) * DX
    y = (j - (NPIX - 1) / 2) * DX
    r = np.hypot(x, y)
    # Struts: the dark pixels well between obscuration and rim, one
    # connected piece each (the wide mask has a double strut, two pieces).
    lab, n = ndimage.label(~lit & (r > 0.65) & (r < 1.08))
    struts = []
    for k in range(1, n + 1):
        m = lab == k
        if m.sum() < 2000:
            continue
        px, py = x[m], y[m]
        cx, cy = px.mean(), py.mean()
        w, v = np.linalg.eigh(np.cov(np.vstack([px - cx, py - cy])))
        u = v[:, 1]
        if u[0] * cx + u[1] * cy < 0:
            u = -u
        phi = np.arctan2(u[1], u[0])
        s = (px - cx) * u[0] + (py - cy) * u[1]
        t = -(px - cx) * u[1] + (py - cy) * u[0]
        # edges: the outermost dark pixel centres across the axis in 10 mm
        # bins, half a pixel further out, fitted by straight lines
        sb, lo, hi = [], [], []
        for a in np.arange(s.min() + 0.01, s.max() - 0.02, 0.01):
            q = (s >= a) & (s < a + 0.01)
            if q.sum() < 10:
                continue
            sb.append(a + 0.005)
            lo.append(t[q].min() - DX / 2)
            hi.append(t[q].max() + DX / 2)
        lb, la = np.polyfit(sb, lo, 1)
        hb, ha = np.polyfit(sb, hi, 1)
        # run the strip from inside the obscuration to beyond the rim
        cu = cx * u[0] + cy * u[1]
        c2 = cx * cx + cy * cy
        smin = -cu + np.sqrt(max(cu * cu - c2 + 0.25 ** 2, 0))
        smax = -cu + np.sqrt(cu * cu - c2 + 1.30 ** 2)
        struts.append([cx, cy, phi, la, lb, ha, hb, min(smin, s.min()), smax])
    struts.sort(key=lambda q: np.arctan2(q[1], q[0]))
    # Rim and obscuration along rays; angles whose crossing lies on or by a
    # strut are healed from their neighbours (the strut covers them).
    radii = np.arange(0.15, 1.26, 0.0002)
    th, prof = ray_profiles(lit, radii)
    rout = crossing(radii, prof, outward=False)
    rin = crossing(radii, prof, outward=True)
    # A ray that runs along a strut, or down the lit gap of a double
    # strut, finds its crossing on the strut rather than at the edge it is
    # after: flag crossings on a strut, and rim radii well inside (or
    # obscuration radii well outside) the running median of their
    # neighbours; the rim is smooth, the obscuration's corners are many
    # degrees apart.
    from scipy.ndimage import median_filter
    for rr, sign, width in ((rout, -1, 41), (rin, +1, 13)):
        bad = strut_inside(struts, rr * np.cos(th), rr * np.sin(th),
                           grow=3 * DX)
        med = median_filter(rr, size=width, mode='wrap')
        bad |= sign * (rr - med) > 2e-3
        rr[:] = heal(rr, bad)
    return rout, rin, struts


def rasterise(rout, rin, struts, n=NPIX):
    """The same test src/optics.c makes, at pixel centres, to check the
    description against the mask."""
    j, i = np.mgrid[0:n, 0:n]
    x = (i - (n - 1) / 2) * DX * NPIX / n
    y = (j - (n - 1) / 2) * DX * NPIX / n
    r = np.hypot(x, y)
    a = (np.arctan2(y, x) + np.pi) / (2 * np.pi) * NANG
    k0 = np.floor(a).astype(int) % NANG
    f = a - np.floor(a)
    k1 = (k0 + 1) % NANG
    ro = rout[k0] * (1 - f) + rout[k1] * f
    ri = rin[k0] * (1 - f) + rin[k1] * f
    return (r <= ro) & (r >= ri) & ~strut_inside(struts, x, y)


def pupils(dir_):
    erows, srows, srcs = [], [], []
    worst = 0
    for mname in ('skinny', 'F184'):
        for sca in range(1, NSCA + 1):
            fn = os.path.join(ROMAN, 'RST_WIM_Filter_%s_SCA_%d.fits.gz'
                              % (mname, sca))
            srcs.append((os.path.basename(fn), sha(fn)))
            mask = fits.getdata(fn)
            rout, rin, struts = describe(mask)
            # quantise as stored, then check
            qo = np.round(rout / UNIT).astype(int)
            qi = np.round(rin / UNIT).astype(int)
            ras = rasterise(qo * UNIT, qi * UNIT, struts)
            lit = mask > 0
            bad = (ras != lit).sum() / lit.sum()
            worst = max(worst, bad)
            print('%s SCA%02d: %d struts, pixels differing %.4f%%'
                  % (mname, sca, len(struts), 100 * bad), file=sys.stderr)
            name = 'wide' if mname == 'F184' else 'skinny'
            for edge, q in (('out', qo), ('in', qi)):
                d = np.diff(q)
                erows.append([name, str(sca), edge, str(q[0])] +
                             [str(v) for v in d])
            for k, st in enumerate(struts):
                srows.append([name, str(sca), str(k + 1)] +
                             ['%.6f' % v for v in st])
    head = '''# Derived by contrib/tables/derive_optics.py from the Cycle-9 pupil masks
# RST_WIM_Filter_{skinny,F184}_SCA_n.fits.gz (GalSim share/roman @ ee177aa5,
# identical to stpsf-data WFI/pupils; 2048x2048, 0/255, PIXELSCL
# 1.17978731902147 mm at the entrance pupil), see roman-data.md 1.1; mask
# "skinny" serves F062 F087 F106 F129 F158 F146, "wide" (the F184 files)
# F184 F213.  Frame: metres from the mask array centre ((2048-1)/2 pixels
# each way), x along NAXIS1, y along NAXIS2, as stored (no flip).
# The clear aperture is rim(theta) >= r >= obscuration(theta), theta =
# atan2(y, x), less the struts of pupil_strut.tsv.  Check: rasterised at the
# masks' own sampling (pixel centres) the description differs from the
# mask in at most %.2f%% of the lit pixels, all on edges.
# Inputs (sha256 prefix): %s=%s, ... (all 36 masks the same way)
''' % (100 * worst, srcs[0][0], srcs[0][1])
    with open(os.path.join(dir_, 'pupil_edge.tsv'), 'w') as f:
        f.write('''# pupil_edge.tsv - the rim and the central obscuration of the Roman WFI
# entrance pupil per mask and SCA, as radii from the array centre at %d
# angles theta_k = -pi + 2 pi k / %d, linearly interpolated between them.
# Each radius is where the mask, bilinearly interpolated along the ray,
# crosses 1/2 (walking inwards for the rim, outwards for the obscuration);
# angles where that crossing lies on a strut, or (a ray along a strut or
# down the lit gap of a double strut) more than 2 mm inside the running
# median of the rim over 20 degrees or outside that of the obscuration over
# 6 degrees, are interpolated from their neighbours.  Units of 0.1 mm; r0 is the radius at k = 0 and each
# further column the change from the previous angle (delta coded).
''' % (NANG, NANG) + head)
        f.write('\t'.join(['mask', 'sca', 'edge', 'r0'] +
                           ['d%d' % k for k in range(1, NANG)]) + '\n')
        for row in erows:
            f.write('\t'.join(row) + '\n')
    with open(os.path.join(dir_, 'pupil_strut.tsv'), 'w') as f:
        f.write('''# pupil_strut.tsv - the secondary-mirror struts of the Roman WFI entrance
# pupil per mask and SCA (six, seven where the wide mask shows a double
# strut as two pieces), each a straight, slightly tapered strip: with s
# along the axis through (x0, y0) at angle phi and t across it (t = s
# rotated +90 degrees), the strut blocks smin <= s <= smax,
# lo_a + lo_b s <= t <= hi_a + hi_b s.  The edges are straight-line fits to
# the outermost dark pixel centres (plus half a pixel) across the axis in
# 10 mm bins; the strip runs from inside the obscuration to beyond the rim.
# Metres and radians.
''' + head)
        f.write('\t'.join(['mask', 'sca', 'k', 'x0', 'y0', 'phi', 'lo_a',
                           'lo_b', 'hi_a', 'hi_b', 'smin', 'smax']) + '\n')
        for row in srows:
            f.write('\t'.join(row) + '\n')


def zernikes(out):
    fn = os.path.join(ROMAN, 'wim_zernikes_cycle9.csv.gz')
    t = Table.read(gzip.open(fn, 'rt').read().splitlines(), format='csv')
    with open(out, 'w') as f:
        f.write('''# zernike.tsv - the Cycle-9 Roman WFI wavefront model: Noll Zernike
# coefficients Z4..Z22 per SCA, field point and wavelength.
# Derived by contrib/tables/derive_optics.py from wim_zernikes_cycle9.csv.gz
# (Roman-HLIS-Cosmology-PIT/PSFSim @ c55d8ae5, the table STPSF reads as
# stpsf-data/WFI/wim_zernikes_cycle9.csv; sha256 %s), see
# roman-data.md 1.2.  Kept: sca, field point (1 centre, 2-5 corners), the
# field point's local_x/local_y in mm on the SCA (STPSF places it at pixel
# x = round(2048 - 100 local_x), y = round(2048 + 100 local_y) of the 4096
# frame), the wavelength in micron, and Z4..Z22 converted from waves at
# that wavelength to nm of wavefront (x 1000 x wave), rounded to 0.001 nm
# (the source has 6 significant digits).  Z1-Z3 (piston, tip, tilt) are
# dropped: STPSF zeroes them.  Unit-RMS circular Zernikes over a 1.2 m
# radius (STPSF's PUPIL_RADIUS), applied after STPSF's y-flip of the pupil.
''' % sha(fn))
        cols = ['sca', 'fp', 'local_x', 'local_y', 'wave'] + \
            ['Z%d' % k for k in range(4, 23)]
        f.write('\t'.join(cols) + '\n')
        for r in t:
            row = ['%d' % r['sca'], '%d' % r['field_point'],
                   '%.4f' % r['local_x'], '%.4f' % r['local_y'],
                   '%g' % r['wavelength']]
            row += ['%.3f' % (r['Z%d' % k] * r['wavelength'] * 1000)
                    for k in range(4, 23)]
            f.write('\t'.join(row) + '\n')


FILTERS = ['F062', 'F087', 'F106', 'F129', 'F158', 'F184', 'F213', 'F146']


def throughput(out):
    tabs = []
    srcs = []
    for sca in range(1, NSCA + 1):
        fn = os.path.join(ROMAN, 'Roman_effarea_v8_SCA%02d_20240301.ecsv' % sca)
        srcs.append(sha(fn))
        # the YAML header of these files does not parse; the body is
        # plain CSV after the '#' lines
        with open(fn) as fh:
            body = [ln for ln in fh if not ln.startswith('#')]
        names = [c.strip() for c in body[0].split(',')]
        vals = np.loadtxt(body[1:], delimiter=',')
        tabs.append({n: vals[:, k] for k, n in enumerate(names)})
    wave = np.array(tabs[0]['Wave'], dtype=float)
    step = 5   # rows of 1 nm
    with open(out, 'w') as f:
        f.write('''# throughput.tsv - Roman WFI effective area (m^2: telescope x filter x
# QE) per filter and SCA, for the photon weights of polychromatic PSFs.
# Derived by contrib/tables/derive_optics.py from the RTI per-SCA tables
# Roman_effarea_v8_SCA01..18_20240301.ecsv (RomanSpaceTelescope/
# roman-technical-information @ 229bd3cc, CC0; sha256 of SCA01 %s),
# see roman-data.md 1.3: each filter's column averaged over 5 nm (five
# 1 nm rows) at 5 nm steps, kept where any SCA exceeds 0.5%% of the
# filter's peak.  wave is the bin centre in micron.
''' % srcs[0])
        f.write('\t'.join(['filter', 'wave'] + ['sca%02d' % s for s in
                                                range(1, NSCA + 1)]) + '\n')
        for flt in FILTERS:
            a = np.array([np.array(t[flt], dtype=float) for t in tabs])
            nb = len(wave) // step
            ab = a[:, :nb * step].reshape(NSCA, nb, step).mean(axis=2)
            wb = wave[:nb * step].reshape(nb, step).mean(axis=1)
            keep = ab.max(axis=0) > 0.005 * ab.max()
            idx = np.nonzero(keep)[0]
            for k in range(idx[0], idx[-1] + 1):
                f.write('\t'.join([flt, '%.4f' % wb[k]] +
                                  ['%.4f' % v for v in ab[:, k]]) + '\n')


def main():
    os.makedirs(DATA, exist_ok=True)
    zernikes(os.path.join(DATA, 'zernike.tsv'))
    throughput(os.path.join(DATA, 'throughput.tsv'))
    pupils(DATA)


if __name__ == '__main__':
    main()
