/*
 * table_fits.c - the FITS table reader: binary (and ASCII) tables through
 * cfitsio, for the table core (table.c, table_build.h).
 *
 * Every table HDU is read in turn, as STIPS writes one HDU per chunk of
 * 100,000 rows; all must have the columns of the first.  Rows are read in
 * chunks with fits_read_col on row ranges, so memory stays flat however
 * long an HDU is.  Keywords of the primary header and the first table's
 * header are the metadata (TYPE, FILTER, FLUXUNIT).  cfitsio must seek, so
 * stdin and compressed input are first spooled to an unlinked temporary
 * file.
 */
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fitsio.h>

#include "err.h"
#include "input.h"
#include "table_build.h"
#include "tempfile.h"

/* Text of one chunk at most this size: a table with very wide string
 * columns is read in fewer rows per chunk. */
#define FITS_ARENA_MAX (64u << 20)

struct fits_col {
	int num;                /* cfitsio column number */
	int type;               /* cfitsio type code */
	long width;             /* characters of a string column */
	size_t text_width;      /* bytes of text per cell, NUL included */
	size_t text_off;        /* this chunk's text of the column in arena */
	int digits;             /* of its text: 9 (E) or 17 (D) */
};

struct table_fits {
	struct table *t;
	fitsfile *f;
	long long fsize;        /* bytes in the file, -1 if unknown */
	int fd;                 /* the file, for its size and tail; -1 */
	int nhdu, hdu;          /* cfitsio HDU numbers, 1-based */
	long long nrows, row;   /* rows of the current HDU; next row, 0-based */
	int ncol;
	struct fits_col *col;
	size_t chunk_rows;
	char *fname;            /* "name[ext]" for messages */
	size_t fname_cap;

	double *num;            /* ncol x chunk_rows */
	long long *ibuf;        /* chunk_rows */
	char *lbuf;             /* chunk_rows */
	char **sptr;            /* chunk_rows */
	char *arena;
	size_t arena_cap;
	const char **cells;     /* ncol x chunk_rows */
	const char ***text;
	const double **nums;
	long *line;
};

/* 10^0 .. 10^22 as 128-bit integers: every one is exact. */
static unsigned __int128 pow10_u128(int k)
{
	unsigned __int128 p = 1;

	while (k-- > 0)
		p *= 10;
	return p;
}

static int bits_u128(unsigned __int128 x)
{
	int n = 0;

	while (x) {
		x >>= 1;
		n++;
	}
	return n;
}

/* round(v * 10^s) for v = m * 2^e > 0, exactly, ties to even, or -1 when
 * the numbers leave 128 bits. */
static long long scaled_digits(uint64_t m, int e, int s)
{
	unsigned __int128 num = m, den = 1, q, r;

	if (s > 22 || s < -22)
		return -1;
	if (s >= 0)
		num *= pow10_u128(s);   /* < 2^53 * 2^74 */
	else
		den = pow10_u128(-s);
	if (e >= 0) {
		if (bits_u128(num) + e > 127)
			return -1;
		num <<= e;
	} else {
		if (bits_u128(den) - e > 127)
			return -1;
		den <<= -e;
	}
	q = num / den;
	r = num % den;
	if (2 * r > den || (2 * r == den && (q & 1)))
		q++;
	return q > (unsigned __int128)LLONG_MAX ? -1 : (long long)q;
}

/*
 * Write v as printf's "%.*g" with digits (9 or 17) significant digits
 * would, but exactly and without printf's multi-precision arithmetic,
 * which costs far more than the read itself.  v = m 2^e with m < 2^53, so
 * v 10^s is computed exactly in 128-bit integers and rounded to even, as
 * glibc rounds.  Values out of that range (tiny, huge, non-finite) go to
 * snprintf.  Returns the length.
 */
