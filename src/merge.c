/*
 * merge.c - `wfiscene merge`: put one exposure back together from the files
 * of runs split by SCA.
 *
 * Every random number is keyed by (seed, filter, SCA, stage, pixel), so a
 * run of --sca 1-9 and one of --sca 10-18 write exactly the image HDUs that
 * one --sca 1-18 run writes, and their primary HDUs differ at most in DATE.
 * Merging therefore never decodes anything: it copies the first input's
 * primary HDU and then every image HDU, header and data blocks as they are,
 * in SCA order.  The result is the single run's file byte for byte, and
 * tile-compressed HDUs (binary tables with ZIMAGE = T) go through without
 * being recompressed.
 *
 * What the copy relies on (FITS Standard 4.0, sections 3.3, 4.4 and 7.1): a
 * file is a sequence of HDUs made of 2880-byte blocks; a header is 80-byte
 * ASCII cards up to END, padded to a whole block; the data that follow are
 * |BITPIX|/8 * GCOUNT * (PCOUNT + NAXIS1 * ... * NAXISn) bytes (GCOUNT = 1,
 * PCOUNT = 0 in a primary HDU), padded to a whole block.  So an HDU's extent
 * follows from its header alone, and inputs are scanned with preads from
 * block to block without reading their data until they are copied.
 *
 * The output is written as the scene writer writes it (see fitsout.h):
 * under ".NAME.XXXXXX" next to NAME, flushed, fsync'ed and renamed, so NAME
 * only ever holds a complete file; "-" streams to stdout.  The raw copy has
 * its own small writer because fitsout.h builds headers from cards and
 * converts floats, where merge must pass blocks through untouched.  The
 * temporary is in tempfile.h's registry: SIGINT, SIGTERM or SIGHUP remove it
 * and exit 4 under the one signal policy main() set.
 */
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "commands.h"
#include "err.h"
#include "fitsout.h"
#include "names.h"
#include "options.h"
#include "tempfile.h"
#include "instrument.h"

#define MERGE_CARD 80
#define MERGE_BLOCK 2880
#define MERGE_CARDS_PER_BLOCK (MERGE_BLOCK / MERGE_CARD)
/* Copy buffer: few enough syscalls per 64 MB image. */
#define MERGE_BUF_SIZE (1u << 20)
/* A header longer than this is not one of ours (wfiscene's have about 40
 * cards); the limit keeps a stray binary file from being read to its end
 * in search of an END card. */
#define MERGE_MAX_HEADER_BLOCKS 1000
/* Larger data than any file system holds is a corrupt header. */
#define MERGE_MAX_DATA (1ull << 60)

/* What merge's options fill in. */
struct merge_cmd {
	const char *output;
	int verbose;            /* -1 quiet, 0 normal, 1 verbose */
};

static const struct opt merge_options[] = {
	{ OPT("output", 'o', "FILE", NULL, "output file ('-' for stdout)", opt_string,
	  offsetof(struct merge_cmd, output)) },
	{ OPT("quiet", 'q', NULL, NULL, "no messages but errors", opt_store_lo,
	  offsetof(struct merge_cmd, verbose)), .lo = -1 },
	{ OPT("verbose", 'v', NULL, NULL, "say where each SCA comes from", opt_count,
	  offsetof(struct merge_cmd, verbose)) },
	{ OPT("help", 'h', NULL, NULL, "this text", opt_show_help, 0) },
	OPT_END
};

static const struct opt_cmd merge_cmd_line = {
	.prog = "wfiscene merge",
	.usage =
"usage: wfiscene merge [-q] [-v] -o OUT.fits IN.fits ...\n"
"\n"
"Assemble one exposure from the files of runs split by SCA (--sca 1-9 and\n"
"--sca 10-18, or -o 'part%d.fits') and by rows (--rows 1-2044 and\n"
"--rows 2045-4088): the first input's primary HDU, then every SCA image of\n"
"all inputs in SCA order, each header and data copied byte for byte (the\n"
"parts of an SCA joined in row order).  The inputs' primary headers must\n"
"agree on every keyword but DATE, no SCA may appear twice, and the row\n"
"parts of an SCA must cover its rows once each.\n"
"\n",
	.epilog =
"\n"
"Exit status: 0 ok, 1 usage or bad input, 2 I/O error, 4 interrupted.\n",
	.opts = merge_options,
};

/* One image HDU of an input. */
struct merge_hdu {
	int input;              /* index of its file in struct merge.in */
	int number;             /* HDU number in that file (1 = primary) */
	off_t offset;           /* where its header starts */
	off_t length;           /* header and data blocks */
	int sca;                /* from EXTNAME = 'WFInn' */
	int kind;               /* 0 'WFInn', 1 .. 4 the level-2 planes
	                           'WFInn_ERR', _DQ, _VAR_POISSON, _VAR_RNOISE */
	int compressed;         /* a binary table with ZIMAGE = T */
	char cmptype[72];       /* ZCMPTYPE of a compressed HDU */
	/* A part of --rows A-B (ROWS = 'A-B'): rows A to B of the SCA; 0 0
	 * for a whole image.  Its cards are kept to rebuild the header. */
	int row_first, row_last;
	off_t header_length;
	char *cards;
	int ncards;
};

