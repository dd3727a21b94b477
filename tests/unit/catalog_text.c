/*
 * catalog_text.c - the text catalog formats (CSV, whitespace, IPAC, ECSV),
 * compression, column meanings and the documented error messages.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "catalog.h"
#include "err.h"
#include "input.h"
#include "instrument.h"
#include "tap.h"

static char dir[] = "/tmp/wfs-cat-XXXXXX";
static char path[512];

static const char *fixture(const char *name, const char *text, size_t len)
{
	FILE *f;

	snprintf(path, sizeof(path), "%s/%s", dir, name);
	f = fopen(path, "wb");
	if (!f)
		exit(2);
	fwrite(text, 1, len, f);
	fclose(f);
	return path;
}

#define FIX(name, text) fixture(name, text, sizeof(text) - 1)

static struct catalog_opts opts(void)
{
	struct catalog_opts o = { .filter = F129 };

	return o;
}

/* Read a whole catalog; returns rows read or -1 with the message in e. */
static long read_all(const char *p, struct catalog_opts o, struct err *e)
{
	struct catalog *c;
	struct rows r;
	long n, total = 0;

	err_clear(e);
	c = catalog_open(p, &o, e);
	if (!c)
		return -1;
	while ((n = catalog_read(c, &r, e)) > 0)
		total += n;
	catalog_close(c);
	return n < 0 ? -1 : total;
}

/* The catalog must fail with a message containing want. */
static void fails(const char *p, struct catalog_opts o, const char *want,
		  int code, const char *what)
{
	struct err e;
	long n = read_all(p, o, &e);

	if (!ok(n < 0 && strstr(e.msg, want) && e.code == code, "%s", what))
		diag("got %ld rows, code %d, message '%s'; want '%s'", n,
		     e.code, e.msg, want);
}

static void test_csv(void)
{
	struct catalog_opts o = opts();
	struct catalog *c;
	struct rows r;
	struct err e = { 0 };
	const char *p = FIX("a.csv",
		"\xef\xbb\xbf# a comment\r\n"
		"RA, Dec ,flux,TYPE,n,notes\r\n"
		"10.5,-20.25,100,point,,\"a, b\"\n"
		"\n"
		"  # another comment\n"
		"10.6,-20.5,2.5e3,Sersic-Quick,1.5,\"say \"\"hi\"\"\"\r\n"
		"1e1,0,1,,2,\"multi\nline\"\n"
		"11,1,7,point,,last");
	long n;
	int cn;
	double v;

	c = catalog_open(p, &o, &e);
	ok(c != NULL, "CSV opens (BOM, CRLF, comment): %s", e.msg);
	if (!c)
		return;
	n = catalog_read(c, &r, &e);
	ok(n == 4, "4 rows (got %ld: %s)", n, e.msg);
	is_near(r.ra[0], 10.5, 0, "ra");
	is_near(r.dec[1], -20.5, 0, "dec");
	is_near(r.flux[1], 2500, 0, "flux 2.5e3");
	ok(r.unit[0] == UNIT_COUNTS, "counts by default");
	ok(strcmp(r.type[1], "sersic-quick") == 0, "type lower-cased");
	ok(strcmp(r.type[2], "point") == 0, "empty type is point");
	ok(r.line[0] == 3 && r.line[1] == 6 && r.line[2] == 7 && r.line[3] == 9,
	   "line numbers %ld %ld %ld %ld", r.line[0], r.line[1], r.line[2], r.line[3]);
	ok(r.id[0] == 1 && r.id[3] == 4, "ids default to row numbers");
	ok(isnan(r.x[0]) && isnan(r.y[0]), "no pixel positions");
	cn = rows_column(&r, "NOTES");
	ok(cn >= 0 && strcmp(r.text[cn][0], "a, b") == 0, "quoted cell with comma");
	ok(cn >= 0 && strcmp(r.text[cn][1], "say \"hi\"") == 0, "doubled quotes: '%s'",
	   cn >= 0 ? r.text[cn][1] : "");
	ok(cn >= 0 && strcmp(r.text[cn][2], "multi\nline") == 0, "quoted line end");
	ok(cn >= 0 && strcmp(r.text[cn][3], "last") == 0, "no final line end");
	cn = rows_column(&r, "n");
	ok(rows_number(&r, cn, 0, 4.0, &v, &e) == 0 && v == 4.0, "empty cell gives fallback");
	ok(rows_number(&r, cn, 1, 4.0, &v, &e) == 0 && v == 1.5, "n = 1.5");
	ok(rows_column(&r, "Dec") == 1 && strcmp(r.colname[1], "dec") == 0,
	   "names trimmed and lower-case");
	n = catalog_read(c, &r, &e);
	ok(n == 0, "then the end");
	ok(catalog_rows(c) == 4, "catalog_rows");
	catalog_close(c);
}

