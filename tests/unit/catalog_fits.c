/*
 * catalog_fits.c - FITS binary table catalogs: several HDUs read in row
 * chunks, header keywords as metadata, compressed and stdin input through
 * a spool file, and the column-type errors.
 */
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <fitsio.h>

#include "catalog.h"
#include "err.h"
#include "instrument.h"
#include "table_build.h"
#include "tap.h"

static char dir[] = "/tmp/wfs-catfits-XXXXXX";

static char *fpath(const char *name)
{
	static char p[4][512];
	static int k;

	k = (k + 1) % 4;
	snprintf(p[k], sizeof(p[k]), "%s/%s", dir, name);
	return p[k];
}

/* A table HDU with columns ra dec flux type id, rows values from base. */
static void add_table(fitsfile *f, int nrow, int base, const char *fluxform,
		      int *status)
{
	char *names[] = { "RA", "Dec", "flux", "TYPE", "id" };
	char *forms[] = { "D", "D", (char *)fluxform, "12A", "K" };
	char *units[] = { "deg", "deg", "", "", "" };
	double ra[64], dec[64];
	float fl[64];
	long long id[64];
	char tb[64][16], *tp[64];

	fits_create_tbl(f, BINARY_TBL, nrow, 5, names, forms, units, "CAT", status);
	for (int i = 0; i < nrow; i++) {
		ra[i] = 10 + 0.001 * (base + i);
		dec[i] = -5 - 0.001 * (base + i);
		fl[i] = (float)(base + i + 1) * 0.5f;
		id[i] = 9000000000000000000ll + base + i;
		snprintf(tb[i], sizeof(tb[i]), (base + i) % 2 ? "Sersic" : "point");
		tp[i] = tb[i];
	}
	fits_write_col(f, TDOUBLE, 1, 1, 1, nrow, ra, status);
	fits_write_col(f, TDOUBLE, 2, 1, 1, nrow, dec, status);
	fits_write_col(f, TFLOAT, 3, 1, 1, nrow, fl, status);
	fits_write_col(f, TSTRING, 4, 1, 1, nrow, tp, status);
	fits_write_col(f, TLONGLONG, 5, 1, 1, nrow, id, status);
}

static int make_fits(const char *path, int nhdu, const char *type)
{
	fitsfile *f;
	int status = 0;

	remove(path);
	fits_create_file(&f, path, &status);
	fits_create_img(f, 8, 0, NULL, &status);
	if (type) {
		fits_write_key(f, TSTRING, "TYPE", (void *)type, NULL, &status);
		fits_write_key(f, TSTRING, "FILTER", "F129", NULL, &status);
	}
	for (int h = 0; h < nhdu; h++)
		add_table(f, 5, 5 * h, "E", &status);
	fits_close_file(f, &status);
	return status;
}

