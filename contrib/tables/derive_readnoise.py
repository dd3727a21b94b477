#!/usr/bin/env python3
"""Derive wfiscene's correlated read-noise table from public Roman files
in ../shared/roman/:

  data/readnoise.tsv  per SCA the amplitudes (e- per read) of the read
                      noise's parts (src/readnoise.c): white per pixel,
                      pedestal per channel and read, pink shared by the
                      channels, pink of each channel, alternating columns,
                      and the slow part of each pixel (rms, correlation
                      time)

Two of the Project's measurements per SCA fix two amplitudes:
WFI_CDS_Noise_summary.ecsv (median CDS noise) and WFI_Total_noise.ecsv
(median total noise: 55 reads, top and column reference correction, the
slope through all reads times the exposure time).

The structure and the ratios of the channel parts to the white part are
the example parameters of Rauscher (2015, PASP 127, 1144, NGHXRG), H2RG
of JWST NIRSpec: white 4, pedestal 4, shared pink 3, own pink 1,
alternating columns 0.5.  With them alone, measured as the Project
measures (build/tests/readnoise_stats calib, reference-corrected), a
white part w gives a CDS noise CDS_WHITE w and a total read noise
TOTAL_WHITE w (the dark current's shot noise apart): the total then falls
7-21 % short of the Project's.  What is missing is noise a pixel keeps
over many reads, which the reference pixels cannot remove: the slow part,
a Gauss-Markov sequence per pixel of rms s and correlation time TAU at
knots every KNOT reads, linear between them (src/readnoise.c).  Its
shares of the CDS and total variance, CS s^2 and TS s^2, are computed
here exactly from that definition.  Per SCA, w and s solve

  CDS_WHITE^2 w^2 + CS s^2 = CDS^2
  TOTAL_WHITE^2 w^2 + TS s^2 = TOTAL^2 - DARK

(DARK the slope's variance from the median dark current's shot noise,
times the exposure time squared, as readnoise_stats adds it).  TAU is not
fixed by the two tables (any TAU well above a read time fits both); 100 s,
inside the range of random-telegraph time constants reported for HxRG
pixels, keeps s a few e-.

Development-time only: the product embeds the table this writes and never
reads ../shared.

    python3 contrib/tables/derive_readnoise.py [SHARED_ROMAN_DIR] [DATA_DIR]
"""
import math
import os
import sys

from roman_files import ecsv_rows, manifest, source

roman = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
    os.path.dirname(__file__), "..", "..", "..", "shared", "roman")
out = sys.argv[2] if len(sys.argv) > 2 else os.path.join(
    os.path.dirname(__file__), "..", "..", "data")

# build/tests/readnoise_stats calib (the parts below, no slow part)
CDS_WHITE = 1.5608
TOTAL_WHITE = 0.5086
RATIO = {"ped": 1.0, "cpink": 0.75, "upink": 0.25, "acn": 0.125}
NREAD = 55
READ_TIME = 3.16247     # s, data/detector.tsv read_time
KNOT = 8                # reads between knots, src/readnoise.h RN_KNOT
TAU = 100.0             # s


def column(name, col):
    """SCU number -> the column col of the Project's table name."""
    head, cells = ecsv_rows(os.path.join(roman, name))
    c = head.index(col)
    return {int(f[0]): float(f[c]) for f in cells if f[0].isdigit()}


def slope_weights():
    t = [k * READ_TIME for k in range(1, NREAD + 1)]
    tm = sum(t) / NREAD
    s2 = sum((x - tm) ** 2 for x in t)
    return [(x - tm) / s2 for x in t]


