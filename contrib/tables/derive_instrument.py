#!/usr/bin/env python3
"""Derive wfiscene's instrument tables (data/sca.tsv, data/filters.tsv) from the
public Roman reference files in ../shared/roman/.  Development-time only: the
product embeds the tables this writes and never reads ../shared.

    python3 contrib/tables/derive_instrument.py [SHARED_ROMAN_DIR] [DATA_DIR]
"""
import math
import os
import sys

from siaf_xml import siaf_entries

roman = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
    os.path.dirname(__file__), "..", "..", "..", "shared", "roman")
out = sys.argv[2] if len(sys.argv) > 2 else os.path.join(
    os.path.dirname(__file__), "..", "..", "data")

FILTERS = ["F062", "F087", "F106", "F129", "F158", "F184", "F213", "F146"]


def unit(v2, v3):
    """V2/V3 (arcsec) are spherical angles (longitude V2, latitude V3)."""
    a, d = math.radians(v2 / 3600), math.radians(v3 / 3600)
    return (math.cos(d) * math.cos(a), math.cos(d) * math.sin(a), math.sin(d))


def tangent(ref, p):
    """Gnomonic (TAN) coordinates of p about ref, in arcsec, with xi along
    increasing V2 and eta along increasing V3 at ref."""
    a0, d0 = math.radians(ref[0] / 3600), math.radians(ref[1] / 3600)
    x, y, z = unit(*p)
    # rotate ref to (1, 0, 0): first about z by -a0, then about y by d0
    x, y = x * math.cos(a0) + y * math.sin(a0), -x * math.sin(a0) + y * math.cos(a0)
    x, z = x * math.cos(d0) + z * math.sin(d0), -x * math.sin(d0) + z * math.cos(d0)
    k = 180 / math.pi * 3600
    return (y / x * k, z / x * k)


def ideal(ref_entry, p):
    """Focal-plane tangent coordinates of p in the ideal frame of ref_entry:
    rotate the V2/V3 tangent offsets by V3IdlYAngle and apply VIdlParity, as
    the SIAF defines the ideal frame (x_idl along the science +x axis)."""
    ref = (float(ref_entry["V2Ref"]), float(ref_entry["V3Ref"]))
    du, dv = tangent(ref, p)
    ang = math.radians(float(ref_entry["V3IdlYAngle"]))
    par = float(ref_entry["VIdlParity"])
    x = par * (du * math.cos(ang) - dv * math.sin(ang))
    y = du * math.sin(ang) + dv * math.cos(ang)
    return x, y


def write_sca(siaf):
    wfi01, cen = siaf["WFI01_FULL"], siaf["WFI_CEN"]
    rows = []
    for n in range(1, 19):
        e = siaf["WFI%02d_FULL" % n]
        p = (float(e["V2Ref"]), float(e["V3Ref"]))
        x1, y1 = ideal(wfi01, p)
        xb, yb = ideal(cen, p)
        # the science axes' rotation in the ideal frame, from the linear terms
        rot = math.degrees(math.atan2(float(e["Sci2IdlY10"]), float(e["Sci2IdlX10"])))
        rows.append((n, x1, y1, xb, yb, rot, float(e["XSciScale"]), float(e["YSciScale"])))
    with open(os.path.join(out, "sca.tsv"), "w") as f:
        f.write("# Roman WFI SCA layout, derived by contrib/tables/derive_instrument.py from\n"
                "# the Roman SIAF (pysiaf prd_data/Roman/roman_siaf.xml, Dec 2023 delivery):\n"
                "# each WFInn_FULL reference point (V2Ref, V3Ref, spherical angles) is\n"
                "# projected gnomonically about WFI01's reference point (x_wfi01, y_wfi01)\n"
                "# and about WFI_CEN, the WFI boresight (x_bore, y_bore), and rotated into\n"
                "# the ideal frame (V3IdlYAngle -60 deg, VIdlParity -1), whose x and y run\n"
                "# along the science-frame pixel axes.  Units: arcsec.  sci_rot is the\n"
                "# rotation of the science axes in the ideal frame from Sci2Idl linear terms\n"
                "# (deg; informational, wfiscene aligns all SCAs as STIPS does);\n"
                "# xscale/yscale the SIAF mean pixel scales (informational: wfiscene uses\n"
                "# 0.11 arcsec/pixel like STIPS).\n")
        f.write("sca\tx_wfi01\ty_wfi01\tx_bore\ty_bore\tsci_rot\txscale\tyscale\n")
        for r in rows:
            f.write("%d\t%.4f\t%.4f\t%.4f\t%.4f\t%.4f\t%.6f\t%.6f\n" % r)


