#!/usr/bin/python3
"""Derive data/siaf.tsv, wfiscene's Roman WFI geometry, from the Roman SIAF
(../shared/roman/roman_siaf.xml).  Development-time only: the product embeds
the table and never reads ../shared.

    /usr/bin/python3 contrib/tables/siaf.py [SHARED_ROMAN_DIR] [DATA_DIR]

One row per WFInn_FULL aperture (sca 1..18) and one for WFI_CEN (sca 0, the
boresight; it has no pixels).  Columns:

  v2ref v3ref            reference point, arcsec (spherical V2/V3)
  v3idlyangle vidlparity ideal frame: +y_idl at V3IdlYAngle from +V3 toward
                         +V2, x_idl = parity * (the +V2-ward axis)
  xsciref ysciref        science pixel (1-based) of the reference point
  xsciscale ysciscale    the SIAF's nominal scales, arcsec/pixel
  sx_i_j sy_i_j          Sci2IdlX/Y coefficient of (xsci - xsciref)^(i-j)
                         * (ysci - ysciref)^j, arcsec (SIAF naming: i the
                         total degree, j the power of y), 1 <= i <= 5
  ix_i_j iy_i_j          Idl2SciX/Y, the SIAF's approximate inverse
  a_p_q b_p_q            SIP forward (order 5, 2 <= p+q <= 5): u + A(u,v),
                         v + B(u,v), u = xsci - xsciref, is the ideal point
                         through the inverse of the linear Sci2Idl terms.
                         Exact, by algebra: A = L^-1 (Sci2Idl - L).
  ap_p_q bp_p_q          SIP inverse (order SIP_INV, 1 <= p+q): least-squares
                         fit of the exact inverse of Sci2Idl on a grid over
                         the whole SCA; the worst error on a finer grid is in
                         the header.
"""
import os
import sys

import numpy as np

from siaf_xml import siaf_entries

roman = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
    os.path.dirname(__file__), "..", "..", "..", "shared", "roman")
out = sys.argv[2] if len(sys.argv) > 2 else os.path.join(
    os.path.dirname(__file__), "..", "..", "data")

DEG = 5          # Sci2Idl / Idl2Sci degree in this SIAF
SIP_INV = 6      # order of the fitted inverse (5: 3.7e-3 px, 6: 2.3e-4 px)
HALF = 2044.0    # science pixels from the reference to the edge (4088 / 2)
COMMIT = "1aa2e85c6057dbbd95fb7f4de6a36f9e0d30988b"


def coeffs(e, name):
    """{(i, j): value} of a SIAF polynomial, i = total degree, j = power of y."""
    return {(i, j): float(e.get("%s%d%d" % (name, i, j), "0") or 0)
            for i in range(DEG + 1) for j in range(i + 1)}


def poly(c, u, v):
    return sum(c[(i, j)] * u ** (i - j) * v ** j for (i, j) in c)


def sip_forward(sx, sy):
    """A/B of order DEG: L^-1 times the non-linear Sci2Idl terms."""
    L = np.array([[sx[(1, 0)], sx[(1, 1)]], [sy[(1, 0)], sy[(1, 1)]]])
    Li = np.linalg.inv(L)
    a, b = {}, {}
    for i in range(2, DEG + 1):
        for j in range(i + 1):
            p, q = i - j, j
            a[(p, q)] = Li[0, 0] * sx[(i, j)] + Li[0, 1] * sy[(i, j)]
            b[(p, q)] = Li[1, 0] * sx[(i, j)] + Li[1, 1] * sy[(i, j)]
    return L, a, b


def exact_ideal_uv(sx, sy, L, u, v):
    """Sci2Idl through L^-1: the SIP intermediate pixel coordinates U, V."""
    x, y = poly(sx, u, v), poly(sy, u, v)
    Li = np.linalg.inv(L)
    return Li[0, 0] * x + Li[0, 1] * y, Li[1, 0] * x + Li[1, 1] * y


def terms(order, lo):
    return [(p, n - p) for n in range(lo, order + 1) for p in range(n, -1, -1)]


