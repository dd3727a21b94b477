/*
 * fitsout.c - writing the output FITS file; see fitsout.h.
 *
 * Two writers sit behind one interface:
 *
 *  - Uncompressed output (a regular file, stdout, or another non-regular
 *    target such as a pipe or /dev/null) is written by our own code, straight
 *    into a file descriptor through a fixed 1 MiB buffer.  A FITS image is a
 *    sequence of 2880-byte blocks: header cards (80 ASCII characters each,
 *    padded with blank cards after END), then big-endian IEEE-754 data padded
 *    with zero bytes.  Writing it ourselves keeps memory bounded on stdout
 *    (cfitsio's "-" holds the whole file in memory until it is closed) and
 *    makes a file and stdout byte-for-byte the same.
 *
 *  - Tile-compressed output goes through cfitsio (fits_create_diskfile on the
 *    temporary name, which takes the name literally: no "[ext]" or "!"
 *    parsing of user paths).  Compression needs seeks back into the file, so
 *    it is refused for stdout and other non-regular targets.
 *
 * Regular files are written under ".NAME.XXXXXX" in the target's directory,
 * then fsync'ed, renamed over NAME and the directory fsync'ed, so NAME only
 * ever holds a complete file.  Every write, fsync and close is checked; the
 * first failure is kept (sticky) and names the requested file.
 */
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <fitsio.h>

#include "err.h"
#include "fitsout.h"
#include "simd.h"
#include "tempfile.h"

#define CARD 80
#define BLOCK 2880
#define CARDS_PER_BLOCK (BLOCK / CARD)
/* Write-buffer size: large enough that write(2) calls are few, small enough
 * to be irrelevant next to the image buffers; a multiple of the page size. */
#define WBUF_SIZE (1u << 20)

enum fitsout_state {
	ST_EMPTY,               /* nothing written yet */
	ST_READY,               /* primary written, between images */
	ST_IMAGE,               /* inside an image: rows expected */
	ST_GROUP,               /* inside a group of HDUs written by offset */
};

/* One HDU of a group (fitsout_group_begin). */
struct group_hdu {
	long long data_off;     /* file offset of its data */
	long nx, ny, nz;
	int bitpix;
	long long rows;         /* rows written, all planes */
	char name[72];
};

struct fitsout {
	char *path;             /* requested name ("-" for stdout) */
	const char *name;       /* for messages: path or "<stdout>" */
	char *tmp;              /* temporary name, NULL when streaming */
	int fd;                 /* our writer; -1 when cfitsio writes */
	int close_fd;           /* fd is ours to close (not stdout) */
	int failed;             /* a write failed: everything after fails */
	enum fitsout_state state;
	int nhdu;               /* HDUs begun so far */

	fitsfile *fz;           /* compressed output, or NULL */
	int ctype;              /* cfitsio compression type, 0 = none */

	long nx, ny, rows;      /* current image: size, rows written */
	char hduname[72];       /* EXTNAME of the current image, for messages */

	unsigned char *buf;     /* write buffer (our writer only) */
	size_t len;
	long long wlo, whi;     /* bytes written in order whose writing back
				   is not yet asked for (tempfile_writeback) */
	float *scratch;         /* row copy handed to cfitsio */
	size_t scratch_n;

	struct group_hdu *grp;  /* the HDUs of the current group */
	int ngrp;
	long long grp_end;      /* file offset after the group */
	unsigned char *gbuf;    /* big-endian copy of a group write */
	size_t gbuf_n;
};

/* ---- card formatting ---- */

/* Start a blank 80-character card with the keyword and its value
 * indicator; *pos is the column where the value goes. */
static void card_start(char *buf, const char *key, int *pos)
{
	size_t klen = strlen(key);

	memset(buf, ' ', CARD);
	buf[CARD] = 0;
	if (klen <= 8) {
		memcpy(buf, key, klen);
		buf[8] = '=';
		*pos = 10;
	} else {
		/* ESO HIERARCH convention for keywords longer than eight
		 * characters; cfitsio and astropy both read it. */
		int n = snprintf(buf, CARD + 1, "HIERARCH %.60s = ", key);
		buf[n] = ' ';
		*pos = n;
	}
}

/* Append " / comment" if it fits; the comment is what gets cut when space
 * runs out, never the value. */
static void card_comment(char *buf, int pos, const char *comment)
{
	if (!comment || !*comment || pos + 3 >= CARD)
		return;
	buf[pos + 1] = '/';
	for (int i = pos + 3; i < CARD && *comment; i++, comment++)
		buf[i] = (*comment >= 32 && *comment <= 126) ? *comment : '?';
	buf[CARD] = 0;
}

/* A fixed-format value: right-justified to column 30 when it fits. */
static void card_value(char *buf, const char *key, const char *val,
		       const char *comment)
{
	int pos, vlen = (int)strlen(val);

	card_start(buf, key, &pos);
	if (pos == 10 && vlen <= 20)
		pos = 30 - vlen;
	if (vlen > CARD - pos)
		vlen = CARD - pos;
	memcpy(buf + pos, val, (size_t)vlen);
	card_comment(buf, pos + vlen, comment);
}

