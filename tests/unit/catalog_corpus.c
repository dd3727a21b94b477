/*
 * catalog_corpus.c - replay the fuzz corpus (tests/fuzz/corpus: the seeds
 * and any input that once crashed the fuzzer) through catalog reading:
 * every input must read or fail with a message, never crash.  Run from the
 * top of the tree, as make check runs it.
 */
#include <dirent.h>
#include <stdio.h>
#include <string.h>

#include "catalog.h"
#include "err.h"
#include "instrument.h"
#include "tap.h"

int main(void)
{
	const char *dirname = "tests/fuzz/corpus";
	DIR *d = opendir(dirname);
	struct dirent *de;
	int n = 0;

	if (!d)
		skip_all("tests/fuzz/corpus not found (run from the top of the tree)");
	while ((de = readdir(d))) {
		char path[1024];
		struct catalog_opts o = { .filter = F129, .chunk_rows = 3 };
		struct catalog *c;
		struct rows r;
		struct err e = { 0 };
		long k = 0, rows = 0;

		if (de->d_name[0] == '.')
			continue;
		snprintf(path, sizeof(path), "%s/%s", dirname, de->d_name);
		c = catalog_open(path, &o, &e);
		while (c && (k = catalog_read(c, &r, &e)) > 0)
			rows += k;
		catalog_close(c);
		ok((c && k == 0) || (e.code != EXIT_OK && e.msg[0]),
		   "%s: %s", de->d_name, c && k == 0 ? "read" : e.msg);
		(void)rows;
		n++;
	}
	closedir(d);
	ok(n > 0, "%d corpus files", n);
	return done_testing();
}