static long read_all(const char *p, size_t chunk, struct err *e)
{
	struct catalog_opts o = { .filter = F129, .chunk_rows = chunk };
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

static void fails(const char *p, const char *want, const char *what)
{
	struct err e;
	long n = read_all(p, 0, &e);

	if (!ok(n < 0 && strstr(e.msg, want) && e.code == EXIT_INPUT, "%s", what))
		diag("got %ld rows, code %d, '%s'; want '%s'", n, e.code, e.msg, want);
}

static void test_read(void)
{
	struct catalog_opts o = { .filter = F129, .chunk_rows = 3 };
	struct catalog *c;
	struct rows r;
	struct err e = { 0 };
	long n, total = 0;
	int good = 1, chunks = 0;
	const char *p = fpath("two.fits");

	ok(make_fits(p, 2, "internal") == 0, "wrote a 2-HDU table");
	c = catalog_open(p, &o, &e);
	ok(c != NULL, "FITS opens: %s", e.msg);
	if (!c)
		return;
	while ((n = catalog_read(c, &r, &e)) > 0) {
		chunks++;
		for (long i = 0; i < n; i++) {
			long k = total + i;
			int t = rows_column(&r, "type");

			if (r.ra[i] != 10 + 0.001 * k || r.dec[i] != -5 - 0.001 * k ||
			    r.flux[i] != (k + 1) * 0.5 || r.id[i] != 9000000000000000000ll + k ||
			    strcmp(r.type[i], k % 2 ? "sersic" : "point") != 0 ||
			    strcmp(r.text[t][i], r.type[i]) != 0 || r.line[i] != k % 5 + 1 ||
			    !r.sersic_ie) {
				good = 0;
				diag("row %ld: ra %.17g flux %g id %lld type %s line %ld", k,
				     r.ra[i], r.flux[i], r.id[i], r.type[i], r.line[i]);
			}
		}
		if (total == 0)
			ok(strstr(r.file, "two.fits[1]") != NULL, "first HDU named %s", r.file);
		total += n;
		if (total == 10)
			ok(strstr(r.file, "two.fits[2]") != NULL, "second HDU named %s", r.file);
	}
	ok(n == 0 && total == 10 && good, "10 rows from 2 HDUs, values exact (%s)", e.msg);
	ok(chunks == 4, "chunks of 3 rows within each HDU (%d)", chunks);
	{
		int c0 = rows_column(&r, "ra");
		(void)c0;
	}
	catalog_close(c);
}

static void test_spool(void)
{
	struct err e;
	char cmd[1200];
	const char *p = fpath("two.fits");
	int fd, saved;
	long n;

	snprintf(cmd, sizeof(cmd), "gzip -c %s > %s && zstd -q -c %s > %s", p,
		 fpath("two.fits.gz"), p, fpath("two.fz"));
	if (system(cmd) != 0) {
		ok(1, "# skip: no gzip or zstd");
		return;
	}
	n = read_all(fpath("two.fits.gz"), 0, &e);
	ok(n == 10, "gzip FITS through a spool file: %ld %s", n, e.msg);
	n = read_all(fpath("two.fz"), 4, &e);
	ok(n == 10, "zstd FITS through a spool file: %ld %s", n, e.msg);

	saved = dup(0);
	fd = open(fpath("two.fits.gz"), O_RDONLY);
	dup2(fd, 0);
	close(fd);
	n = read_all("-", 0, &e);
	dup2(saved, 0);
	close(saved);
	ok(n == 10, "compressed FITS on stdin: %ld %s", n, e.msg);
}

static void test_errors(void)
{
	fitsfile *f;
	int status = 0;
	char *p;

	/* ra as a string column. */
	p = fpath("str.fits");
	{
		char *names[] = { "ra", "dec", "flux" };
		char *forms[] = { "8A", "D", "D" };
		char *v[] = { "12.5" };
		double d = 1;

		remove(p);
		fits_create_file(&f, p, &status);
		fits_create_tbl(f, BINARY_TBL, 1, 3, names, forms, NULL, NULL, &status);
		fits_write_col(f, TSTRING, 1, 1, 1, 1, v, &status);
		fits_write_col(f, TDOUBLE, 2, 1, 1, 1, &d, &status);
		fits_write_col(f, TDOUBLE, 3, 1, 1, 1, &d, &status);
		fits_close_file(f, &status);
	}
	fails(p, "str.fits: column 'ra' is a string column, not a number", "ra as a string");

	/* flux as a logical column: named as one. */
	p = fpath("logical.fits");
	{
		char *names[] = { "ra", "dec", "flux" };
		char *forms[] = { "D", "D", "L" };
		double d = 1;
		char l = 1;

		remove(p);
		fits_create_file(&f, p, &status);
		fits_create_tbl(f, BINARY_TBL, 1, 3, names, forms, NULL, NULL, &status);
		fits_write_col(f, TDOUBLE, 1, 1, 1, 1, &d, &status);
		fits_write_col(f, TDOUBLE, 2, 1, 1, 1, &d, &status);
		fits_write_col(f, TLOGICAL, 3, 1, 1, 1, &l, &status);
		fits_close_file(f, &status);
	}
	fails(p, "logical.fits: column 'flux' is a logical column, not a number",
	      "flux as a logical");

	p = fpath("vec.fits");
	{
		char *names[] = { "ra", "dec", "flux" };
		char *forms[] = { "D", "D", "3D" };

		remove(p);
		fits_create_file(&f, p, &status);
		fits_create_tbl(f, BINARY_TBL, 1, 3, names, forms, NULL, NULL, &status);
		fits_close_file(f, &status);
	}
	fails(p, "vec.fits[1]: column 'flux': vector column (3 values per row) is not supported",
	      "vector column");

	p = fpath("nan.fits");
	{
		char *names[] = { "ra", "dec", "flux" };
		char *forms[] = { "D", "D", "D" };
		double a[2] = { 1, 2 }, fl[2] = { 1, NAN };

		remove(p);
		fits_create_file(&f, p, &status);
		fits_create_tbl(f, BINARY_TBL, 2, 3, names, forms, NULL, NULL, &status);
		fits_write_col(f, TDOUBLE, 1, 1, 1, 2, a, &status);
		fits_write_col(f, TDOUBLE, 2, 1, 1, 2, a, &status);
		fits_write_col(f, TDOUBLE, 3, 1, 1, 2, fl, &status);
		fits_close_file(f, &status);
	}
	fails(p, "nan.fits[1]:2: column 'flux': not a finite number: 'nan'", "NaN in FITS");

	p = fpath("diff.fits");
	remove(p);
	fits_create_file(&f, p, &status);
	fits_create_img(f, 8, 0, NULL, &status);
	add_table(f, 2, 0, "E", &status);
	{
		char *names[] = { "ra", "dec", "mag", "type", "id" };
		char *forms[] = { "D", "D", "E", "12A", "K" };

		fits_create_tbl(f, BINARY_TBL, 0, 5, names, forms, NULL, NULL, &status);
	}
	fits_close_file(f, &status);
	fails(p, "diff.fits[2]: column 3 is 'mag', in the first table it is 'flux'",
	      "HDUs with other columns");

	p = fpath("img.fits");
	remove(p);
	fits_create_file(&f, p, &status);
	fits_create_img(f, 8, 0, NULL, &status);
	fits_close_file(f, &status);
	fails(p, "img.fits: no table in this FITS file", "FITS without a table");

	make_fits(fpath("f158.fits"), 1, "mixed");
	fails(fpath("f158.fits"), "catalog type 'mixed' needs a 'units' column",
	      "keywords are metadata");
	ok(status == 0, "fixtures written");
}

/* The fast %.17g / %.9g writer must agree with printf character for
 * character. */
static void test_format(void)
{
	unsigned long long st = 0x9e3779b97f4a7c15ull;
	static const double special[] = { 0.0, -0.0, 1, -1, 0.1, 270.0, 1e16, 1e17,
		9.9999999999999998e16, 99999999999999999.0, 123456789.0, 1e-4, 9.9999e-5,
		1e-5, 0.5, 2.5, 1e22, 1e23, 5e-324, 1.7976931348623157e308, 4.35,
		1e100, 1e-100, 123456789012345678.0 };
	char a[64], b[64];
	int bad = 0;

	for (int i = 0; i < 600000 && bad < 5; i++) {
		double v;
		int digits = i % 2 ? 9 : 17;

		st ^= st << 13, st ^= st >> 7, st ^= st << 17;
		if (i < (int)(sizeof(special) / sizeof(special[0])))
			v = special[i];
		else if (i % 4 == 0)
			v = ldexp((double)(st >> 11), (int)(st % 160) - 120);
		else if (i % 4 == 1)
			v = (float)ldexp((double)(st >> 40), (int)(st % 60) - 40);
		else if (i % 4 == 2)
			v = (double)(long long)(st % 100000000000ull) / 1000.0;
		else
			memcpy(&v, &st, sizeof(v));
		if (st & 1)
			v = -v;
		snprintf(a, sizeof(a), "%.*g", digits, v);
		table_format_double(b, sizeof(b), v, digits);
		if (strcmp(a, b) != 0) {
			bad++;
			diag("%.17g with %d digits: printf '%s', ours '%s'", v, digits, a, b);
		}
	}
	ok(bad == 0, "the fast number writer agrees with printf on 6e5 values");
}

int main(void)
{
	char cmd[600];

	if (!mkdtemp(dir))
		skip_all("no temporary directory");
	test_format();
	test_read();
	test_spool();
	test_errors();
	snprintf(cmd, sizeof(cmd), "rm -rf %s", dir);
	if (system(cmd) != 0)
		diag("could not remove %s", dir);
	return done_testing();
}