void fits_card_str(char *buf, const char *key, const char *value,
		   const char *comment)
{
	int pos, n;
	const char *v = value ? value : "";

	card_start(buf, key, &pos);
	buf[pos++] = '\'';
	/* Room for the value and its closing quote.  A quote is written as
	 * two; a pair is never split, so a truncated value stays well formed.
	 * Characters outside printable ASCII are not allowed in headers. */
	for (n = 0; *v && pos < CARD - 1; v++, n++) {
		char c = (*v >= 32 && *v <= 126) ? *v : '?';
		if (c == '\'') {
			if (pos + 2 > CARD - 1)
				break;
			buf[pos++] = '\'';
		}
		buf[pos++] = c;
	}
	/* Fixed format pads short strings to eight characters. */
	for (; n < 8 && pos < CARD - 1; n++)
		buf[pos++] = ' ';
	buf[pos++] = '\'';
	if (pos < 30)
		pos = 30;
	card_comment(buf, pos, comment);
}

void fits_card_dbl(char *buf, const char *key, double value,
		   const char *comment)
{
	char val[40];
	int pos;

	if (!isfinite(value)) {
		/* FITS has no NaN or infinity: write an undefined value. */
		card_start(buf, key, &pos);
		card_comment(buf, 30, comment);
		return;
	}
	/* The shortest of %.15G, %.16G, %.17G that reads back exactly. */
	for (int prec = 15; prec <= 17; prec++) {
		snprintf(val, sizeof(val), "%.*G", prec, value);
		if (strtod(val, NULL) == value)
			break;
	}
	/* A real needs a point or an exponent, else readers see an integer. */
	if (!strpbrk(val, ".E")) {
		strcat(val, ".0");
	} else if (!strchr(val, '.')) {
		/* "1E+20" -> "1.0E+20", for readers that expect a point. */
		char *x = strchr(val, 'E');
		memmove(x + 2, x, strlen(x) + 1);
		x[0] = '.';
		x[1] = '0';
	}
	card_value(buf, key, val, comment);
}

void fits_card_int(char *buf, const char *key, long long value,
		   const char *comment)
{
	char val[32];

	snprintf(val, sizeof(val), "%lld", value);
	card_value(buf, key, val, comment);
}

void fits_card_bool(char *buf, const char *key, int value,
		    const char *comment)
{
	card_value(buf, key, value ? "T" : "F", comment);
}

/* ---- caller card validation ---- */

static int reserved_keyword(const char *kw)
{
	static const char *const names[] = {
		"SIMPLE", "BITPIX", "NAXIS", "EXTEND", "XTENSION", "PCOUNT",
		"GCOUNT", "END", "BSCALE", "BZERO", "BLANK", "ZIMAGE",
		"ZBITPIX", "ZNAXIS", "ZCMPTYPE", "ZQUANTIZ", "ZDITHER0",
	};
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++)
		if (!strcmp(kw, names[i]))
			return 1;
	/* NAXISn, ZNAXISn, ZTILEn */
	if (!strncmp(kw, "NAXIS", 5) || !strncmp(kw, "ZNAXIS", 6) ||
	    !strncmp(kw, "ZTILE", 5))
		return 1;
	return 0;
}

/* A value that opens a quote must close it ('' is an escaped quote).
 * cfitsio's own parser accepts an unclosed string, so check here. */
static int string_closed(const char *c)
{
	int i = 10;

	while (i < CARD && c[i] == ' ')
		i++;
	if (i == CARD || c[i] != '\'')
		return 1;
	for (i++; i < CARD; i++) {
		if (c[i] != '\'')
			continue;
		if (i + 1 < CARD && c[i + 1] == '\'')
			i++;
		else
			return 1;
	}
	return 0;
}

/* Check the caller's cards: whole cards, printable ASCII, valid keyword
 * names, no structural keywords (those are ours), closed quotes. */
static int check_cards(struct fitsout *f, const char *cards, int ncards,
		       struct err *e)
{
	if (ncards < 0 || (ncards > 0 && !cards))
		return err_set(e, EXIT_SYSTEM, "%s: HDU %d: bad header card list",
			       f->name, f->nhdu + 1);
	if (ncards > 0 && memchr(cards, 0, (size_t)ncards * CARD))
		return err_set(e, EXIT_SYSTEM,
			       "%s: HDU %d: header cards end before card %d "
			       "(each card is 80 characters)", f->name,
			       f->nhdu + 1, ncards);
	for (int i = 0; i < ncards; i++) {
		const char *c = cards + (size_t)i * CARD;
		char kw[9];
		int k;

		memcpy(kw, c, 8);
		kw[8] = 0;
		for (k = 7; k >= 0 && kw[k] == ' '; k--)
			kw[k] = 0;
		for (int j = 0; j < CARD; j++)
			if (c[j] < 32 || c[j] > 126)
				return err_set(e, EXIT_SYSTEM,
					       "%s: HDU %d card %d ('%s'): "
					       "character 0x%02x is not allowed "
					       "in a FITS header", f->name,
					       f->nhdu + 1, i + 1, kw,
					       (unsigned char)c[j]);
		for (k = 0; kw[k]; k++)
			if (!((kw[k] >= 'A' && kw[k] <= 'Z') ||
			      (kw[k] >= '0' && kw[k] <= '9') ||
			      kw[k] == '-' || kw[k] == '_'))
				return err_set(e, EXIT_SYSTEM,
					       "%s: HDU %d card %d: bad keyword "
					       "'%s'", f->name, f->nhdu + 1,
					       i + 1, kw);
		if (reserved_keyword(kw))
			return err_set(e, EXIT_SYSTEM,
				       "%s: HDU %d card %d: keyword '%s' is "
				       "written by the FITS writer itself",
				       f->name, f->nhdu + 1, i + 1, kw);
		if (c[8] == '=' && c[9] == ' ' && !string_closed(c))
			return err_set(e, EXIT_SYSTEM,
				       "%s: HDU %d card %d ('%s'): string value "
				       "has no closing quote", f->name,
				       f->nhdu + 1, i + 1, kw);
	}
	return 0;
}

