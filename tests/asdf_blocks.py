"""An ASDF file's binary blocks and which top-level array of `roman` each
holds, read from the file's own bytes by the ASDF Standard (1.6.0), for
the tests' scripts (imported: python puts the script's directory on the
path).

    tree_end(raw)  the offset just past the tree's "...\\n"
    blocks(raw)    a Block per block, in file order
    sources(raw)   {array name: block index} of roman's top-level ndarrays
"""
import re
import struct
from collections import namedtuple

# head: the offset of the block's magic; at: of its stored bytes; comp the
# compression field (4 bytes); alloc, used, size as the header has them;
# md5 its 16 checksum bytes (zeros: not computed)
Block = namedtuple("Block", "head at comp alloc used size md5")


def tree_end(raw):
    return raw.find(b"\n...\n") + 5


def blocks(raw):
    off, out = tree_end(raw), []
    while raw[off:off + 4] == b"\xd3BLK":
        hs = struct.unpack(">H", raw[off + 4:off + 6])[0]
        flags, comp, alloc, used, size = struct.unpack(">I4sQQQ", raw[off + 6:off + 38])
        out.append(Block(off, off + 6 + hs, bytes(comp), alloc, used, size,
                         bytes(raw[off + 38:off + 54])))
        off += 6 + hs + alloc
    return out


def sources(raw):
    tree = bytes(raw[:tree_end(raw)]).decode()
    return {m.group(1): int(m.group(2)) for m in
            re.finditer(r"^  (\w+): !core/ndarray-1\.1\.0\n\s+source: (\d+)", tree, re.M)}
