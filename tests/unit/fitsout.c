/*
 * fitsout.c - tests of the FITS writer: cards, a two-HDU file read back
 * with cfitsio, stdout bytes equal to file bytes, atomic commit and abort,
 * compression, and the errors.
 *
 * With arguments it is a helper for tests/t4*-fits*.sh instead:
 *   fitsout write PATH [none|rice|gzip]   write the sample file, exit 2 on
 *                                         error with the message on stderr
 *   fitsout big PATH N                    N full-size 4088 x 4088 images,
 *                                         from one row of memory
 */
#include <dirent.h>
#include <errno.h>
#include <signal.h>
#include <stdint.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fitsio.h>

#include "err.h"
#include "fitsout.h"
#include "tempfile.h"
#include "tap.h"

#define NX1 37
#define NY1 23
#define NX2 50
#define NY2 11

/* Deterministic pixel values with structure, negatives and exact zeros. */
static float pixel(int hdu, int x, int y)
{
	if ((x + y) % 11 == 0)
		return 0.0f;
	return (float)(hdu * 1000 + (x - 10) * 1.25 + y * 0.0625 +
		       ((x * 7 + y * 13) % 17) * 0.37);
}

/* Append one card to a growing card string. */
static void add(char *cards, int *n, const char *card)
{
	memcpy(cards + (size_t)*n * 80, card, 80);
	cards[(size_t)++*n * 80] = 0;
}

/* The sample file: a primary with settings, WFI01 and WFI02, the rows of
 * each written in uneven chunks (1, 2, 3, ... rows per call). */
static int write_sample(const char *path, const char *compress, struct err *e)
{
	char cards[40 * 80 + 1], c[81];
	int n = 0, nx[2] = { NX1, NX2 }, ny[2] = { NY1, NY2 };
	struct fitsout *f = fitsout_open(path, compress, e);

	if (!f)
		return -1;
	fits_card_str(c, "FILTER", "F129", "Roman WFI filter");
	add(cards, &n, c);
	fits_card_dbl(c, "EXPTIME", 139.8, "exposure time [s]");
	add(cards, &n, c);
	fits_card_int(c, "SEED", 1234567890123LL, "random seed");
	add(cards, &n, c);
	fits_card_bool(c, "POISSON", 1, "Poisson noise on");
	add(cards, &n, c);
	fits_card_str(c, "CATALOG", "it's a 'quoted' name", NULL);
	add(cards, &n, c);
	if (fitsout_primary(f, cards, n, e))
		goto fail;
	for (int h = 0; h < 2; h++) {
		char name[16];
		float *img = malloc(sizeof(float) * nx[h] * ny[h]);
		int y = 0, k = 1;

		n = 0;
		snprintf(name, sizeof(name), "WFI%02d", h + 1);
		fits_card_str(c, "EXTNAME", name, "detector");
		add(cards, &n, c);
		fits_card_str(c, "CTYPE1", "RA---TAN", NULL);
		add(cards, &n, c);
		fits_card_dbl(c, "CRVAL1", 250.4235, NULL);
		add(cards, &n, c);
		fits_card_str(c, "BUNIT", "e-/s", NULL);
		add(cards, &n, c);
		for (int yy = 0; yy < ny[h]; yy++)
			for (int x = 0; x < nx[h]; x++)
				img[yy * nx[h] + x] = pixel(h + 1, x, yy);
		if (fitsout_image_begin(f, nx[h], ny[h], cards, n, e)) {
			free(img);
			goto fail;
		}
		while (y < ny[h]) {
			int m = k < ny[h] - y ? k : ny[h] - y;
			if (fitsout_image_rows(f, img + y * nx[h], m, e)) {
				free(img);
				goto fail;
			}
			y += m;
			k++;
		}
		free(img);
		if (fitsout_image_end(f, e))
			goto fail;
	}
	return fitsout_commit(f, e);
fail:
	fitsout_abort(f);
	return -1;
}

