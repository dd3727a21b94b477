#!/usr/bin/python3
"""sersic-figures.py - figures of the Sérsic accuracy/cost table.

Reads the markdown table that contrib/sersic-bench.py prints (from a file or
stdin) and draws, for quick and precise, the total-flux error, the worst
central-pixel error and the microseconds per galaxy against n, one line per
r_e.  Usage:

    /usr/bin/python3 contrib/sersic-bench.py > sersic.md
    /usr/bin/python3 contrib/sersic-figures.py sersic.md -o sersic.png
"""
import argparse
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read_table(f):
    rows = []
    for line in f:
        cells = [c.strip().replace(",", "") for c in line.strip().strip("|").split("|")]
        if len(cells) < 6 or not cells[0][:1].isdigit():
            continue
        rows.append([float(c) for c in cells])
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("table", nargs="?")
    ap.add_argument("-o", "--output", default="sersic.png")
    a = ap.parse_args()
    rows = read_table(open(a.table) if a.table else sys.stdin)
    res = sorted({r[1] for r in rows})
    fig, ax = plt.subplots(3, 2, figsize=(10, 10), sharex=True)
    for col, (name, off) in enumerate((("quick", 2), ("precise", 6))):
        for re in res:
            sel = [r for r in rows if r[1] == re]
            n = [r[0] for r in sel]
            ax[0][col].semilogy(n, [max(abs(r[off]), 1e-13) for r in sel], "o-", label=f"r_e = {re:g} px")
            ax[1][col].semilogy(n, [max(r[off + 1], 1e-13) for r in sel], "o-", label=f"r_e = {re:g} px")
            ax[2][col].semilogy(n, [r[off + 2] for r in sel], "o-", label=f"r_e = {re:g} px")
        ax[0][col].set_title(f"sersic-{name}")
        ax[0][col].axhline(1e-2 if name == "quick" else 1e-3, color="grey", ls="--")
        ax[1][col].axhline(1e-2, color="grey", ls="--")
        ax[2][col].set_xlabel("Sérsic index n")
    ax[0][0].set_ylabel("|total flux error|")
    ax[1][0].set_ylabel("worst central 5x5 pixel error")
    ax[2][0].set_ylabel("µs per galaxy (with PSF)")
    ax[0][0].legend()
    fig.tight_layout()
    fig.savefig(a.output, dpi=100)


if __name__ == "__main__":
    main()