def slow_factors():
    """The slow part's CDS variance (reads 1, 2) and total variance (the
    slope's times T^2) per unit s^2."""
    rho = math.exp(-KNOT * READ_TIME / TAU)

    def lin(k):             # read k's weights on the knots
        j, f = k // KNOT, (k % KNOT) / KNOT
        return {j: 1 - f, j + 1: f}

    def cov(u, v):
        return sum(a * b * rho ** abs(i - j) for i, a in u.items() for j, b in v.items())

    d = {}
    for i, a in lin(2).items():
        d[i] = d.get(i, 0) + a
    for i, a in lin(1).items():
        d[i] = d.get(i, 0) - a
    cs = cov(d, d)
    w = slope_weights()
    tot = {}
    for k in range(1, NREAD + 1):
        for i, a in lin(k).items():
            tot[i] = tot.get(i, 0) + w[k - 1] * a
    T = (NREAD - 1) * READ_TIME
    return cs, cov(tot, tot) * T * T


def dark_part(dark):
    w = slope_weights()
    T = (NREAD - 1) * READ_TIME
    v = sum(w[i] * w[j] * (min(i, j) + 1) * READ_TIME * dark
            for i in range(NREAD) for j in range(NREAD))
    return v * T * T


def main():
    m = manifest(roman)
    cds = column("WFI_CDS_Noise_summary.ecsv", "CDS Noise - Median")
    total = column("WFI_Total_noise.ecsv", "Total noise - median")
    dark = column("WFI_Dark_current_summary.ecsv", "Dark Current - Median")
    cs, ts = slow_factors()
    rows = []
    for scu in sorted(cds):
        # CDS_WHITE^2 w2 + cs s2 = C^2, TOTAL_WHITE^2 w2 + ts s2 = T^2 - D
        c2, t2 = cds[scu] ** 2, total[scu] ** 2 - dark_part(dark[scu])
        det = CDS_WHITE ** 2 * ts - cs * TOTAL_WHITE ** 2
        w2 = (c2 * ts - cs * t2) / det
        s2 = (CDS_WHITE ** 2 * t2 - TOTAL_WHITE ** 2 * c2) / det
        if w2 <= 0 or s2 < 0:
            sys.exit("WFI%02d: no solution (w^2 %g, s^2 %g)" % (scu, w2, s2))
        rows.append((scu, cds[scu], total[scu], math.sqrt(w2), math.sqrt(s2)))
    src = lambda n: source(m, n)
    with open(os.path.join(out, "readnoise.tsv"), "w") as o:
        o.write("# Roman WFI read noise in parts, e- per read (src/readnoise.c).\n")
        o.write("# Derived by contrib/tables/derive_readnoise.py (SCU n as WFInn) from the\n")
        o.write("#   Project's median CDS noise (cds), %s,\n" % src("WFI_CDS_Noise_summary.ecsv"))
        o.write("#   median total noise of 55 reads (total), %s,\n" % src("WFI_Total_noise.ecsv"))
        o.write("#   and median dark current, %s:\n" % src("WFI_Dark_current_summary.ecsv"))
        o.write("#   white and slow solve CDS_WHITE^2 white^2 + %.6f slow^2 = cds^2 and\n" % cs)
        o.write("#   TOTAL_WHITE^2 white^2 + %.4f slow^2 = total^2 - dark part, with\n" % ts)
        o.write("#   CDS_WHITE = %.4f, TOTAL_WHITE = %.4f (build/tests/readnoise_stats calib)\n"
                % (CDS_WHITE, TOTAL_WHITE))
        o.write("#   and slow_tau %g s, knots every %d reads (the script's docstring).\n"
                % (TAU, KNOT))
        o.write("# The channel parts' ratios to the white part: NGHXRG's example parameters\n")
        o.write("#   (Rauscher 2015, PASP 127, 1144): pedestal 1, shared pink 0.75,\n")
        o.write("#   own pink 0.25, alternating columns 0.125.\n")
        o.write("sca\tcds\ttotal\twhite\tped\tcpink\tupink\tacn\tslow\tslow_tau\n")
        for scu, c, t, w, s in rows:
            o.write("WFI%02d\t%.2f\t%.2f\t%.4f\t%.4f\t%.4f\t%.4f\t%.4f\t%.4f\t%g\n" % (
                scu, c, t, w, w * RATIO["ped"], w * RATIO["cpink"],
                w * RATIO["upink"], w * RATIO["acn"], s, TAU))


main()