struct merge_input {
	const char *path;
	int fd;
	off_t size;
	char *primary;          /* the primary header's cards, END excluded */
	int nprimary;
	off_t primary_length;   /* primary header and data blocks */
};

/* Where the output goes.  tmp is NULL when streaming (stdout or an
 * existing device or FIFO, which a rename would replace). */
struct merge_out {
	const char *path;
	const char *name;       /* for messages: path or "<stdout>" */
	char *tmp;
	int fd;
	int close_fd;
};

struct merge {
	struct merge_input *in;
	int nin;
	struct merge_hdu *hdu;
	int nhdu, cap;
	unsigned char *buf;     /* MERGE_BUF_SIZE bytes */
	int verbose;            /* -1 quiet, 0 normal, 1 verbose */
	struct err *e;
};

/* ---- header cards ---- */

/* The card of keyword key among n cards, or NULL.  Only value cards
 * ("KEY     = ...") count; COMMENT and HISTORY never match. */
static const char *merge_find(const char *cards, int n, const char *key)
{
	size_t klen = strlen(key);

	for (int i = 0; i < n; i++) {
		const char *c = cards + (size_t)i * MERGE_CARD;

		if (!memcmp(c, key, klen) && c[8] == '=' && c[9] == ' ') {
			size_t k = klen;
			while (k < 8 && c[k] == ' ')
				k++;
			if (k == 8)
				return c;
		}
	}
	return NULL;
}

/* The value of a value card as text: a string unquoted ('' is a quote,
 * trailing blanks do not count, as FITS says), anything else trimmed and
 * cut at its comment.  Returns 1 for a string, 0 otherwise. */
static int merge_value(const char *card, char *out, size_t n)
{
	int i = 10, quoted = 0;
	size_t len = 0;

	while (i < MERGE_CARD && card[i] == ' ')
		i++;
	if (i < MERGE_CARD && card[i] == '\'') {
		quoted = 1;
		for (i++; i < MERGE_CARD; i++) {
			if (card[i] == '\'') {
				if (i + 1 < MERGE_CARD && card[i + 1] == '\'')
					i++;
				else
					break;
			}
			if (len + 1 < n)
				out[len++] = card[i];
		}
	} else {
		for (; i < MERGE_CARD && card[i] != '/'; i++)
			if (len + 1 < n)
				out[len++] = card[i];
	}
	while (len > 0 && out[len - 1] == ' ')
		len--;
	out[len] = 0;
	return quoted;
}

/* Two values agree when their text does, or when both are numbers that
 * read as the same double ("1.0" and "1.00", "1E3" and "1000."). */
static int merge_same_value(const char *a, const char *b)
{
	char *ea, *eb;
	double x, y;

	if (!strcmp(a, b))
		return 1;
	if (!*a || !*b)
		return 0;
	x = strtod(a, &ea);
	y = strtod(b, &eb);
	return !*ea && !*eb && x == y;
}

/* An integer keyword: 0, or -1 with a message when missing or not one. */
static int merge_int(struct merge *m, const char *what, const char *cards,
		     int n, const char *key, long long *v)
{
	const char *c = merge_find(cards, n, key);
	char text[MERGE_CARD + 1], *end;

	if (!c)
		return err_set(m->e, EXIT_INPUT, "%s: no %s keyword", what, key);
	if (merge_value(c, text, sizeof(text)) == 0) {
		errno = 0;
		*v = strtoll(text, &end, 10);
		if (end != text && !*end && errno != ERANGE)
			return 0;
	}
	return err_set(m->e, EXIT_INPUT, "%s: %s is not an integer: '%s'", what,
		       key, text);
}

/*
 * Read the header that starts at offset at of input i into a new array of
 * cards (END excluded).  primary says which first keyword it must have:
 * SIMPLE for a primary header, XTENSION for an extension.  *len gets the
 * header's length in bytes, whole blocks.
 */