int table_format_double(char *buf, size_t size, double v, int digits)
{
	long long q = -1, lo = 1, hi;
	int x, s, e, neg = v < 0, n = 0, len;
	double v0 = v;
	uint64_t m;
	char d[24];

	for (int i = 1; i < digits; i++)
		lo *= 10;
	hi = lo * 10;
	if (!isfinite(v) || v == 0 || size < 26)
		return snprintf(buf, size, "%.*g", digits, v);
	if (neg)
		v = -v;
	m = (uint64_t)ldexp(frexp(v, &e), 53);
	e -= 53;
	x = (int)floor(log10(v));
	for (int tries = 0; tries < 3; tries++) {
		s = digits - 1 - x;
		q = scaled_digits(m, e, s);
		if (q < 0)
			break;
		if (q >= hi)
			x++;
		else if (q < lo)
			x--;
		else
			break;
	}
	if (q < lo || q >= hi)
		return snprintf(buf, size, "%.*g", digits, v0);
	for (int i = digits - 1; i >= 0; i--, q /= 10)
		d[i] = (char)('0' + q % 10);
	len = digits;
	while (len > 1 && d[len - 1] == '0')
		len--;
	if (neg)
		buf[n++] = '-';
	if (x < -4 || x >= digits) {
		buf[n++] = d[0];
		if (len > 1) {
			buf[n++] = '.';
			memcpy(buf + n, d + 1, (size_t)len - 1);
			n += len - 1;
		}
		buf[n++] = 'e';
		buf[n++] = x < 0 ? '-' : '+';
		if (x < 0)
			x = -x;
		if (x >= 100)
			buf[n++] = (char)('0' + x / 100);
		buf[n++] = (char)('0' + x / 10 % 10);
		buf[n++] = (char)('0' + x % 10);
		buf[n] = 0;
		return n;
	}
	if (x < 0) {
		buf[n++] = '0';
		buf[n++] = '.';
		for (int i = -1; i > x; i--)
			buf[n++] = '0';
		memcpy(buf + n, d, (size_t)len);
		n += len;
	} else {
		memcpy(buf + n, d, (size_t)(x + 1 < len ? x + 1 : len));
		n += x + 1 < len ? x + 1 : len;
		for (int i = len; i < x + 1; i++)
			buf[n++] = '0';
		if (len > x + 1) {
			buf[n++] = '.';
			memcpy(buf + n, d + x + 1, (size_t)(len - x - 1));
			n += len - x - 1;
		}
	}
	buf[n] = 0;
	return n;
}

static int is_integer_type(int type)
{
	return type == TBYTE || type == TSBYTE || type == TSHORT ||
		type == TUSHORT || type == TINT || type == TUINT ||
		type == TLONG || type == TULONG || type == TLONGLONG;
}

/* cfitsio could not open the file: one that ends inside its primary
 * header is cut short, bad input; anything else is cfitsio's to say. */
static int open_failed(struct table_fits *x, int status, const char *name,
		       struct err *e)
{
	if ((status == END_OF_FILE || status == READ_ERROR) && x->fsize >= 0)
		return err_set(e, EXIT_INPUT, "%s: truncated FITS file: it ends "
			       "inside its primary header (%lld bytes)", name,
			       x->fsize);
	return err_fits(e, status, "%s", name);
}

/* Copy the decompressed input to an unlinked temporary file, open it. */
static int spool(struct table_fits *x, struct input *in, struct err *e)
{
	char name[PATH_MAX];
	char *buf;
	int fd, status = 0;
	ssize_t r;

	/* registered, so that a signal during the copy removes it too */
	if ((fd = tempfile_scratch(input_name(in), "wfiscene-fits", name, sizeof(name), e)) < 0)
		return -1;
	buf = malloc(1u << 20);
	if (!buf) {
		close(fd);
		tempfile_discard(name);
		return err_set(e, EXIT_SYSTEM, "out of memory");
	}
	while ((r = input_read(in, buf, 1u << 20, e)) > 0) {
		char *p = buf;

		while (r > 0) {
			ssize_t w = write(fd, p, (size_t)r);

			if (w < 0 && errno == EINTR)
				continue;
			if (w < 0) {
				err_sys(e, "%s: cannot write %s", input_name(in), name);
				r = -1;
				break;
			}
			p += w;
			r -= w;
		}
		if (r < 0)
			break;
	}
	free(buf);
	if (r < 0) {
		close(fd);
		tempfile_discard(name);
		return -1;
	}
	struct stat st;
	x->fsize = fstat(fd, &st) == 0 ? (long long)st.st_size : -1;
	fits_open_diskfile(&x->f, name, READONLY, &status);
	/* cfitsio holds its own descriptor: the name can go now, so the
	 * file disappears however the run ends. */
	tempfile_discard(name);
	x->fd = fd;
	if (status)
		return open_failed(x, status, input_name(in), e);
	return 0;
}

