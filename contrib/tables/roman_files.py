"""The public Roman files in ../shared/roman/ as the derive_*.py scripts read
them: where each came from (MANIFEST.tsv) and the rows of the Project's
simple comma-separated ECSV tables.  Development-time only, like them."""
import os


def manifest(roman):
    """File name -> (repository, path, commit) from roman/MANIFEST.tsv."""
    rows = {}
    for line in open(os.path.join(roman, "MANIFEST.tsv")):
        f = line.rstrip("\n").split("\t")
        if len(f) >= 6 and not line.startswith("#"):
            rows[f[0]] = (f[3], f[4], f[5])
    return rows


def source(m, name):
    """A file's origin as a table header quotes it: repository path@commit."""
    repo, path, commit = m[name]
    return "%s %s@%s" % (repo, path, commit[:12])


def ecsv_rows(path):
    """The header and the data rows of a simple comma-separated ECSV, as
    lists of strings (the YAML header's lines, all '#', skipped)."""
    lines = [l.rstrip("\n") for l in open(path) if not l.startswith("#")]
    return lines[0].split(","), [l.split(",") for l in lines[1:] if l.strip()]