/* ---- our writer: a buffered file descriptor ---- */

/* Write n bytes whole, retrying short writes and EINTR: at the file's
 * position when off < 0 (the sequential writer), else at offset off (the
 * multi-HDU group writer fills its planes in any order). */
static int write_at(struct fitsout *f, const void *p, size_t n, long long off,
		    struct err *e)
{
	const unsigned char *q = p;

	while (n > 0) {
		ssize_t w = off < 0 ? write(f->fd, q, n)
				    : pwrite(f->fd, q, n, (off_t)off);

		if (w < 0 && errno == EINTR)
			continue;
		if (w <= 0) {
			if (w == 0)
				errno = EIO;
			f->failed = 1;
			return err_sys(e, "%s: write error", f->name);
		}
		q += w;
		n -= (size_t)w;
		if (off >= 0)
			off += w;
	}
	return 0;
}

/*
 * As the temporary file is written, the kernel is asked to start writing
 * it back (tempfile_writeback): each WBACK bytes written in order, and
 * each positioned write of a group's rows of at least WBACK_AT.  The
 * fsync() that ends the file then waits for its last pages only, where it
 * waited for the whole file (26 ms of a 0.5 s run of 10^6 stars on one
 * SCA, 122 ms of a level-2 SCA).
 */
#define WBACK (8u << 20)
#define WBACK_AT (1u << 20)

static int wflush(struct fitsout *f, struct err *e)
{
	int r = write_at(f, f->buf, f->len, -1, e);
	long long end = r == 0 && f->tmp ? (long long)lseek(f->fd, 0, SEEK_CUR) : -1;

	/* the bytes just written, [end - len, end), join the pending run, or
	 * (after a seek: a group's headers) begin it afresh */
	if (end >= 0) {
		if (end - (long long)f->len != f->whi) {
			tempfile_writeback(f->fd, f->wlo, f->whi);
			f->wlo = end - (long long)f->len;
		}
		f->whi = end;
		if (f->whi - f->wlo >= WBACK)
			f->wlo = tempfile_writeback(f->fd, f->wlo, f->whi);
	}
	f->len = 0;
	return r;
}

static int wput(struct fitsout *f, const void *p, size_t n, struct err *e)
{
	const unsigned char *s = p;

	while (n > 0) {
		size_t room = WBUF_SIZE - f->len, k = n < room ? n : room;
		memcpy(f->buf + f->len, s, k);
		f->len += k;
		s += k;
		n -= k;
		if (f->len == WBUF_SIZE && wflush(f, e))
			return -1;
	}
	return 0;
}

/* n zero bytes (block padding of the data unit). */
static int wzeros(struct fitsout *f, size_t n, struct err *e)
{
	static const unsigned char zero[BLOCK];

	while (n > 0) {
		size_t k = n < BLOCK ? n : BLOCK;
		if (wput(f, zero, k, e))
			return -1;
		n -= k;
	}
	return 0;
}

/* u with its bytes in big-endian order in memory. */
static inline uint32_t swap32(uint32_t u)
{
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
	return u;
#else
	return (u >> 24) | (u >> 8 & 0xff00) | (u << 8 & 0xff0000) | u << 24;
#endif
}

/* n 32-bit words of v into q, each byte-swapped (big-endian on a little-
 * endian machine): the plain loop, and AVX2 eight words a step (a byte
 * shuffle; the same bytes), which keeps the main thread's share of
 * writing an image to the write() calls. */
static void swap_words_c(unsigned char *q, const void *v, size_t n)
{
	const unsigned char *p = v;

	for (size_t i = 0; i < n; i++, q += 4, p += 4) {
		uint32_t u;

		memcpy(&u, p, 4);
		u = swap32(u);
		memcpy(q, &u, 4);
	}
}

#if defined(SIMD_X86) && !(defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__)
__attribute__((target("avx2"))) static void swap_words_avx2(unsigned char *q, const void *v,
							     size_t n)
{
	const unsigned char *p = v;
	const __m256i rev = _mm256_setr_epi8(3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12,
					     3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12);
	size_t i = 0;

	for (; i + 8 <= n; i += 8)
		_mm256_storeu_si256((__m256i *)(q + 4 * i),
				    _mm256_shuffle_epi8(_mm256_loadu_si256((const __m256i *)(p + 4 * i)),
							rev));
	swap_words_c(q + 4 * i, p + 4 * i, n - i);
}
#endif

static void swap_words(unsigned char *q, const void *v, size_t n)
{
#if defined(SIMD_X86) && !(defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__)
	if (simd_flags() & SIMD_AVX2) {
		swap_words_avx2(q, v, n);
		return;
	}
#endif
	swap_words_c(q, v, n);
}