/* n full-size SCA images written a row at a time, so that the memory a
 * run needs is the writer's own (the shell test measures it). */
static int write_big(const char *path, int n, struct err *e)
{
	enum { NPIX = 4088 };
	static float row[NPIX];
	struct fitsout *f = fitsout_open(path, NULL, e);
	char c[81];

	if (!f)
		return -1;
	if (fitsout_primary(f, NULL, 0, e))
		goto fail;
	for (int h = 1; h <= n; h++) {
		char name[16];
		snprintf(name, sizeof(name), "WFI%02d", h);
		fits_card_str(c, "EXTNAME", name, NULL);
		if (fitsout_image_begin(f, NPIX, NPIX, c, 1, e))
			goto fail;
		for (int y = 0; y < NPIX; y++) {
			for (int x = 0; x < NPIX; x++)
				row[x] = (float)(h + x * 1e-3 + y);
			if (fitsout_image_rows(f, row, 1, e))
				goto fail;
		}
		if (fitsout_image_end(f, e))
			goto fail;
	}
	return fitsout_commit(f, e);
fail:
	fitsout_abort(f);
	return -1;
}

/* Count the entries of dir other than . and .., and those starting with a
 * dot (temporary files). */
static int count_entries(const char *dir, int *hidden)
{
	DIR *d = opendir(dir);
	struct dirent *de;
	int n = 0;

	*hidden = 0;
	if (!d)
		return -1;
	while ((de = readdir(d))) {
		if (!strcmp(de->d_name, ".") || !strcmp(de->d_name, ".."))
			continue;
		n++;
		if (de->d_name[0] == '.')
			(*hidden)++;
	}
	closedir(d);
	return n;
}

static unsigned char *slurp(const char *path, size_t *len)
{
	FILE *fp = fopen(path, "rb");
	unsigned char *b = NULL;
	long n;

	*len = 0;
	if (!fp)
		return NULL;
	fseek(fp, 0, SEEK_END);
	n = ftell(fp);
	rewind(fp);
	b = malloc(n > 0 ? (size_t)n : 1);
	if (b && fread(b, 1, (size_t)n, fp) == (size_t)n)
		*len = (size_t)n;
	fclose(fp);
	return b;
}