def sip_inverse(sx, sy, L):
    """AP/BP: least squares over a grid covering the SCA, in scaled units."""
    g = np.linspace(-HALF - 0.5, HALF + 0.5, 61)
    u, v = [a.ravel() for a in np.meshgrid(g, g)]
    U, V = exact_ideal_uv(sx, sy, L, u, v)
    t = terms(SIP_INV, 1)
    M = np.stack([(U / HALF) ** p * (V / HALF) ** q for p, q in t], axis=1)
    ca, *_ = np.linalg.lstsq(M, u - U, rcond=None)
    cb, *_ = np.linalg.lstsq(M, v - V, rcond=None)
    ap = {pq: ca[k] / HALF ** (pq[0] + pq[1]) for k, pq in enumerate(t)}
    bp = {pq: cb[k] / HALF ** (pq[0] + pq[1]) for k, pq in enumerate(t)}
    # the worst error on a finer, offset grid, forward composed with inverse
    g = np.linspace(-HALF - 0.5, HALF + 0.5, 203)
    u, v = [a.ravel() for a in np.meshgrid(g, g)]
    U, V = exact_ideal_uv(sx, sy, L, u, v)
    du = U + sum(c * U ** p * V ** q for (p, q), c in ap.items()) - u
    dv = V + sum(c * U ** p * V ** q for (p, q), c in bp.items()) - v
    return ap, bp, float(np.max(np.hypot(du, dv)))


def main():
    siaf = siaf_entries(os.path.join(roman, "roman_siaf.xml"))
    names = [("WFI%02d_FULL" % n, n) for n in range(1, 19)] + [("WFI_CEN", 0)]
    fwd = terms(DEG, 2)
    inv = terms(SIP_INV, 1)
    poly_cols = ["%s_%d_%d" % (k, i, j) for k in ("sx", "sy", "ix", "iy")
                 for i in range(1, DEG + 1) for j in range(i + 1)]
    cols = (["aperture", "sca", "v2ref", "v3ref", "v3idlyangle", "vidlparity",
             "xsciref", "ysciref", "xsciscale", "ysciscale"] + poly_cols +
            ["a_%d_%d" % t for t in fwd] + ["b_%d_%d" % t for t in fwd] +
            ["ap_%d_%d" % t for t in inv] + ["bp_%d_%d" % t for t in inv])
    rows, worst = [], 0.0
    for name, sca in names:
        e = siaf[name]
        row = [name, str(sca)] + ["%.17g" % float(e[k]) for k in
                                  ("V2Ref", "V3Ref", "V3IdlYAngle", "VIdlParity")]
        if sca == 0:
            row += ["0"] * (len(cols) - len(row))
            rows.append(row)
            continue
        row += ["%.17g" % float(e[k]) for k in ("XSciRef", "YSciRef", "XSciScale", "YSciScale")]
        pc = {k: coeffs(e, n) for k, n in (("sx", "Sci2IdlX"), ("sy", "Sci2IdlY"),
                                          ("ix", "Idl2SciX"), ("iy", "Idl2SciY"))}
        for k in ("sx", "sy", "ix", "iy"):
            if pc[k][(0, 0)] != 0:
                sys.exit("%s: %s has a constant term; wfiscene assumes none" % (name, k))
            row += ["%.17g" % pc[k][(i, j)] for i in range(1, DEG + 1) for j in range(i + 1)]
        L, a, b = sip_forward(pc["sx"], pc["sy"])
        ap, bp, err = sip_inverse(pc["sx"], pc["sy"], L)
        worst = max(worst, err)
        row += ["%.17g" % a[t] for t in fwd] + ["%.17g" % b[t] for t in fwd]
        row += ["%.17g" % ap[t] for t in inv] + ["%.17g" % bp[t] for t in inv]
        rows.append(row)
    with open(os.path.join(out, "siaf.tsv"), "w") as f:
        f.write(
            "# Roman WFI geometry, derived by contrib/tables/siaf.py from the Roman SIAF\n"
            "# (roman_siaf.xml of spacetelescope/pysiaf, pysiaf/prd_data/Roman, commit\n"
            "# %s, BSD-3; the Dec 2023 delivery): per WFInn_FULL\n"
            "# aperture the reference point, ideal-frame angle and parity, science\n"
            "# reference pixel, nominal scales and the degree-5 Sci2Idl / Idl2Sci\n"
            "# polynomials copied as numbers; WFI_CEN (sca 0) is the boresight.\n"
            "# a_p_q/b_p_q: SIP forward coefficients of u^p v^q (pixels), exact by algebra\n"
            "# from Sci2Idl; ap_p_q/bp_p_q: SIP inverse of order %d, least squares on a\n"
            "# 61 x 61 grid over the SCA; worst error on a 203 x 203 grid: %.2e pixel.\n"
            "# The script's docstring defines every column.\n" % (COMMIT, SIP_INV, worst))
        f.write("\t".join(cols) + "\n")
        for r in rows:
            f.write("\t".join(r) + "\n")
    print("SIP inverse order %d: worst %.3e px" % (SIP_INV, worst))


if __name__ == "__main__":
    main()
