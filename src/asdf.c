/* asdf.c - writing ASDF files: the tree through libfyaml, the blocks at
 * their offsets; see asdf.h. */
#include <errno.h>
#include <fcntl.h>
#include <libfyaml.h>
#include <lz4.h>
#include <math.h>
#include <md5.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include "asdf.h"
#include "options.h"
#include "date.h"
#include "err.h"
#include "pool.h"
#include "tempfile.h"

#define BLOCK_HEADER 48         /* the header_size field's value */
#define BLOCK_MAGIC "\323BLK"
#define CHUNK ((size_t)1 << 22) /* asdf's lz4 compression_block_size */
#define DICT 32768              /* deflate's window: a zlib chunk's priming */
#define ZSLACK 64               /* a deflate chunk's bound beyond compressBound */

size_t asdf_dtype_size(int dtype)
{
	static const size_t size[] = { 1, 2, 4, 2, 4, 8 };

	return size[dtype];
}

const char *asdf_dtype_name(int dtype)
{
	static const char *const name[] = { "uint8", "uint16", "uint32", "float16", "float32",
					     "float64" };

	return name[dtype];
}

/* ---- the tree ---- */

static void put(struct asdf_tree *t, struct fy_node *map, const char *key, struct fy_node *v)
{
	struct fy_node *k;

	if (!map)
		return;
	if (!v || !(k = fy_node_create_scalar_copy(t->d, key, FY_NT)) ||
	    fy_node_mapping_append(map, k, v)) {
		t->bad = 1;
		return;
	}
}

void asdf_put(struct asdf_tree *t, struct fy_node *map, const char *key, struct fy_node *v)
{
	if (!map || !v) {
		t->bad = 1;
		return;
	}
	put(t, map, key, v);
}

struct fy_node *asdf_map(struct asdf_tree *t, struct fy_node *map, const char *key,
			 const char *tag)
{
	struct fy_node *m;

	if (!map && key)
		return NULL;
	m = fy_node_create_mapping(t->d);
	if (m && tag && fy_node_set_tag(m, tag, FY_NT))
		m = NULL;
	if (!m) {
		t->bad = 1;
		return NULL;
	}
	put(t, map, key, m);
	return t->bad ? NULL : m;
}

struct fy_node *asdf_seq(struct asdf_tree *t, struct fy_node *map, const char *key)
{
	struct fy_node *s;

	if (!map)
		return NULL;
	if (!(s = fy_node_create_sequence(t->d))) {
		t->bad = 1;
		return NULL;
	}
	put(t, map, key, s);
	return t->bad ? NULL : s;
}

/* A double-quoted YAML scalar of v: backslash and quote escaped, control
 * characters as \xNN. */
static struct fy_node *quoted(struct asdf_tree *t, const char *v)
{
	size_t n = strlen(v), k = 0;
	char *q = malloc(4 * n + 3);
	struct fy_node *r;

	if (!q)
		return NULL;
	q[k++] = '"';
	for (const unsigned char *c = (const unsigned char *)v; *c; c++)
		if (*c == '"' || *c == '\\') {
			q[k++] = '\\';
			q[k++] = (char)*c;
		} else if (*c < 0x20 || *c == 0x7f) {
			k += (size_t)sprintf(q + k, "\\x%02x", *c);
		} else {
			q[k++] = (char)*c;
		}
	q[k++] = '"';
	/* the document keeps the text it was built from: it takes q */
	if (!(r = fy_node_build_from_malloc_string(t->d, q, k)))
		free(q);
	return r;
}

void asdf_str(struct asdf_tree *t, struct fy_node *map, const char *key, const char *v)
{
	if (map)
		put(t, map, key, quoted(t, v));
}

void asdf_num(struct asdf_tree *t, struct fy_node *map, const char *key, double v)
{
	if (!map)
		return;
	if (!isfinite(v))
		put(t, map, key, fy_node_create_scalar(t->d, isnan(v) ? ".nan" : v > 0 ? ".inf" :
						       "-.inf", FY_NT));
	else
		put(t, map, key, fy_node_create_scalarf(t->d, "%.17g", v));
}

void asdf_int(struct asdf_tree *t, struct fy_node *map, const char *key, long long v)
{
	if (map)
		put(t, map, key, fy_node_create_scalarf(t->d, "%lld", v));
}