/* Floats as big-endian IEEE-754, converted straight into the buffer. */
static int wfloats(struct fitsout *f, const float *v, size_t n, struct err *e)
{
	while (n > 0) {
		size_t room = (WBUF_SIZE - f->len) / 4, k = n < room ? n : room;

		swap_words(f->buf + f->len, v, k);
		f->len += k * 4;
		v += k;
		n -= k;
		if (WBUF_SIZE - f->len < 4 && wflush(f, e))
			return -1;
	}
	return 0;
}

/* One header: our structural cards, the caller's, END, blank padding. */
static int write_header(struct fitsout *f, const char *structural, int nstruct,
			const char *cards, int ncards, struct err *e)
{
	char end[CARD + 1];
	long total = nstruct + ncards + 1;

	memset(end, ' ', CARD);
	memcpy(end, "END", 3);
	if (wput(f, structural, (size_t)nstruct * CARD, e) ||
	    wput(f, cards, (size_t)ncards * CARD, e) ||
	    wput(f, end, CARD, e))
		return -1;
	while (total % CARDS_PER_BLOCK) {
		memset(end, ' ', CARD);
		if (wput(f, end, CARD, e))
			return -1;
		total++;
	}
	return 0;
}

/* ---- cfitsio writer (compressed output) ---- */

/* A cfitsio failure as a message naming our file.  A failed write keeps
 * errno from the C library, which says more (ENOSPC) than cfitsio does. */
static int fz_fail(struct fitsout *f, int status, int saved_errno,
		   const char *what, struct err *e)
{
	f->failed = 1;
	if (saved_errno && (status == WRITE_ERROR || status == FILE_NOT_CREATED ||
			    status == FILE_NOT_CLOSED)) {
		fits_clear_errmsg();
		errno = saved_errno;
		if (status == WRITE_ERROR)
			what = "write error";
		return err_sys(e, "%s: %s", f->name, what);
	}
	return err_fits(e, status, "%s: %s", f->name, what);
}

static int fz_cards(struct fitsout *f, const char *cards, int ncards,
		    struct err *e)
{
	int status = 0;

	for (int i = 0; i < ncards && !status; i++) {
		char c[CARD + 1];
		memcpy(c, cards + (size_t)i * CARD, CARD);
		c[CARD] = 0;
		fits_write_record(f->fz, c, &status);
	}
	return status ? fz_fail(f, status, errno, "writing header", e) : 0;
}

/* ---- open, commit, abort ---- */

static void fitsout_free(struct fitsout *f)
{
	if (!f)
		return;
	free(f->path);
	free(f->tmp);
	free(f->buf);
	free(f->scratch);
	free(f->grp);
	free(f->gbuf);
	free(f);
}

/* The temporary file beside the output (tempfile.h), its name in f->tmp. */
static int make_temp(struct fitsout *f, struct err *e)
{
	size_t n = TEMPFILE_SIZE(f->path);

	if (!(f->tmp = malloc(n)))
		return err_sys(e, "%s", f->path);
	return tempfile_beside(f->path, f->tmp, n, e);
}

static int parse_compress(const char *s, int *ctype, struct err *e)
{
	if (!s || !strcmp(s, "none"))
		*ctype = 0;
	else if (!strcmp(s, "rice"))
		*ctype = RICE_1;
	else if (!strcmp(s, "gzip"))
		*ctype = GZIP_2;
	else
		return err_set(e, EXIT_INPUT,
			       "unknown compression '%s' (use rice, gzip or none)",
			       s);
	return 0;
}

struct fitsout *fitsout_open(const char *path, const char *compress,
			     struct err *e)
{
	struct fitsout *f;
	struct stat st;
	int ctype = 0;

	if (!path || !*path) {
		err_set(e, EXIT_INPUT, "no output file name");
		return NULL;
	}
	if (parse_compress(compress, &ctype, e))
		return NULL;
	f = calloc(1, sizeof(*f));
	if (!f || !(f->path = strdup(path))) {
		err_sys(e, "%s", path);
		free(f);
		return NULL;
	}
	f->fd = -1;
	f->ctype = ctype;
	f->name = f->path;

	if (!strcmp(path, "-")) {
		f->name = "<stdout>";
		if (ctype) {
			err_set(e, EXIT_INPUT, "<stdout>: tile compression needs "
				"a regular file (it seeks back); write to a file "
				"or use --compress none");
			goto fail;
		}
		if (isatty(STDOUT_FILENO)) {
			err_set(e, EXIT_INPUT, "<stdout>: refusing to write FITS "
				"to a terminal; redirect it or use -o FILE");
			goto fail;
		}
		f->fd = STDOUT_FILENO;
	} else if (stat(path, &st) == 0 && !S_ISREG(st.st_mode)) {
		/* A directory is a mistake; a device, FIFO or socket
		 * (/dev/null, /dev/stdout, a named pipe) is streamed to in
		 * place: renaming a temporary file over it would replace the
		 * device node itself. */
		if (S_ISDIR(st.st_mode)) {
			err_set(e, EXIT_INPUT, "%s: is a directory", path);
			goto fail;
		}
		if (ctype) {
			err_set(e, EXIT_INPUT, "%s: not a regular file; tile "
				"compression needs one", path);
			goto fail;
		}
		f->fd = open(path, O_WRONLY | O_CLOEXEC | O_NOCTTY);
		if (f->fd < 0) {
			err_sys(e, "%s", path);
			goto fail;
		}
		f->close_fd = 1;
	} else {
		int fd = make_temp(f, e);
		if (fd < 0)
			goto fail;
		if (ctype) {
			/* The O_EXCL file reserved the name and proved the
			 * directory writable; cfitsio wants to create the file
			 * itself. */
			int status = 0;
			close(fd);
			unlink(f->tmp);
			fits_clear_errmsg();
			errno = 0;
			if (fits_create_diskfile(&f->fz, f->tmp, &status)) {
				f->fz = NULL;
				fz_fail(f, status, errno,
					"creating temporary file", e);
				goto fail;
			}
		} else {
			f->fd = fd;
			f->close_fd = 1;
		}
	}
	if (f->fd >= 0 && !(f->buf = malloc(WBUF_SIZE))) {
		err_sys(e, "%s", f->name);
		goto fail;
	}
	return f;
fail:
	fitsout_abort(f);
	return NULL;
}

