/*
 * asdf_read.c - reading an ASDF file (asdf.h's layout) for --into: the
 * header lines, the tree through libfyaml, the blocks' headers checked
 * against the file, a block's data read (zlib and lz4 blocks
 * decompressed, lz4 in asdf's framing) and its MD5 checked where the
 * writer computed one.
 */
#include <errno.h>
#include <fcntl.h>
#include <libfyaml.h>
#include <lz4.h>
#include <md5.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include "asdf_read.h"
#include "err.h"

#define BLOCK_MAGIC "\323BLK"
#define TREE_MAX (256u << 20)   /* a tree larger than this is refused */

static int read_at(int fd, void *p, size_t n, uint64_t off)
{
	unsigned char *q = p;

	while (n > 0) {
		ssize_t r = pread(fd, q, n, (off_t)off);

		if (r < 0 && errno == EINTR)
			continue;
		if (r <= 0)
			return -1;
		q += r;
		n -= (size_t)r;
		off += (uint64_t)r;
	}
	return 0;
}

static uint64_t get64(const unsigned char *p)
{
	uint64_t v = 0;

	for (int i = 0; i < 8; i++)
		v = v << 8 | p[i];
	return v;
}

void asdf_in_free(struct asdf_in *a)
{
	if (!a)
		return;
	if (a->d)
		fy_document_destroy(a->d);
	if (a->fd >= 0)
		close(a->fd);
	free(a->text);
	free(a->b);
	free(a->path);
	free(a);
}

/* The version x.y.z as a number x * 10000 + y * 100 + z, or -1. */
static int version(const char *s)
{
	int x, y, z;

	if (sscanf(s, "%d.%d.%d", &x, &y, &z) != 3)
		return -1;
	return x * 10000 + y * 100 + z;
}

/* The blocks after the tree: each header checked against the file. */
static int read_blocks(struct asdf_in *a, uint64_t off, struct err *e)
{
	int cap = 0;

	while (off + 4 <= a->size) {
		unsigned char h[6 + 48];
		struct asdf_block *b;
		unsigned hs;

		if (read_at(a->fd, h, 4, off) < 0)
			return err_sys(e, "%s: reading", a->path);
		if (memcmp(h, BLOCK_MAGIC, 4)) {
			if (a->nblock == 0 && (h[0] == ' ' || h[0] == '\n' || h[0] == 0)) {
				off++;  /* padding before the first block */
				continue;
			}
			break;  /* the block index, or whatever follows */
		}
		if (off + sizeof(h) > a->size)
			return err_set(e, EXIT_INPUT, "%s: block %d: the file ends in its header "
				       "(truncated)", a->path, a->nblock);
		if (read_at(a->fd, h, sizeof(h), off) < 0)
			return err_sys(e, "%s: reading", a->path);
		hs = (unsigned)h[4] << 8 | h[5];
		if (hs < 48)
			return err_set(e, EXIT_INPUT, "%s: block %d: header size %u, less than the "
				       "48 the Standard requires", a->path, a->nblock, hs);
		if (a->nblock == cap) {
			void *m = realloc(a->b, (size_t)(cap ? 2 * cap : 16) * sizeof(*a->b));

			if (!m)
				return err_sys(e, "%s", a->path);
			a->b = m;
			cap = cap ? 2 * cap : 16;
		}
		b = &a->b[a->nblock];
		b->off = off;
		b->data_off = off + 6 + hs;
		b->flags = (uint32_t)h[6] << 24 | (uint32_t)h[7] << 16 | (uint32_t)h[8] << 8 | h[9];
		memcpy(b->comp, h + 10, 4);
		b->allocated = get64(h + 14);
		b->used = get64(h + 22);
		b->data = get64(h + 30);
		memcpy(b->md5, h + 38, 16);
		if (b->used > b->allocated)
			return err_set(e, EXIT_INPUT, "%s: block %d: used size %llu exceeds its "
				       "allocated size %llu", a->path, a->nblock,
				       (unsigned long long)b->used, (unsigned long long)b->allocated);
		if (!memcmp(b->comp, "\0\0\0\0", 4) && b->used != b->data)
			return err_set(e, EXIT_INPUT, "%s: block %d: uncompressed, yet its data size "
				       "%llu is not its used size %llu", a->path, a->nblock,
				       (unsigned long long)b->data, (unsigned long long)b->used);
		/* compared without adding: a size near 2^64 must not wrap */
		if (b->data_off > a->size || b->allocated > a->size - b->data_off)
			return err_set(e, EXIT_INPUT, "%s: block %d: %llu bytes from offset %llu, "
				       "beyond the file's end at %llu (truncated)", a->path, a->nblock,
				       (unsigned long long)b->allocated,
				       (unsigned long long)b->data_off, (unsigned long long)a->size);
		a->nblock++;
		off = b->data_off + b->allocated;
	}
	a->blocks_end = off;
	return 0;
}