static void test_chunks(void)
{
	struct catalog_opts o = opts();
	struct catalog *c;
	struct rows r;
	struct err e = { 0 };
	FILE *f;
	long n, total = 0, chunks = 0;
	int good = 1;

	snprintf(path, sizeof(path), "%s/big.txt", dir);
	f = fopen(path, "w");
	fprintf(f, "x y sca flux id\n");
	for (int i = 0; i < 10000; i++)
		fprintf(f, "%d.5\t%d %d %d %d\n", i % 4000 + 1, i % 3000 + 1, i % 18 + 1,
			i + 1, 1000000 + i);
	fclose(f);
	o.chunk_rows = 777;
	c = catalog_open(path, &o, &e);
	ok(c != NULL, "whitespace table opens");
	if (!c)
		return;
	while ((n = catalog_read(c, &r, &e)) > 0) {
		chunks++;
		if (n > 777)
			good = 0;
		for (long i = 0; i < n; i++) {
			long k = total + i;

			if (r.x[i] != k % 4000 + 0.5 || r.y[i] != k % 3000 ||
			    r.sca[i] != (int)(k % 18 + 1) || r.flux[i] != k + 1 ||
			    r.id[i] != 1000000 + k || r.line[i] != k + 2)
				good = 0;
		}
		total += n;
	}
	ok(n == 0 && total == 10000 && good, "10000 rows in %ld chunks, values exact", chunks);
	ok(chunks == 13, "chunks of at most 777 rows");
	catalog_close(c);
}

/* A very wide table is read in fewer rows per chunk. */
static void test_wide(void)
{
	struct catalog_opts o = opts();
	struct catalog *c;
	struct rows r;
	struct err e = { 0 };
	FILE *f;
	long n, total = 0, most = 0;

	snprintf(path, sizeof(path), "%s/wide.csv", dir);
	f = fopen(path, "w");
	fprintf(f, "ra,dec,flux");
	for (int i = 0; i < 20000; i++)
		fprintf(f, ",c%d", i);
	fprintf(f, "\n");
	for (int k = 0; k < 1000; k++) {
		fprintf(f, "1,2,%d", k + 1);
		for (int i = 0; i < 20000; i++)
			fputs(",", f);
		fprintf(f, "\n");
	}
	fclose(f);
	c = catalog_open(path, &o, &e);
	while (c && (n = catalog_read(c, &r, &e)) > 0) {
		if (r.flux[0] != total + 1 || r.ncol != 20003)
			break;
		total += n;
		if (n > most)
			most = n;
	}
	ok(c && total == 1000 && most <= (8 << 20) / 20003,
	   "20003 columns: %ld rows, chunks of at most %ld", total, most);
	catalog_close(c);
}