static int set_fname(struct table_fits *x)
{
	const char *n = table_name(x->t);
	size_t need = strlen(n) + 32;

	if (need > x->fname_cap) {
		char *f = realloc(x->fname, need);

		if (!f)
			return -1;
		x->fname = f;
		x->fname_cap = need;
	}
	snprintf(x->fname, x->fname_cap, "%s[%d]", n, x->hdu - 1);
	return 0;
}

static int read_keywords(struct table_fits *x, struct err *e)
{
	int nkeys = 0, status = 0;

	fits_get_hdrspace(x->f, &nkeys, NULL, &status);
	for (int k = 1; k <= nkeys && !status; k++) {
		char key[FLEN_KEYWORD], val[FLEN_VALUE], com[FLEN_COMMENT];

		fits_read_keyn(x->f, k, key, val, com, &status);
		if (status || !key[0] || !val[0] || strcmp(key, "COMMENT") == 0 ||
		    strcmp(key, "HISTORY") == 0)
			continue;
		if (table_add_meta(x->t, key, strlen(key), val, strlen(val), e) < 0)
			return -1;
	}
	if (status)
		return err_fits(e, status, "%s: header", x->fname);
	return 0;
}

/*
 * A file cut short (a copy or a download that stopped) is bad input, said
 * so, rather than a read error deep in a column.  The current HDU's data
 * (NAXIS1 x NAXIS2 bytes and the heap, PCOUNT) must end within the file.
 */
static int check_whole(struct table_fits *x, struct err *e)
{
	LONGLONG head, data, end;
	long long w = 0, h = 0, pc = 0;
	int status = 0;

	if (x->fsize < 0)
		return 0;
	fits_get_hduaddrll(x->f, &head, &data, &end, &status);
	fits_read_key(x->f, TLONGLONG, "NAXIS1", &w, NULL, &status);
	fits_read_key(x->f, TLONGLONG, "NAXIS2", &h, NULL, &status);
	if (status)
		return err_fits(e, status, "%s: HDU %d", table_name(x->t), x->hdu);
	fits_read_key(x->f, TLONGLONG, "PCOUNT", &pc, NULL, &status);
	if (status)
		pc = 0;
	if (w < 0 || h < 0 || pc < 0 || (w && h > (LLONG_MAX - data - pc) / w) ||
	    data + w * h + pc > x->fsize)
		return err_set(e, EXIT_INPUT, "%s: truncated FITS file: extension %d "
			       "(%lld rows of %lld bytes) needs %lld bytes, the file "
			       "has %lld", table_name(x->t), x->hdu - 1, h, w,
			       (long long)(data + w * h + pc), x->fsize);
	return 0;
}

/* A header cut short after the last complete HDU: cfitsio does not count
 * it as an HDU, so it would look like a file without that table. */
static int check_tail(struct table_fits *x, struct err *e)
{
	LONGLONG head, data, end;
	char buf[8];
	int status = 0, type;

	if (x->fsize < 0)
		return 0;
	fits_movabs_hdu(x->f, x->nhdu, &type, &status);
	fits_get_hduaddrll(x->f, &head, &data, &end, &status);
	if (status || end >= x->fsize || x->fsize - end < 8)
		return 0;
	if (x->fd >= 0 && pread(x->fd, buf, 8, (off_t)end) == 8 &&
	    !memcmp(buf, "XTENSION", 8))
		return err_set(e, EXIT_INPUT, "%s: truncated FITS file: the header "
			       "of extension %d ends at byte %lld, incomplete",
			       table_name(x->t), x->nhdu, x->fsize);
	return 0;
}