void asdf_bool(struct asdf_tree *t, struct fy_node *map, const char *key, int v)
{
	if (map)
		put(t, map, key, fy_node_create_scalar(t->d, v ? "true" : "false", FY_NT));
}

void asdf_null(struct asdf_tree *t, struct fy_node *map, const char *key)
{
	if (map)
		put(t, map, key, fy_node_create_scalar(t->d, "null", FY_NT));
}

static void seq_add(struct asdf_tree *t, struct fy_node *seq, struct fy_node *v)
{
	if (!seq)
		return;
	if (!v || fy_node_sequence_append(seq, v))
		t->bad = 1;
}

void asdf_seq_add(struct asdf_tree *t, struct fy_node *seq, struct fy_node *v)
{
	if (!v)
		t->bad = 1;
	seq_add(t, seq, v);
}

struct fy_node *asdf_node_yaml(struct asdf_tree *t, const char *yaml)
{
	char *c = strdup(yaml);
	struct fy_node *n = NULL;

	if (c && !(n = fy_node_build_from_malloc_string(t->d, c, strlen(c))))
		free(c);
	if (!n)
		t->bad = 1;
	return n;
}

struct fy_node *asdf_root(struct asdf_tree *t)
{
	return fy_document_root(t->d);
}

struct fy_node *asdf_seq_seq(struct asdf_tree *t, struct fy_node *seq)
{
	struct fy_node *s;

	if (!seq)
		return NULL;
	s = fy_node_create_sequence(t->d);
	seq_add(t, seq, s);
	return t->bad ? NULL : s;
}

void asdf_seq_num(struct asdf_tree *t, struct fy_node *seq, double v)
{
	if (seq)
		seq_add(t, seq, fy_node_create_scalarf(t->d, "%.17g", v));
}

void asdf_seq_int(struct asdf_tree *t, struct fy_node *seq, long long v)
{
	if (seq)
		seq_add(t, seq, fy_node_create_scalarf(t->d, "%lld", v));
}

void asdf_yaml(struct asdf_tree *t, struct fy_node *map, const char *key, const char *yaml)
{
	if (map)
		put(t, map, key, asdf_node_yaml(t, yaml));
}

static int little_endian(void)
{
	const uint16_t one = 1;

	return *(const unsigned char *)&one == 1;
}

void asdf_ndarray(struct asdf_tree *t, struct fy_node *map, const char *key, int block,
		  int dtype, int ndim, const long *shape)
{
	struct fy_node *a = asdf_map(t, map, key, "!core/ndarray-1.1.0"), *s;

	asdf_int(t, a, "source", block);
	asdf_str(t, a, "datatype", asdf_dtype_name(dtype));
	asdf_str(t, a, "byteorder", little_endian() ? "little" : "big");
	s = asdf_seq(t, a, "shape");
	for (int i = 0; i < ndim; i++)
		asdf_seq_int(t, s, shape[i]);
}

struct fy_node *asdf_inline(struct asdf_tree *t, const double *v, int rows, int cols)
{
	struct fy_node *a = asdf_map(t, NULL, NULL, "!core/ndarray-1.1.0"), *d, *s;

	d = asdf_seq(t, a, "data");
	for (int r = 0; r < (rows ? rows : 1); r++) {
		struct fy_node *row = rows ? asdf_seq_seq(t, d) : d;

		for (int c = 0; c < cols; c++)
			asdf_seq_num(t, row, v[r * cols + c]);
	}
	asdf_str(t, a, "datatype", "float64");
	s = asdf_seq(t, a, "shape");
	if (rows)
		asdf_seq_int(t, s, rows);
	asdf_seq_int(t, s, cols);
	return a;
}

void asdf_time(struct asdf_tree *t, struct fy_node *map, const char *key, double mjd)
{
	char when[40], yaml[64];

	date_format(mjd, when, sizeof(when));
	snprintf(yaml, sizeof(yaml), "!time/time-1.2.0 \"%s\"", when);
	asdf_yaml(t, map, key, yaml);
}

