"""Write a copy of an ASDF file with one block's header changed.

    asdf_break.py IN OUT size|wrap|md5|md5-right K [OUT size|...|md5-right K]...

size: block K's used size made larger than its allocated size; wrap: its
allocated and used sizes 2^64 - 1, a zlib block (offset plus size wraps
around, a reader that adds them sees a block that ends inside the file);
md5: a checksum that is not its data's; md5-right: its data's true MD5 (a
file that must still be read).  Several OUTs, each with its own change,
read IN once.
"""
import hashlib
import mmap
import struct
import sys

from asdf_blocks import blocks

args = sys.argv[1:]
if len(args) < 4 or (len(args) - 1) % 3:
    sys.exit("usage: " + __doc__.splitlines()[3].strip())
with open(args[0], "rb") as f:  # mapped, not read: 300 MB not copied
    src = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
bb = blocks(src)
for i in range(1, len(args), 3):
    dst, what, k = args[i], args[i + 1], int(args[i + 2])
    pos, used = bb[k].head, bb[k].used
    b = bytearray(src[pos:pos + 54])  # the block's magic and header
    if what == "size":
        b[22:30] = struct.pack(">Q", used + 8)
    elif what == "wrap":
        b[10:14] = b"zlib"
        b[14:30] = struct.pack(">QQ", 2**64 - 1, 2**64 - 1)
    elif what == "md5":
        b[38:54] = bytes(range(1, 17))
    elif what == "md5-right":
        b[38:54] = hashlib.md5(src[bb[k].at:bb[k].at + used]).digest()
    else:
        sys.exit("asdf_break.py: unknown change " + what)
    with open(dst, "wb") as f:
        view = memoryview(src)
        f.write(view[:pos])
        f.write(b)
        f.write(view[pos + 54:])