static void test_compressed(void)
{
	struct catalog_opts o = opts();
	struct err e;
	char cmd[1200];
	long n;

	FIX("z2.csv", "7,8,9\n10,11,12\n");
	FIX("z.csv", "ra,dec,flux\n1,2,3\n4,5,6\n");
	snprintf(cmd, sizeof(cmd), "cd %s && zstd -q -f z.csv -o z.zst && gzip -c z.csv > z.gz"
		 " && zstd -q -c z2.csv | cat z.zst - > zz.zst && gzip -c z2.csv | cat z.gz - > zz.gz",
		 dir);
	if (system(cmd) != 0) {
		ok(1, "# skip zstd or gzip missing");
		return;
	}
	snprintf(path, sizeof(path), "%s/z.zst", dir);
	n = read_all(path, o, &e);
	ok(n == 2, "zstd: %ld rows %s", n, e.msg);
	snprintf(path, sizeof(path), "%s/z.gz", dir);
	n = read_all(path, o, &e);
	ok(n == 2, "gzip: %ld rows %s", n, e.msg);
	snprintf(path, sizeof(path), "%s/zz.zst", dir);
	n = read_all(path, o, &e);
	ok(n == 4, "concatenated zstd frames: %ld rows %s", n, e.msg);
	snprintf(path, sizeof(path), "%s/zz.gz", dir);
	n = read_all(path, o, &e);
	ok(n == 4, "concatenated gzip members: %ld rows %s", n, e.msg);

	snprintf(cmd, sizeof(cmd), "head -c -5 %s/z.zst > %s/t.zst && head -c -3 %s/z.gz > %s/t.gz",
		 dir, dir, dir, dir);
	if (system(cmd) != 0)
		return;
	snprintf(path, sizeof(path), "%s/t.zst", dir);
	fails(path, o, "truncated zstd stream", EXIT_INPUT, "truncated zstd is an error");
	snprintf(path, sizeof(path), "%s/t.gz", dir);
	fails(path, o, "truncated gzip stream", EXIT_INPUT, "truncated gzip is an error");
}