int asdf_tree_new(struct asdf_tree *t)
{
	struct fy_node *root, *lib;

	t->bad = 0;
	if (!(t->d = fy_document_create(NULL)))
		return -1;
	if (!(root = fy_node_create_mapping(t->d)) ||
	    fy_node_set_tag(root, "!core/asdf-1.1.0", FY_NT) ||
	    fy_document_set_root(t->d, root)) {
		asdf_tree_free(t);
		return -1;
	}
	lib = asdf_map(t, root, "asdf_library", "!core/software-1.0.0");
	asdf_str(t, lib, "name", "wfiscene");
	asdf_str(t, lib, "version", WFS_VERSION);
	if (t->bad) {
		asdf_tree_free(t);
		return -1;
	}
	return 0;
}

void asdf_tree_free(struct asdf_tree *t)
{
	if (t->d)
		fy_document_destroy(t->d);
	t->d = NULL;
}

/* ---- blocks ---- */

/* zlib's level for compressed blocks: --set asdf-zlib-level (1-9, asdf's
 * and python's 6 by default), read with asdf-compression before any block
 * is written, the same for the whole run. */
static int zlib_level = 6;

int asdf_compression_setting(const char *const *settings, int *c, struct err *e)
{
	const char *v = setting_last(settings, "asdf-compression");
	const char *lv = setting_last(settings, "asdf-zlib-level");

	if (lv) {
		if (lv[0] < '1' || lv[0] > '9' || lv[1])
			return err_set(e, EXIT_INPUT, "--set asdf-zlib-level=%s: expected a "
				       "level from 1 (fastest) to 9 (smallest)", lv);
		zlib_level = lv[0] - '0';
	}
	if (!v)
		*c = ASDF_KEEP;
	else if (!strcmp(v, "none"))
		*c = ASDF_NONE;
	else if (!strcmp(v, "zlib"))
		*c = ASDF_ZLIB;
	else if (!strcmp(v, "lz4"))
		*c = ASDF_LZ4;
	else
		return err_set(e, EXIT_INPUT, "--set asdf-compression=%s: expected none, zlib or "
			       "lz4", v);
	return 0;
}

const char *asdf_compression_field(int c)
{
	return c == ASDF_ZLIB ? "zlib" : c == ASDF_LZ4 ? "lz4\0" : "\0\0\0\0";
}

/* Bytes of a chunk: whole elements, as asdf's lz4 (4 MiB for every
 * datatype here); zlib's the same. */
static size_t chunk_bytes(const struct asdf_block_src *s)
{
	size_t is = s->itemsize ? s->itemsize : 1;

	return is <= CHUNK ? CHUNK / is * is : is;
}

static uint64_t nchunks(const struct asdf_block_src *s)
{
	size_t c = chunk_bytes(s);
	uint64_t n = (s->n + c - 1) / c;

	/* an empty zlib block is still a stream (python's zlib.compress(b"")) */
	return s->compression == ASDF_ZLIB && n == 0 ? 1 : n;
}

/* The most bytes one compressed chunk of len bytes takes. */
static size_t chunk_bound(int compression, size_t len)
{
	if (compression == ASDF_LZ4)
		return 8 + (size_t)LZ4_compressBound((int)len);
	return (size_t)compressBound((uLong)len) + ZSLACK;
}

uint64_t asdf_block_bound(const struct asdf_block_src *s)
{
	size_t c = chunk_bytes(s);

	if (s->compression == ASDF_NONE)
		return 6 + BLOCK_HEADER + s->n;
	/* zlib: its 2-byte header and 4-byte Adler-32 */
	return 6 + BLOCK_HEADER + 6 + nchunks(s) * (uint64_t)chunk_bound(s->compression, c);
}

/* A batch of chunks being compressed: the raw data contiguous in raw
 * (chunk k of the batch at k * csize), chunk first + k of the block. */
struct batch {
	const struct asdf_block_src *s;
	size_t csize, cap;      /* raw bytes a chunk, compressed room a chunk */
	uint64_t first, nchunk; /* the batch's first chunk, the block's chunks */
	int nb;
	unsigned char *raw, *dict;      /* dict: the DICT bytes before the batch */
	size_t dict_n;
	unsigned char **out;
	size_t *out_n;
	uLong *adler;
	int *bad;
};

static size_t chunk_len(const struct batch *b, int k)
{
	uint64_t at = (b->first + (uint64_t)k) * b->csize;

	return b->s->n - at < b->csize ? (size_t)(b->s->n - at) : b->csize;
}

