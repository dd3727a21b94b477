"""Write a copy of an ASDF file with one block's header changed.

    asdf_break.py IN OUT size|wrap|md5|md5-right K

size: block K's used size made larger than its allocated size; wrap: its
allocated and used sizes 2^64 - 1, a zlib block (offset plus size wraps
around, a reader that adds them sees a block that ends inside the file);
md5: a checksum that is not its data's; md5-right: its data's true MD5 (a
file that must still be read).
"""
import hashlib
import struct
import sys

src, dst, what, k = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
b = bytearray(open(src, "rb").read())
pos = b.index(b"\xd3BLK")
for _ in range(k):
    hs = struct.unpack(">H", b[pos + 4:pos + 6])[0]
    alloc = struct.unpack(">Q", b[pos + 14:pos + 22])[0]
    pos = pos + 6 + hs + alloc
hs = struct.unpack(">H", b[pos + 4:pos + 6])[0]
used = struct.unpack(">Q", b[pos + 22:pos + 30])[0]
if what == "size":
    b[pos + 22:pos + 30] = struct.pack(">Q", used + 8)
elif what == "wrap":
    b[pos + 10:pos + 14] = b"zlib"
    b[pos + 14:pos + 30] = struct.pack(">QQ", 2**64 - 1, 2**64 - 1)
elif what == "md5":
    b[pos + 38:pos + 54] = bytes(range(1, 17))
else:
    data = b[pos + 6 + hs:pos + 6 + hs + used]
    b[pos + 38:pos + 54] = hashlib.md5(data).digest()
open(dst, "wb").write(b)
