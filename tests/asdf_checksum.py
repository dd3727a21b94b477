"""Read ASDF files with asdf's checksum checks on, and check every
block's MD5 here too: "FILE: ok" for each file whose blocks' MD5s match
their data, else "FILE: FAILED" and why; exit 0 when every file is ok.

    asdf_checksum.py FILE...

python3-asdf 2.14 checks the MD5 of the first block (data) only, read on
opening; the blocks it finds through the block index it does not check.
So each ndarray under `roman` is also read and the MD5 in its block's
header (where one is given) compared with the MD5 of its bytes before
compression, python3-asdf's convention (wfiscene leaves its own blocks'
MD5s zero, "not computed", and writes one only where --into kept a block
that had one); the count of those that match is printed.  Several files
in one call spare python3-asdf's start-up per file.
"""
import hashlib
import mmap
import sys
import warnings

import numpy as np
import asdf
import asdf.tags.core.ndarray as nd

from asdf_blocks import blocks, sources

warnings.simplefilter("ignore")
nd._datatype_names.setdefault("float16", "f2")
if len(sys.argv) < 2:
    sys.exit("usage: " + __doc__.splitlines()[4].strip())
bad = 0
for path in sys.argv[1:]:
    try:
        with open(path, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as raw:
            sums, source = [b.md5 for b in blocks(raw)], sources(raw)
        n = 0
        with asdf.open(path, validate_checksums=True) as af:
            roman = af.tree["roman"]
            first = float(roman["data"][0, 0])
            for k, src in source.items():
                if sums[src] == bytes(16):
                    continue
                got = hashlib.md5(np.ascontiguousarray(np.asarray(roman[k])).tobytes()).digest()
                assert got == sums[src], "%s: block %d's MD5 is not that of its data" % (k, src)
                n += 1
        print("%s: ok %r, %d MD5s right" % (path, first, n), flush=True)
    except Exception as e:  # python3-asdf refusing the checksum, ours, or the file
        print("%s: FAILED %s: %s" % (path, type(e).__name__, e), flush=True)
        bad += 1
sys.exit(1 if bad else 0)