static void be32(unsigned char *p, uint32_t v)
{
	p[0] = (unsigned char)(v >> 24);
	p[1] = (unsigned char)(v >> 16);
	p[2] = (unsigned char)(v >> 8);
	p[3] = (unsigned char)v;
}

/* Compress chunk k of the batch into b->out[k] (pool_fn). */
static void compress_chunk(void *arg, int worker, size_t task)
{
	struct batch *b = arg;
	int k = (int)task;
	size_t len = chunk_len(b, k);
	const unsigned char *in = b->raw + (size_t)k * b->csize;
	unsigned char *out = b->out[k];

	(void)worker;
	b->bad[k] = 1;
	if (b->s->compression == ASDF_LZ4) {
		int c = LZ4_compress_default((const char *)in, (char *)out + 8, (int)len,
					     (int)(b->cap - 8));

		if (c <= 0)
			return;
		be32(out, (uint32_t)c + 4);
		out[4] = (unsigned char)len;
		out[5] = (unsigned char)(len >> 8);
		out[6] = (unsigned char)(len >> 16);
		out[7] = (unsigned char)(len >> 24);
		b->out_n[k] = (size_t)c + 8;
	} else {
		z_stream z;
		int last = b->first + (uint64_t)k == b->nchunk - 1, r;

		memset(&z, 0, sizeof(z));
		if (deflateInit2(&z, zlib_level, Z_DEFLATED, -15, 8,
				 Z_DEFAULT_STRATEGY) != Z_OK)
			return;
		/* primed with the data before the chunk, as one stream would
		 * have it in its window */
		if (k > 0) {
			size_t d = (size_t)k * b->csize < DICT ? (size_t)k * b->csize : DICT;

			r = deflateSetDictionary(&z, in - d, (uInt)d);
		} else {
			r = b->dict_n ? deflateSetDictionary(&z, b->dict, (uInt)b->dict_n) : Z_OK;
		}
		z.next_in = (unsigned char *)in;
		z.avail_in = (uInt)len;
		z.next_out = out;
		z.avail_out = (uInt)b->cap;
		if (r == Z_OK)
			r = deflate(&z, last ? Z_FINISH : Z_SYNC_FLUSH);
		b->out_n[k] = b->cap - z.avail_out;
		deflateEnd(&z);
		if (last ? r != Z_STREAM_END : r != Z_OK || z.avail_in || z.avail_out == 0)
			return;
		b->adler[k] = adler32(adler32(0, NULL, 0), in, (uInt)len);
	}
	b->bad[k] = 0;
}

/* The n bytes at off of a temporary, in their final place, handed to the
 * kernel to write back now (tempfile_writeback) when there are at least
 * ASDF_WBACK of them: the fsync() that ends the file then waits for the
 * last blocks only (fitsout.c does the same).  Not the staged copies of
 * blocks compressed later, which the file does not keep. */
#define ASDF_WBACK (1u << 20)

static void writeback(int fd, uint64_t off, uint64_t n)
{
	if (n >= ASDF_WBACK)
		tempfile_writeback(fd, (long long)off, (long long)(off + n));
}

int asdf_fd_write(int fd, const void *p, size_t n, uint64_t off, const char *path,
		  struct err *e)
{
	const unsigned char *q = p;

	while (n > 0) {
		ssize_t w = pwrite(fd, q, n, (off_t)off);

		if (w < 0 && errno == EINTR)
			continue;
		if (w <= 0) {
			if (w == 0)
				errno = EIO;
			return err_sys(e, "%s: write error", path);
		}
		q += w;
		n -= (size_t)w;
		off += (uint64_t)w;
	}
	return 0;
}

static void be64(unsigned char *p, uint64_t v)
{
	for (int i = 7; i >= 0; i--, v >>= 8)
		p[i] = (unsigned char)v;
}