static int merge_read_header(struct merge *m, int i, int number, off_t at,
			     int primary, char **cards, int *ncards, off_t *len)
{
	const struct merge_input *in = &m->in[i];
	char *h = NULL;
	int nblocks = 0;

	*cards = NULL;
	for (;;) {
		char *block;
		ssize_t r;
		char *grown;

		if (nblocks == MERGE_MAX_HEADER_BLOCKS) {
			err_set(m->e, EXIT_INPUT, "%s: HDU %d: no END card in the "
				"first %d header blocks", in->path, number,
				MERGE_MAX_HEADER_BLOCKS);
			goto fail;
		}
		if (!(grown = realloc(h, (size_t)(nblocks + 1) * MERGE_BLOCK))) {
			err_sys(m->e, "%s", in->path);
			goto fail;
		}
		h = grown;
		block = h + (size_t)nblocks * MERGE_BLOCK;
		do
			r = pread(in->fd, block, MERGE_BLOCK,
				  at + (off_t)nblocks * MERGE_BLOCK);
		while (r < 0 && errno == EINTR);
		if (r < 0) {
			err_sys(m->e, "%s: read error", in->path);
			goto fail;
		}
		if (r < MERGE_BLOCK) {
			if (nblocks == 0 && primary)
				err_set(m->e, EXIT_INPUT, "%s: not a FITS file "
					"(shorter than one 2880-byte block)",
					in->path);
			else if (nblocks == 0)
				err_set(m->e, EXIT_INPUT, "%s: %lld bytes after "
					"HDU %d are not a FITS extension",
					in->path, (long long)(in->size - at),
					number - 1);
			else
				err_set(m->e, EXIT_INPUT, "%s: HDU %d: truncated "
					"header (the file ends before its END "
					"card)", in->path, number);
			goto fail;
		}
		if (nblocks == 0) {
			/* The first card says what this is, before anything
			 * else of it is trusted. */
			if (primary && (memcmp(block, "SIMPLE  = ", 10) ||
					block[29] != 'T')) {
				err_set(m->e, EXIT_INPUT, "%s: not a FITS file "
					"(it does not start with SIMPLE = T)",
					in->path);
				goto fail;
			}
			if (!primary && memcmp(block, "XTENSION= ", 10)) {
				err_set(m->e, EXIT_INPUT, "%s: %lld bytes after "
					"HDU %d are not a FITS extension",
					in->path, (long long)(in->size - at),
					number - 1);
				goto fail;
			}
		}
		for (int k = 0; k < MERGE_BLOCK; k++)
			if (block[k] < 32 || block[k] > 126) {
				err_set(m->e, EXIT_INPUT, "%s: HDU %d: byte 0x%02x "
					"in the header is not FITS header text",
					in->path, number, (unsigned char)block[k]);
				goto fail;
			}
		nblocks++;
		for (int k = 0; k < MERGE_CARDS_PER_BLOCK; k++) {
			const char *c = block + k * MERGE_CARD;

			if (!memcmp(c, "END", 3) &&
			    !memcmp(c + 3, "     ", 5)) {
				*ncards = (nblocks - 1) * MERGE_CARDS_PER_BLOCK + k;
				*len = (off_t)nblocks * MERGE_BLOCK;
				*cards = h;
				return 0;
			}
		}
	}
fail:
	free(h);
	return -1;
}

/* Bytes of data after a header, padded to whole blocks. */
static int merge_data_length(struct merge *m, const char *what,
			     const char *cards, int n, int primary, off_t *len)
{
	long long bitpix, naxis, pcount = 0, gcount = 1, v;
	unsigned long long count = 0, bytes;
	char key[32];           /* "NAXISn", n up to 999; room for any long long */

	if (merge_int(m, what, cards, n, "BITPIX", &bitpix) ||
	    merge_int(m, what, cards, n, "NAXIS", &naxis))
		return -1;
	if (bitpix != 8 && bitpix != 16 && bitpix != 32 && bitpix != 64 &&
	    bitpix != -32 && bitpix != -64)
		return err_set(m->e, EXIT_INPUT, "%s: BITPIX = %lld is not a FITS "
			       "BITPIX", what, bitpix);
	if (naxis < 0 || naxis > 999)
		return err_set(m->e, EXIT_INPUT, "%s: NAXIS = %lld is out of "
			       "range", what, naxis);
	if (!primary && (merge_int(m, what, cards, n, "PCOUNT", &pcount) ||
			 merge_int(m, what, cards, n, "GCOUNT", &gcount)))
		return -1;
	if (pcount < 0 || gcount < 0 || (unsigned long long)pcount > MERGE_MAX_DATA ||
	    (unsigned long long)gcount > MERGE_MAX_DATA)
		return err_set(m->e, EXIT_INPUT, "%s: PCOUNT = %lld, GCOUNT = %lld: "
			       "out of range", what, pcount, gcount);
	/* An HDU with NAXIS = 0 has no data, whatever PCOUNT says of a heap
	 * that cannot exist without a table. */
	if (naxis > 0) {
		count = 1;
		for (long long k = 1; k <= naxis; k++) {
			snprintf(key, sizeof(key), "NAXIS%lld", k);
			if (merge_int(m, what, cards, n, key, &v))
				return -1;
			if (v < 0 || (v > 0 && count > MERGE_MAX_DATA / (unsigned long long)v))
				return err_set(m->e, EXIT_INPUT, "%s: %s = %lld: "
					       "out of range", what, key, v);
			count *= (unsigned long long)v;
		}
		count += (unsigned long long)pcount;
		if (count > MERGE_MAX_DATA / 8 / ((unsigned long long)gcount + 1))
			return err_set(m->e, EXIT_INPUT, "%s: data size out of "
				       "range", what);
		count *= (unsigned long long)gcount;
	}
	bytes = count * (unsigned long long)(bitpix < 0 ? -bitpix : bitpix) / 8;
	bytes = (bytes + MERGE_BLOCK - 1) / MERGE_BLOCK * MERGE_BLOCK;
	*len = (off_t)bytes;
	return 0;
}

/* ---- reading the inputs ---- */

/* The primary headers must describe the same exposure: every keyword but
 * DATE (when each file was written) present in both with the same value. */
