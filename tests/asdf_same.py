"""Compare the arrays of two ASDF files of wfiscene, and say how the
second one's blocks are stored.

    asdf_same.py A.asdf B.asdf [none|zlib|lz4] [--lz4-as-asdf]

Every ndarray under `roman` of A equals B's (NaN equal to NaN).  With a
compression named, every block of B is stored so (its header's
compression field).  --lz4-as-asdf: each lz4 block of B holds, byte for
byte, what python3-asdf's own lz4 compressor makes of the array.  Prints
"ok" and the sizes, or fails with an assertion.
"""
import re
import struct
import sys
import warnings

import numpy as np
import asdf
import asdf.compression
import asdf.tags.core.ndarray as nd

warnings.simplefilter("ignore")
nd._datatype_names.setdefault("float16", "f2")

a_path, b_path = sys.argv[1], sys.argv[2]
want = sys.argv[3] if len(sys.argv) > 3 and not sys.argv[3].startswith("--") else None
as_asdf = "--lz4-as-asdf" in sys.argv


def blocks(path):
    """The header fields and stored bytes of each block, by the Standard."""
    raw = open(path, "rb").read()
    off = raw.index(b"\n...\n") + 5
    out = []
    while raw[off:off + 4] == b"\xd3BLK":
        hs = struct.unpack(">H", raw[off + 4:off + 6])[0]
        flags, comp, alloc, used, size = struct.unpack(">I4sQQQ", raw[off + 6:off + 38])
        out.append((comp, used, size, raw[off + 6 + hs:off + 6 + hs + used]))
        off += 6 + hs + alloc
    return out


tree = open(b_path, "rb").read()
tree = tree[:tree.index(b"\n...\n")].decode()
source = {m.group(1): int(m.group(2)) for m in
          re.finditer(r"^  (\w+): !core/ndarray-1\.1\.0\n\s+source: (\d+)", tree, re.M)}
field = {"none": b"\0\0\0\0", "zlib": b"zlib", "lz4": b"lz4\0"}
bb = blocks(b_path)
if want:
    for k, (comp, used, size, _) in enumerate(bb):
        assert comp == field[want], (k, comp)
        assert want != "none" or used == size, k
with asdf.open(a_path, copy_arrays=True) as a, asdf.open(b_path, copy_arrays=True) as b:
    ra, rb = a.tree["roman"], b.tree["roman"]
    n = 0
    for k, v in ra.items():
        if k == "meta":
            continue
        x, y = np.asarray(v), np.asarray(rb[k])
        assert x.dtype == y.dtype and x.shape == y.shape, (k, x.dtype, y.dtype)
        assert np.array_equal(x, y, equal_nan=True), k
        n += 1
        if as_asdf:
            src = source[k]
            comp, used, size, data = bb[src]
            assert comp == b"lz4\0", (k, comp)
            mine = b"".join(asdf.compression._get_compressor("lz4").compress(
                memoryview(np.ascontiguousarray(y).ravel())))
            assert mine == data, "%s: lz4 bytes differ from python3-asdf's" % k
    assert n >= 3, n
print("ok %d arrays equal; %d blocks, %d of %d bytes stored" %
      (n, len(bb), sum(x[1] for x in bb), sum(x[2] for x in bb)))