int asdf_block_write(int fd, uint64_t at, const struct asdf_block_src *s, struct pool *pool,
		     const char *path, uint64_t *end, struct err *e)
{
	unsigned char h[6 + BLOCK_HEADER] = { 0 };
	uint64_t pos = at + sizeof(h), nchunk = nchunks(s);
	struct batch b = { .s = s, .csize = chunk_bytes(s), .nchunk = nchunk };
	int nb = pool ? 2 * pool_threads(pool) : 1, r = -1;
	uLong adler = adler32(0, NULL, 0);
	MD5_CTX md5;

	if (s->compression == ASDF_NONE)
		nb = 1;
	if ((uint64_t)nb > nchunk)
		nb = nchunk ? (int)nchunk : 1;
	b.cap = s->compression == ASDF_NONE ? 0 : chunk_bound(s->compression, b.csize);
	b.raw = malloc((size_t)nb * b.csize);
	b.dict = malloc(DICT);
	b.out = calloc((size_t)nb, sizeof(*b.out));
	b.out_n = calloc((size_t)nb, sizeof(*b.out_n));
	b.adler = calloc((size_t)nb, sizeof(*b.adler));
	b.bad = calloc((size_t)nb, sizeof(*b.bad));
	if (!b.raw || !b.dict || !b.out || !b.out_n || !b.adler || !b.bad)
		goto nomem;
	for (int k = 0; k < nb && b.cap; k++)
		if (!(b.out[k] = malloc(b.cap)))
			goto nomem;
	if (s->md5)
		MD5Init(&md5);
	if (s->compression == ASDF_ZLIB) {
		/* deflate, 32 KiB window, default level: python's zlib.compress */
		static const unsigned char zh[2] = { 0x78, 0x9c };

		if (asdf_fd_write(fd, zh, 2, pos, path, e) < 0)
			goto done;
		pos += 2;
	}
	for (b.first = 0; b.first < nchunk; b.first += (uint64_t)b.nb) {
		size_t got = 0;

		b.nb = nchunk - b.first < (uint64_t)nb ? (int)(nchunk - b.first) : nb;
		for (int k = 0; k < b.nb; k++) {
			size_t len = chunk_len(&b, k);

			if (len && s->get(s->arg, (b.first + (uint64_t)k) * b.csize,
					  b.raw + (size_t)k * b.csize, len, e) < 0)
				goto done;
			got += len;
		}
		if (s->md5)
			MD5Update(&md5, b.raw, got);
		if (s->compression == ASDF_NONE) {
			if (asdf_fd_write(fd, b.raw, got, pos, path, e) < 0)
				goto done;
			pos += got;
			continue;
		}
		if (pool && b.nb > 1)
			pool_run(pool, compress_chunk, &b, (size_t)b.nb);
		else
			for (int k = 0; k < b.nb; k++)
				compress_chunk(&b, 0, (size_t)k);
		for (int k = 0; k < b.nb; k++) {
			if (b.bad[k]) {
				err_set(e, EXIT_SYSTEM, "%s: %s could not compress a block's chunk",
					path, s->compression == ASDF_LZ4 ? "lz4" : "zlib");
				goto done;
			}
			if (asdf_fd_write(fd, b.out[k], b.out_n[k], pos, path, e) < 0)
				goto done;
			pos += b.out_n[k];
			if (s->compression == ASDF_ZLIB)
				adler = adler32_combine(adler, b.adler[k], (z_off_t)chunk_len(&b, k));
		}
		/* the next batch's first chunk is primed with this one's end */
		b.dict_n = got < DICT ? got : DICT;
		memcpy(b.dict, b.raw + got - b.dict_n, b.dict_n);
	}
	if (s->compression == ASDF_ZLIB) {
		unsigned char t[4];

		be32(t, (uint32_t)adler);
		if (asdf_fd_write(fd, t, 4, pos, path, e) < 0)
			goto done;
		pos += 4;
	}
	/* the header: flags 0; allocated = used, the stored bytes; data size
	 * the array's; the MD5 of the data or zeros */
	memcpy(h, BLOCK_MAGIC, 4);
	h[5] = BLOCK_HEADER;
	memcpy(h + 10, asdf_compression_field(s->compression), 4);
	be64(h + 14, pos - at - sizeof(h));
	be64(h + 22, pos - at - sizeof(h));
	be64(h + 30, s->n);
	if (s->md5)
		MD5Final(h + 38, &md5);
	if (asdf_fd_write(fd, h, sizeof(h), at, path, e) < 0)
		goto done;
	writeback(fd, at, pos - at);
	*end = pos;
	r = 0;
	goto done;
nomem:
	err_sys(e, "%s", path);
done:
	for (int k = 0; k < nb && b.out; k++)
		free(b.out[k]);
	free(b.out);
	free(b.out_n);
	free(b.adler);
	free(b.bad);
	free(b.raw);
	free(b.dict);
	return r;
}