static int merge_check_primary(struct merge *m, int i)
{
	const struct merge_input *a = &m->in[0], *b = &m->in[i];
	char va[MERGE_CARD + 1], vb[MERGE_CARD + 1], key[9];

	for (int pass = 0; pass < 2; pass++) {
		const struct merge_input *x = pass ? b : a, *y = pass ? a : b;

		for (int k = 0; k < x->nprimary; k++) {
			const char *c = x->primary + (size_t)k * MERGE_CARD, *d;
			int len = 8;

			if (c[8] != '=' || c[9] != ' ')
				continue;
			while (len > 0 && c[len - 1] == ' ')
				len--;
			snprintf(key, sizeof(key), "%.*s", len, c);
			if (!strcmp(key, "DATE"))
				continue;
			d = merge_find(y->primary, y->nprimary, key);
			merge_value(c, va, sizeof(va));
			if (!d)
				return err_set(m->e, EXIT_INPUT, "%s: keyword %s "
					       "(= '%s') is in %s's primary "
					       "header but not in %s's: not the "
					       "same exposure", b->path, key, va,
					       x->path, y->path);
			if (pass)
				continue;
			merge_value(d, vb, sizeof(vb));
			if (!merge_same_value(va, vb))
				return err_set(m->e, EXIT_INPUT, "%s: %s is '%s', "
					       "but '%s' in %s: not the same "
					       "exposure", b->path, key, vb, va,
					       a->path);
		}
	}
	return 0;
}

static int merge_add_hdu(struct merge *m, const struct merge_hdu *h)
{
	if (m->nhdu == m->cap) {
		int cap = m->cap ? 2 * m->cap : 32;
		struct merge_hdu *p = realloc(m->hdu, (size_t)cap * sizeof(*p));

		if (!p)
			return err_sys(m->e, "merge");
		m->hdu = p;
		m->cap = cap;
	}
	m->hdu[m->nhdu++] = *h;
	return 0;
}

/* A part of --rows A-B: ROWS = 'A-B' on a plain float32 image of A-B+1 rows
 * of a whole SCA's width. */
static int merge_rows(struct merge *m, const char *what, struct merge_hdu *h,
		      const char *card, const char *cards, int ncards)
{
	char value[MERGE_CARD + 1];
	long long bitpix, naxis, nx, ny;
	int a, b, used;

	merge_value(card, value, sizeof(value));
	if (sscanf(value, "%d-%d%n", &a, &b, &used) != 2 || used != (int)strlen(value) ||
	    a < 1 || b > WFS_NPIX || a > b)
		return err_set(m->e, EXIT_INPUT, "%s: ROWS = '%s' is not a row range "
			       "'A-B' within 1-%d", what, value, WFS_NPIX);
	if (h->compressed)
		return err_set(m->e, EXIT_INPUT, "%s: rows %s of a tile-compressed "
			       "image cannot be joined", what, value);
	if (merge_int(m, what, cards, ncards, "BITPIX", &bitpix) ||
	    merge_int(m, what, cards, ncards, "NAXIS", &naxis) ||
	    merge_int(m, what, cards, ncards, "NAXIS1", &nx) ||
	    merge_int(m, what, cards, ncards, "NAXIS2", &ny))
		return -1;
	/* float32, or the 32-bit DQ of level 2; a level-1 cube has planes
	 * that cannot be joined by appending rows */
	if ((bitpix != -32 && bitpix != 32) || naxis != 2 || nx != WFS_NPIX ||
	    ny != b - a + 1)
		return err_set(m->e, EXIT_INPUT, "%s: rows %s: a %lld x %lld image of "
			       "BITPIX %lld with NAXIS %lld, not %d x %d float32 (the "
			       "row parts of a --level 1 cube cannot be merged)", what,
			       value, nx, ny, bitpix, naxis, WFS_NPIX, b - a + 1);
	h->row_first = a;
	h->row_last = b;
	return 0;
}

