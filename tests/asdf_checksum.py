"""Read the level-2 data array of ASDF files with asdf's checksum checks
on: "FILE: ok" for each file whose block's MD5 matches its data, else
"FILE: FAILED" and why; exit 0 when every file is ok.

    asdf_checksum.py FILE...

Several files in one call spare python3-asdf's start-up per file.
"""
import sys
import warnings

import asdf
import asdf.tags.core.ndarray as nd

warnings.simplefilter("ignore")
nd._datatype_names.setdefault("float16", "f2")
if len(sys.argv) < 2:
    sys.exit("usage: " + __doc__.splitlines()[4].strip())
bad = 0
for path in sys.argv[1:]:
    try:
        with asdf.open(path, validate_checksums=True) as af:
            print("%s: ok %r" % (path, float(af.tree["roman"]["data"][0, 0])), flush=True)
    except Exception as e:  # python3-asdf refusing the checksum, or the file
        print("%s: FAILED %s: %s" % (path, type(e).__name__, e), flush=True)
        bad += 1
sys.exit(1 if bad else 0)