/* ---- the file ---- */

struct asdf_out {
	char *path, *tmp;
	int fd;
	int nblock;
	int compression;
	struct pool *pool;
	uint64_t *off;          /* each block's header: offset in the file */
	uint64_t *data;         /* where its data are written (staged, compressed) */
	uint64_t *size;         /* its data's bytes */
	size_t *itemsize;
	uint64_t tree_end;      /* the first block's offset */
	uint64_t end;           /* where the block index goes */
	int failed;
};

int asdf_out_target(const char *path, struct err *e)
{
	struct stat st;

	/* never renamed over a device or a named pipe (as root, /dev/null
	 * itself) */
	if (stat(path, &st) < 0 || S_ISREG(st.st_mode))
		return 0;
	if (S_ISDIR(st.st_mode))
		return err_set(e, EXIT_INPUT, "%s: is a directory", path);
	return err_set(e, EXIT_INPUT, "%s: not a regular file; an ASDF file's blocks are "
		       "written at offsets and it replaces NAME when done, which would "
		       "replace a device or a named pipe", path);
}

struct asdf_out *asdf_out_open(const char *path, int compression, struct pool *pool,
			       struct err *e)
{
	struct asdf_out *a;
	size_t n = TEMPFILE_SIZE(path);

	if (!strcmp(path, "-")) {
		err_set(e, EXIT_INPUT, "-o -: an ASDF file is written at offsets and needs a "
			"file, not stdout");
		return NULL;
	}
	if (asdf_out_target(path, e) < 0)
		return NULL;
	if (!(a = calloc(1, sizeof(*a))) || !(a->path = strdup(path)) ||
	    !(a->tmp = malloc(n))) {
		err_sys(e, "%s", path);
		if (a)
			free(a->path);
		free(a);
		return NULL;
	}
	a->compression = compression == ASDF_KEEP ? ASDF_NONE : compression;
	a->pool = pool;
	a->fd = tempfile_beside(path, a->tmp, n, e);
	if (a->fd < 0) {
		free(a->tmp);
		free(a->path);
		free(a);
		return NULL;
	}
	return a;
}

/* n bytes at offset off, whole. */
static int write_at(struct asdf_out *a, const void *p, size_t n, uint64_t off, struct err *e)
{
	if (asdf_fd_write(a->fd, p, n, off, a->path, e) < 0) {
		a->failed = 1;
		return -1;
	}
	return 0;
}