/* The structural cards of the primary HDU: no data, extensions follow. */
static int primary_struct(char *s)
{
	fits_card_bool(s + 0 * CARD, "SIMPLE", 1, "conforms to FITS standard");
	fits_card_int(s + 1 * CARD, "BITPIX", 8, "no data in the primary HDU");
	fits_card_int(s + 2 * CARD, "NAXIS", 0, "no data in the primary HDU");
	fits_card_bool(s + 3 * CARD, "EXTEND", 1, "image extensions follow");
	return 4;
}

int fitsout_primary(struct fitsout *f, const char *cards, int ncards,
		    struct err *e)
{
	char s[4 * CARD + 1];
	int status = 0;

	if (f->failed)
		return err_set(e, EXIT_SYSTEM, "%s: earlier write failed", f->name);
	if (f->state != ST_EMPTY)
		return err_set(e, EXIT_SYSTEM, "%s: primary HDU written twice",
			       f->name);
	if (check_cards(f, cards, ncards, e))
		return -1;
	f->nhdu = 1;
	f->state = ST_READY;
	if (!f->fz)
		return write_header(f, s, primary_struct(s), cards, ncards, e);
	fits_clear_errmsg();
	errno = 0;
	if (fits_create_img(f->fz, BYTE_IMG, 0, NULL, &status))
		return fz_fail(f, status, errno, "writing primary HDU", e);
	return fz_cards(f, cards, ncards, e);
}

int fitsout_image_begin(struct fitsout *f, int nx, int ny, const char *cards,
			int ncards, struct err *e)
{
	char s[7 * CARD + 1];
	int status = 0, n = 0;

	if (f->failed)
		return err_set(e, EXIT_SYSTEM, "%s: earlier write failed", f->name);
	if (f->state == ST_IMAGE)
		return err_set(e, EXIT_SYSTEM, "%s: HDU %d ('%s') not ended",
			       f->name, f->nhdu, f->hduname);
	if (nx <= 0 || ny <= 0)
		return err_set(e, EXIT_SYSTEM, "%s: HDU %d: bad image size "
			       "%d x %d", f->name, f->nhdu + 1, nx, ny);
	/* A file must start with a primary HDU; an empty one will do. */
	if (f->state == ST_EMPTY && fitsout_primary(f, NULL, 0, e))
		return -1;
	if (check_cards(f, cards, ncards, e))
		return -1;

	/* Remember EXTNAME for messages about this HDU. */
	snprintf(f->hduname, sizeof(f->hduname), "HDU %d", f->nhdu + 1);
	for (int i = 0; i < ncards; i++) {
		char c[CARD + 1], value[CARD + 1], comm[CARD + 1];
		memcpy(c, cards + (size_t)i * CARD, CARD);
		c[CARD] = 0;
		if (!strncmp(c, "EXTNAME = ", 10) &&
		    !ffpsvc(c, value, comm, &status)) {
			char *v = value + (value[0] == '\'');
			size_t l = strlen(v);
			if (l && v[l - 1] == '\'')
				v[--l] = 0;
			while (l && v[l - 1] == ' ')
				v[--l] = 0;
			snprintf(f->hduname, sizeof(f->hduname), "%s", v);
		}
		status = 0;
	}

	f->nhdu++;
	f->nx = nx;
	f->ny = ny;
	f->rows = 0;
	f->state = ST_IMAGE;
	if (!f->fz) {
		fits_card_str(s + n++ * CARD, "XTENSION", "IMAGE", "image extension");
		fits_card_int(s + n++ * CARD, "BITPIX", -32, "IEEE single precision");
		fits_card_int(s + n++ * CARD, "NAXIS", 2, "number of axes");
		fits_card_int(s + n++ * CARD, "NAXIS1", nx, "columns (x)");
		fits_card_int(s + n++ * CARD, "NAXIS2", ny, "rows (y)");
		fits_card_int(s + n++ * CARD, "PCOUNT", 0, "no parameters");
		fits_card_int(s + n++ * CARD, "GCOUNT", 1, "one group");
		return write_header(f, s, n, cards, ncards, e);
	}

	{
		long naxes[2] = { nx, ny }, tile[2] = { nx, 1 };
		fits_clear_errmsg();
		errno = 0;
		fits_set_compression_type(f->fz, f->ctype, &status);
		/* One row per tile: rows arrive in order and any number per
		 * call, so every write covers whole tiles. */
		fits_set_tile_dim(f->fz, 2, tile, &status);
		if (f->ctype == GZIP_2) {
			/* Lossless: no quantization of the floats. */
			fits_set_quantize_level(f->fz, 0, &status);
		} else {
			/* Rice needs integers, so floats are quantized to
			 * 1/4 of the noise measured in each tile (cfitsio's
			 * default level).  SUBTRACTIVE_DITHER_2 keeps exact
			 * zeros exact; a fixed dither seed keeps the output
			 * the same from run to run (the default seeds from
			 * the clock). */
			fits_set_quantize_level(f->fz, 4, &status);
			fits_set_quantize_method(f->fz, SUBTRACTIVE_DITHER_2,
						 &status);
			fits_set_dither_seed(f->fz, 1, &status);
		}
		fits_create_img(f->fz, FLOAT_IMG, 2, naxes, &status);
		if (status)
			return fz_fail(f, status, errno, "creating image HDU", e);
		return fz_cards(f, cards, ncards, e);
	}
}