static void test_ipac_ecsv(void)
{
	struct catalog_opts o = opts();
	struct catalog *c;
	struct rows r;
	struct err e = { 0 };
	const char *p;
	long n;

	p = FIX("a.tbl",
		"\\type = 'internal'\n"
		"\\filter = 'F129'\n"
		"\\ a comment\n"
		"|         ra|   dec|  flux|  type|notes|\n"
		"|     double|double|double|  char| char|\n"
		"|           |      |      |      |     |\n"
		"|       null|  null|  null|  null| null|\n"
		" 1.123456789   -3.5  100.0  point   a b \n"
		"         2.0    4.0 0.0025 sersic       \n");
	c = catalog_open(p, &o, &e);
	ok(c != NULL, "IPAC opens: %s", e.msg);
	if (c) {
		n = catalog_read(c, &r, &e);
		ok(n == 2, "IPAC 2 rows: %s", e.msg);
		if (n == 2) {
			is_near(r.ra[0], 1.123456789, 0, "IPAC ra");
			is_near(r.flux[1], 0.0025, 0, "IPAC flux");
			ok(strcmp(r.type[1], "sersic") == 0, "IPAC type");
			ok(strcmp(r.text[4][0], "a b") == 0 && strcmp(r.text[4][1], "") == 0,
			   "IPAC notes sliced by pipes");
			ok(r.sersic_ie == 1, "internal: Sersic flux is Ie");
		}
		catalog_close(c);
	}
	o.filter = F158;
	fails(p, o, "catalog type 'internal' is for filter 'F129', the scene's is 'F158'",
	      EXIT_INPUT, "internal catalog of another filter");

	/* Header lines split by their own pipes; units and null values. */
	o = opts();
	p = FIX("b.tbl",
		"|ra |dec |flux|type|\n"
		"|double|double|double|char|\n"
		"| deg | deg|mag(AB)| |\n"
		"|null|null|-99 |none|\n"
		" 1   2    20   none\n"
		" 1   2    -99  point\n");
	c = catalog_open(p, &o, &e);
	n = c ? catalog_read(c, &r, &e) : -1;
	ok(n < 0 && strstr(e.msg, "b.tbl:6: column 'flux': empty value"),
	   "IPAC null value is an empty cell: %s", e.msg);
	catalog_close(c);
	err_clear(&e);
	o.chunk_rows = 1;
	c = catalog_open(p, &o, &e);
	n = c ? catalog_read(c, &r, &e) : -1;
	ok(n == 1 && r.unit[0] == UNIT_ABMAG && r.flux[0] == 20 &&
	   strcmp(r.type[0], "point") == 0, "IPAC units line mag(AB), null type is point");
	catalog_close(c);
	o = opts();
	fails(FIX("c.tbl", "|ra|dec|flux|\n|double|double|\n"), o,
	      "c.tbl:2: IPAC header line has 3 pipes, the name line has 4", EXIT_INPUT,
	      "IPAC header lines must have the name line's columns");
	fails(FIX("d.tbl", "|ra|dec|flux\n"), o, "d.tbl:1: IPAC header needs", EXIT_INPUT,
	      "IPAC name line must end in a pipe");

	o = opts();
	p = FIX("a.ecsv",
		"# %ECSV 1.0\n"
		"# ---\n"
		"# delimiter: ','\n"
		"# datatype:\n"
		"# - {name: ra, unit: deg, datatype: float64}\n"
		"# - {name: dec, datatype: float64}\n"
		"# - {name: flux, unit: mag(AB), datatype: float64}\n"
		"# - {name: notes, datatype: string}\n"
		"# meta: !!omap\n"
		"# - {fluxunit: jy}\n"
		"# schema: astropy-2.0\n"
		"ra,dec,flux,notes\n"
		"1,2,20.5,\"x y\"\n");
	c = catalog_open(p, &o, &e);
	ok(c != NULL, "ECSV opens: %s", e.msg);
	if (c) {
		n = catalog_read(c, &r, &e);
		ok(n == 1 && r.unit[0] == UNIT_ABMAG && r.flux[0] == 20.5,
		   "ECSV column unit mag(AB) wins over metadata");
		ok(n == 1 && strcmp(r.text[3][0], "x y") == 0, "ECSV quoted text");
		catalog_close(c);
	}
	p = FIX("b.ecsv",
		"# %ECSV 1.0\n"
		"# ---\n"
		"# datatype:\n"
		"# - name: ra\n"
		"#   datatype: float64\n"
		"# - {name: dec, datatype: float64}\n"
		"# - {name: flux, datatype: float64}\n"
		"# meta:\n"
		"#   fluxunit: jy\n"
		"ra dec flux\n"
		"1 2 3.5e-6\n");
	c = catalog_open(p, &o, &e);
	ok(c != NULL, "ECSV with block YAML opens: %s", e.msg);
	if (c) {
		n = catalog_read(c, &r, &e);
		ok(n == 1 && r.unit[0] == UNIT_JY, "ECSV meta fluxunit jy");
		catalog_close(c);
	}
}