int asdf_out_begin(struct asdf_out *a, struct asdf_tree *t, int nblock,
		   const uint64_t *bytes, const size_t *itemsize, struct err *e)
{
	static const char head[] = "#ASDF 1.0.0\n#ASDF_STANDARD 1.6.0\n%YAML 1.1\n"
				   "%TAG ! tag:stsci.edu:asdf/\n--- ";
	char *body;
	size_t nb;
	uint64_t off;
	int r = -1;

	body = fy_emit_document_to_string(t->d, FYECF_MODE_BLOCK | FYECF_WIDTH_INF |
					  FYECF_INDENT_2 | FYECF_DOC_START_MARK_OFF |
					  FYECF_DOC_END_MARK_OFF | FYECF_VERSION_DIR_OFF |
					  FYECF_TAG_DIR_OFF);
	if (!body)
		return err_sys(e, "%s: the ASDF tree", a->path);
	nb = strlen(body);
	if (!(a->off = calloc((size_t)nblock + 1, sizeof(*a->off))) ||
	    !(a->data = calloc((size_t)nblock + 1, sizeof(*a->data))) ||
	    !(a->size = calloc((size_t)nblock + 1, sizeof(*a->size))) ||
	    !(a->itemsize = calloc((size_t)nblock + 1, sizeof(*a->itemsize)))) {
		err_sys(e, "%s", a->path);
		goto done;
	}
	a->nblock = nblock;
	if (write_at(a, head, sizeof(head) - 1, 0, e) < 0 ||
	    write_at(a, body, nb, sizeof(head) - 1, e) < 0 ||
	    write_at(a, (nb && body[nb - 1] == '\n') ? "...\n" : "\n...\n",
		     (nb && body[nb - 1] == '\n') ? 4 : 5, sizeof(head) - 1 + nb, e) < 0)
		goto done;
	off = sizeof(head) - 1 + nb + ((nb && body[nb - 1] == '\n') ? 4 : 5);
	a->tree_end = off;
	for (int k = 0; k < nblock; k++) {
		a->size[k] = bytes[k];
		a->itemsize[k] = itemsize ? itemsize[k] : 1;
	}
	if (a->compression != ASDF_NONE) {
		/* the arrays staged beyond the farthest byte the compressed
		 * blocks and the index can reach */
		for (int k = 0; k < nblock; k++) {
			struct asdf_block_src s = { .compression = a->compression, .n = bytes[k],
						    .itemsize = a->itemsize[k] };

			off += asdf_block_bound(&s);
		}
		off += 64 + 24 * (uint64_t)nblock;
		for (int k = 0; k < nblock; k++) {
			a->data[k] = off;
			off += bytes[k];
		}
	} else {
		for (int k = 0; k < nblock; k++) {
			unsigned char h[6 + BLOCK_HEADER] = { 0 };

			memcpy(h, BLOCK_MAGIC, 4);
			h[4] = 0;
			h[5] = BLOCK_HEADER;
			/* flags 0, compression none; allocated = used = data
			 * size; the MD5 left zero: "not computed", as the
			 * Standard allows */
			be64(h + 14, bytes[k]);
			be64(h + 22, bytes[k]);
			be64(h + 30, bytes[k]);
			if (write_at(a, h, sizeof(h), off, e) < 0)
				goto done;
			a->off[k] = off;
			a->data[k] = off + sizeof(h);
			off += sizeof(h) + bytes[k];
		}
		a->end = off;
	}
	/* the data's room: holes until written */
	if (ftruncate(a->fd, (off_t)off)) {
		a->failed = 1;
		err_sys(e, "%s: write error", a->path);
		goto done;
	}
	r = 0;
done:
	free(body);
	return r;
}

int asdf_out_put(struct asdf_out *a, int k, uint64_t off, const void *p, size_t n,
		 struct err *e)
{
	if (k < 0 || k >= a->nblock || off + n > a->size[k])
		return err_set(e, EXIT_SYSTEM, "%s: block %d: %zu bytes at %llu beyond its %llu",
			       a->path, k, n, (unsigned long long)off,
			       (unsigned long long)a->size[k]);
	if (write_at(a, p, n, a->data[k] + off, e) < 0)
		return -1;
	if (a->compression == ASDF_NONE)
		writeback(a->fd, a->data[k] + off, n);
	return 0;
}

/* A staged block's bytes, for asdf_block_write. */
struct staged {
	struct asdf_out *a;
	int fd;                 /* the temporary opened for reading */
	int k;
};

static int staged_get(void *arg, uint64_t off, void *buf, size_t n, struct err *e)
{
	const struct staged *st = arg;
	unsigned char *q = buf;

	off += st->a->data[st->k];
	while (n > 0) {
		ssize_t r = pread(st->fd, q, n, (off_t)off);

		if (r < 0 && errno == EINTR)
			continue;
		if (r <= 0) {
			if (r == 0)
				errno = EIO;
			return err_sys(e, "%s: reading back block %d", st->a->path, st->k);
		}
		q += r;
		n -= (size_t)r;
		off += (uint64_t)r;
	}
	return 0;
}

/* The staged blocks compressed into their places after the tree. */
static int compress_staged(struct asdf_out *a, struct err *e)
{
	uint64_t at = a->tree_end;
	/* (the temporary is made write-only) */
	int fd = open(a->tmp, O_RDONLY | O_CLOEXEC), r = 0;

	if (fd < 0)
		return err_sys(e, "%s: reading back its temporary", a->path);
	for (int k = 0; k < a->nblock && r == 0; k++) {
		struct staged st = { a, fd, k };
		struct asdf_block_src s = { .compression = a->compression, .n = a->size[k],
					    .itemsize = a->itemsize[k], .get = staged_get,
					    .arg = &st };

		a->off[k] = at;
		r = asdf_block_write(a->fd, at, &s, a->pool, a->path, &at, e);
	}
	close(fd);
	a->end = at;
	if (r < 0)
		a->failed = 1;
	return r;
}