/* One extension of input i at offset at: which SCA it is and how long. */
static int merge_scan_extension(struct merge *m, int i, int number, off_t at,
				off_t *next)
{
	const struct merge_input *in = &m->in[i];
	struct merge_hdu h = { .input = i, .number = number, .offset = at };
	char *cards = NULL, what[PATH_MAX + 32], value[MERGE_CARD + 1];
	char xtension[MERGE_CARD + 1];
	const char *c;
	int ncards, sca, used;
	off_t hlen, dlen;

	if (merge_read_header(m, i, number, at, 0, &cards, &ncards, &hlen))
		return -1;
	snprintf(what, sizeof(what), "%s: HDU %d", in->path, number);
	c = merge_find(cards, ncards, "EXTNAME");
	if (!c) {
		err_set(m->e, EXIT_INPUT, "%s: no EXTNAME: not a wfiscene SCA "
			"image", what);
		goto fail;
	}
	merge_value(c, value, sizeof(value));
	if (sscanf(value, "WFI%2d%n", &sca, &used) != 1 || used != 5 ||
	    sca < 1 || sca > WFS_NSCA) {
		err_set(m->e, EXIT_INPUT, "%s: EXTNAME '%s' is not an SCA image "
			"(WFI01 to WFI%02d)", what, value, WFS_NSCA);
		goto fail;
	}
	{
		static const char *const suffix[] = { "", "_ERR", "_DQ", "_VAR_POISSON",
						      "_VAR_RNOISE" };
		int kind = -1;

		for (int s = 0; s < 5; s++)
			if (!strcmp(value + 5, suffix[s]))
				kind = s;
		if (kind < 0) {
			err_set(m->e, EXIT_INPUT, "%s: EXTNAME '%s' is not an SCA image "
				"(WFI01 to WFI%02d, with _ERR, _DQ, _VAR_POISSON or "
				"_VAR_RNOISE at --level 2)", what, value, WFS_NSCA);
			goto fail;
		}
		h.kind = kind;
	}
	snprintf(what, sizeof(what), "%s: %s", in->path, value);
	h.sca = sca;
	merge_value(cards, xtension, sizeof(xtension));
	if (!strcmp(xtension, "BINTABLE") &&
	    (c = merge_find(cards, ncards, "ZIMAGE")) &&
	    merge_value(c, value, sizeof(value)) == 0 && !strcmp(value, "T")) {
		h.compressed = 1;
		if ((c = merge_find(cards, ncards, "ZCMPTYPE")))
			merge_value(c, h.cmptype, sizeof(h.cmptype));
	} else if (strcmp(xtension, "IMAGE")) {
		err_set(m->e, EXIT_INPUT, "%s: a '%s' extension, not an image",
			what, xtension);
		goto fail;
	}
	if (merge_data_length(m, what, cards, ncards, 0, &dlen))
		goto fail;
	h.length = hlen + dlen;
	h.header_length = hlen;
	if (h.length > in->size - at) {
		err_set(m->e, EXIT_INPUT, "%s: truncated: its data need %lld "
			"bytes, the file has %lld after the header", what,
			(long long)dlen, (long long)(in->size - at - hlen));
		goto fail;
	}
	if ((c = merge_find(cards, ncards, "ROWS"))) {
		if (merge_rows(m, what, &h, c, cards, ncards))
			goto fail;
		h.cards = cards;
		h.ncards = ncards;
		cards = NULL;
	}
	free(cards);
	*next = at + h.length;
	if (merge_add_hdu(m, &h)) {
		free(h.cards);
		return -1;
	}
	return 0;
fail:
	free(cards);
	return -1;
}

/* Open input i, read its primary header and find its image HDUs. */
static int merge_scan(struct merge *m, int i)
{
	struct merge_input *in = &m->in[i];
	struct stat st;
	const char *c;
	char value[MERGE_CARD + 1], what[PATH_MAX + 32];
	off_t hlen, dlen, at;

	in->fd = open(in->path, O_RDONLY | O_CLOEXEC);
	if (in->fd < 0)
		return err_sys(m->e, "%s: cannot open", in->path);
	if (fstat(in->fd, &st))
		return err_sys(m->e, "%s", in->path);
	/* The HDUs are found by seeking from header to header, and copied
	 * later: a pipe cannot do either. */
	if (!S_ISREG(st.st_mode))
		return err_set(m->e, EXIT_INPUT, "%s: not a regular file",
			       in->path);
	in->size = st.st_size;
	if (merge_read_header(m, i, 1, 0, 1, &in->primary, &in->nprimary, &hlen))
		return -1;
	c = merge_find(in->primary, in->nprimary, "ORIGIN");
	if (!c || (merge_value(c, value, sizeof(value)), strcmp(value, "wfiscene")))
		return err_set(m->e, EXIT_INPUT, "%s: not a wfiscene file (its "
			       "primary header has no ORIGIN = 'wfiscene')",
			       in->path);
	snprintf(what, sizeof(what), "%s: primary HDU", in->path);
	if (merge_data_length(m, what, in->primary, in->nprimary, 1, &dlen))
		return -1;
	in->primary_length = hlen + dlen;
	if (in->primary_length > in->size)
		return err_set(m->e, EXIT_INPUT, "%s: truncated in its primary "
			       "HDU", in->path);
	at = in->primary_length;
	for (int number = 2; at < in->size; number++)
		if (merge_scan_extension(m, i, number, at, &at))
			return -1;
	return i > 0 ? merge_check_primary(m, i) : 0;
}

static const char *merge_storage(const struct merge_hdu *h)
{
	return !h->compressed ? "not compressed" :
	       h->cmptype[0] ? h->cmptype : "tile-compressed";
}

static int merge_by_sca(const void *a, const void *b)
{
	const struct merge_hdu *x = a, *y = b;

	if (x->sca != y->sca)
		return (x->sca > y->sca) - (x->sca < y->sca);
	if (x->kind != y->kind)
		return (x->kind > y->kind) - (x->kind < y->kind);
	if (x->row_first != y->row_first)
		return (x->row_first > y->row_first) - (x->row_first < y->row_first);
	/* Equal starts: keep the order of the inputs, for the messages. */
	return (x->input > y->input) - (x->input < y->input);
}

/* The keywords in which the row parts of one SCA differ by nature. */
static int merge_part_key(const char *c)
{
	return !memcmp(c, "NAXIS2  ", 8) || !memcmp(c, "CRPIX2  ", 8) ||
	       !memcmp(c, "ROWS    ", 8);
}

/* Two row parts of one SCA have the same header but for the keywords
 * above, card for card. */
