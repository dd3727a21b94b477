"""Compare the arrays of ASDF files of wfiscene, pair by pair, and say
how the second file of each pair stores its blocks.

    asdf_same.py A.asdf B.asdf [none|zlib|lz4] [--lz4-as-asdf] [--checksums]
                 [A2.asdf B2.asdf [none|zlib|lz4] [--lz4-as-asdf] [--checksums]]...

For each pair A B: every ndarray under `roman` of A equals B's (NaN equal
to NaN).  With a compression named, every block of B is stored so (its
header's compression field).  --lz4-as-asdf: each lz4 block of B holds,
byte for byte, what python3-asdf's own lz4 compressor makes of the array.
--checksums: B is opened as asdf_checksum.py opens a file, with
python3-asdf's checksum checks on, and its arrays read: an MD5 that
python3-asdf checks and finds wrong fails (python3-asdf 2.14 checks the
first block, data, read on opening; those it finds through the block
index it does not).  So the MD5 in every array's block header is also
checked here against the array's bytes before compression (python3-asdf's
convention, which wfiscene writes where it writes one) and the count of
those that match printed.
The words after a pair are for that pair alone.

Several pairs in one call spare python3-asdf's start-up (seconds) per
pair, and an A named in several pairs is read once.  Prints "ok B: " and
the sizes for each pair in turn, or stops at the first failure, the pair
named, with exit 1.
"""
import hashlib
import mmap
import sys
import traceback
import warnings

import numpy as np
import asdf
import asdf.compression
import asdf.tags.core.ndarray as nd

from asdf_blocks import blocks, sources

warnings.simplefilter("ignore")
nd._datatype_names.setdefault("float16", "f2")

FIELD = {"none": b"\0\0\0\0", "zlib": b"zlib", "lz4": b"lz4\0"}


def parse(argv):
    """The pairs: [a, b, compression or None, lz4-as-asdf, checksums]."""
    pairs, files = [], []
    for arg in argv:
        if arg in FIELD or arg in ("--lz4-as-asdf", "--checksums"):
            if files or not pairs:
                sys.exit("asdf_same.py: %s before a pair A B" % arg)
            if arg in FIELD:
                pairs[-1][2] = arg
            else:
                pairs[-1][3 if arg == "--lz4-as-asdf" else 4] = True
        elif arg.startswith("--"):
            sys.exit("asdf_same.py: unknown option " + arg)
        else:
            files.append(arg)
            if len(files) == 2:
                pairs.append(files + [None, False, False])
                files = []
    if files or not pairs:
        sys.exit("usage: " + __doc__.splitlines()[3].strip())
    return pairs


def arrays(path, checksums=False):
    """The ndarrays under `roman` of a file, read by python3-asdf."""
    with asdf.open(path, copy_arrays=True, validate_checksums=checksums) as af:
        return [(k, np.asarray(v)) for k, v in af.tree["roman"].items() if k != "meta"]


def mapped(path):
    """arrays(path) for an A: memory-mapped where its blocks are stored
    uncompressed, not copied (the file stays open, for later pairs)."""
    af = asdf.open(path, copy_arrays=False)
    return [(k, np.asarray(v)) for k, v in af.tree["roman"].items() if k != "meta"]


def equal(x, y):
    """np.array_equal(x, y, equal_nan=True), sooner when x and y have one
    dtype and shape and the same bytes (then every value is the same)."""
    if x.dtype == y.dtype and x.shape == y.shape and np.array_equal(
            np.ascontiguousarray(x).reshape(-1).view(np.uint8),
            np.ascontiguousarray(y).reshape(-1).view(np.uint8)):
        return True
    return np.array_equal(x, y, equal_nan=True)


cache = {}


def check(a_path, b_path, want, as_asdf, checksums):
    with open(b_path, "rb") as f:
        raw = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
    source = sources(raw)
    bb = blocks(raw)
    if want:
        for k, b in enumerate(bb):
            assert b.comp == FIELD[want], (k, b.comp)
            assert want != "none" or b.used == b.size, k
    if a_path not in cache:
        cache[a_path] = mapped(a_path)
    rb = dict(arrays(b_path, checksums))
    n = 0
    for k, x in cache[a_path]:
        y = rb[k]
        assert x.dtype == y.dtype and x.shape == y.shape, (k, x.dtype, y.dtype)
        assert equal(x, y), k
        n += 1
        if as_asdf:
            b = bb[source[k]]
            assert b.comp == b"lz4\0", (k, b.comp)
            mine = b"".join(asdf.compression._get_compressor("lz4").compress(
                memoryview(np.ascontiguousarray(y).ravel())))
            assert mine == raw[b.at:b.at + b.used], "%s: lz4 bytes differ from python3-asdf's" % k
    assert n >= 3, n
    summed = 0
    if checksums:
        for k, y in rb.items():
            md5 = bb[source[k]].md5
            if md5 != bytes(16):
                got = hashlib.md5(np.ascontiguousarray(y).tobytes()).digest()
                assert got == md5, "%s: block %d's MD5 is not that of its data" % (k, source[k])
                summed += 1
    raw.close()
    return "ok %s: %d arrays equal; %d blocks, %d of %d bytes stored%s" % (
        b_path, n, len(bb), sum(b.used for b in bb), sum(b.size for b in bb),
        "; %d MD5s right" % summed if checksums else "")


for a, b, want, as_asdf, checksums in parse(sys.argv[1:]):
    try:
        line = check(a, b, want, as_asdf, checksums)
    except Exception as e:  # an assertion, or python3-asdf refusing a checksum
        traceback.print_exc()
        sys.exit("asdf_same.py: %s against %s: %s: %s" % (b, a, type(e).__name__, e))
    print(line, flush=True)