/* Read the sample back with cfitsio; tol is the allowed pixel error. */
static void check_sample(const char *path, double tol, const char *what)
{
	fitsfile *fp;
	int status = 0, nhdu = 0, bitpix = 0, naxis = 0, bool_ = 0;
	char str[FLEN_VALUE];
	double d = 0;
	long long ll = 0;
	long naxes[2];

	fits_open_diskfile(&fp, path, READONLY, &status);
	if (!ok(status == 0, "%s: cfitsio opens it", what))
		return;
	fits_get_num_hdus(fp, &nhdu, &status);
	ok(nhdu == 3, "%s: three HDUs (got %d)", what, nhdu);
	fits_get_img_param(fp, 2, &bitpix, &naxis, naxes, &status);
	ok(status == 0 && naxis == 0, "%s: empty primary", what);
	fits_read_key(fp, TSTRING, "FILTER", str, NULL, &status);
	ok(status == 0 && !strcmp(str, "F129"), "%s: FILTER = F129", what);
	fits_read_key(fp, TDOUBLE, "EXPTIME", &d, NULL, &status);
	ok(status == 0 && d == 139.8, "%s: EXPTIME = 139.8 exactly", what);
	fits_read_key(fp, TLONGLONG, "SEED", &ll, NULL, &status);
	ok(status == 0 && ll == 1234567890123LL, "%s: SEED", what);
	fits_read_key(fp, TLOGICAL, "POISSON", &bool_, NULL, &status);
	ok(status == 0 && bool_ == 1, "%s: POISSON = T", what);
	fits_read_key(fp, TSTRING, "CATALOG", str, NULL, &status);
	ok(status == 0 && !strcmp(str, "it's a 'quoted' name"),
	   "%s: quotes survive: %s", what, str);
	for (int h = 1; h <= 2; h++) {
		int nx = h == 1 ? NX1 : NX2, ny = h == 1 ? NY1 : NY2;
		char name[16];
		float *img = malloc(sizeof(float) * nx * ny);
		double maxerr = 0;
		long fpixel[2] = { 1, 1 };

		snprintf(name, sizeof(name), "WFI%02d", h);
		status = 0;
		fits_movnam_hdu(fp, IMAGE_HDU, name, 0, &status);
		ok(status == 0, "%s: EXTNAME %s found", what, name);
		fits_get_img_param(fp, 2, &bitpix, &naxis, naxes, &status);
		ok(status == 0 && bitpix == FLOAT_IMG && naxis == 2 &&
		   naxes[0] == nx && naxes[1] == ny,
		   "%s: %s is float32 %d x %d (got %d, %d: %ld x %ld)", what,
		   name, nx, ny, bitpix, naxis, naxes[0], naxes[1]);
		fits_read_key(fp, TSTRING, "BUNIT", str, NULL, &status);
		ok(status == 0 && !strcmp(str, "e-/s"), "%s: %s BUNIT", what, name);
		fits_read_pix(fp, TFLOAT, fpixel, (long)nx * ny, NULL, img, NULL,
			      &status);
		for (int y = 0; y < ny; y++)
			for (int x = 0; x < nx; x++) {
				double err = fabs(img[y * nx + x] - pixel(h, x, y));
				if (!(err <= maxerr))
					maxerr = isnan(err) ? INFINITY : err;
			}
		ok(status == 0 && maxerr <= tol,
		   "%s: %s pixels within %g (max error %g)", what, name, tol,
		   maxerr);
		free(img);
	}
	fits_close_file(fp, &status);
}

static void test_cards(void)
{
	char c[81], v[81], cm[81];
	int status;
	static const double vals[] = { 0.1, 1.0 / 3, 1e-300, 1e20, -0.0,
		123456789012345678.0, 2.5e-7, 250.4235, -36.4613, 4088 };

	fits_card_str(c, "FILTER", "F129", "filter");
	ok(strlen(c) == 80 && !strncmp(c, "FILTER  = 'F129    '           / filter", 39),
	   "string card in fixed format: [%s]", c);
	fits_card_int(c, "NAXIS1", 4088, NULL);
	ok(!strncmp(c, "NAXIS1  =                 4088", 30) && c[30] == ' ',
	   "integer right-justified to column 30");
	fits_card_bool(c, "SIMPLE", 1, "x");
	ok(c[29] == 'T' && !strncmp(c + 30, " / x", 4), "logical T at column 30");
	fits_card_bool(c, "NOISE", 0, NULL);
	ok(c[29] == 'F', "logical F");

	for (size_t i = 0; i < sizeof(vals) / sizeof(vals[0]); i++) {
		double back;
		fits_card_dbl(c, "VAL", vals[i], "c");
		status = 0;
		ffpsvc(c, v, cm, &status);
		back = strtod(v, NULL);
		ok(status == 0 && back == vals[i] && strpbrk(v, ".E") &&
		   signbit(back) == signbit(vals[i]),
		   "double %.17g round-trips as '%s'", vals[i], v);
	}
	fits_card_dbl(c, "NAN", NAN, "undefined");
	status = 0;
	ffpsvc(c, v, cm, &status);
	ok(status == 0 && v[0] == 0 && !strcmp(cm, "undefined"),
	   "NaN becomes an undefined value");

	{
		char longv[200];
		memset(longv, 'x', sizeof(longv));
		longv[199] = 0;
		longv[65] = '\'';
		fits_card_str(c, "LONG", longv, "this comment goes first");
		status = 0;
		ok(strlen(c) == 80 && c[79] == '\'' && !ffpsvc(c, v, cm, &status),
		   "long string truncated to a well-formed card");
		ok(!strstr(c, "comment"), "the comment is dropped before the value");
	}
	{
		/* A quote pair must not be split by truncation. */
		char q[100];
		memset(q, '\'', sizeof(q));
		q[99] = 0;
		fits_card_str(c, "QUOTES", q, NULL);
		status = 0;
		ok(strlen(c) == 80 && !ffpsvc(c, v, cm, &status),
		   "a string of quotes truncates cleanly (status %d)", status);
	}
	fits_card_str(c, "CTRL", "a\tb\n", NULL);
	ok(!strchr(c, '\t') && !strchr(c, '\n'), "control characters replaced");
	fits_card_dbl(c, "DESCRIPTION", 1.5, "long key");
	status = 0;
	ok(!strncmp(c, "HIERARCH DESCRIPTION = ", 23) && strlen(c) == 80,
	   "keywords over 8 characters use HIERARCH: [%.40s]", c);
	fits_card_str(c, "COMMENTED", "v",
		      "a very long comment that will not fit in the card at all, "
		      "no way, not even close");
	ok(strlen(c) == 80, "long comment cut at 80 characters");
}

