/*
 * input_stream.c - the decompressing reader: codecs by magic number, peek,
 * pipes that deliver a byte at a time, and every truncation of a zstd or
 * gzip stream reported as an error, never as a shorter input.
 */
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "err.h"
#include "input.h"
#include "tap.h"

static char dir[] = "/tmp/wfs-input-XXXXXX";

static char *fpath(const char *name)
{
	static char p[4][512];
	static int k;

	k = (k + 1) % 4;
	snprintf(p[k], sizeof(p[k]), "%s/%s", dir, name);
	return p[k];
}

static unsigned char *slurp(const char *path, size_t *len)
{
	FILE *f = fopen(path, "rb");
	unsigned char *b;
	long n;

	if (!f)
		return NULL;
	fseek(f, 0, SEEK_END);
	n = ftell(f);
	fseek(f, 0, SEEK_SET);
	b = malloc((size_t)n + 1);
	if (fread(b, 1, (size_t)n, f) != (size_t)n)
		n = 0;
	fclose(f);
	*len = (size_t)n;
	return b;
}

static void spit(const char *path, const void *b, size_t n)
{
	FILE *f = fopen(path, "wb");

	if (fwrite(b, 1, n, f) != n)
		exit(2);
	fclose(f);
}

/* Read all of path through input.h in reads of step bytes.  Returns the
 * byte count or -1; *out receives the data. */
static long read_all(const char *path, size_t step, unsigned char **out,
		     struct err *e)
{
	struct input *in;
	size_t cap = 1 << 16, len = 0;
	unsigned char *b = malloc(cap);
	ssize_t r;

	err_clear(e);
	in = input_open(path, e);
	if (!in) {
		free(b);
		return -1;
	}
	for (;;) {
		if (len + step > cap)
			b = realloc(b, cap *= 2);
		r = input_read(in, b + len, step, e);
		if (r <= 0)
			break;
		len += (size_t)r;
	}
	input_close(in);
	if (r < 0) {
		free(b);
		return -1;
	}
	if (out)
		*out = b;
	else
		free(b);
	return (long)len;
}

static void test_codecs(const unsigned char *plain, size_t plen)
{
	static const char *names[] = { "p.txt", "p.txt.zst", "p.txt.gz", "pp.zst", "pp.gz" };
	static const int codec[] = { INPUT_PLAIN, INPUT_ZSTD, INPUT_GZIP, INPUT_ZSTD, INPUT_GZIP };
	struct err e;

	for (int i = 0; i < 5; i++) {
		unsigned char *got = NULL;
		size_t want = i >= 3 ? 2 * plen : plen;
		long n = read_all(fpath(names[i]), i % 2 ? 1000 : 65536, &got, &e);
		struct input *in = input_open(fpath(names[i]), &e);

		ok(n == (long)want && memcmp(got, plain, plen) == 0 &&
		   (i < 3 || memcmp(got + plen, plain, plen) == 0),
		   "%s: %ld bytes, as written (%s)", names[i], n, e.msg);
		ok(in && (int)input_codec(in) == codec[i], "%s: codec by magic", names[i]);
		if (in) {
			const void *p;
			char b[5];
			ssize_t k = input_peek(in, &p, 5, &e);

			ok(k == 5 && memcmp(p, plain, 5) == 0 &&
			   input_read(in, b, 5, &e) == 5 && memcmp(b, plain, 5) == 0,
			   "%s: peek then read give the first bytes", names[i]);
		}
		input_close(in);
		free(got);
	}
}

