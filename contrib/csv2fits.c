/*
 * csv2fits - turn a numeric CSV table on stdin into a FITS binary table, for
 * benchmarks and tests of wfiscene's FITS catalog reader:
 *
 *   starfield -n 1000000 | csv2fits stars.fits
 *
 * The first line names the columns; every cell must be a number.  A column
 * named "id" becomes a 64-bit integer column (TFORM K), the others doubles
 * (D).  Rows are written in blocks of 65536, so memory does not grow with
 * the table.  Exit status 0, or 1 with a message naming the line.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <fitsio.h>

#define BLOCK 65536
#define MAXCOL 64

static int fits_fail(int status, const char *path)
{
	char msg[FLEN_ERRMSG];

	fits_get_errstatus(status, msg);
	fprintf(stderr, "csv2fits: %s: %s\n", path, msg);
	return 1;
}

int main(int argc, char **argv)
{
	char *line = NULL, *name[MAXCOL], *form[MAXCOL], path[4096];
	size_t cap = 0;
	ssize_t len;
	double *col[MAXCOL];
	int ncol = 0, status = 0, isid[MAXCOL];
	long long lineno = 1, row = 1, n = 0;
	fitsfile *f;

	if (argc != 2) {
		fprintf(stderr, "usage: csv2fits OUT.fits < table.csv\n");
		return 1;
	}
	if ((len = getline(&line, &cap, stdin)) <= 0) {
		fprintf(stderr, "csv2fits: <stdin>: no header line\n");
		return 1;
	}
	line[strcspn(line, "\r\n")] = 0;
	for (char *s = strtok(line, ","); s; s = strtok(NULL, ",")) {
		if (ncol == MAXCOL) {
			fprintf(stderr, "csv2fits: more than %d columns\n", MAXCOL);
			return 1;
		}
		name[ncol] = strdup(s);
		isid[ncol] = strcmp(s, "id") == 0;
		form[ncol] = isid[ncol] ? "1K" : "1D";
		if (!name[ncol] || !(col[ncol] = malloc(BLOCK * sizeof(double))))
			return fprintf(stderr, "csv2fits: out of memory\n"), 1;
		ncol++;
	}
	snprintf(path, sizeof(path), "!%s", argv[1]);
	if (fits_create_file(&f, path, &status) ||
	    fits_create_tbl(f, BINARY_TBL, 0, ncol, name, form, NULL, "CATALOG", &status))
		return fits_fail(status, argv[1]);
	for (;;) {
		len = getline(&line, &cap, stdin);
		if (len > 0) {
			char *p = line, *end;

			lineno++;
			for (int c = 0; c < ncol; c++) {
				errno = 0;
				col[c][n] = strtod(p, &end);
				if (end == p || errno || (*end != ',' && c + 1 < ncol) ||
				    (c + 1 == ncol && *end != '\n' && *end != '\r' && *end)) {
					fprintf(stderr, "csv2fits: <stdin>:%lld: column '%s': not a number\n",
						lineno, name[c]);
					return 1;
				}
				p = end + 1;
			}
			n++;
		}
		if (n == BLOCK || (len <= 0 && n > 0)) {
			for (int c = 0; c < ncol; c++) {
				if (isid[c]) {
					long long *v = (long long *)col[c];

					/* in place: a double is as wide as a long long */
					for (long long i = 0; i < n; i++)
						v[i] = (long long)col[c][i];
					fits_write_col(f, TLONGLONG, c + 1, row, 1, n, v, &status);
				} else {
					fits_write_col(f, TDOUBLE, c + 1, row, 1, n, col[c], &status);
				}
			}
			if (status)
				return fits_fail(status, argv[1]);
			row += n;
			n = 0;
		}
		if (len <= 0)
			break;
	}
	if (ferror(stdin)) {
		fprintf(stderr, "csv2fits: <stdin>: %s\n", strerror(errno));
		return 1;
	}
	if (fits_close_file(f, &status))
		return fits_fail(status, argv[1]);
	for (int c = 0; c < ncol; c++) {
		free(name[c]);
		free(col[c]);
	}
	free(line);
	return 0;
}