struct asdf_in *asdf_in_open(const char *path, struct err *e)
{
	struct asdf_in *a = calloc(1, sizeof(*a));
	struct fy_parse_cfg cfg = { .flags = FYPCF_QUIET };
	struct fy_diag_cfg dcfg;
	struct stat st;
	char line[256];
	size_t cap = 1 << 16, n = 0, lines = 0;
	char *end = NULL;

	if (!a || !(a->path = strdup(path))) {
		err_sys(e, "%s", path);
		free(a);
		return NULL;
	}
	a->fd = open(path, O_RDONLY | O_CLOEXEC);
	if (a->fd < 0 || fstat(a->fd, &st)) {
		err_sys(e, "%s", path);
		if (errno != ENOENT || access(path, F_OK) == 0)
			e->code = EXIT_INPUT;
		goto fail;
	}
	a->size = (uint64_t)st.st_size;
	/* the header lines and the tree: read until the tree's end marker */
	if (!(a->text = malloc(cap + 1)))
		goto nomem;
	for (;;) {
		ssize_t r;

		if (n == cap) {
			char *m;

			if (cap >= TREE_MAX) {
				err_set(e, EXIT_INPUT, "%s: no end of the ASDF tree in its first %u MB",
					path, TREE_MAX >> 20);
				goto fail;
			}
			if (!(m = realloc(a->text, 2 * cap + 1)))
				goto nomem;
			a->text = m;
			cap *= 2;
		}
		r = pread(a->fd, a->text + n, cap - n, (off_t)n);
		if (r < 0 && errno == EINTR)
			continue;
		if (r < 0) {
			err_sys(e, "%s: reading", path);
			goto fail;
		}
		n += (size_t)r;
		a->text[n] = 0;
		if ((end = strstr(a->text, "\n...\n")) || (end = strstr(a->text, "\n...\r\n")) ||
		    r == 0)
			break;
	}
	if (strncmp(a->text, "#ASDF ", 6)) {
		err_set(e, EXIT_INPUT, "%s: not an ASDF file (it does not begin with '#ASDF')", path);
		goto fail;
	}
	/* the comment lines: the file format and the Standard's version */
	a->standard = -1;
	for (const char *p = a->text; *p == '#'; lines++) {
		const char *nl = strchr(p, '\n');
		size_t k = nl ? (size_t)(nl - p) : strlen(p);

		snprintf(line, sizeof(line), "%.*s", (int)(k < 255 ? k : 255), p);
		if (!strncmp(line, "#ASDF_STANDARD ", 15))
			a->standard = version(line + 15);
		if (!nl)
			break;
		p = nl + 1;
		a->tree_off = (uint64_t)(p - a->text);
	}
	if (a->standard < 0) {
		err_set(e, EXIT_INPUT, "%s: no #ASDF_STANDARD line: the file's ASDF Standard is "
			"unknown", path);
		goto fail;
	}
	if (!end) {
		err_set(e, EXIT_INPUT, "%s: the ASDF tree has no end ('...'): truncated", path);
		goto fail;
	}
	a->tree_end = (uint64_t)(end - a->text) + (end[4] == '\r' ? 6 : 5);
	/* libfyaml's errors collected, not printed: the first one is told
	 * with its line in the file */
	fy_diag_cfg_default(&dcfg);
	dcfg.fp = NULL;
	if (!(cfg.diag = fy_diag_create(&dcfg)))
		goto nomem;
	fy_diag_set_collect_errors(cfg.diag, true);
	a->d = fy_document_build_from_string(&cfg, a->text + a->tree_off,
					     (size_t)(a->tree_end - a->tree_off));
	if (!a->d) {
		void *it = NULL;
		struct fy_diag_error *de = fy_diag_errors_iterate(cfg.diag, &it);

		if (de && de->msg)
			err_set(e, EXIT_INPUT, "%s:%zu:%d: the ASDF tree is not valid YAML: %s",
				path, lines + (size_t)de->line, de->column, de->msg);
		else
			err_set(e, EXIT_INPUT, "%s: the ASDF tree is not valid YAML", path);
		fy_diag_destroy(cfg.diag);
		goto fail;
	}
	fy_diag_destroy(cfg.diag);
	if (read_blocks(a, a->tree_end, e) < 0)
		goto fail;
	return a;
nomem:
	err_sys(e, "%s", path);
fail:
	asdf_in_free(a);
	return NULL;
}

struct fy_node *asdf_in_root(const struct asdf_in *a)
{
	return fy_document_root(a->d);
}

/*
 * asdf's lz4 framing (asdf/compression.py, Lz4Compressor): the data cut
 * into chunks of 4 MB, each stored as its compressed size (4 bytes, big
 * endian), then what python-lz4's lz4.block.compress writes: the chunk's
 * size (4 bytes, little endian) and the LZ4 block.  0 or -1 (a message
 * naming the block).
 */