static int merge_same_part(struct merge *m, const struct merge_hdu *a,
			   const struct merge_hdu *b)
{
	int i = 0, j = 0;

	for (;;) {
		while (i < a->ncards && merge_part_key(a->cards + (size_t)i * MERGE_CARD))
			i++;
		while (j < b->ncards && merge_part_key(b->cards + (size_t)j * MERGE_CARD))
			j++;
		if (i == a->ncards || j == b->ncards)
			break;
		if (memcmp(a->cards + (size_t)i * MERGE_CARD,
			   b->cards + (size_t)j * MERGE_CARD, MERGE_CARD))
			return err_set(m->e, EXIT_INPUT, "%s: WFI%02d rows %d-%d: its "
				       "header has '%.30s' where %s (rows %d-%d) has "
				       "'%.30s': not parts of one image",
				       m->in[b->input].path, b->sca, b->row_first,
				       b->row_last, b->cards + (size_t)j * MERGE_CARD,
				       m->in[a->input].path, a->row_first, a->row_last,
				       a->cards + (size_t)i * MERGE_CARD);
		i++;
		j++;
	}
	if (i != a->ncards || j != b->ncards)
		return err_set(m->e, EXIT_INPUT, "%s: WFI%02d rows %d-%d: its header has "
			       "%s cards than %s's (rows %d-%d): not parts of one image",
			       m->in[b->input].path, b->sca, b->row_first, b->row_last,
			       j == b->ncards ? "fewer" : "more", m->in[a->input].path,
			       a->row_first, a->row_last);
	return 0;
}

/* Sorted by SCA and first row: every SCA is one whole image, or row parts
 * that cover rows 1 to WFS_NPIX once each; every image is stored alike (a
 * file that mixes compressed and plain SCAs is no single run's output). */
static int merge_check_hdus(struct merge *m)
{
	for (int k = 0; k < m->nhdu; k++) {
		const struct merge_hdu *h = &m->hdu[k], *first = &m->hdu[0];
		const struct merge_hdu *prev = k > 0 && m->hdu[k - 1].sca == h->sca &&
					       m->hdu[k - 1].kind == h->kind ?
					       &m->hdu[k - 1] : NULL;
		const char *path = m->in[h->input].path;

		if (h->compressed != first->compressed ||
		    strcmp(h->cmptype, first->cmptype))
			return err_set(m->e, EXIT_INPUT, "%s: WFI%02d is %s, but "
				       "WFI%02d in %s is %s: merge the outputs "
				       "of runs with the same --compress", path,
				       h->sca, merge_storage(h), first->sca,
				       m->in[first->input].path,
				       merge_storage(first));
		if (prev && (!prev->row_first || !h->row_first)) {
			if (prev->input == h->input)
				return err_set(m->e, EXIT_INPUT, "%s: WFI%02d "
					       "appears twice (HDUs %d and %d)",
					       path, h->sca, prev->number, h->number);
			return err_set(m->e, EXIT_INPUT, "%s: WFI%02d is also in "
				       "%s: each SCA may come from one input "
				       "only", path, h->sca, m->in[prev->input].path);
		}
		if (!h->row_first)
			continue;
		if (!prev && h->row_first != 1)
			return err_set(m->e, EXIT_INPUT, "WFI%02d: rows 1-%d are in no "
				       "input (the first part, in %s, has rows %d-%d)",
				       h->sca, h->row_first - 1, path, h->row_first,
				       h->row_last);
		if (prev && h->row_first <= prev->row_last)
			return err_set(m->e, EXIT_INPUT, "%s: WFI%02d rows %d-%d overlap "
				       "rows %d-%d in %s", path, h->sca, h->row_first,
				       h->row_last, prev->row_first, prev->row_last,
				       m->in[prev->input].path);
		if (prev && h->row_first > prev->row_last + 1)
			return err_set(m->e, EXIT_INPUT, "WFI%02d: rows %d-%d are in no "
				       "input (%s has rows %d-%d, %s rows %d-%d)", h->sca,
				       prev->row_last + 1, h->row_first - 1,
				       m->in[prev->input].path, prev->row_first,
				       prev->row_last, path, h->row_first, h->row_last);
		if (prev && merge_same_part(m, prev, h))
			return -1;
		if ((k + 1 == m->nhdu || m->hdu[k + 1].sca != h->sca ||
		     m->hdu[k + 1].kind != h->kind) && h->row_last != WFS_NPIX)
			return err_set(m->e, EXIT_INPUT, "WFI%02d: rows %d-%d are in no "
				       "input (the last part, in %s, has rows %d-%d)",
				       h->sca, h->row_last + 1, WFS_NPIX, path,
				       h->row_first, h->row_last);
	}
	return 0;
}

/* ---- the output ---- */

/* The output (tempfile_open_output): its temporary, or a device or FIFO
 * in place (o->tmp NULL then). */
static int merge_out_file(struct merge_out *o, struct err *e)
{
	size_t n = TEMPFILE_SIZE(o->path);

	if (!(o->tmp = malloc(n)))
		return err_sys(e, "%s", o->path);
	if ((o->fd = tempfile_open_output(o->path, o->tmp, n, e)) < 0 || !o->tmp[0]) {
		free(o->tmp);
		o->tmp = NULL;
	}
	if (o->fd < 0)
		return -1;
	o->close_fd = 1;
	return 0;
}