int fitsout_image_rows(struct fitsout *f, const float *rows, int nrows,
		       struct err *e)
{
	size_t n;

	if (f->failed)
		return err_set(e, EXIT_SYSTEM, "%s: earlier write failed", f->name);
	if (f->state != ST_IMAGE)
		return err_set(e, EXIT_SYSTEM, "%s: image rows outside an image",
			       f->name);
	if (nrows < 0 || nrows > f->ny - f->rows)
		return err_set(e, EXIT_SYSTEM, "%s: '%s': %d rows would make "
			       "%ld, more than the %ld in the image", f->name,
			       f->hduname, nrows, f->rows + nrows, f->ny);
	if (nrows == 0)
		return 0;
	n = (size_t)nrows * (size_t)f->nx;
	if (!f->fz) {
		if (wfloats(f, rows, n, e))
			return -1;
		f->rows += nrows;
		return 0;
	}

	/* cfitsio takes a non-const buffer; hand it a copy of a bounded
	 * number of rows at a time rather than cast const away. */
	{
		long per = (long)((WBUF_SIZE / 4) / (size_t)f->nx);
		if (per < 1)
			per = 1;
		if (!f->scratch) {
			f->scratch_n = (size_t)per * (size_t)f->nx;
			f->scratch = malloc(f->scratch_n * sizeof(float));
			if (!f->scratch)
				return err_sys(e, "%s", f->name);
		}
		per = (long)(f->scratch_n / (size_t)f->nx);
		while (nrows > 0) {
			long k = nrows < per ? nrows : per;
			long fpixel[2] = { 1, f->rows + 1 };
			int status = 0;
			memcpy(f->scratch, rows, (size_t)k * f->nx * sizeof(float));
			fits_clear_errmsg();
			errno = 0;
			if (fits_write_pix(f->fz, TFLOAT, fpixel, k * f->nx,
					   f->scratch, &status))
				return fz_fail(f, status, errno,
					       "writing image data", e);
			rows += (size_t)k * f->nx;
			nrows -= (int)k;
			f->rows += k;
		}
	}
	return 0;
}

int fitsout_image_end(struct fitsout *f, struct err *e)
{
	unsigned long long bytes;

	if (f->failed)
		return err_set(e, EXIT_SYSTEM, "%s: earlier write failed", f->name);
	if (f->state != ST_IMAGE)
		return err_set(e, EXIT_SYSTEM, "%s: no image to end", f->name);
	if (f->rows != f->ny)
		return err_set(e, EXIT_SYSTEM, "%s: '%s': %ld of %ld rows written",
			       f->name, f->hduname, f->rows, f->ny);
	f->state = ST_READY;
	if (f->fz)
		return 0;
	bytes = (unsigned long long)f->nx * (unsigned long long)f->ny * 4;
	return wzeros(f, (size_t)((BLOCK - bytes % BLOCK) % BLOCK), e);
}

/* ---- groups: several HDUs laid out first, their data written by offset ---- */

static int bytes_per(int bitpix)
{
	return bitpix == 16 ? 2 : 4;
}

int fitsout_group_begin(struct fitsout *f, int nhdu, const struct fitsout_hdu *h,
			struct err *e)
{
	long long off;