static void test_units_and_types(void)
{
	struct catalog_opts o = opts();
	struct catalog *c;
	struct rows r;
	struct err e = { 0 };
	const char *p;
	long n;

	p = FIX("m.csv", "ra,dec,flux,units,type\n1,2,3,j,sersic\n1,2,3,,point\n1,2,22,m,point\n");
	o.flux_unit = UNIT_ABMAG;
	c = catalog_open(p, &o, &e);
	n = c ? catalog_read(c, &r, &e) : -1;
	ok(n == 3 && r.unit[0] == UNIT_JY && r.unit[1] == UNIT_ABMAG && r.unit[2] == UNIT_ABMAG,
	   "per-row units over the scene default");
	ok(n == 3 && r.sersic_ie == 0, "plain catalogs: Sersic flux is the total");
	catalog_close(c);
	o = opts();

	p = FIX("mag.csv", "x,y,mag\n1,1,20\n");
	c = catalog_open(p, &o, &e);
	n = c ? catalog_read(c, &r, &e) : -1;
	ok(n == 1 && r.unit[0] == UNIT_ABMAG && r.x[0] == 0 && r.y[0] == 0 && r.sca[0] == 0,
	   "mag column, x y 1-based, sca 0");
	catalog_close(c);

	p = FIX("meta.csv", "\\fluxunit=abmag\nra,dec,flux\n1,2,25\n");
	c = catalog_open(p, &o, &e);
	n = c ? catalog_read(c, &r, &e) : -1;
	ok(n == 1 && r.unit[0] == UNIT_ABMAG, "\\fluxunit=abmag in a CSV");
	catalog_close(c);

	p = FIX("multi.csv", "\\type=multifilter\nra,dec,F129,f158,type,re\n1,2,30,40,sersic,2\n");
	c = catalog_open(p, &o, &e);
	n = c ? catalog_read(c, &r, &e) : -1;
	ok(n == 1 && r.flux[0] == 30 && r.sersic_ie == 1, "multifilter takes column F129");
	catalog_close(c);
	o.filter = F087;
	fails(p, o, "catalog type 'multifilter' has no column 'F087'", EXIT_INPUT,
	      "multifilter without the scene's filter");
	o = opts();

	p = FIX("gen.csv", "\\type=generic\nra,dec,f129,type\n1,2,30,sersic\n");
	c = catalog_open(p, &o, &e);
	n = c ? catalog_read(c, &r, &e) : -1;
	ok(n == 1 && r.flux[0] == 30 && strcmp(r.type[0], "point") == 0,
	   "generic: filter column, all points");
	catalog_close(c);

	p = FIX("mixed.csv", "\\type=mixed\n\\filter=f129\nra,dec,flux,units\n1,2,30,p\n1,2,1,e\n1,2,1,c\n");
	c = catalog_open(p, &o, &e);
	n = c ? catalog_read(c, &r, &e) : -1;
	ok(n == 3 && r.unit[0] == UNIT_PHOT && r.unit[1] == UNIT_ERG && r.unit[2] == UNIT_COUNTS,
	   "mixed: units p, e, c (%s)", e.msg);
	catalog_close(c);
	fails(FIX("mixed2.csv", "\\type=mixed\n\\filter=F129\nra,dec,flux\n1,2,3\n"), o,
	      "catalog type 'mixed' needs a 'units' column", EXIT_INPUT, "mixed without units");
	fails(FIX("int.csv", "\\type=internal\nra,dec,flux\n1,2,3\n"), o,
	      "catalog type 'internal' needs metadata 'filter'", EXIT_INPUT,
	      "internal without filter");
	fails(FIX("ph.csv", "\\type=phoenix\nra,dec,flux\n1,2,3\n"), o,
	      "catalog type 'phoenix' needs stellar or galaxy spectra", EXIT_INPUT,
	      "phoenix needs STIPS");
	fails(FIX("bc.csv", "\\type=bc95\nra,dec,flux\n1,2,3\n"), o,
	      "catalog type 'bc95' needs", EXIT_INPUT, "bc95 needs STIPS");
}