static int merge_out_open(struct merge_out *o, const char *path, struct err *e)
{
	memset(o, 0, sizeof(*o));
	o->fd = -1;
	o->path = o->name = path;
	if (!strcmp(path, "-")) {
		o->name = "<stdout>";
		if (isatty(STDOUT_FILENO))
			return err_set(e, EXIT_INPUT, "<stdout>: refusing to write "
				       "FITS to a terminal; redirect it or use "
				       "-o FILE");
		o->fd = STDOUT_FILENO;
		return 0;
	}
	return merge_out_file(o, e);
}

static int merge_out_write(struct merge_out *o, const unsigned char *p,
			   size_t n, struct err *e)
{
	while (n > 0) {
		ssize_t w = write(o->fd, p, n);

		if (w < 0 && errno == EINTR)
			continue;
		if (w <= 0) {
			if (w == 0)
				errno = EIO;
			return err_sys(e, "%s: write error", o->name);
		}
		p += w;
		n -= (size_t)w;
	}
	return 0;
}

/* Make the rename durable: sync the directory that holds the new name.
 * Some file systems cannot (EINVAL); that is no error. */
static int merge_sync_dir(const char *path, struct err *e)
{
	const char *slash = strrchr(path, '/');
	char dir[PATH_MAX];
	int fd, r = 0;

	if (!slash)
		snprintf(dir, sizeof(dir), ".");
	else if (slash == path)
		snprintf(dir, sizeof(dir), "/");
	else
		snprintf(dir, sizeof(dir), "%.*s", (int)(slash - path), path);
	fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
	if (fd < 0)
		return err_sys(e, "%s: opening directory '%s' to sync", path, dir);
	if (fsync(fd) && errno != EINVAL && errno != ENOTSUP)
		r = err_sys(e, "%s: syncing directory '%s'", path, dir);
	close(fd);
	return r;
}

/* Give up: close and remove the temporary file.  Safe to call twice. */
static void merge_out_abort(struct merge_out *o)
{
	if (o->close_fd && o->fd >= 0)
		close(o->fd);
	o->close_fd = 0;
	o->fd = -1;
	if (o->tmp)
		tempfile_discard(o->tmp);
	free(o->tmp);
	o->tmp = NULL;
}

static int merge_out_commit(struct merge_out *o, struct err *e)
{
	int fd = o->fd;

	if (!o->close_fd)
		return 0;               /* stdout: the caller's to close */
	if (o->tmp && fsync(fd)) {
		err_sys(e, "%s: write error", o->name);
		goto fail;
	}
	o->close_fd = 0;
	o->fd = -1;
	if (close(fd)) {
		err_sys(e, "%s: write error", o->name);
		goto fail;
	}
	if (!o->tmp)
		return 0;
	if (tempfile_commit(o->tmp, o->path, e) < 0)
		goto fail;
	free(o->tmp);
	o->tmp = NULL;
	return merge_sync_dir(o->path, e);
fail:
	merge_out_abort(o);
	return -1;
}

/* ---- copying ---- */

/* Copy length bytes from offset of input i to the output as they are. */
static int merge_copy(struct merge *m, struct merge_out *o, int i, off_t offset,
		      off_t length)
{
	const struct merge_input *in = &m->in[i];

	while (length > 0) {
		size_t want = length < (off_t)MERGE_BUF_SIZE ? (size_t)length :
			      MERGE_BUF_SIZE;
		ssize_t r = pread(in->fd, m->buf, want, offset);

		if (r < 0 && errno == EINTR)
			continue;
		if (r < 0)
			return err_sys(m->e, "%s: read error", in->path);
		if (r == 0)
			return err_set(m->e, EXIT_SYSTEM, "%s: the file shrank "
				       "while it was being merged", in->path);
		if (merge_out_write(o, m->buf, (size_t)r, m->e))
			return -1;
		offset += r;
		length -= r;
	}
	return 0;
}

/*
 * The row parts of one SCA, hdu[k] (rows 1-...) and those after it, as the
 * one image a run of the whole SCA writes.  Their headers are that run's
 * but for NAXIS2 (the part's rows), CRPIX2 (counted from the part's first
 * row) and ROWS: the first part's CRPIX2 is the whole image's, NAXIS2 is
 * written as fitsout writes it, and ROWS goes.  The data are the parts'
 * rows one after the other, without their padding, padded once at the end.
 */
