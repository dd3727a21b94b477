#!/usr/bin/env python3
"""Derive wfiscene's correlated read-noise table from a public Roman file
in ../shared/roman/:

  data/readnoise.tsv  per SCA the amplitudes (e- per read) of the read
                      noise's parts (src/readnoise.c): white per pixel,
                      pedestal per channel and read, pink shared by the
                      channels, pink of each channel, alternating columns

The structure and the ratios of the parts are those of the example
parameters of Rauscher (2015, PASP 127, 1144, NGHXRG), H2RG of JWST
NIRSpec: white 4, pedestal 4, shared pink 3, own pink 1, alternating
columns 0.5.  The scale: the Project's median CDS noise per SCA
(WFI_CDS_Noise_summary.ecsv) taken as that of reference-corrected reads,
whose noise is the white part and the channel's own pink (the other
parts are what the reference pixels remove): white^2 + own^2 = CDS^2 / 2,
then all parts divided by CAL: the shared pink the smoothed side columns
miss adds to a corrected read too.  CAL = 1.075 is the mean over the 18
SCAs of the corrected CDS noise that build/tests/readnoise_stats all
measured with the parts before that division, over the Project's (from
1.049 to 1.109, one exposure each).

Development-time only: the product embeds the table this writes and never
reads ../shared.

    python3 contrib/tables/derive_readnoise.py [SHARED_ROMAN_DIR] [DATA_DIR]
"""
import math
import os
import sys

from roman_files import ecsv_rows, manifest

roman = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
    os.path.dirname(__file__), "..", "..", "..", "shared", "roman")
out = sys.argv[2] if len(sys.argv) > 2 else os.path.join(
    os.path.dirname(__file__), "..", "..", "data")

CAL = 1.075
RATIO = {"ped": 1.0, "cpink": 0.75, "upink": 0.25, "acn": 0.125}


def main():
    name = "WFI_CDS_Noise_summary.ecsv"
    m = manifest(roman)
    repo, path, commit = m[name]
    head, cells = ecsv_rows(os.path.join(roman, name))
    cds_col = head.index("CDS Noise - Median")
    rows = []
    for f in cells:
        if not f[0].isdigit():
            continue
        w0 = float(f[cds_col]) / math.sqrt(2)
        white = w0 / math.sqrt(1 + RATIO["upink"] ** 2) / CAL
        rows.append((int(f[0]), float(f[cds_col]), white))
    with open(os.path.join(out, "readnoise.tsv"), "w") as o:
        o.write("# Roman WFI read noise in parts, e- per read (src/readnoise.c).\n")
        o.write("# Derived by contrib/tables/derive_readnoise.py from the Project's median\n")
        o.write("#   CDS noise, %s %s@%s (SCU n as WFInn),\n" % (repo, path, commit[:12]))
        o.write("#   taken as that of reference-corrected reads: white^2 + upink^2 = CDS^2/2,\n")
        o.write("#   the parts then / %.3f, the mean excess of the corrected CDS noise\n" % CAL)
        o.write("#   build/tests/readnoise_stats measured without it (shared pink missed).\n")
        o.write("# The parts' ratios to the white part: NGHXRG's example parameters\n")
        o.write("#   (Rauscher 2015, PASP 127, 1144): pedestal 1, shared pink 0.75,\n")
        o.write("#   own pink 0.25, alternating columns 0.125.\n")
        o.write("sca\tcds\twhite\tped\tcpink\tupink\tacn\n")
        for scu, cds, w in rows:
            o.write("WFI%02d\t%.2f\t%.4f\t%.4f\t%.4f\t%.4f\t%.4f\n" % (
                scu, cds, w, w * RATIO["ped"], w * RATIO["cpink"],
                w * RATIO["upink"], w * RATIO["acn"]))


main()
