"""Rewrite a wfiscene level-2 ASDF file as the Roman pipeline's files can
differ from it, for --into's tests.

    asdf_rewrite.py IN.asdf OUT.asdf [--gwcs MODE] [--compress NAME=zlib|lz4]...
                    [--corrupt NAME] [--md5] [OUT2.asdf [options]...]...

Each OUT is IN rewritten as the options after it (up to the next OUT)
say; several OUTs in one call read IN once and compress and sum each
block once, sparing python3-asdf's start-up and the work per OUT.

--gwcs MODE     meta.wcs replaced by a gwcs built and serialized by
                python3-gwcs and python3-asdf, as romancal's assign_wcs and
                romanisim build it (detector -> v2v3 the file's own
                distortion; v2v3 -> v2v3vacorr romancal's velocity
                aberration step, scale 1.00004; v2v3vacorr -> world
                Scale, SphericalToCartesian, RotationSequence3D,
                CartesianToSpherical), its pointing 2" east, 1.5" north and
                0.02 degrees of roll away from meta.wcsinfo, which is kept:
                  romancal     as said (its inverse: the distortion's own)
                  newton       the distortion's inverse removed
                  unsupported  a Sine1D (no transform wfiscene evaluates)
                               added after the rotation
--compress      block of array roman.NAME compressed by python3-asdf's own
                compressor (asdf.compression.compress: zlib, or lz4 in
                asdf's framing), its MD5 as python3-asdf computes it
--corrupt NAME  a byte in the middle of roman.NAME's stored data flipped
--md5           every block's MD5 set, as python3-asdf computes it

The tree keeps its tags (python3-asdf 2.14 would drop the Roman ones if
it wrote the whole file), so the blocks are laid out here, byte for byte
as the ASDF Standard says.
"""
import hashlib
import io
import mmap
import re
import struct
import sys
import warnings

import numpy as np
import asdf
import asdf.compression
import asdf.tags.core.ndarray as nd

import asdf_blocks
from asdf_blocks import sources, tree_end

warnings.simplefilter("ignore")
nd._datatype_names.setdefault("float16", "f2")

args = sys.argv[1:]
if len(args) < 2 or args[1].startswith("--"):
    sys.exit("usage: " + __doc__.splitlines()[3].strip() + " ...")
src = args[0]
outs = []  # (OUT, its options)
i = 1
while i < len(args):
    if not args[i].startswith("--"):
        outs.append((args[i], {"compress": {}, "gwcs": None, "corrupt": None, "md5": False}))
        i += 1
        continue
    opts = outs[-1][1]
    if args[i] == "--compress":
        k, v = args[i + 1].split("=")
        opts["compress"][k] = v
        i += 2
    elif args[i] in ("--gwcs", "--corrupt"):
        opts[args[i][2:]] = args[i + 1]
        i += 2
    elif args[i] == "--md5":
        opts["md5"] = True
        i += 1
    else:
        sys.exit("asdf_rewrite.py: unknown option " + args[i])

# IN memory-mapped, its blocks views of the map: no copy of its 300 MB
with open(src, "rb") as f:
    raw = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
end = tree_end(raw)
tree = raw[:end].decode()

# the blocks' data, and which block each top-level array of roman is
blocks = []
for b in asdf_blocks.blocks(raw):
    assert b.comp == b"\0\0\0\0", "the input's blocks must be uncompressed"
    blocks.append(memoryview(raw)[b.at:b.at + b.used])
source = sources(raw)