int asdf_out_commit(struct asdf_out *a, struct err *e)
{
	char *idx = NULL;
	size_t n = 0;
	FILE *m;
	int r = -1;

	if (a->failed) {
		err_set(e, EXIT_SYSTEM, "%s: earlier write failed", a->path);
		goto done;
	}
	if (a->compression != ASDF_NONE && compress_staged(a, e) < 0)
		goto done;
	if (!(m = open_memstream(&idx, &n))) {
		err_sys(e, "%s", a->path);
		goto done;
	}
	fputs("#ASDF BLOCK INDEX\n%YAML 1.1\n---\n", m);
	for (int k = 0; k < a->nblock; k++)
		fprintf(m, "- %llu\n", (unsigned long long)a->off[k]);
	fputs("...\n", m);
	if (fclose(m)) {
		err_sys(e, "%s", a->path);
		goto done;
	}
	if (a->nblock && write_at(a, idx, n, a->end, e) < 0)
		goto done;
	/* the staging cut off */
	if (a->compression != ASDF_NONE &&
	    ftruncate(a->fd, (off_t)(a->end + (a->nblock ? n : 0)))) {
		err_sys(e, "%s: write error", a->path);
		goto done;
	}
	if (fsync(a->fd)) {
		err_sys(e, "%s: write error", a->path);
		goto done;
	}
	if (close(a->fd)) {
		a->fd = -1;
		err_sys(e, "%s: write error", a->path);
		goto done;
	}
	a->fd = -1;
	if (tempfile_commit(a->tmp, a->path, e) < 0)
		goto done;
	r = 0;
done:
	free(idx);
	asdf_out_abort(a);
	return r;
}

void asdf_out_abort(struct asdf_out *a)
{
	if (!a)
		return;
	if (a->fd >= 0)
		close(a->fd);
	if (a->tmp && a->tmp[0])
		tempfile_discard(a->tmp);
	free(a->tmp);
	free(a->path);
	free(a->off);
	free(a->data);
	free(a->size);
	free(a->itemsize);
	free(a);
}

/* IEEE 754 binary16 of f, rounded to nearest even: the exponent rebiased
 * from 127 to 15, subnormals below 2^-14.  A finite f that rounds beyond
 * 65504 (|f| >= 65520) saturates to +-65504, the largest finite half,
 * rather than overflowing to infinity as IEEE rounding would: RAD stores
 * chisq and the variances as float16, and a cosmic-ray pixel's chisq
 * past 65504 is a large number, not an infinite one.  Infinity and NaN
 * stay so. */
uint16_t asdf_half(float f)
{
	uint32_t x;
	uint16_t sign;
	int exp;
	uint32_t man;

	memcpy(&x, &f, 4);
	sign = (uint16_t)(x >> 16 & 0x8000);
	exp = (int)(x >> 23 & 0xff);
	man = x & 0x7fffff;
	if (exp == 0xff)
		return sign | 0x7c00 | (man ? 0x200 : 0);
	exp -= 127 - 15;
	if (exp >= 31)
		return sign | 0x7bff;
	if (exp <= 0) {
		/* subnormal: the implicit bit made explicit, shifted */
		uint32_t m, half, rest;
		int shift = 14 - exp;

		if (shift > 24)
			return sign;
		m = man | 0x800000;
		half = 1u << (shift - 1);
		rest = m & ((1u << shift) - 1);
		m >>= shift;
		if (rest > half || (rest == half && (m & 1)))
			m++;
		return sign | (uint16_t)m;
	}
	{
		uint32_t rest = man & 0x1fff, m = man >> 13;
		uint32_t h = (uint32_t)exp << 10 | m;

		if (rest > 0x1000 || (rest == 0x1000 && (m & 1)))
			h++;    /* may carry into the exponent: still right, or past 65504 */
		return sign | (uint16_t)(h >= 0x7c00 ? 0x7bff : h);
	}
}

float asdf_half_to_float(uint16_t h)
{
	int exp = h >> 10 & 0x1f;
	int man = h & 0x3ff;
	float v;

	if (exp == 0)
		v = ldexpf((float)man, -24);
	else if (exp == 31)
		v = man ? NAN : INFINITY;
	else
		v = ldexpf((float)(man | 0x400), exp - 25);
	return h & 0x8000 ? -v : v;
}