static void test_file(const char *dir)
{
	char path[4096];
	struct err e = { 0 };
	size_t len;
	unsigned char *b;
	int hidden;

	snprintf(path, sizeof(path), "%s/two.fits", dir);
	ok(write_sample(path, NULL, &e) == 0, "write a two-HDU file: %s", e.msg);
	check_sample(path, 0, "plain");
	b = slurp(path, &len);
	ok(b && len % 2880 == 0 && len > 0, "size %zu is whole 2880-byte blocks",
	   len);
	ok(b && !memcmp(b, "SIMPLE  =                    T", 30),
	   "starts with SIMPLE = T");
	free(b);
	ok(count_entries(dir, &hidden) == 1 && hidden == 0,
	   "only the file is left in the directory");

	/* Overwriting an existing file replaces it atomically. */
	err_clear(&e);
	ok(write_sample(path, NULL, &e) == 0, "overwrite: %s", e.msg);
	ok(count_entries(dir, &hidden) == 1 && hidden == 0,
	   "still one file after an overwrite");
	unlink(path);
}

/* The same file written to a pipe from "-" is byte-for-byte the file. */
static void test_stdout(const char *dir)
{
	char path[4096];
	struct err e = { 0 };
	int pfd[2];
	pid_t pid;
	size_t flen, slen = 0, cap = 1 << 16;
	unsigned char *fb, *sb = malloc(cap);
	ssize_t r;
	int st;

	snprintf(path, sizeof(path), "%s/file.fits", dir);
	write_sample(path, NULL, &e);
	fb = slurp(path, &flen);
	if (pipe(pfd))
		return;
	fflush(stdout);
	pid = fork();
	if (pid == 0) {
		struct err ce = { 0 };
		dup2(pfd[1], STDOUT_FILENO);
		close(pfd[0]);
		close(pfd[1]);
		_exit(write_sample("-", NULL, &ce) ? 1 : 0);
	}
	close(pfd[1]);
	while ((r = read(pfd[0], sb + slen, cap - slen)) > 0) {
		slen += (size_t)r;
		if (slen == cap)
			sb = realloc(sb, cap *= 2);
	}
	close(pfd[0]);
	waitpid(pid, &st, 0);
	ok(WIFEXITED(st) && WEXITSTATUS(st) == 0, "writing to a pipe succeeds");
	ok(fb && slen == flen && !memcmp(fb, sb, flen),
	   "stdout bytes equal file bytes (%zu and %zu)", slen, flen);
	free(fb);
	free(sb);
	unlink(path);

	/* Compression cannot stream. */
	err_clear(&e);
	ok(!fitsout_open("-", "rice", &e) && strstr(e.msg, "<stdout>") &&
	   strstr(e.msg, "compression"), "compressing to stdout is refused: %s",
	   e.msg);
}

