/*
 * input.c - catalog bytes from a file or stdin, decompressed on the fly;
 * see input.h.
 *
 * The codec is chosen from the first raw bytes.  Decompressed data goes
 * straight into the caller's buffer; only the raw (compressed) side has a
 * buffer of our own, sized by the library (ZSTD_DStreamInSize()).  A stream
 * that ends inside a zstd frame or gzip member is reported as truncated,
 * never as a clean end of input: a pipe from a producer that died must not
 * look like a shorter catalog.
 */
#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <zlib.h>
#include <zstd.h>

#include "err.h"
#include "input.h"

#define INPUT_PEEK_MAX 4096
#define INPUT_GZ_RAW (128 * 1024)

struct input {
	int fd;
	int own_fd;
	char *name;
	char *path;
	enum input_codec codec;
	unsigned long long raw_bytes;

	/* Raw bytes read but not yet decoded: raw[raw_pos, raw_len). */
	unsigned char *raw;
	size_t raw_cap, raw_pos, raw_len;
	int raw_eof;

	ZSTD_DStream *zd;
	size_t zret;            /* last hint from a call that made progress:
	                           0 means we stand between frames */
	z_stream gz;
	int gz_ready;
	int gz_mid;             /* inside a gzip member */

	/* Decoded bytes kept back by input_peek(): peek[peek_pos, peek_len). */
	unsigned char peek[INPUT_PEEK_MAX];
	size_t peek_pos, peek_len;
	int done;               /* the decoder reported the end of input */
};

/* Read more raw bytes into raw[], after the undecoded ones.  Returns the
 * count, 0 at end of file, -1 on a read error. */
static ssize_t raw_fill(struct input *in, struct err *e)
{
	ssize_t r;

	if (in->raw_pos > 0 && in->raw_pos == in->raw_len)
		in->raw_pos = in->raw_len = 0;
	if (in->raw_len == in->raw_cap) {
		memmove(in->raw, in->raw + in->raw_pos, in->raw_len - in->raw_pos);
		in->raw_len -= in->raw_pos;
		in->raw_pos = 0;
	}
	do
		r = read(in->fd, in->raw + in->raw_len, in->raw_cap - in->raw_len);
	while (r < 0 && errno == EINTR);
	if (r < 0)
		return err_sys(e, "%s: read error", in->name);
	if (r == 0)
		in->raw_eof = 1;
	in->raw_len += (size_t)r;
	in->raw_bytes += (unsigned long long)r;
	return r;
}

static ssize_t plain_read(struct input *in, void *buf, size_t n, struct err *e)
{
	ssize_t r;

	/* Bytes read for magic detection come first. */
	if (in->raw_pos < in->raw_len) {
		size_t k = in->raw_len - in->raw_pos;

		if (k > n)
			k = n;
		memcpy(buf, in->raw + in->raw_pos, k);
		in->raw_pos += k;
		return (ssize_t)k;
	}
	if (in->raw_eof)
		return 0;
	do
		r = read(in->fd, buf, n);
	while (r < 0 && errno == EINTR);
	if (r < 0)
		return err_sys(e, "%s: read error", in->name);
	if (r == 0)
		in->raw_eof = 1;
	in->raw_bytes += (unsigned long long)r;
	return r;
}

static ssize_t zstd_read(struct input *in, void *buf, size_t n, struct err *e)
{
	for (;;) {
		ZSTD_inBuffer ib;
		ZSTD_outBuffer ob = { buf, n, 0 };
		size_t ret;

		if (in->raw_pos == in->raw_len && !in->raw_eof &&
		    raw_fill(in, e) < 0)
			return -1;
		ib.src = in->raw;
		ib.size = in->raw_len;
		ib.pos = in->raw_pos;
		ret = ZSTD_decompressStream(in->zd, &ob, &ib);
		if (ZSTD_isError(ret))
			return err_set(e, EXIT_INPUT, "%s: corrupt zstd stream: %s",
				       in->name, ZSTD_getErrorName(ret));
		if (ob.pos > 0 || ib.pos > in->raw_pos)
			in->zret = ret;
		in->raw_pos = ib.pos;
		if (ob.pos > 0)
			return (ssize_t)ob.pos;
		if (in->raw_eof && in->raw_pos == in->raw_len) {
			if (in->zret != 0)
				return err_set(e, EXIT_INPUT,
					       "%s: truncated zstd stream (input ends inside a frame)",
					       in->name);
			return 0;
		}
	}
}

static ssize_t gzip_read(struct input *in, void *buf, size_t n, struct err *e)
{
	if (n > 1u << 30)
		n = 1u << 30;   /* avail_out is an unsigned int */
	for (;;) {
		size_t before_in;
		int rc;

		if (in->raw_pos == in->raw_len && !in->raw_eof &&
		    raw_fill(in, e) < 0)
			return -1;
		if (!in->gz_mid && in->raw_pos == in->raw_len && in->raw_eof)
			return 0;
		in->gz.next_in = in->raw + in->raw_pos;
		in->gz.avail_in = (uInt)(in->raw_len - in->raw_pos);
		in->gz.next_out = buf;
		in->gz.avail_out = (uInt)n;
		before_in = in->gz.avail_in;
		rc = inflate(&in->gz, Z_NO_FLUSH);
		in->raw_pos = in->raw_len - in->gz.avail_in;
		if (before_in > in->gz.avail_in)
			in->gz_mid = 1;
		if (rc == Z_STREAM_END) {
			/* A member ended; another may follow (concatenated
			 * members are one stream, as gzip -d reads them). */
			in->gz_mid = 0;
			if (inflateReset(&in->gz) != Z_OK)
				return err_set(e, EXIT_SYSTEM, "%s: zlib reset failed",
					       in->name);
		} else if (rc == Z_DATA_ERROR || rc == Z_NEED_DICT) {
			return err_set(e, EXIT_INPUT, "%s: corrupt gzip stream: %s",
				       in->name, in->gz.msg ? in->gz.msg : "bad data");
		} else if (rc == Z_MEM_ERROR) {
			return err_set(e, EXIT_SYSTEM, "%s: out of memory in zlib",
				       in->name);
		} else if (rc != Z_OK && rc != Z_BUF_ERROR) {
			return err_set(e, EXIT_INPUT, "%s: gzip error %d", in->name, rc);
		}
		if (n - in->gz.avail_out > 0)
			return (ssize_t)(n - in->gz.avail_out);
		if (in->raw_eof && in->raw_pos == in->raw_len && in->gz_mid)
			return err_set(e, EXIT_INPUT,
				       "%s: truncated gzip stream (input ends inside a member)",
				       in->name);
	}
}

