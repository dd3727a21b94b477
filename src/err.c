/* err.c - error messages as values; see err.h. */
#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include <fitsio.h>

#include "err.h"

static void vset(struct err *e, int code, const char *fmt, va_list ap)
{
	if (!e || e->code != EXIT_OK)
		return;
	e->code = code;
	vsnprintf(e->msg, sizeof(e->msg), fmt, ap);
}

int err_set(struct err *e, int code, const char *fmt, ...)
{
	va_list ap;

	va_start(ap, fmt);
	vset(e, code, fmt, ap);
	va_end(ap);
	return -1;
}

int err_sys(struct err *e, const char *fmt, ...)
{
	int saved = errno;
	va_list ap;
	size_t len;

	if (!e || e->code != EXIT_OK)
		return -1;
	va_start(ap, fmt);
	vset(e, EXIT_SYSTEM, fmt, ap);
	va_end(ap);
	len = strlen(e->msg);
	snprintf(e->msg + len, sizeof(e->msg) - len, ": %s", strerror(saved));
	return -1;
}

int err_fits(struct err *e, int status, const char *fmt, ...)
{
	char text[FLEN_STATUS], line[FLEN_ERRMSG], first[2 * FLEN_ERRMSG] = "";
	va_list ap;
	size_t len;
	int more = 0;

	/* Drain cfitsio's message stack; its first line names the cause.  A
	 * first line that ends in a colon ("... from file:") goes on in the
	 * next (the file's name), which is joined to it; with none the colon
	 * is dropped, so no message ends in one. */
	while (fits_read_errmsg(line)) {
		len = strlen(first);
		if (!len) {
			snprintf(first, sizeof(first), "%s", line);
			len = strlen(first);
			while (len && first[len - 1] == ' ')
				first[--len] = 0;
			more = len && first[len - 1] == ':';
		} else if (more) {
			const char *t = line + strspn(line, " ");

			/* a blank line is passed over: the subject may follow */
			if (*t) {
				snprintf(first + len, sizeof(first) - len, " %s", t);
				more = 0;
			}
		}
	}
	len = strlen(first);
	if (more && len)
		first[len - 1] = 0;
	fits_get_errstatus(status, text);
	if (!e || e->code != EXIT_OK)
		return -1;
	va_start(ap, fmt);
	vset(e, EXIT_SYSTEM, fmt, ap);
	va_end(ap);
	len = strlen(e->msg);
	snprintf(e->msg + len, sizeof(e->msg) - len, ": %s%s%s", text,
		 first[0] ? ": " : "", first);
	return -1;
}

void err_prefix(struct err *e, const char *fmt, ...)
{
	char pre[512], old[sizeof(e->msg) - sizeof(pre) - 2];
	va_list ap;

	if (!e || e->code == EXIT_OK)
		return;
	va_start(ap, fmt);
	vsnprintf(pre, sizeof(pre), fmt, ap);
	va_end(ap);
	memcpy(old, e->msg, sizeof(old) - 1);
	old[sizeof(old) - 1] = 0;
	snprintf(e->msg, sizeof(e->msg), "%s: %s", pre, old);
}

void err_clear(struct err *e)
{
	e->code = EXIT_OK;
	e->msg[0] = 0;
}