static void test_abort(const char *dir)
{
	char path[4096], c[81];
	struct err e = { 0 };
	struct fitsout *f;
	float row[10] = { 0 };
	int hidden, n;

	snprintf(path, sizeof(path), "%s/aborted.fits", dir);
	f = fitsout_open(path, NULL, &e);
	ok(f != NULL, "open");
	fits_card_str(c, "EXTNAME", "WFI01", NULL);
	fitsout_primary(f, NULL, 0, &e);
	fitsout_image_begin(f, 10, 5, c, 1, &e);
	fitsout_image_rows(f, row, 1, &e);
	n = count_entries(dir, &hidden);
	ok(n == 1 && hidden == 1 && access(path, F_OK) != 0,
	   "while writing, only a hidden temporary file exists");
	fitsout_abort(f);
	ok(count_entries(dir, &hidden) == 0, "abort leaves nothing");
	fitsout_abort(NULL);
	ok(1, "fitsout_abort(NULL) is a no-op");

	/* Committing an unfinished image fails and leaves nothing. */
	err_clear(&e);
	f = fitsout_open(path, NULL, &e);
	fitsout_image_begin(f, 10, 5, c, 1, &e);
	fitsout_image_rows(f, row, 1, &e);
	ok(fitsout_commit(f, &e) == -1 && strstr(e.msg, "WFI01") &&
	   strstr(e.msg, "1 of 5 rows"), "unfinished image: %s", e.msg);
	ok(count_entries(dir, &hidden) == 0, "failed commit leaves nothing");

	/* Too many rows is an error, as is ending early. */
	err_clear(&e);
	f = fitsout_open(path, NULL, &e);
	fitsout_image_begin(f, 10, 1, c, 1, &e);
	ok(fitsout_image_rows(f, row, 2, &e) == -1 && strstr(e.msg, "WFI01"),
	   "too many rows: %s", e.msg);
	err_clear(&e);
	ok(fitsout_image_end(f, &e) == -1 && strstr(e.msg, "0 of 1 rows"),
	   "ending early: %s", e.msg);
	fitsout_abort(f);

	/* The signal path: the one policy (tempfile_signals) removes every
	 * live temporary file and exits 4. */
	fflush(stdout);
	if (fork() == 0) {
		struct err ce = { 0 };
		struct fitsout *a, *b;
		char p2[4096];
		snprintf(p2, sizeof(p2), "%s/second.fits", dir);
		tempfile_signals("fitsout test");
		a = fitsout_open(path, NULL, &ce);
		b = fitsout_open(p2, "gzip", &ce);
		fitsout_primary(a, NULL, 0, &ce);
		fitsout_primary(b, NULL, 0, &ce);
		if (!a || !b || ce.code || count_entries(dir, &hidden) != 2 || hidden != 2)
			_exit(1);
		if (!freopen("/dev/null", "w", stderr))
			_exit(1);
		raise(SIGTERM);
		_exit(1);
	}
	wait(&n);
	ok(WIFEXITED(n) && WEXITSTATUS(n) == EXIT_SIGNAL &&
	   count_entries(dir, &hidden) == 0,
	   "SIGTERM removes both temporary files and exits 4 (status %d)",
	   WIFEXITED(n) ? WEXITSTATUS(n) : -1);
}

