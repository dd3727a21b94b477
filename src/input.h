/*
 * input.h - catalog bytes from a file or stdin, decompressed on the fly.
 *
 * Compression is recognised by magic number, never by name: zstd
 * (28 b5 2f fd), gzip (1f 8b), otherwise plain.  Concatenated frames and
 * members are read through.  A stream that ends inside a frame is an error
 * ("truncated zstd stream"), never a silent end of input.
 */
#ifndef WFS_INPUT_H
#define WFS_INPUT_H

#include <stddef.h>
#include <sys/types.h>

struct err;

enum input_codec { INPUT_PLAIN, INPUT_ZSTD, INPUT_GZIP };

struct input;

/* Open path, or stdin for "-".  NULL with a message on failure. */
struct input *input_open(const char *path, struct err *e);

/* Read up to n decompressed bytes.  Returns the count, 0 at the end of a
 * complete stream, -1 on error (read error, corrupt or truncated data). */
ssize_t input_read(struct input *in, void *buf, size_t n, struct err *e);

/* Look at the first up to n decompressed bytes without consuming them
 * (n <= 4096).  Returns the count available (less at end of input), -1. */
ssize_t input_peek(struct input *in, const void **p, size_t n, struct err *e);

/* The name for messages: the path, or "<stdin>". */
const char *input_name(const struct input *in);
enum input_codec input_codec(const struct input *in);
/* The path of the underlying file, or NULL for stdin. */
const char *input_path(const struct input *in);
/* Compressed bytes consumed so far (for rate reports). */
unsigned long long input_raw_bytes(const struct input *in);

void input_close(struct input *in);

#endif
