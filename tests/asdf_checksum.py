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
import re
import struct
import sys
import warnings

import numpy as np
import asdf
import asdf.tags.core.ndarray as nd

warnings.simplefilter("ignore")
nd._datatype_names.setdefault("float16", "f2")


def md5s(path):
    """The MD5 field of each block, by the Standard, and the block of each
    ndarray under `roman` (its source), from the file's own bytes."""
    with open(path, "rb") as f:
        raw = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
    end = raw.find(b"\n...\n")
    tree = raw[:end].decode()
    source = {m.group(1): int(m.group(2)) for m in
              re.finditer(r"^  (\w+): !core/ndarray-1\.1\.0\n\s+source: (\d+)", tree, re.M)}
    off, out = end + 5, []
    while raw[off:off + 4] == b"\xd3BLK":
        hs = struct.unpack(">H", raw[off + 4:off + 6])[0]
        alloc = struct.unpack(">Q", raw[off + 14:off + 22])[0]
        out.append(bytes(raw[off + 38:off + 54]))
        off += 6 + hs + alloc
    raw.close()
    return out, source


if len(sys.argv) < 2:
    sys.exit("usage: " + __doc__.splitlines()[4].strip())
bad = 0
for path in sys.argv[1:]:
    try:
        sums, source = md5s(path)
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
