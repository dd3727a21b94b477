/*
 * err.h - errors as values.
 *
 * Functions return 0 (or a pointer) on success and -1 (or NULL) on failure,
 * leaving a message in a struct err that the caller passed in.  Only main()
 * prints it and exits.  Messages name the place first and quote the subject:
 *
 *   stars.csv:1234: column 'flux': not a number: 'abc'
 *
 * and carry the exit status the failure deserves (see enum wfs_exit).
 */
#ifndef WFS_ERR_H
#define WFS_ERR_H

#include <stddef.h>

/* Exit statuses, documented in wfiscene(1). */
enum wfs_exit {
	EXIT_OK = 0,
	EXIT_INPUT = 1,         /* usage, bad catalog, bad option value */
	EXIT_SYSTEM = 2,        /* I/O, memory, disk full, FITS library */
	EXIT_PLUGIN = 3,        /* a model plugin failed to load or render */
	EXIT_SIGNAL = 4,        /* interrupted by SIGINT or SIGTERM */
};

struct err {
	int code;               /* enum wfs_exit, EXIT_OK when no error */
	char msg[2048];
};

/* Record a message with exit status code.  Returns -1.  If an error is
 * already recorded, the first one is kept (it is the cause). */
int err_set(struct err *e, int code, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

/* Like err_set with ": strerror(errno)" appended. */
int err_sys(struct err *e, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));

/* Record the pending cfitsio error for status (draining cfitsio's message
 * stack) as "prefix: cfitsio message".  Returns -1. */
int err_fits(struct err *e, int status, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

/* Put "prefix: " in front of the recorded message. */
void err_prefix(struct err *e, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));

void err_clear(struct err *e);

#endif