static ssize_t decode(struct input *in, void *buf, size_t n, struct err *e)
{
	ssize_t r;

	if (in->done || n == 0)
		return 0;
	switch (in->codec) {
	case INPUT_ZSTD:
		r = zstd_read(in, buf, n, e);
		break;
	case INPUT_GZIP:
		r = gzip_read(in, buf, n, e);
		break;
	default:
		r = plain_read(in, buf, n, e);
		break;
	}
	if (r == 0)
		in->done = 1;
	return r;
}

struct input *input_open(const char *path, struct err *e)
{
	struct input *in = calloc(1, sizeof(*in));
	int stdin_ = !path || strcmp(path, "-") == 0;

	if (!in) {
		err_set(e, EXIT_SYSTEM, "out of memory");
		return NULL;
	}
	in->fd = -1;
	in->name = strdup(stdin_ ? "<stdin>" : path);
	in->path = stdin_ ? NULL : strdup(path);
	if (!in->name || (!stdin_ && !in->path)) {
		err_set(e, EXIT_SYSTEM, "out of memory");
		goto fail;
	}
	if (stdin_) {
		in->fd = 0;
	} else {
		in->fd = open(path, O_RDONLY | O_CLOEXEC);
		if (in->fd < 0) {
			err_sys(e, "%s: cannot open", path);
			goto fail;
		}
		in->own_fd = 1;
	}
	in->raw_cap = ZSTD_DStreamInSize();
	if (in->raw_cap < INPUT_GZ_RAW)
		in->raw_cap = INPUT_GZ_RAW;
	in->raw = malloc(in->raw_cap);
	if (!in->raw) {
		err_set(e, EXIT_SYSTEM, "out of memory");
		goto fail;
	}
	/* Gather the 4 magic bytes (a pipe may deliver fewer at a time). */
	while (in->raw_len < 4 && !in->raw_eof)
		if (raw_fill(in, e) < 0)
			goto fail;
	if (in->raw_len >= 4 && memcmp(in->raw, "\x28\xb5\x2f\xfd", 4) == 0) {
		in->codec = INPUT_ZSTD;
		in->zd = ZSTD_createDStream();
		if (!in->zd || ZSTD_isError(ZSTD_initDStream(in->zd))) {
			err_set(e, EXIT_SYSTEM, "%s: cannot start zstd", in->name);
			goto fail;
		}
		in->zret = 1;
	} else if (in->raw_len >= 2 && in->raw[0] == 0x1f && in->raw[1] == 0x8b) {
		in->codec = INPUT_GZIP;
		/* 16 + MAX_WBITS: gzip wrapper only, so a raw zlib stream
		 * that happens to start 1f 8b is not misread. */
		if (inflateInit2(&in->gz, 16 + MAX_WBITS) != Z_OK) {
			err_set(e, EXIT_SYSTEM, "%s: cannot start zlib", in->name);
			goto fail;
		}
		in->gz_ready = 1;
		in->gz_mid = 1;
	} else {
		in->codec = INPUT_PLAIN;
	}
	return in;
fail:
	input_close(in);
	return NULL;
}

ssize_t input_read(struct input *in, void *buf, size_t n, struct err *e)
{
	if (in->peek_pos < in->peek_len) {
		size_t k = in->peek_len - in->peek_pos;

		if (k > n)
			k = n;
		memcpy(buf, in->peek + in->peek_pos, k);
		in->peek_pos += k;
		return (ssize_t)k;
	}
	return decode(in, buf, n, e);
}

ssize_t input_peek(struct input *in, const void **p, size_t n, struct err *e)
{
	if (n > INPUT_PEEK_MAX)
		n = INPUT_PEEK_MAX;
	if (in->peek_pos > 0) {
		memmove(in->peek, in->peek + in->peek_pos, in->peek_len - in->peek_pos);
		in->peek_len -= in->peek_pos;
		in->peek_pos = 0;
	}
	while (in->peek_len < n && !in->done) {
		ssize_t r = decode(in, in->peek + in->peek_len, n - in->peek_len, e);

		if (r < 0)
			return -1;
		in->peek_len += (size_t)r;
	}
	*p = in->peek;
	return (ssize_t)(in->peek_len < n ? in->peek_len : n);
}

const char *input_name(const struct input *in)
{
	return in->name;
}

enum input_codec input_codec(const struct input *in)
{
	return in->codec;
}

const char *input_path(const struct input *in)
{
	return in->path;
}

unsigned long long input_raw_bytes(const struct input *in)
{
	return in->raw_bytes;
}

void input_close(struct input *in)
{
	if (!in)
		return;
	if (in->zd)
		ZSTD_freeDStream(in->zd);
	if (in->gz_ready)
		inflateEnd(&in->gz);
	if (in->own_fd && in->fd >= 0)
		close(in->fd);
	free(in->raw);
	free(in->name);
	free(in->path);
	free(in);
}