static void test_compress(const char *dir)
{
	char path[4096];
	struct err e = { 0 };
	size_t plain_len, len;
	unsigned char *b;
	int hidden;

	snprintf(path, sizeof(path), "%s/plain.fits", dir);
	write_sample(path, NULL, &e);
	free(slurp(path, &plain_len));
	unlink(path);

	snprintf(path, sizeof(path), "%s/gzip.fits", dir);
	ok(write_sample(path, "gzip", &e) == 0, "gzip-compressed file: %s", e.msg);
	check_sample(path, 0, "gzip");
	b = slurp(path, &len);
	ok(b && len % 2880 == 0 && strstr((char *)b, "GZIP_2") &&
	   strstr((char *)b, "ZQUANTIZ= 'NONE"),
	   "gzip is lossless GZIP_2 tiles");
	free(b);
	unlink(path);

	/* Rice quantizes floats in steps of a quarter of the noise cfitsio
	 * measures in each tile (from pixel-to-pixel differences).  The
	 * sample's pixel-to-pixel scatter is about 1.5, so steps are about
	 * 0.37 and errors at most half a step: under 0.25. */
	snprintf(path, sizeof(path), "%s/rice.fits", dir);
	err_clear(&e);
	ok(write_sample(path, "rice", &e) == 0, "rice-compressed file: %s", e.msg);
	check_sample(path, 0.25, "rice");
	{
		size_t len2;
		unsigned char *b2;
		char p2[4096];
		b = slurp(path, &len);
		snprintf(p2, sizeof(p2), "%s/rice2.fits", dir);
		write_sample(p2, "rice", &e);
		b2 = slurp(p2, &len2);
		ok(b && b2 && len == len2 && !memcmp(b, b2, len),
		   "rice output is the same from run to run (fixed dither seed)");
		free(b);
		free(b2);
		unlink(p2);
	}
	unlink(path);
	ok(count_entries(dir, &hidden) == 0, "no temporary files left");

	err_clear(&e);
	ok(!fitsout_open(path, "lzma", &e) && strstr(e.msg, "'lzma'"),
	   "unknown compression: %s", e.msg);
}