	if (f->failed)
		return err_set(e, EXIT_SYSTEM, "%s: earlier write failed", f->name);
	if (f->state == ST_IMAGE || f->state == ST_GROUP)
		return err_set(e, EXIT_SYSTEM, "%s: HDU %d ('%s') not ended",
			       f->name, f->nhdu, f->hduname);
	if (f->fz)
		return err_set(e, EXIT_INPUT, "%s: the planes of --level 1 and 2 are "
			       "written side by side, which tile compression cannot do: "
			       "leave out --compress", f->name);
	/* asked before anything is written, so that a pipe gets no header */
	if (lseek(f->fd, 0, SEEK_CUR) < 0)
		return err_set(e, EXIT_INPUT, "%s: the planes of --level 1 and 2 are "
			       "written side by side and need a file that can seek "
			       "(not a pipe or stdout)", f->name);
	if (f->state == ST_EMPTY && fitsout_primary(f, NULL, 0, e))
		return -1;
	if (wflush(f, e))
		return -1;
	off = (long long)lseek(f->fd, 0, SEEK_CUR);
	if (off < 0)
		return err_sys(e, "%s", f->name);
	free(f->grp);
	if (!(f->grp = calloc((size_t)nhdu, sizeof(*f->grp))))
		return err_sys(e, "%s", f->name);
	f->ngrp = nhdu;
	for (int k = 0; k < nhdu; k++) {
		char s[10 * CARD + 1];
		int n = 0, nax = h[k].nz > 1 ? 3 : 2;
		unsigned long long bytes;
		struct group_hdu *g = &f->grp[k];

		if (check_cards(f, h[k].cards, h[k].ncards, e))
			return -1;
		if (h[k].bitpix != 16 && h[k].bitpix != 32 && h[k].bitpix != -32)
			return err_set(e, EXIT_SYSTEM, "%s: BITPIX %d", f->name, h[k].bitpix);
		g->nx = h[k].nx;
		g->ny = h[k].ny;
		g->nz = h[k].nz > 1 ? h[k].nz : 1;
		g->bitpix = h[k].bitpix;
		snprintf(g->name, sizeof(g->name), "%s", h[k].name ? h[k].name : "");
		fits_card_str(s + n++ * CARD, "XTENSION", "IMAGE", "image extension");
		fits_card_int(s + n++ * CARD, "BITPIX", g->bitpix,
			      g->bitpix == -32 ? "IEEE single precision" :
			      g->bitpix == 16 ? "16-bit integers (unsigned with BZERO)" :
			      "32-bit integers (unsigned with BZERO)");
		fits_card_int(s + n++ * CARD, "NAXIS", nax, "number of axes");
		fits_card_int(s + n++ * CARD, "NAXIS1", g->nx, "columns (x)");
		fits_card_int(s + n++ * CARD, "NAXIS2", g->ny, "rows (y)");
		if (nax == 3)
			fits_card_int(s + n++ * CARD, "NAXIS3", g->nz, "planes");
		fits_card_int(s + n++ * CARD, "PCOUNT", 0, "no parameters");
		fits_card_int(s + n++ * CARD, "GCOUNT", 1, "one group");
		if (g->bitpix == 16)
			fits_card_int(s + n++ * CARD, "BZERO", 32768, "unsigned 16-bit");
		else if (g->bitpix == 32)
			fits_card_dbl(s + n++ * CARD, "BZERO", 2147483648.0, "unsigned 32-bit");
		if (g->bitpix > 0)
			fits_card_int(s + n++ * CARD, "BSCALE", 1, NULL);
		if (lseek(f->fd, (off_t)off, SEEK_SET) < 0 ||
		    write_header(f, s, n, h[k].cards, h[k].ncards, e) || wflush(f, e))
			return f->failed ? -1 : err_sys(e, "%s: seek", f->name);
		off += ((long long)(n + h[k].ncards + 1 + CARDS_PER_BLOCK - 1) /
			CARDS_PER_BLOCK) * BLOCK;
		g->data_off = off;
		bytes = (unsigned long long)g->nx * g->ny * g->nz * bytes_per(g->bitpix);
		off += (long long)((bytes + BLOCK - 1) / BLOCK * BLOCK);
		f->nhdu++;
	}
	f->grp_end = off;
	/* the data and its padding read as zeros until written */
	if (ftruncate(f->fd, (off_t)off) && errno != EINVAL)
		return err_sys(e, "%s: write error", f->name);
	snprintf(f->hduname, sizeof(f->hduname), "%s", f->grp[0].name);
	f->state = ST_GROUP;
	return 0;
}

int fitsout_group_rows(struct fitsout *f, int k, int plane, long y0, int nrows,
		       const void *data, struct err *e)
{
	struct group_hdu *g;
	size_t n, bp;
	long long off;

	if (f->failed)
		return err_set(e, EXIT_SYSTEM, "%s: earlier write failed", f->name);
	if (f->state != ST_GROUP || k < 0 || k >= f->ngrp)
		return err_set(e, EXIT_SYSTEM, "%s: group rows outside a group", f->name);
	g = &f->grp[k];
	if (plane < 0 || plane >= g->nz || y0 < 0 || nrows < 0 || y0 + nrows > g->ny)
		return err_set(e, EXIT_SYSTEM, "%s: '%s': rows %ld-%ld of plane %d "
			       "out of range", f->name, g->name, y0, y0 + nrows, plane);
	bp = (size_t)bytes_per(g->bitpix);
	n = (size_t)nrows * (size_t)g->nx;
	if (f->gbuf_n < n * bp) {
		free(f->gbuf);
		if (!(f->gbuf = malloc(n * bp))) {
			f->gbuf_n = 0;
			return err_sys(e, "%s", f->name);
		}
		f->gbuf_n = n * bp;
	}
	if (bp == 2) {
		const uint16_t *v = data;

		/* unsigned stored as signed with BZERO 32768: flip the top bit */
		for (size_t i = 0; i < n; i++) {
			uint16_t u = (uint16_t)(v[i] ^ 0x8000u);

			f->gbuf[2 * i] = (unsigned char)(u >> 8);
			f->gbuf[2 * i + 1] = (unsigned char)u;
		}
	} else {
		const uint32_t *v = data;
		uint32_t flip = g->bitpix == 32 ? 0x80000000u : 0;

		/* big-endian words by the byte swap, in a loop simple enough
		 * to run several words at a time */
		for (size_t i = 0; i < n; i++) {
			uint32_t u = swap32(v[i] ^ flip);

			memcpy(f->gbuf + 4 * i, &u, 4);
		}
	}
	off = g->data_off + (((long long)plane * g->ny + y0) * g->nx) * (long long)bp;
	if (write_at(f, f->gbuf, n * bp, off, e))
		return -1;
	if (n * bp >= WBACK_AT && f->tmp)
		tempfile_writeback(f->fd, off, off + (long long)(n * bp));
	g->rows += nrows;
	return 0;
}