static int merge_join_rows(struct merge *m, struct merge_out *o, int k)
{
	const struct merge_hdu *first = &m->hdu[k];
	unsigned char *header;
	size_t nh = 0, bytes = 0, pad;
	int rc = -1;

	if (!(header = calloc((size_t)first->ncards / MERGE_CARDS_PER_BLOCK + 1,
			      MERGE_BLOCK)))
		return err_sys(m->e, "merge");
	memset(header, ' ', ((size_t)first->ncards / MERGE_CARDS_PER_BLOCK + 1) *
	       MERGE_BLOCK);
	for (int i = 0; i < first->ncards; i++) {
		const char *c = first->cards + (size_t)i * MERGE_CARD;
		char card[MERGE_CARD + 1];

		if (!memcmp(c, "ROWS    ", 8))
			continue;
		if (!memcmp(c, "NAXIS2  ", 8)) {
			fits_card_int(card, "NAXIS2", WFS_NPIX, "rows (y)");
			c = card;
		}
		memcpy(header + nh++ * MERGE_CARD, c, MERGE_CARD);
	}
	memcpy(header + nh++ * MERGE_CARD, "END", 3);
	if (merge_out_write(o, header, (nh + MERGE_CARDS_PER_BLOCK - 1) /
			    MERGE_CARDS_PER_BLOCK * MERGE_BLOCK, m->e))
		goto done;
	for (int j = k; j < m->nhdu && m->hdu[j].sca == first->sca &&
			m->hdu[j].kind == first->kind; j++) {
		const struct merge_hdu *h = &m->hdu[j];
		size_t n = (size_t)(h->row_last - h->row_first + 1) * WFS_NPIX * 4;

		if (merge_copy(m, o, h->input, h->offset + h->header_length, (off_t)n))
			goto done;
		bytes += n;
	}
	pad = (MERGE_BLOCK - bytes % MERGE_BLOCK) % MERGE_BLOCK;
	memset(header, 0, pad);
	if (merge_out_write(o, header, pad, m->e))
		goto done;
	rc = 0;
done:
	free(header);
	return rc;
}

static int merge_run(struct merge *m, const char *output)
{
	struct merge_out o;

	for (int i = 0; i < m->nin; i++)
		if (merge_scan(m, i))
			return -1;
	qsort(m->hdu, (size_t)m->nhdu, sizeof(*m->hdu), merge_by_sca);
	if (merge_check_hdus(m))
		return -1;
	if (m->verbose > 0)
		for (int k = 0; k < m->nhdu; k++) {
			const struct merge_hdu *h = &m->hdu[k];

			if (h->row_first)
				fprintf(stderr, "wfiscene merge: WFI%02d rows %d-%d from %s "
					"(HDU %d)\n", h->sca, h->row_first, h->row_last,
					m->in[h->input].path, h->number);
			else
				fprintf(stderr, "wfiscene merge: WFI%02d from %s (HDU %d, "
					"%s)\n", h->sca, m->in[h->input].path, h->number,
					merge_storage(h));
		}
	if (!(m->buf = malloc(MERGE_BUF_SIZE)))
		return err_sys(m->e, "merge");
	if (merge_out_open(&o, output, m->e))
		return -1;
	if (merge_copy(m, &o, 0, 0, m->in[0].primary_length))
		goto fail;
	for (int k = 0; k < m->nhdu; k++) {
		const struct merge_hdu *h = &m->hdu[k];

		if (!h->row_first) {
			if (merge_copy(m, &o, h->input, h->offset, h->length))
				goto fail;
		} else if (h->row_first == 1) {
			if (merge_join_rows(m, &o, k))
				goto fail;
		}
	}
	if (merge_out_commit(&o, m->e))
		return -1;
	if (m->verbose > 0) {
		int nsca = 0;

		for (int k = 0; k < m->nhdu; k++)
			nsca += k == 0 || m->hdu[k].sca != m->hdu[k - 1].sca;
		fprintf(stderr, "wfiscene merge: %s: %d SCA images from %d "
			"files\n", o.name, nsca, m->nin);
	}
	return 0;
fail:
	merge_out_abort(&o);
	return -1;
}

int merge_main(int argc, char **argv)
{
	struct merge_cmd c = { 0 };
	struct err e = { 0 };
	struct merge m = { .e = &e };
	const char *output;
	char name[PATH_MAX];
	int first, status;

	first = opt_parse(&merge_cmd_line, argc, argv, &c, &e);
	if (first == OPT_PARSE_DONE)
		return EXIT_OK;
	if (first < 0)
		return opt_fail(&merge_cmd_line, first, &e);
	m.verbose = c.verbose;
	output = c.output;
	if (first == argc) {
		fprintf(stderr, "wfiscene merge: no input files: give the "
			"files of one exposure to merge\n");
		return EXIT_INPUT;
	}
	if (!output) {
		if (isatty(STDOUT_FILENO)) {
			fprintf(stderr, "wfiscene merge: no output: give -o FILE "
				"(or -o - for stdout)\n");
			return EXIT_INPUT;
		}
		output = "-";
	}
	/* one file: '%%' is its only escape (names.h) */
	if (name_check("-o", output, 0, 0, &e) < 0 ||
	    name_expand(name, sizeof(name), "-o", output, 0, NULL, &e) < 0) {
		fprintf(stderr, "wfiscene merge: %s\n", e.msg);
		return e.code;
	}
	output = name;

	m.nin = argc - first;
	m.in = calloc((size_t)m.nin, sizeof(*m.in));
	if (!m.in) {
		err_sys(&e, "merge");
	} else {
		for (int i = 0; i < m.nin; i++) {
			m.in[i].path = argv[first + i];
			m.in[i].fd = -1;
		}
		merge_run(&m, output);
	}
	status = e.code;
	if (status)
		fprintf(stderr, "wfiscene merge: %s\n", e.msg);
	for (int i = 0; m.in && i < m.nin; i++) {
		if (m.in[i].fd >= 0)
			close(m.in[i].fd);
		free(m.in[i].primary);
	}
	for (int k = 0; k < m.nhdu; k++)
		free(m.hdu[k].cards);
	free(m.in);
	free(m.hdu);
	free(m.buf);
	return status;
}