/* Move to the next table HDU after x->hdu; 0 when there is none. */
static int next_table(struct table_fits *x, struct err *e)
{
	int status = 0, type;

	while (++x->hdu <= x->nhdu) {
		fits_movabs_hdu(x->f, x->hdu, &type, &status);
		if (status)
			return err_fits(e, status, "%s: HDU %d", table_name(x->t), x->hdu);
		if (type == BINARY_TBL || type == ASCII_TBL) {
			fits_get_num_rowsll(x->f, &x->nrows, &status);
			if (status)
				return err_fits(e, status, "%s: HDU %d", table_name(x->t), x->hdu);
			if (check_whole(x, e) < 0)
				return -1;
			x->row = 0;
			if (set_fname(x) < 0)
				return err_set(e, EXIT_SYSTEM, "out of memory");
			return 1;
		}
	}
	return 0;
}

/* Columns of the current HDU: define them (first table) or check that
 * they are the first table's. */
static int read_columns(struct table_fits *x, int first, struct err *e)
{
	int ncol = 0, status = 0;

	fits_get_num_cols(x->f, &ncol, &status);
	if (status)
		return err_fits(e, status, "%s", x->fname);
	if (!first && ncol != x->ncol)
		return err_set(e, EXIT_INPUT, "%s: %d columns, the first table has %d",
			       x->fname, ncol, x->ncol);
	if (first) {
		x->col = calloc((size_t)(ncol ? ncol : 1), sizeof(*x->col));
		if (!x->col)
			return err_set(e, EXIT_SYSTEM, "out of memory");
		x->ncol = ncol;
	}
	for (int i = 0; i < ncol; i++) {
		char kw[FLEN_KEYWORD], name[FLEN_VALUE] = "", unit[FLEN_VALUE] = "";
		int type = 0;
		long repeat = 0, width = 0;
		struct fits_col *c = &x->col[i];
		enum table_kind kind;
		size_t tw;

		fits_make_keyn("TTYPE", i + 1, kw, &status);
		fits_read_key(x->f, TSTRING, kw, name, NULL, &status);
		if (status == KEY_NO_EXIST)
			return err_set(e, EXIT_INPUT, "%s: column %d has no name (TTYPE%d)",
				       x->fname, i + 1, i + 1);
		fits_make_keyn("TUNIT", i + 1, kw, &status);
		fits_read_key(x->f, TSTRING, kw, unit, NULL, &status);
		if (status == KEY_NO_EXIST) {
			status = 0;
			fits_clear_errmsg();
		}
		fits_get_eqcoltype(x->f, i + 1, &type, &repeat, &width, &status);
		if (status)
			return err_fits(e, status, "%s: column %d", x->fname, i + 1);
		if (first) {
			char where[FLEN_KEYWORD + 16];

			if (table_add_column(x->t, name, strlen(name), e) < 0)
				return -1;
			/* the unit's place for messages: kw is its TUNITn */
			snprintf(where, sizeof(where), "[%d] %s", x->hdu - 1, kw);
			if (unit[0] && table_set_unit_at(x->t, i, unit, strlen(unit), where, e) < 0)
				return -1;
		} else if (strcasecmp(name, table_colname(x->t, i)) != 0) {
			return err_set(e, EXIT_INPUT,
				       "%s: column %d is '%s', in the first table it is '%s'",
				       x->fname, i + 1, name, table_colname(x->t, i));
		}
		if (type < 0)
			return err_set(e, EXIT_INPUT,
				       "%s: column '%s': variable-length arrays are not supported",
				       x->fname, table_colname(x->t, i));
		if (type == TBIT || type == TCOMPLEX || type == TDBLCOMPLEX)
			return err_set(e, EXIT_INPUT,
				       "%s: column '%s': bit and complex columns are not supported",
				       x->fname, table_colname(x->t, i));
		if (type == TSTRING) {
			if (width < 1)
				width = 1;
			kind = TABLE_STRING;
			tw = (size_t)width + 1;
		} else if (repeat != 1) {
			goto vector;
		} else if (type == TLOGICAL) {
			kind = TABLE_LOGICAL;   /* text "T" or "F" */
			tw = 2;
		} else {
			kind = TABLE_NUMBER;
			tw = 26;
		}
		if (first) {
			table_set_kind(x->t, i, kind);
			c->text_width = tw;
		} else if (kind != table_colkind(x->t, i) ||
			   (type == TLOGICAL) != (c->type == TLOGICAL)) {
			return err_set(e, EXIT_INPUT,
				       "%s: column '%s' has another type than in the first table",
				       x->fname, table_colname(x->t, i));
		} else if (tw > c->text_width) {
			return err_set(e, EXIT_INPUT,
				       "%s: column '%s' is wider than in the first table",
				       x->fname, table_colname(x->t, i));
		}
		c->num = i + 1;
		c->type = type;
		c->width = width;
		continue;
vector:
		return err_set(e, EXIT_INPUT,
			       "%s: column '%s': vector column (%ld values per row) is not supported",
			       x->fname, table_colname(x->t, i), repeat);
	}
	return 0;
}

