"""Summaries of FITS images for the shell tests.

    fitsinfo.py FILE            per image HDU: EXTNAME sum max xmax ymax
    fitsinfo.py --same A B      exit 0 when every image HDU has equal data
    fitsinfo.py --pix FILE HDU X Y   the value of 0-based pixel (X, Y)
"""
import sys

import numpy as np
from astropy.io import fits


def images(path, dtype=np.float64):
    """(EXTNAME, data) of each image HDU, as dtype (None: as stored)."""
    with fits.open(path) as h:
        for hdu in h:
            if hdu.data is not None and hdu.is_image:
                yield hdu.name, np.array(hdu.data, dtype=dtype)


def main(argv):
    if argv[0] == "--same":
        # compared as stored: converting to float64 changes no value and
        # makes no two values equal, so np.array_equal says the same
        a, b = list(images(argv[1], None)), list(images(argv[2], None))
        if [n for n, _ in a] != [n for n, _ in b]:
            print("different HDUs:", [n for n, _ in a], [n for n, _ in b])
            return 1
        for (n, x), (_, y) in zip(a, b):
            if x.shape != y.shape or not np.array_equal(x, y):
                x, y = x.astype(np.float64), y.astype(np.float64)
                print("HDU %s differs: max |diff| %g" % (n, np.abs(x - y).max()))
                return 1
        return 0
    if argv[0] == "--pix":
        for n, d in images(argv[1]):
            if n == argv[2]:
                print("%.9g" % d[int(argv[4]), int(argv[3])])
                return 0
        return 1
    for n, d in images(argv[0]):
        y, x = np.unravel_index(np.argmax(d), d.shape)
        print("%s %.9g %.9g %d %d" % (n, d.sum(), d.max(), x, y))
    return 0


sys.exit(main(sys.argv[1:]))