static void test_errors(const char *dir)
{
	char path[4096], cards[3 * 80 + 1], c[81];
	struct err e = { 0 };
	struct fitsout *f;
	int hidden;

	snprintf(path, sizeof(path), "%s/nodir/x.fits", dir);
	ok(!fitsout_open(path, NULL, &e) && strstr(e.msg, path) &&
	   strstr(e.msg, "No such file"), "missing directory: %s", e.msg);

	/* An unwritable directory.  root writes anywhere it has a mode bit,
	 * so as root use sysfs, where even root cannot create files. */
	snprintf(path, sizeof(path), "%s/ro", dir);
	mkdir(path, 0555);
	if (access(path, W_OK) == 0)
		snprintf(path, sizeof(path), "/sys/wfs-test.fits");
	else
		snprintf(path, sizeof(path), "%s/ro/x.fits", dir);
	err_clear(&e);
	f = fitsout_open(path, NULL, &e);
	ok(!f && strstr(e.msg, path) && strstr(e.msg, "Permission denied"),
	   "unwritable directory: %s", e.msg);
	if (f)
		fitsout_abort(f);
	snprintf(path, sizeof(path), "%s/ro", dir);
	rmdir(path);

	err_clear(&e);
	ok(!fitsout_open(dir, NULL, &e) && strstr(e.msg, "is a directory"),
	   "a directory: %s", e.msg);

	/* /dev/null is written in place, never replaced by a renamed file. */
	{
		struct stat st;
		err_clear(&e);
		ok(write_sample("/dev/null", NULL, &e) == 0 &&
		   stat("/dev/null", &st) == 0 && S_ISCHR(st.st_mode),
		   "/dev/null stays a device: %s", e.msg);
	}

	/* A full device: the error names it and says why. */
	err_clear(&e);
	if (access("/dev/full", W_OK) == 0)
		ok(write_sample("/dev/full", NULL, &e) == -1 &&
		   strstr(e.msg, "/dev/full") &&
		   strstr(e.msg, "No space left on device"),
		   "writing to /dev/full: %s", e.msg);

	/* A reader that went away: EPIPE is an error, not silence (with
	 * SIGPIPE ignored, as a program may do).  The read end is closed
	 * before the writer starts, so no write can land in the pipe's
	 * buffer first (the test was flaky when the writer won that race). */
	{
		int pfd[2], st;
		fflush(stdout);
		if (pipe(pfd) == 0 && close(pfd[0]) == 0 && fork() == 0) {
			struct err ce = { 0 };
			signal(SIGPIPE, SIG_IGN);
			dup2(pfd[1], STDOUT_FILENO);
			close(pfd[1]);
			if (write_sample("-", NULL, &ce) == 0)
				_exit(1);
			_exit(strstr(ce.msg, "<stdout>") &&
			      strstr(ce.msg, "Broken pipe") ? 0 : 2);
		}
		close(pfd[1]);
		wait(&st);
		ok(WIFEXITED(st) && WEXITSTATUS(st) == 0,
		   "a closed pipe is reported as '<stdout>: ... Broken pipe'");
	}

	snprintf(path, sizeof(path), "%s/bad.fits", dir);
	err_clear(&e);
	f = fitsout_open(path, NULL, &e);
	fits_card_int(c, "NAXIS1", 5, NULL);
	memcpy(cards, c, 81);
	ok(fitsout_primary(f, cards, 1, &e) == -1 && strstr(e.msg, "NAXIS1"),
	   "structural keyword refused: %s", e.msg);
	fitsout_abort(f);

	err_clear(&e);
	f = fitsout_open(path, NULL, &e);
	memset(cards, ' ', 80);
	memcpy(cards, "OBJECT  = 'open quote", 21);
	cards[80] = 0;
	ok(fitsout_primary(f, cards, 1, &e) == -1 && strstr(e.msg, "OBJECT"),
	   "unterminated string refused: %s", e.msg);
	fitsout_abort(f);

	err_clear(&e);
	f = fitsout_open(path, NULL, &e);
	fits_card_str(c, "OBJECT", "x", NULL);
	c[15] = (char)0xe9;
	ok(fitsout_primary(f, c, 1, &e) == -1 && strstr(e.msg, "0xe9"),
	   "non-ASCII refused: %s", e.msg);
	fitsout_abort(f);

	err_clear(&e);
	f = fitsout_open(path, NULL, &e);
	ok(fitsout_primary(f, "SHORT   = 1", 1, &e) == -1 &&
	   strstr(e.msg, "80 characters"), "short card refused: %s", e.msg);
	fitsout_abort(f);

	/* An empty run still makes a valid file: just the primary. */
	err_clear(&e);
	f = fitsout_open(path, NULL, &e);
	ok(fitsout_commit(f, &e) == 0, "empty commit");
	{
		size_t len;
		unsigned char *b = slurp(path, &len);
		ok(b && len == 2880 && strstr((char *)b, "END     "),
		   "an empty file is one header block");
		free(b);
	}
	unlink(path);
	ok(count_entries(dir, &hidden) == 0, "nothing left behind");
}

int main(int argc, char **argv)
{
	char dir[] = "/tmp/wfs-fitsout.XXXXXX";

	if (argc == 4 && !strcmp(argv[1], "big")) {
		struct err e = { 0 };
		if (write_big(argv[2], atoi(argv[3]), &e)) {
			fprintf(stderr, "fitsout: %s\n", e.msg);
			return e.code ? e.code : 2;
		}
		return 0;
	}
	if (argc >= 3 && !strcmp(argv[1], "write")) {
		struct err e = { 0 };
		if (write_sample(argv[2], argc > 3 ? argv[3] : NULL, &e)) {
			fprintf(stderr, "fitsout: %s\n", e.msg);
			return e.code ? e.code : 2;
		}
		return 0;
	}
	if (!mkdtemp(dir))
		skip_all("cannot make a temporary directory");
	test_cards();
	test_file(dir);
	test_stdout(dir);
	test_abort(dir);
	test_compress(dir);
	test_errors(dir);
	rmdir(dir);
	return done_testing();
}
