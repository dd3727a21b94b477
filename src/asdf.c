/* asdf.c - writing ASDF files: the tree through libfyaml, the blocks at
 * their offsets; see asdf.h. */
#include <errno.h>
#include <fcntl.h>
#include <libfyaml.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "asdf.h"
#include "date.h"
#include "err.h"
#include "tempfile.h"

#define BLOCK_HEADER 48         /* the header_size field's value */
#define BLOCK_MAGIC "\323BLK"

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

/* ---- the file ---- */

struct asdf_out {
	char *path, *tmp;
	int fd;
	int nblock;
	uint64_t *off, *size;   /* each block's data: offset in the file, bytes */
	uint64_t end;           /* where the block index goes */
	int failed;
};

struct asdf_out *asdf_out_open(const char *path, struct err *e)
{
	struct asdf_out *a;
	size_t n = TEMPFILE_SIZE(path);

	if (!strcmp(path, "-")) {
		err_set(e, EXIT_INPUT, "-o -: an ASDF file is written at offsets and needs a "
			"file, not stdout");
		return NULL;
	}
	if (!(a = calloc(1, sizeof(*a))) || !(a->path = strdup(path)) ||
	    !(a->tmp = malloc(n))) {
		err_sys(e, "%s", path);
		if (a)
			free(a->path);
		free(a);
		return NULL;
	}
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
	const unsigned char *q = p;

	while (n > 0) {
		ssize_t w = pwrite(a->fd, q, n, (off_t)off);

		if (w < 0 && errno == EINTR)
			continue;
		if (w <= 0) {
			if (w == 0)
				errno = EIO;
			a->failed = 1;
			return err_sys(e, "%s: write error", a->path);
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

int asdf_out_begin(struct asdf_out *a, struct asdf_tree *t, int nblock,
		   const uint64_t *bytes, struct err *e)
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
	    !(a->size = calloc((size_t)nblock + 1, sizeof(*a->size)))) {
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
	for (int k = 0; k < nblock; k++) {
		unsigned char h[6 + BLOCK_HEADER] = { 0 };

		memcpy(h, BLOCK_MAGIC, 4);
		h[4] = 0;
		h[5] = BLOCK_HEADER;
		/* flags 0, compression none; allocated = used = data size;
		 * the MD5 left zero: "not computed", as the Standard allows */
		be64(h + 14, bytes[k]);
		be64(h + 22, bytes[k]);
		be64(h + 30, bytes[k]);
		if (write_at(a, h, sizeof(h), off, e) < 0)
			goto done;
		a->off[k] = off;
		a->size[k] = bytes[k];
		off += sizeof(h) + bytes[k];
	}
	a->end = off;
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
	return write_at(a, p, n, a->off[k] + 6 + BLOCK_HEADER + off, e);
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
	free(a->size);
	free(a);
}

/* IEEE 754 binary16 of f, rounded to nearest even: the exponent rebiased
 * from 127 to 15, subnormals below 2^-14, infinity beyond 65504. */
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
		return sign | 0x7c00;
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
			h++;    /* may carry into the exponent: still right */
		return sign | (uint16_t)(h >= 0x7c00 ? 0x7c00 : h);
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