static int alloc_buffers(struct table_fits *x, struct err *e)
{
	size_t row_bytes = 0, n = x->chunk_rows, nc = (size_t)(x->ncol ? x->ncol : 1);

	for (int i = 0; i < x->ncol; i++)
		row_bytes += x->col[i].text_width;
	if (row_bytes && n > FITS_ARENA_MAX / row_bytes)
		n = FITS_ARENA_MAX / row_bytes;
	/* And at most 8 Mi cells (their pointers and values) per chunk. */
	if (n > (8u << 20) / nc)
		n = (8u << 20) / nc;
	if (n < 1)
		n = 1;
	x->chunk_rows = n;
	x->arena_cap = row_bytes * n + 1;
	x->arena = malloc(x->arena_cap);
	x->num = malloc(nc * n * sizeof(double));
	x->ibuf = malloc(n * sizeof(long long));
	x->lbuf = malloc(n);
	x->sptr = malloc(n * sizeof(char *));
	x->cells = malloc(nc * n * sizeof(char *));
	x->text = calloc(nc, sizeof(*x->text));
	x->nums = calloc(nc, sizeof(*x->nums));
	x->line = malloc(n * sizeof(long));
	if (!x->arena || !x->num || !x->ibuf || !x->lbuf || !x->sptr ||
	    !x->cells || !x->text || !x->nums || !x->line)
		return err_set(e, EXIT_SYSTEM, "out of memory");
	for (int i = 0; i < x->ncol; i++) {
		x->text[i] = x->cells + (size_t)i * n;
		if (table_colkind(x->t, i) == TABLE_NUMBER)
			x->nums[i] = x->num + (size_t)i * n;
	}
	return 0;
}

static long fits_read(void *rd, struct table_chunk *c, struct err *e);
static void fits_close(void *rd);
static const struct table_reader fits_ops = { fits_read, fits_close };

int table_fits_open(struct table *t, struct input *in, size_t chunk_rows,
		    struct err *e)
{
	struct table_fits *x = calloc(1, sizeof(*x));
	int status = 0, r;