static void test_truncation(const char *name, const char *what)
{
	unsigned char *z;
	size_t zlen;
	int all = 1;
	struct err e;

	z = slurp(fpath(name), &zlen);
	/* Every proper prefix past the magic number must be an error. */
	for (size_t k = 4; k < zlen; k += 1 + k / 64) {
		spit(fpath("cut"), z, k);
		if (read_all(fpath("cut"), 4096, NULL, &e) >= 0 ||
		    !strstr(e.msg, what) || e.code != EXIT_INPUT) {
			all = 0;
			diag("prefix %zu of %zu: '%s'", k, zlen, e.msg);
			break;
		}
	}
	ok(all, "%s: every truncation is '%s'", name, what);
	/* Trailing garbage after a complete stream is corrupt, not ignored. */
	z = realloc(z, zlen + 16);
	memcpy(z + zlen, "garbage garbage!", 16);
	spit(fpath("cut"), z, zlen + 16);
	ok(read_all(fpath("cut"), 4096, NULL, &e) < 0 && strstr(e.msg, "corrupt"),
	   "%s: trailing garbage is an error: %s", name, e.msg);
	free(z);
}

/* A writer that delivers the file a few bytes at a time into a pipe. */
static void test_pipe(const char *name, size_t want)
{
	int fd[2], saved;
	pid_t pid;
	struct err e;
	long n;

	if (pipe(fd) < 0)
		return;
	pid = fork();
	if (pid == 0) {
		size_t len;
		unsigned char *b = slurp(fpath(name), &len);

		close(fd[0]);
		for (size_t i = 0; i < len; i += 3) {
			if (write(fd[1], b + i, len - i < 3 ? len - i : 3) < 0)
				_exit(1);
			if (i < 64)
				usleep(1000);
		}
		_exit(0);
	}
	close(fd[1]);
	saved = dup(0);
	dup2(fd[0], 0);
	close(fd[0]);
	n = read_all("-", 777, NULL, &e);
	dup2(saved, 0);
	close(saved);
	waitpid(pid, NULL, 0);
	ok(n == (long)want, "%s through a slow pipe on stdin: %ld bytes (%s)", name, n, e.msg);
}

int main(void)
{
	char cmd[1024];
	unsigned char *plain;
	size_t plen;
	FILE *f;
	struct err e;

	signal(SIGPIPE, SIG_IGN);
	if (!mkdtemp(dir))
		skip_all("no temporary directory");
	f = fopen(fpath("p.txt"), "w");
	for (int i = 0; i < 30000; i++)
		fprintf(f, "%d,%d.%03d,%x\n", i, i * 7, i % 1000, i * 2654435761u);
	fclose(f);
	plain = slurp(fpath("p.txt"), &plen);
	snprintf(cmd, sizeof(cmd),
		 "cd %s && zstd -q -f p.txt && gzip -k -f p.txt && cat p.txt.zst p.txt.zst > pp.zst"
		 " && cat p.txt.gz p.txt.gz > pp.gz", dir);
	if (system(cmd) != 0)
		skip_all("zstd or gzip is missing");
	test_codecs(plain, plen);
	test_truncation("p.txt.zst", "truncated zstd stream");
	test_truncation("p.txt.gz", "truncated gzip stream");
	test_pipe("p.txt.zst", plen);
	test_pipe("p.txt.gz", plen);
	test_pipe("p.txt", plen);

	spit(fpath("empty"), "", 0);
	ok(read_all(fpath("empty"), 10, NULL, &e) == 0, "an empty file is empty input");
	spit(fpath("one"), "\x28", 1);
	ok(read_all(fpath("one"), 10, NULL, &e) == 1, "a 1-byte file is plain");
	spit(fpath("magic"), "\x28\xb5\x2f\xfd", 4);
	ok(read_all(fpath("magic"), 10, NULL, &e) < 0 && strstr(e.msg, "zstd"),
	   "zstd magic alone: %s", e.msg);
	err_clear(&e);
	ok(input_open(fpath("nosuch"), &e) == NULL && e.code == EXIT_SYSTEM &&
	   strstr(e.msg, "nosuch: cannot open"), "a missing file: %s", e.msg);
	free(plain);
	snprintf(cmd, sizeof(cmd), "rm -rf %s", dir);
	if (system(cmd) != 0)
		diag("could not remove %s", dir);
	return done_testing();
}