static void test_errors(void)
{
	struct catalog_opts o = opts();
	struct err e;
	char *big;
	size_t len = (16u << 20) + 100;

	fails(FIX("e1.csv", "ra,dec,flux\n1,2,3\n1,2,abc\n"), o,
	      "e1.csv:3: column 'flux': not a number: 'abc'", EXIT_INPUT, "not a number");
	fails(FIX("e2.csv", "ra,dec,flux\n1,2,nan\n"), o,
	      "e2.csv:2: column 'flux': not a finite number: 'nan'", EXIT_INPUT, "NaN");
	fails(FIX("e3.csv", "ra,dec,flux\n1,inf,3\n"), o,
	      "e3.csv:2: column 'dec': not a finite number: 'inf'", EXIT_INPUT, "Inf");
	fails(FIX("e4.csv", "ra,dec,flux\n1,2,-3\n"), o,
	      "e4.csv:2: column 'flux': flux must be positive: '-3'", EXIT_INPUT, "negative flux");
	fails(FIX("e5.csv", "ra,dec,flux\n1,2,0\n"), o,
	      "column 'flux': flux must be positive: '0'", EXIT_INPUT, "zero flux");
	fails(FIX("e6.csv", "ra,dec,mag\n1,2,99\n"), o,
	      "e6.csv:2: column 'mag': magnitude out of range [-20, 50]: '99'", EXIT_INPUT,
	      "absurd magnitude");
	fails(FIX("e7.csv", "ra,dec\n1,2\n"), o,
	      "e7.csv:1: no flux column: need 'flux' or 'mag'", EXIT_INPUT, "no flux");
	fails(FIX("e8.csv", "flux,mag\n1,2\n"), o,
	      "e8.csv:1: no position columns: need 'ra' and 'dec', or 'x' and 'y'",
	      EXIT_INPUT, "no positions");
	fails(FIX("e9.csv", "ra,dec,flux,RA\n1,2,3,4\n"), o,
	      "e9.csv:1: duplicate column 'ra'", EXIT_INPUT, "duplicate column");
	fails(FIX("e10.csv", "ra,dec,flux\n1,2,3\n1,2,3,4\n"), o,
	      "e10.csv:3: row has 4 fields, the header has 3", EXIT_INPUT, "too many fields");
	fails(FIX("e11.csv", "ra,dec,flux\n1,2\n"), o,
	      "e11.csv:2: row has 2 fields, the header has 3", EXIT_INPUT, "too few fields");
	fails(FIX("e12.csv", "ra,dec,flux\n1,2,3\n1,\0002,3\n"), o,
	      "e12.csv:3: binary data: byte 0x00", EXIT_INPUT, "NUL byte");
	fails(FIX("e13.csv", "ra,dec,flux\n1,2,\xff\xfe\n"), o,
	      "e13.csv:2: invalid UTF-8", EXIT_INPUT, "invalid UTF-8");
	fails(FIX("e14.csv", "ra,dec,flux\n1,2,\"3\n"), o,
	      "e14.csv:2: unterminated quoted field", EXIT_INPUT, "unterminated quote");
	fails(FIX("e15.csv", "ra,dec,flux\r1,2,3\r"), o,
	      "stray carriage return", EXIT_INPUT, "old Mac line ends");
	fails(FIX("e16.csv", "ra,dec,flux,units\n1,2,3,q\n"), o,
	      "e16.csv:2: column 'units': unknown unit 'q'", EXIT_INPUT, "unknown row unit");
	fails(FIX("e17.csv", "x,y,sca,flux\n1,2,19,3\n"), o,
	      "e17.csv:2: column 'sca': not an SCA (1 to 18): '19'", EXIT_INPUT, "bad sca");
	fails(FIX("e18.csv", "ra,dec,flux,id\n1,2,3,1.5\n"), o,
	      "e18.csv:2: column 'id': not an integer: '1.5'", EXIT_INPUT, "bad id");
	fails(FIX("e19.csv", "ra,dec,flux\n1,2,\n"), o,
	      "e19.csv:2: column 'flux': empty value", EXIT_INPUT, "empty flux");
	fails(FIX("e20.csv", "\\type=foo\nra,dec,flux\n1,2,3\n"), o,
	      "unknown catalog type 'foo'", EXIT_INPUT, "unknown type");
	fails(FIX("e21.csv", "\\fluxunit=watts\nra,dec,flux\n1,2,3\n"), o,
	      "metadata 'fluxunit': unknown unit 'watts'", EXIT_INPUT, "unknown fluxunit");
	fails(FIX("e22.csv", "ra,flux\n1,3\n"), o,
	      "column 'ra' without 'dec'", EXIT_INPUT, "ra without dec");
	fails(FIX("e23.csv", "ra,dec,flux\n1,91,3\n"), o,
	      "column 'dec': out of range [-90, 90]", EXIT_INPUT, "dec > 90");
	fails("/nonexistent/cat.csv", o, "/nonexistent/cat.csv: cannot open",
	      EXIT_SYSTEM, "missing file is a system error");

	/* A line longer than the cap, and one just under it. */
	big = malloc(len + 64);
	memcpy(big, "ra,dec,flux,notes\n1,2,3,", 24);
	memset(big + 24, 'a', len - 24);
	big[len] = '\n';
	fails(fixture("long.csv", big, len + 1), o, "long.csv:2: line longer than 16 MiB",
	      EXIT_INPUT, "over-long line");
	len = (8u << 20) + 5;
	memset(big + 24, 'b', len - 24);
	big[len] = '\n';
	fixture("long2.csv", big, len + 1);
	ok(read_all(path, o, &e) == 1, "a 8 MiB line is fine: %s", e.msg);
	free(big);
}