def gwcs_yaml(mode):
    from astropy import coordinates as coord
    from astropy import units as u
    from astropy.modeling.models import (Identity, RotationSequence3D, Scale, Shift,
                                         Sine1D)
    from gwcs import coordinate_frames as cf
    from gwcs.geometry import CartesianToSpherical, SphericalToCartesian
    from gwcs.wcs import WCS

    with asdf.open(src) as af:
        meta = af.tree["roman"]["meta"]
        d2v = meta["wcs"].get_transform("detector", "v2v3")
        info = dict(meta["wcsinfo"])
    if mode == "newton":
        for m in d2v.traverse_postorder():
            if getattr(m, "has_user_inverse", False):
                del m.inverse
        if d2v.has_user_inverse:
            del d2v.inverse
    va, v2, v3 = 1.00004, info["v2_ref"], info["v3_ref"]
    dva = (Scale(va) & Scale(va)) | (Shift((1 - va) * v2) & Shift((1 - va) * v3))
    ra = info["ra_ref"] + 2.0 / 3600 / np.cos(np.radians(info["dec_ref"]))
    dec = info["dec_ref"] + 1.5 / 3600
    rot = RotationSequence3D([v2 / 3600, -v3 / 3600, info["roll_ref"] + 0.02, dec, -ra],
                             axes_order="zyxyz")
    tel2sky = ((Scale(1 / 3600) & Scale(1 / 3600)) | SphericalToCartesian(wrap_lon_at=180) |
               rot | CartesianToSpherical(wrap_lon_at=360))
    if mode == "unsupported":
        tel2sky = tel2sky | (Identity(1) & (Identity(1) + Sine1D(amplitude=0, frequency=1)))
    det = cf.Frame2D(name="detector", axes_order=(0, 1), unit=(u.pix, u.pix))
    f1 = cf.Frame2D(name="v2v3", axes_order=(0, 1), axes_names=("v2", "v3"),
                    unit=(u.arcsec, u.arcsec))
    f2 = cf.Frame2D(name="v2v3vacorr", axes_order=(0, 1), axes_names=("v2", "v3"),
                    unit=(u.arcsec, u.arcsec))
    world = cf.CelestialFrame(reference_frame=coord.ICRS(), name="world")
    w = WCS([(det, d2v), (f1, dva), (f2, tel2sky), (world, None)])
    buf = io.BytesIO()
    asdf.AsdfFile({"wcs": w}).write_to(buf, all_array_storage="inline")
    text = buf.getvalue().decode()
    body = text[text.index("\nwcs: ") + 1:text.index("\n...\n") + 1]
    lines = body.splitlines()
    # "wcs: ..." at the top level, indented to sit under roman.meta
    return "    " + lines[0] + "\n" + "".join("    " + ln + "\n" for ln in lines[1:])


compressed = {}  # (block, compression): its stored bytes
md5s = {}  # block: python3-asdf's MD5, of the array's bytes before compression
gwcs = {}  # mode: its yaml
for dst, opts in outs:
    text = tree
    if opts["gwcs"]:
        if opts["gwcs"] not in gwcs:
            gwcs[opts["gwcs"]] = gwcs_yaml(opts["gwcs"])
        m = re.search(r"^    wcs: .*\n((?:      .*\n|    -.*\n)*)", text, re.M)
        assert m, "no meta.wcs"
        text = text[:m.start()] + gwcs[opts["gwcs"]] + text[m.end():]

    with open(dst, "wb") as out:
        out.write(text.encode())
        where = []
        for k, data in enumerate(blocks):
            name = [n for n, b in source.items() if b == k]
            comp = opts["compress"].get(name[0]) if name else None
            stored = data
            if comp:
                if (k, comp) not in compressed:
                    buf = io.BytesIO()
                    asdf.compression.compress(buf, np.frombuffer(data, np.uint8), comp)
                    compressed[k, comp] = buf.getvalue()
                stored = compressed[k, comp]
            if name and opts["corrupt"] == name[0]:
                b = bytearray(stored)
                b[len(b) // 2] ^= 0xFF
                b[len(b) // 2 + 1] ^= 0x5A
                stored = bytes(b)
            if opts["md5"] or comp:
                if k not in md5s:
                    md5s[k] = hashlib.md5(data).digest()
                md5 = md5s[k]
            else:
                md5 = b"\0" * 16
            where.append(out.tell())
            out.write(b"\xd3BLK" + struct.pack(">HI4sQQQ16s", 48, 0,
                                               (comp or "").encode().ljust(4, b"\0"),
                                               len(stored), len(stored), len(data), md5))
            out.write(stored)
        out.write(b"#ASDF BLOCK INDEX\n%YAML 1.1\n---\n" +
                  "".join("- %d\n" % w for w in where).encode() + b"...\n")
