#!/bin/sh
# The error of a bright star's halo of a spectrum (psf-halo-colour-steps)
# against the exact halo of that spectrum, in F146 on SCA 1: each test
# spectrum's halo and the eight class halos from `wfiscene psf --halo`
# (cached like the scene's), the blend of the spectrum's class pair at
# its class (`wfiscene psf --report`) rounded to 1/N as point.so blends
# it, and per N the worst relative error of the light in rings 10-20,
# 20-44, 44-62, 62-88, 88-128 and 128-250 px, the light beyond 44 px put
# at the wrong radius, and the largest sample error beyond 10 px over the
# peak; "default" is the default spectrum's halo for every star.
#
#   contrib/bench/halo-colour.sh [BUILD]
#
# Building the 17 halos takes some 70 CPU s the first time.
set -e
B=${1:-build}
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
PY=/usr/bin/python3
psf() { "$B/wfiscene" psf --filter F146 --sca 1 "$@"; }
psf --report | awk '$1 == 1 { print $2, $3, $4 }' > "$W/classes"
: > "$W/tests"
for s in "teff 3000" "teff 4500" "teff 8000" "teff 15000" "teff 30000" "beta -2" "beta 0" \
	"beta 2"; do
	set -- $s
	psf --report --$1 $2 | tail -n 1 | awk '{ print $2, $3, $4 }' >> "$W/tests"
done
while read -r k kind v; do
	psf --halo 256 --$kind "$v" -o "$W/class$k.fits"
done < "$W/classes"
while read -r u kind v; do
	psf --halo 256 --$kind "$v" -o "$W/$kind$v.fits"
done < "$W/tests"
psf --halo 256 -o "$W/default.fits"
cd "$W"
$PY - <<'EOF'
import numpy as np
from astropy.io import fits

get = lambda p: fits.getdata(p)[0].astype(np.float64)
classes = [l.split() for l in open("classes")]
n = len(classes) // 2
H = {int(k): get("class%s.fits" % k) for k, _, _ in classes}
D = get("default.fits")
c = (D.shape[0] - 1) // 2
j, i = np.indices(D.shape)
d = np.hypot(i - c, j - c) / 2
edges = [10, 20, 44, 62, 88, 128, 250]
masks = [(d >= a) & (d < b) for a, b in zip(edges, edges[1:])]
far = d >= 10

def rings(a):
    return np.array([a[m].sum() for m in masks]) / a.sum()

worst = {}
for u, kind, v in (l.split() for l in open("tests")):
    E = get("%s%s.fits" % (kind, v))
    re, peak = rings(E), (E / E.sum()).max()
    a = int(float(u))
    f = float(u) - a
    if a % n == n - 1:
        a, f = a - 1, f + 1
    for N in ["default", 1, 2, 4, 8, 16, "exact"]:
        if N == "default":
            B = D
        else:
            g = f if N == "exact" else int(f * N + 0.5) / N
            B = ((1 - g) * H[a] + g * H[a + 1]).astype(np.float32).astype(np.float64)
        rb = rings(B)
        w = [np.abs(rb / re - 1).max(), np.abs(rb - re)[2:].sum(),
             np.abs(B / B.sum() - E / E.sum())[far].max() / peak]
        worst[N] = np.maximum(worst.get(N, 0), w)
        print("%s %s N=%s: rings %s" % (kind, v, N, " ".join("%+.4f" % e for e in rb / re - 1)))
print("| psf-halo-colour-steps | worst ring error | light misplaced beyond 44 px | max sample error / peak |")
print("|---|---|---|---|")
for N, w in worst.items():
    print("| %s | %.2f %% | %.1e | %.1e |" % (N, 100 * w[0], w[1], w[2]))
EOF