static void test_empty(void)
{
	struct catalog_opts o = opts();
	struct err e;

	ok(read_all(FIX("empty.csv", ""), o, &e) == 0, "0-byte file: empty catalog");
	ok(read_all(FIX("hdr.csv", "ra,dec,flux\n"), o, &e) == 0, "header only: empty catalog");
	ok(read_all(FIX("cmt.csv", "# nothing\n\n"), o, &e) == 0, "comments only: empty catalog");
	ok(read_all(FIX("hdr2.csv", "ra,dec,flux\n\n# c\n"), o, &e) == 0,
	   "header and blank lines: empty");
	fails(FIX("hdr3.csv", "ra,dec\n"), o, "no flux column", EXIT_INPUT,
	      "header-only still needs the columns");
}

static void test_numbers(void)
{
	static const char *good[] = { "0", "-0", "1", "-1.5", "3.14159", "1e-300",
		"2.2250738585072014e-308", "4.9e-324", "1.7976931348623157e308",
		"0.1", "123456789012345678901234567890", ".5", "5.", "+2",
		"1.000000000000000000000001", "9007199254740993", " 7 ", "1E5",
		"0.30000000000000004", "12345.6789e-3", "1e22", "1e23", "8e-23" };
	int all = 1;

	for (size_t i = 0; i < sizeof(good) / sizeof(good[0]); i++) {
		double v = -1, w = strtod(good[i], NULL);

		if (catalog_parse_double(good[i], &v) != 0 || v != w ||
		    signbit(v) != signbit(w)) {
			all = 0;
			diag("'%s': got %.17g want %.17g", good[i], v, w);
		}
	}
	ok(all, "numbers parse exactly as strtod does");
	{
		double v;

		ok(catalog_parse_double("abc", &v) == 1 && catalog_parse_double("1e", &v) == 1 &&
		   catalog_parse_double("", &v) == 1 && catalog_parse_double("1 2", &v) == 1 &&
		   catalog_parse_double("0x10", &v) == 1 && catalog_parse_double("-", &v) == 1,
		   "garbage is not a number");
		ok(catalog_parse_double("nan", &v) == 2 && catalog_parse_double("-inf", &v) == 2 &&
		   catalog_parse_double("1e999", &v) == 2, "NaN, Inf and overflow are not finite");
	}
	/* Random round trips. */
	{
		unsigned long long s = 88172645463325252ull;
		char b[64];

		all = 1;
		for (int i = 0; i < 200000; i++) {
			double v, w;

			s ^= s << 13, s ^= s >> 7, s ^= s << 17;
			snprintf(b, sizeof(b), "%.*g", (int)(s % 17) + 1,
				 ldexp((double)(s >> 11), (int)(s % 64) - 70));
			w = strtod(b, NULL);
			if (catalog_parse_double(b, &v) != 0 || v != w) {
				all = 0;
				diag("'%s'", b);
				break;
			}
		}
		ok(all, "200000 random decimals parse exactly");
	}
}

