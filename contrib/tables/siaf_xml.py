"""Reading the Roman SIAF XML (roman_siaf.xml of pysiaf), shared by the
table scripts beside this file (derive_instrument.py, siaf.py).

Each <SiafEntry> is a flat list of <Field>text</Field> elements; the file
is read with two regular expressions, which is all its flat layout needs.
"""
import re


def siaf_entries(path):
    """Aperture name -> {field: text} for every SiafEntry in a SIAF XML."""
    with open(path) as f:
        text = f.read()
    entries = {}
    for block in re.findall(r"<SiafEntry>(.*?)</SiafEntry>", text, re.S):
        fields = dict(re.findall(r"<(\w+)>([^<]*)</\1>", block))
        entries[fields["AperName"]] = fields
    return entries