	if (!x)
		return table_oom(e);
	x->t = t;
	x->chunk_rows = chunk_rows;
	x->fd = -1;
	x->fsize = -1;
	if (input_codec(in) == INPUT_PLAIN && input_path(in)) {
		struct stat st;

		x->fd = open(input_path(in), O_RDONLY | O_CLOEXEC);
		if (x->fd >= 0 && fstat(x->fd, &st) == 0 && S_ISREG(st.st_mode))
			x->fsize = (long long)st.st_size;
		/* fits_open_diskfile: the name is a plain path, never
		 * cfitsio's extended syntax ("cat.fits[2]"). */
		fits_open_diskfile(&x->f, input_path(in), READONLY, &status);
		if (status) {
			open_failed(x, status, input_name(in), e);
			goto fail;
		}
	} else if (spool(x, in, e) < 0) {
		goto fail;
	}
	x->hdu = 1;
	if (set_fname(x) < 0) {
		err_set(e, EXIT_SYSTEM, "out of memory");
		goto fail;
	}
	fits_get_num_hdus(x->f, &x->nhdu, &status);
	if (status) {
		err_fits(e, status, "%s", input_name(in));
		goto fail;
	}
	if (check_tail(x, e) < 0)
		goto fail;
	status = 0;
	fits_movabs_hdu(x->f, 1, NULL, &status);
	if (status) {
		err_fits(e, status, "%s", input_name(in));
		goto fail;
	}
	if (read_keywords(x, e) < 0)
		goto fail;
	r = next_table(x, e);
	if (r < 0)
		goto fail;
	if (r == 0) {
		err_set(e, EXIT_INPUT, "%s: no table in this FITS file", input_name(in));
		goto fail;
	}
	if (read_keywords(x, e) < 0 || read_columns(x, 1, e) < 0 ||
	    alloc_buffers(x, e) < 0)
		goto fail;
	table_set_reader(t, &fits_ops, x);
	return 0;
fail:
	fits_close(x);
	return -1;
}

/* v as "%lld" writes it; s has room for 21 bytes. */
static void format_integer(char *s, long long v)
{
	char d[24];
	int n = 0;
	unsigned long long u = v < 0 ? 0 - (unsigned long long)v : (unsigned long long)v;

	do
		d[n++] = (char)('0' + u % 10);
	while (u /= 10);
	if (v < 0)
		*s++ = '-';
	while (n)
		*s++ = d[--n];
	*s = 0;
}

/* Write the text of a double cell (table_chunk cell_text). */
static const char *fits_text(void *rd, int col, size_t row)
{
	struct table_fits *x = rd;
	struct fits_col *fc = &x->col[col];
	char *s = x->arena + fc->text_off + row * fc->text_width;

	table_format_double(s, fc->text_width, x->nums[col][row], fc->digits);
	x->text[col][row] = s;
	return s;
}

/* n rows from first of integer column i, as integers so that large ids
 * stay exact in the text: its cells' text at arena + used, its numbers
 * (NaN where empty).  An unsigned 64-bit column (K with TZERO 2^63) as
 * such, 2^63 and beyond too. */
static void read_integers(struct table_fits *x, int i, LONGLONG first, size_t n, size_t used,
			  int *status)
{
	struct fits_col *fc = &x->col[i];
	const char **cell = x->text[i];
	double *d = x->num + (size_t)i * x->chunk_rows;
	unsigned long long *u = (unsigned long long *)x->ibuf;
	LONGLONG nul = LLONG_MIN;
	int anynul = 0, uns = fc->type == TULONGLONG;

	if (uns)
		fits_read_colnull(x->f, TULONGLONG, fc->num, first, 1, (LONGLONG)n, u, x->lbuf,
				  &anynul, status);
	else
		fits_read_col(x->f, TLONGLONG, fc->num, first, 1, (LONGLONG)n, &nul, x->ibuf,
			      &anynul, status);
	for (size_t k = 0; k < n; k++) {
		char *s = x->arena + used + k * fc->text_width;

		if (uns ? x->lbuf[k] != 0 : x->ibuf[k] == LLONG_MIN) {
			s[0] = 0;
			d[k] = NAN;
		} else if (uns) {
			snprintf(s, fc->text_width, "%llu", u[k]);
			d[k] = (double)u[k];
		} else {
			format_integer(s, x->ibuf[k]);
			d[k] = (double)x->ibuf[k];
		}
		cell[k] = s;
	}
}