static int lz4_blocks(const struct asdf_in *a, int k, const unsigned char *p, uint64_t used,
		      unsigned char *out, size_t n, struct err *e)
{
	uint64_t at = 0;
	size_t done = 0;

	while (at < used) {
		uint64_t len, size;
		int got;

		if (used - at < 8)
			return err_set(e, EXIT_INPUT, "%s: block %d: lz4 data cut short at byte "
				       "%llu", a->path, k, (unsigned long long)at);
		len = (uint64_t)p[at] << 24 | (uint64_t)p[at + 1] << 16 | (uint64_t)p[at + 2] << 8 |
		      p[at + 3];
		size = (uint64_t)p[at + 4] | (uint64_t)p[at + 5] << 8 | (uint64_t)p[at + 6] << 16 |
		       (uint64_t)p[at + 7] << 24;
		if (len < 4 || len - 4 > used - at - 8 || len - 4 > INT32_MAX ||
		    size > n - done || size > INT32_MAX)
			return err_set(e, EXIT_INPUT, "%s: block %d: an lz4 chunk at byte %llu of "
				       "%llu bytes for %llu: not the block's sizes", a->path, k,
				       (unsigned long long)at, (unsigned long long)len,
				       (unsigned long long)size);
		got = LZ4_decompress_safe((const char *)p + at + 8, (char *)out + done,
					  (int)(len - 4), (int)size);
		if (got < 0 || (uint64_t)got != size)
			return err_set(e, EXIT_INPUT, "%s: block %d: the lz4 chunk at byte %llu "
				       "does not decompress (corrupt)", a->path, k,
				       (unsigned long long)at);
		done += (size_t)size;
		at += 4 + len;
	}
	if (done != n)
		return err_set(e, EXIT_INPUT, "%s: block %d: its lz4 data decompress to %zu "
			       "bytes, not %zu", a->path, k, done, n);
	return 0;
}

int asdf_in_block(struct asdf_in *a, int k, void *out, size_t n, struct err *e)
{
	struct asdf_block *b;
	unsigned char *raw = NULL, sum[16];
	static const unsigned char zero[16];
	int r = -1;

	if (k < 0 || k >= a->nblock)
		return err_set(e, EXIT_INPUT, "%s: block %d: the file has %d blocks", a->path, k,
			       a->nblock);
	b = &a->b[k];
	if (b->data != n)
		return err_set(e, EXIT_INPUT, "%s: block %d holds %llu bytes, its array %zu",
			       a->path, k, (unsigned long long)b->data, n);
	if (!memcmp(b->comp, "\0\0\0\0", 4)) {
		if (read_at(a->fd, out, n, b->data_off) < 0)
			return err_sys(e, "%s: reading block %d", a->path, k);
		raw = out;
	} else if (!memcmp(b->comp, "zlib", 4) || !memcmp(b->comp, "lz4\0", 4)) {
		if (!(raw = malloc(b->used ? b->used : 1)))
			return err_sys(e, "%s", a->path);
		if (read_at(a->fd, raw, b->used, b->data_off) < 0) {
			err_sys(e, "%s: reading block %d", a->path, k);
			goto done;
		}
		if (b->comp[0] == 'z') {
			uLongf got = (uLongf)n;
			int z = uncompress(out, &got, raw, (uLong)b->used);

			if (z != Z_OK || got != n) {
				err_set(e, EXIT_INPUT, "%s: block %d: its zlib data %s", a->path, k,
					z == Z_OK || z == Z_BUF_ERROR ? "do not inflate to the "
					"block's data size (corrupt)" : "are corrupt");
				goto done;
			}
		} else if (lz4_blocks(a, k, raw, b->used, out, n, e) < 0) {
			goto done;
		}
	} else {
		return err_set(e, EXIT_INPUT, "%s: block %d: compression '%.4s' is not read "
			       "here (zlib, lz4 and none are)", a->path, k, b->comp);
	}
	/* the checksum: the Standard's is of the used (stored) data,
	 * python3-asdf's of the data before compression; either will do */
	if (memcmp(b->md5, zero, 16)) {
		MD5_CTX c;

		MD5Init(&c);
		MD5Update(&c, raw, (size_t)b->used);
		MD5Final(sum, &c);
		if (memcmp(sum, b->md5, 16) && raw != out) {
			MD5Init(&c);
			MD5Update(&c, out, n);
			MD5Final(sum, &c);
		}
		if (memcmp(sum, b->md5, 16)) {
			err_set(e, EXIT_INPUT, "%s: block %d: its MD5 checksum does not match its "
				"data", a->path, k);
			goto done;
		}
	}
	r = 0;
done:
	if (raw != out)
		free(raw);
	return r;
}