/* Cells read from a text table take a word-at-a-time path for plain
 * decimals: it must give strtod's double for every length of integer and
 * fraction part, signs, and what it hands on (exponents, long digit runs),
 * wherever the cell ends relative to the buffer. */
static void test_plain_cells(void)
{
	enum { N = 60000 };
	unsigned long long s = 0x9e3779b97f4a7c15ull;
	size_t cap = (size_t)N * 3 * 40 + 64, len = 0;
	char *text = malloc(cap), (*cell)[3][40] = malloc(sizeof(*cell) * N);
	struct catalog_opts o = opts();
	struct catalog *c;
	struct rows r;
	struct err e;
	long n, row = 0;
	int all = 1;

	if (!text || !cell)
		exit(2);
	len += (size_t)snprintf(text, cap, "x,y,flux\n");
	for (int i = 0; i < N; i++) {
		for (int k = 0; k < 3; k++) {
			char *b = cell[i][k];
			int id, fd, p = 0;

			s ^= s << 13, s ^= s >> 7, s ^= s << 17;
			id = (int)(s % 9);              /* 0..8 integer digits */
			fd = (int)(s >> 8) % 20 - 1;    /* no point, or 0..18 digits */
			if (k < 2 && s >> 40 & 1)
				b[p++] = '-';
			for (int d = 0; d < id; d++)
				b[p++] = (char)('0' + (s >> (d * 3 + 12)) % 10);
			if (fd >= 0) {
				unsigned long long t = s * 0x2545f4914f6cdd1dull;

				b[p++] = '.';
				for (int d = 0; d < fd; d++, t = t * 6364136223846793005ull + 1)
					b[p++] = (char)('0' + (t >> 33) % 10);
			}
			if (id == 0 && fd <= 0)
				b[p++] = '7';
			if (k == 2 && (s >> 50 & 7) == 0)
				p += sprintf(b + p, "e-%d", (int)(s >> 53) % 30);
			b[p] = 0;
			if (k == 2 && strtod(b, NULL) <= 0)
				strcpy(b, "3");         /* flux must be positive */
			len += (size_t)snprintf(text + len, cap - len, "%s%c", b, k < 2 ? ',' : '\n');
		}
	}
	fixture("plain.csv", text, len);
	err_clear(&e);
	o.chunk_rows = 4099;
	c = catalog_open(path, &o, &e);
	while (c && (n = catalog_read(c, &r, &e)) > 0)
		for (long i = 0; i < n && all; i++, row++) {
			double want[3], got[3] = { r.x[i] + 1, r.y[i] + 1, r.flux[i] };

			for (int k = 0; k < 3; k++) {
				want[k] = strtod(cell[row][k], NULL);
				if (k < 2) {
					/* x, y are stored 0-based */
					got[k] = k ? r.y[i] : r.x[i];
					want[k] -= 1;
				}
				if (got[k] != want[k] || signbit(got[k]) != signbit(want[k])) {
					all = 0;
					diag("row %ld column %d '%s': got %.17g want %.17g", row + 1, k,
					     cell[row][k], got[k], want[k]);
				}
			}
		}
	if (!c || row != N)
		diag("%ld rows: %s", row, e.msg);
	ok(c && row == N && all, "60000 rows of plain decimals read as strtod reads them");
	catalog_close(c);
	free(text);
	free(cell);
}

int main(void)
{
	char cmd[600];

	if (!mkdtemp(dir))
		skip_all("no temporary directory");
	test_numbers();
	test_plain_cells();
	test_csv();
	test_chunks();
	test_wide();
	test_compressed();
	test_ipac_ecsv();
	test_units_and_types();
	test_errors();
	test_empty();
	snprintf(cmd, sizeof(cmd), "rm -rf %s", dir);
	if (system(cmd) != 0)
		diag("could not remove %s", dir);
	return done_testing();
}
