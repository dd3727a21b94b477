#!/usr/bin/env python3
"""Derive wfiscene's detector tables for the up-the-ramp levels from public
Roman files in ../shared/roman/:

  data/ma_tables.tsv   the read pattern of each MultiAccum table
  data/detector.tsv    every detector constant of levels 1 and 2, per SCA
                       where the Roman Project measured it, with its source

Development-time only: the product embeds the tables this writes and never
reads ../shared.

    python3 contrib/tables/derive_detector.py [SHARED_ROMAN_DIR] [DATA_DIR]
"""
import math
import os
import sys

from roman_files import ecsv_rows, manifest, source

roman = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
    os.path.dirname(__file__), "..", "..", "..", "shared", "roman")
out = sys.argv[2] if len(sys.argv) > 2 else os.path.join(
    os.path.dirname(__file__), "..", "..", "data")

READ_TIME = 3.16247  # s, romanisim parameters.read_time


def ma_tables(m):
    src = os.path.join(roman, "ma_tables.tsv")
    rows = []
    for line in open(src):
        if line.startswith("#") or not line.strip():
            continue
        f = line.rstrip("\n").split("\t")
        table, nres, last, expt, pattern = int(f[0]), int(f[1]), int(f[2]), float(f[3]), f[4]
        groups = [[int(r) for r in g.split(",")] for g in pattern.split(";")]
        # Checks: the counts agree, reads ascend, groups are runs of
        # consecutive reads (gaps between groups are allowed: tables 109).
        assert len(groups) == nres, table
        reads = [r for g in groups for r in g]
        assert reads == sorted(reads) and len(set(reads)) == len(reads), table
        assert reads[-1] == last, table
        for g in groups:
            assert g == list(range(g[0], g[-1] + 1)), (table, g)
        assert abs(last * READ_TIME - expt) < 1e-3, (table, expt)
        rows.append((table, nres, last, last * READ_TIME,
                     ";".join("%d-%d" % (g[0], g[-1]) for g in groups)))
    with open(os.path.join(out, "ma_tables.tsv"), "w") as o:
        repo, path, commit = m["ma_tables.tsv"]
        o.write("# Roman WFI MultiAccum tables: the reads averaged into each resultant.\n")
        o.write("# Source: %s %s, commit %s,\n" % (repo, path, commit[:12]))
        o.write("# tabulated in ma_tables.tsv; derived by contrib/tables/derive_detector.py, which checks\n")
        o.write("# that each resultant is a run of consecutive reads, that the reads ascend\n")
        o.write("# and that exposure = last read x %.5f s.  Read k ends k read times after\n" % READ_TIME)
        o.write("# the reset.  Tables 109 and 110 are test tables (109 skips reads).\n")
        o.write("ma_table\tn_resultants\tlast_read\texposure_s\tresultants (first-last read of each, ';' between)\n")
        for r in rows:
            o.write("%d\t%d\t%d\t%.3f\t%s\n" % r)


def detector(m):
    head, noise = ecsv_rows(os.path.join(roman, "WFI_CDS_Noise_summary.ecsv"))
    _, dark = ecsv_rows(os.path.join(roman, "WFI_Dark_current_summary.ecsv"))
    cds = {int(r[0]): float(r[2]) for r in noise if r[0].isdigit()}
    drk = {int(r[0]): float(r[3]) for r in dark if r[0].isdigit()}
    assert sorted(cds) == list(range(1, 19)) and sorted(drk) == list(range(1, 19))
    rs = "romanisim romanisim/models/parameters.py@492a63c52e58"
    gs = "GalSim galsim/roman/__init__.py"
    consts = [
        ("read_time", READ_TIME, "s", rs + " read_time"),
        ("gain", 2.0, "e-/DN", rs + " reference_data gain"),
        ("saturation", 55000, "DN", rs + " reference_data saturation (measured signal, pedestal included)"),
        ("nonlinearity_beta", -6e-7, "1/e-", gs + " nonlinearity_beta: measured = true + beta true^2"),
        ("pedestal", 10000, "e-", rs + " pedestal (reset level)"),
        ("reset_noise", 8, "e-", rs + " pedestal_extra_noise (once per pixel and exposure)"),
        ("cosmic_rate", 5.0, "hits/cm^2/s", "STIPS two populations, as wfiscene --cosmic-rate (per population)"),
        ("cosmic_e_low", 600, "e-", "STIPS galactic population"),
        ("cosmic_e_high", 5000, "e-", "STIPS solar population"),
        ("pixel_area", 1e-6, "cm^2", "H4RG-10: 10 micron pixels"),
        ("jump_threshold", 5.0, "sigma", "wfiscene's choice (romancal's default is 4-5 sigma)"),
        ("nonlinear_flag", 0.05, "1", "wfiscene's choice: DQ NONLINEAR where the correction of a used resultant exceeds this fraction"),
    ]
    # GalSim's roman IPC kernel (roman_config.py ipc_kernel), normalised to
    # sum 1; rows are y offsets -1, 0, +1, columns x offsets -1, 0, +1.
    ipc = [[0.001269938, 0.015399776, 0.001199862],
           [0.013800177, 1.0, 0.015600367],
           [0.001270391, 0.016129619, 0.001200137]]
    s = sum(sum(r) for r in ipc)
    with open(os.path.join(out, "detector.tsv"), "w") as o:
        o.write("# Roman WFI detector constants of the up-the-ramp levels (--level 1, 2).\n")
        o.write("# Derived by contrib/tables/derive_detector.py.  Per-SCA rows:\n")
        o.write("#   readnoise WFInn: the Project's median CDS noise / sqrt(2) (a CDS\n")
        o.write("#     difference holds two reads), e- per read; %s.\n" % source(m, "WFI_CDS_Noise_summary.ecsv"))
        o.write("#   dark WFInn: the Project's mean dark current, e-/s (hot pixels in the\n")
        o.write("#     mean, as the scene's dark stage); %s.\n" % source(m, "WFI_Dark_current_summary.ecsv"))
        o.write("#   SCU n of those tables is taken as SCA WFInn.\n")
        o.write("# Constants: their source in the last column.  ipc rows: GalSim's roman\n")
        o.write("#   ipc_kernel normalised to sum 1 (sum before %.9f).\n" % s)
        o.write("kind\tkey\tvalue\tunit\tsource\n")
        for k, v, u, src in consts:
            o.write("const\t%s\t%.10g\t%s\t%s\n" % (k, v, u, src))
        for dy in range(3):
            for dx in range(3):
                o.write("ipc\t%+d,%+d\t%.9f\t1\t%s ipc_kernel\n" % (dx - 1, dy - 1, ipc[dy][dx] / s, gs))
        for n in range(1, 19):
            o.write("readnoise\tWFI%02d\t%.4f\te-\tCDS median %.2f e- / sqrt(2)\n" % (n, cds[n] / math.sqrt(2), cds[n]))
        for n in range(1, 19):
            o.write("dark\tWFI%02d\t%.3f\te-/s\tmean dark current\n" % (n, drk[n]))


m = manifest(roman)
ma_tables(m)
detector(m)
