#!/usr/bin/env python3
"""Derive wfiscene's persistence table from public Roman files in
../shared/roman/:

  data/persistence.tsv  per SCA the Roman Project's fitted decay of the
                        persistence current, a e^(-b t) + d e^(-e t) + c
                        (e-/s, t in s after the end of the stimulus), the
                        last time it was measured at, and the constants of
                        the fermi model that scales it with the stimulus

Development-time only: the product embeds the table this writes and never
reads ../shared.

    python3 contrib/tables/derive_persistence.py [SHARED_ROMAN_DIR] [DATA_DIR]
"""
import os
import sys

from roman_files import ecsv_rows, manifest, source

roman = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
    os.path.dirname(__file__), "..", "..", "..", "shared", "roman")
out = sys.argv[2] if len(sys.argv) > 2 else os.path.join(
    os.path.dirname(__file__), "..", "..", "data")


m = manifest(roman)
head, fits = ecsv_rows(os.path.join(roman, "WFI_Persistence_exp_fits.ecsv"))
assert head == ["SCU", "a", "b", "c", "d", "e"], head
shead, summ = ecsv_rows(os.path.join(roman, "WFI_Persistence_summary.ecsv"))
assert shead[0] == "time", shead
tmax = max(float(r[0]) for r in summ)
tmin = min(float(r[0]) for r in summ)
lines = [
    "# Roman WFI persistence: the afterglow of trapped charge (wfiscene(1), PERSISTENCE).",
    "# Derived by contrib/tables/derive_persistence.py.  Per-SCA rows 'decay WFInn':",
    "#   a b c d e of the Project's fit a e^(-b t) + d e^(-e t) + c (e-/s, t s",
    "#   after the end of the stimulus) to the median persistence of SCU n, taken",
    "#   as SCA WFInn; %s." % source(m, "WFI_Persistence_exp_fits.ecsv"),
    "# const tmax: the last time of the measurements the fit was made to",
    "#   (%g .. %g s), beyond which wfiscene releases nothing; %s." % (
        tmin, tmax, source(m, "WFI_Persistence_summary.ecsv")),
    "# fermi rows: the fermi model of GalSim's roman module and romanisim (H4RG-lo),",
    "#   which scales the amplitude with the stimulus's fluence x.",
    "kind\tkey\ta\tb\tc\td\te\tsource",
]
lines.append("const\ttmax\t%.3f\t0\t0\t0\t0\tlast time of WFI_Persistence_summary.ecsv (s)" % tmax)
lines.append("const\tfermi\t0.017\t60000\t50000\t0.045\t50000\tA (e-/s at 1000 s), x0, dx (e-), alpha, half well (e-): romanisim parameters.persistence")
lines.append("const\treference\t100000\t0\t0\t0\t0\tfluence (e-) of the stimulus the Project's curves are taken to follow: a full well (wfiscene's choice)")
for r in fits:
    scu = int(r[0])
    lines.append("decay\tWFI%02d\t%s\t%s\t%s\t%s\t%s\tSCU %d fit" % (
        scu, r[1], r[2], r[3], r[4], r[5], scu))
open(os.path.join(out, "persistence.tsv"), "w").write("\n".join(lines) + "\n")