def read_zeropoints():
    zp = {}
    for line in open(os.path.join(roman, "Roman_zeropoints_20240301.ecsv")):
        if line.startswith("#") or line.startswith("detector"):
            continue
        f = line.split()
        if len(f) >= 4 and f[0].startswith("WFI"):
            zp[(int(f[0][3:]), f[1])] = float(f[3])
    return zp


def read_filter_params():
    par = {}
    for line in open(os.path.join(roman, "filter_parameters.ecsv")):
        if line.startswith("#") or line.startswith("filter"):
            continue
        f = [x.strip() for x in line.split(",")]
        if len(f) > 3 and f[0] in FILTERS:
            par[f[0]] = (float(f[1]), float(f[2]), float(f[3]))
    return par


# STIPS's fixed per-filter values (stips/instruments/wfi.py, 2.3; the paper's
# Table 1 for the background): AB zeropoint, PHOTPLAM in micron, and the
# default "avg" background in counts/s/pixel (Pandeia benchmark zodiacal plus
# internal background at lat 266.3, lon -50, June 19 2023).
STIPS = {
    "F062": (26.77, 0.6291, 0.78), "F087": (26.43, 0.8696, 0.66),
    "F106": (26.45, 1.0567, 0.62), "F129": (26.47, 1.2901, 0.54),
    "F158": (26.50, 1.5749, 0.49), "F184": (26.12, 1.8394, 0.45),
    "F213": (26.06, 2.1230, 3.88), "F146": (27.70, 1.4378, 1.78),
}


def write_filters():
    zp, par = read_zeropoints(), read_filter_params()
    with open(os.path.join(out, "filters.tsv"), "w") as f:
        f.write("# Roman WFI filters, derived by contrib/tables/derive_instrument.py from\n"
                "# roman-technical-information: filter_parameters.ecsv (band edges and\n"
                "# centre, micron, 2024-07-25) and Roman_zeropoints_20240301.ecsv (zp_NN:\n"
                "# the AB magnitude giving 1 e-/s on SCA NN, synphot unit_response with\n"
                "# the 2024-03-01 effective areas).  stips_zp, photplam and bkg_avg are\n"
                "# STIPS 2.3's fixed values: its zeropoint, pivot wavelength (micron) and\n"
                "# the STIPS paper's Table 1 default background (counts/s/pixel; Pandeia\n"
                "# benchmark zodiacal + internal background, lat 266.3 lon -50, defined\n"
                "# 2023-06-19).  wide = 1 for filters imaged through the wide (F184) pupil.\n")
        cols = ["filter", "lam_min", "lam_max", "lam_centre", "photplam", "stips_zp",
                "bkg_avg", "wide"] + ["zp_%02d" % n for n in range(1, 19)]
        f.write("\t".join(cols) + "\n")
        for flt in FILTERS:
            lo, hi, c = par[flt]
            s = STIPS[flt]
            row = [flt, "%.4f" % lo, "%.4f" % hi, "%.4f" % c, "%.4f" % s[1], "%.2f" % s[0],
                   "%.2f" % s[2], "1" if flt in ("F184", "F213") else "0"]
            row += ["%.4f" % zp[(n, flt)] for n in range(1, 19)]
            f.write("\t".join(row) + "\n")


if __name__ == "__main__":
    siaf = siaf_entries(os.path.join(roman, "roman_siaf.xml"))
    write_sca(siaf)
    write_filters()