static long fits_read(void *rd, struct table_chunk *c, struct err *e)
{
	struct table_fits *x = rd;
	size_t n, used = 0;
	int status = 0;

	while (x->row >= x->nrows) {
		int r = next_table(x, e);

		if (r <= 0)
			return r;
		if (read_columns(x, 0, e) < 0)
			return -1;
	}
	n = x->chunk_rows;
	if ((long long)n > x->nrows - x->row)
		n = (size_t)(x->nrows - x->row);
	for (int i = 0; i < x->ncol; i++) {
		struct fits_col *fc = &x->col[i];
		const char **cell = x->text[i];
		LONGLONG first = x->row + 1;
		int anynul = 0;

		if (fc->type == TSTRING) {
			for (size_t k = 0; k < n; k++)
				x->sptr[k] = x->arena + used + k * fc->text_width;
			fits_read_col_str(x->f, fc->num, first, 1, (LONGLONG)n, "",
					  x->sptr, &anynul, &status);
			for (size_t k = 0; k < n; k++) {
				char *s = x->sptr[k];
				size_t len = strlen(s);

				while (len && s[len - 1] == ' ')
					s[--len] = 0;
				while (*s == ' ')
					s++;
				cell[k] = s;
			}
			used += n * fc->text_width;
		} else if (fc->type == TLOGICAL) {
			fits_read_col(x->f, TLOGICAL, fc->num, first, 1, (LONGLONG)n,
				      NULL, x->lbuf, &anynul, &status);
			for (size_t k = 0; k < n; k++) {
				char *s = x->arena + used + 2 * k;

				s[0] = x->lbuf[k] == 1 ? 'T' : x->lbuf[k] == 0 ? 'F' : 0;
				s[1] = 0;
				cell[k] = s;
			}
			used += 2 * n;
		} else if (fc->type == TULONGLONG || is_integer_type(fc->type)) {
			read_integers(x, i, first, n, used, &status);
			used += n * fc->text_width;
		} else {
			double nul = NAN;
			double *d = x->num + (size_t)i * x->chunk_rows;
			/* The shortest text that reads back to the same value:
			 * 9 digits for a float, 17 for a double. */
			int digits = fc->type == TFLOAT ? 9 : 17;

			fits_read_col(x->f, TDOUBLE, fc->num, first, 1, (LONGLONG)n,
				      &nul, d, &anynul, &status);
			fc->text_off = used;
			fc->digits = digits;
			if (digits == 17) {
				/* A double's 17-digit text reads back to the
				 * same value, so it is written only when asked
				 * for (fits_text).  A float's 9-digit text
				 * does not (2.3f is 2.29999995): columns read as
				 * text must keep seeing that text. */
				memset(cell, 0, n * sizeof(*cell));
			} else {
				for (size_t k = 0; k < n; k++)
					cell[k] = fits_text(x, i, k);
			}
			used += n * fc->text_width;
		}
		if (status)
			return err_fits(e, status, "%s: column '%s', rows %lld to %lld",
					x->fname, table_colname(x->t, i), x->row + 1,
					x->row + (long long)n);
	}
	for (size_t k = 0; k < n; k++)
		x->line[k] = (long)(x->row + (long long)k + 1);
	x->row += (long long)n;
	c->n = n;
	c->file = x->fname;
	c->line = x->line;
	c->text = x->text;
	c->num = x->nums;
	c->cell_text = fits_text;
	c->src = x;
	return (long)n;
}

static void fits_close(void *rd)
{
	struct table_fits *x = rd;
	int status = 0;

	if (!x)
		return;
	if (x->f)
		fits_close_file(x->f, &status);
	if (x->fd >= 0)
		close(x->fd);
	free(x->col);
	free(x->fname);
	free(x->num);
	free(x->ibuf);
	free(x->lbuf);
	free(x->sptr);
	free(x->arena);
	free(x->cells);
	free(x->text);
	free(x->nums);
	free(x->line);
	free(x);
}