int fitsout_group_end(struct fitsout *f, struct err *e)
{
	if (f->failed)
		return err_set(e, EXIT_SYSTEM, "%s: earlier write failed", f->name);
	if (f->state != ST_GROUP)
		return err_set(e, EXIT_SYSTEM, "%s: no group to end", f->name);
	for (int k = 0; k < f->ngrp; k++)
		if (f->grp[k].rows != (long long)f->grp[k].ny * f->grp[k].nz)
			return err_set(e, EXIT_SYSTEM, "%s: '%s': %lld of %lld rows written",
				       f->name, f->grp[k].name, f->grp[k].rows,
				       (long long)f->grp[k].ny * f->grp[k].nz);
	if (lseek(f->fd, (off_t)f->grp_end, SEEK_SET) < 0)
		return err_sys(e, "%s: seek", f->name);
	f->state = ST_READY;
	return 0;
}

/* Make a rename durable: fsync the directory that holds the new entry.
 * Some file systems cannot fsync a directory (EINVAL); that is no error. */
static int sync_dir(struct fitsout *f, struct err *e)
{
	const char *slash = strrchr(f->path, '/');
	char *dir;
	int fd, r = 0;

	if (!slash)
		dir = strdup(".");
	else if (slash == f->path)
		dir = strdup("/");
	else
		dir = strndup(f->path, (size_t)(slash - f->path));
	if (!dir)
		return err_sys(e, "%s", f->path);
	fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
	if (fd < 0) {
		r = err_sys(e, "%s: opening directory '%s' to sync", f->path, dir);
	} else {
		if (fsync(fd) && errno != EINVAL && errno != ENOTSUP)
			r = err_sys(e, "%s: syncing directory '%s'", f->path, dir);
		close(fd);
	}
	free(dir);
	return r;
}

int fitsout_commit(struct fitsout *f, struct err *e)
{
	int status = 0;

	if (!f)
		return err_set(e, EXIT_SYSTEM, "fitsout_commit: no file");
	if (f->failed) {
		err_set(e, EXIT_SYSTEM, "%s: earlier write failed", f->name);
		goto fail;
	}
	if (f->state == ST_IMAGE || f->state == ST_GROUP) {
		err_set(e, EXIT_SYSTEM, "%s: '%s' not finished: %ld of %ld rows",
			f->name, f->hduname, f->rows, f->ny);
		goto fail;
	}
	/* An empty run still gives a valid file. */
	if (f->state == ST_EMPTY && fitsout_primary(f, NULL, 0, e))
		goto fail;

	if (f->fz) {
		fits_clear_errmsg();
		errno = 0;
		fits_close_file(f->fz, &status);
		f->fz = NULL;
		if (status) {
			fz_fail(f, status, errno, "closing", e);
			goto fail;
		}
		/* cfitsio closed its stream; reopen only to fsync. */
		f->fd = open(f->tmp, O_WRONLY | O_CLOEXEC);
		if (f->fd < 0) {
			err_sys(e, "%s: reopening '%s' to sync", f->name, f->tmp);
			goto fail;
		}
		f->close_fd = 1;
	} else if (wflush(f, e)) {
		goto fail;
	}

	if (f->tmp) {
		if (fsync(f->fd)) {
			err_sys(e, "%s: write error", f->name);
			goto fail;
		}
		f->close_fd = 0;
		if (close(f->fd)) {
			f->fd = -1;
			err_sys(e, "%s: write error", f->name);
			goto fail;
		}
		f->fd = -1;
		if (tempfile_commit(f->tmp, f->path, e) < 0)
			goto fail;
		free(f->tmp);
		f->tmp = NULL;
		if (sync_dir(f, e)) {
			fitsout_free(f);
			return -1;
		}
	} else if (f->close_fd) {
		f->close_fd = 0;
		if (close(f->fd)) {
			f->fd = -1;
			err_sys(e, "%s: write error", f->name);
			goto fail;
		}
		f->fd = -1;
	}
	fitsout_free(f);
	return 0;
fail:
	fitsout_abort(f);
	return -1;
}

void fitsout_abort(struct fitsout *f)
{
	if (!f)
		return;
	if (f->fz) {
		int status = 0;
		/* Errors here are moot: the file is being thrown away. */
		fits_close_file(f->fz, &status);
		fits_clear_errmsg();
		f->fz = NULL;
	}
	if (f->close_fd && f->fd >= 0)
		close(f->fd);
	if (f->tmp)
		tempfile_discard(f->tmp);
	fitsout_free(f);
}
