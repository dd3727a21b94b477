"""Read the level-2 data array of an ASDF file with asdf's checksum
checks on: exit 0 when its block's MD5 matches its data.

    asdf_checksum.py FILE
"""
import sys
import warnings

import asdf
import asdf.tags.core.ndarray as nd

warnings.simplefilter("ignore")
nd._datatype_names.setdefault("float16", "f2")
with asdf.open(sys.argv[1], validate_checksums=True) as af:
    print(float(af.tree["roman"]["data"][0, 0]))
