#!/bin/sh
# The STIPS paper's photometry and astrometry test (section 3.1-3.2), small:
# 200 stars of 15-26 mag on SCA01 in F129 with background and all noise
# stages, recovered by fitting the ePSF that `wfiscene psf` writes
# (photutils GriddedPSFModel) and by sep.  The full 1000-star run with the
# Gaussian fit too is `make validate` (tests/validate/RESULTS.md).
. "$(dirname "$0")/lib.sh"

require_python
"$PY" -c 'import sep, photutils.psf, scipy' 2>/dev/null ||
	skip_all "python3 with sep, photutils and scipy is absent (Debian packages python3-sep, python3-photutils, python3-scipy)"

test_expect_success 'the 200-star scene is drawn and measured' '
	"$PY" "$TOP/tests/validate/photometry.py" --n 200 --seed 1 --wfs "$WFS" \
		--methods epsf,sep --dir "$TRASH/v" --json "$TRASH/s.json"
'

# check EXPR...: a Python expression over m (methods), bin(m, lo, hi)
check() {
	"$PY" - "$TRASH/s.json" "$1" <<-\EOF
	import json, sys
	s = json.load(open(sys.argv[1]))
	m = s["methods"]
	def bin(meth, lo, hi):
	    for b in m[meth]["bins"]:
	        if b["lo"] == lo and b["hi"] == hi:
	            return b
	    raise KeyError((lo, hi))
	ok = eval(sys.argv[2])
	if not ok:
	    print("failed:", sys.argv[2])
	    for meth in m:
	        for b in m[meth]["bins"]:
	            print(meth, b)
	sys.exit(0 if ok else 1)
	EOF
}

test_expect_success 'ePSF fit recovers every star' '
	check "m[\"epsf\"][\"recovered\"] == 200"
'
test_expect_success 'ePSF fit, 15-21 mag: no magnitude bias (< 0.005), scatter < 0.03' '
	check "abs(bin(\"epsf\", 15, 21)[\"dm_mean\"]) < 0.005 and bin(\"epsf\", 15, 21)[\"dm_std\"] < 0.03"
'
test_expect_success 'ePSF fit, 15-21 mag: positions to 0.004 px (the paper), no offset' '
	check "bin(\"epsf\", 15, 21)[\"dx_rsig\"] < 0.004 and bin(\"epsf\", 15, 21)[\"dy_rsig\"] < 0.004" &&
	check "abs(bin(\"epsf\", 15, 21)[\"dx_mean\"]) < 0.002 and abs(bin(\"epsf\", 15, 21)[\"dy_mean\"]) < 0.002"
'
test_expect_success 'ePSF fit, all 15-26 mag: mean |dm| under the paper (~0.06)' '
	check "bin(\"epsf\", 15, 26)[\"dm_abs\"] < 0.06"
'
test_expect_success 'sep: bright magnitudes right, centroids offset ~0.1 px by the asymmetric PSF' '
	check "abs(bin(\"sep\", 15, 17)[\"dm_mean\"]) < 0.03" &&
	check "0.05 < (bin(\"sep\", 15, 21)[\"dx_mean\"] ** 2 + bin(\"sep\", 15, 21)[\"dy_mean\"] ** 2) ** 0.5 < 0.25"
'

test_done
