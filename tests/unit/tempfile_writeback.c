/*
 * tempfile_writeback.c - the writing back an output's writers ask for as
 * they go: whole pages from lo's up to (not including) hi's, the offset
 * returned, nothing asked for within one page or on a bad descriptor, and
 * the file's bytes untouched.
 */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE     /* SYNC_FILE_RANGE_WRITE, as tempfile.c sees it */
#endif
#include <fcntl.h>
#include <string.h>
#include <unistd.h>

#include "err.h"
#include "tap.h"
#include "tempfile.h"

int main(void)
{
	struct err e = { 0 };
	long page = sysconf(_SC_PAGESIZE) > 0 ? sysconf(_SC_PAGESIZE) : 4096;
	long long n = 3 * (long long)page + 100;
	unsigned char *a = malloc((size_t)n), *b = malloc((size_t)n);
	int fd = tempfile_unnamed("tempfile_writeback", &e);

	if (fd < 0 || !a || !b)
		skip_all("no temporary file or memory");
	for (long long i = 0; i < n; i++)
		a[i] = (unsigned char)(i * 7 + 3);
	ok(write(fd, a, (size_t)n) == n, "the file written");
#ifdef SYNC_FILE_RANGE_WRITE
	ok(tempfile_writeback(fd, 0, n) == 3 * page, "0 to %lld: asked up to the last page's start",
	   n);
	ok(tempfile_writeback(fd, 100, 2 * page) == 2 * page,
	   "from inside the first page: from its start, up to 2 pages");
	ok(tempfile_writeback(fd, 2 * page + 5, 2 * page + 900) == 2 * page + 5,
	   "within one page: nothing, lo back");
	ok(tempfile_writeback(fd, 3 * page, n) == 3 * page, "the last, partial page: nothing");
#else
	ok(tempfile_writeback(fd, 0, n) == 0, "no sync_file_range here: nothing, lo back");
#endif
	ok(tempfile_writeback(-1, 0, n) == 0, "a bad descriptor: nothing");
	ok(tempfile_writeback(fd, -1, n) == -1, "a negative lo: nothing");
	ok(tempfile_writeback(fd, n, 0) == n, "hi before lo: nothing");
	ok(pread(fd, b, (size_t)n, 0) == n && !memcmp(a, b, (size_t)n), "the bytes unchanged");
	close(fd);
	free(a);
	free(b);
	return done_testing();
}
