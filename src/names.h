/*
 * names.h - file names from the templates users give.
 *
 * Every option that names files by SCA or by exposure (-o, --placed,
 * --report, --psf, `wfiscene psf -o`, `preview -o`, `merge -o`) is a
 * template with three escapes and no others:
 *
 *   %d   the SCA number; a width and a 0 flag as in printf ("%02d": 07)
 *   %s   the exposure's name (--pointings)
 *   %%   a '%'
 *
 * A template is checked once, when the options are read, and expanded per
 * file by the one function below.  It is never a printf format: anything
 * else after a '%' (%n, %p, %x, %5s, a '%' at the end) is refused with a
 * message naming the option (exit 1).
 */
#ifndef WFS_NAMES_H
#define WFS_NAMES_H

#include <stddef.h>

#include "err.h"

/* What a template may, or must, hold. */
enum name_field {
	NAME_SCA = 1,           /* %d */
	NAME_EXPOSURE = 2,      /* %s */
	/* not a field: %s is refused only because --pointings is absent
	 * (the message says so) */
	NAME_NEEDS_POINTINGS = 4,
};

/* The widest %d: "%099d" would only make unwieldy names. */
#define NAME_WIDTH_MAX 16

/*
 * Check template tmpl of option `what` (as the message names it, e.g.
 * "--placed"): only the escapes above, at most one %d and one %s, none of
 * the fields outside `allow`, each field in `need` present.  Returns 0, or
 * -1 with a message naming the option, the template and what is wrong
 * (exit 1).
 */
int name_check(const char *what, const char *tmpl, unsigned allow, unsigned need,
	       struct err *e);

/* The fields (enum name_field) tmpl holds; 0 for a template name_check
 * would refuse. */
unsigned name_fields(const char *tmpl);

/*
 * Expand tmpl into out (cap bytes): %d becomes sca, %s becomes expo (NULL
 * is refused if the template holds %s), %% a '%'.  Checks as name_check()
 * with every field allowed, so a template never checked is still never
 * misread.  Returns 0, or -1 with a message naming `what` (exit 1), also
 * when the name would not fit in cap bytes.
 */
int name_expand(char *out, size_t cap, const char *what, const char *tmpl, int sca,
		const char *expo, struct err *e);

#endif
