/*
 * names.c - file-name templates: %d, %s and %% expand, nothing else is
 * read, and whatever a hostile template holds ends in a message.
 */
#include <string.h>

#include "err.h"
#include "names.h"
#include "tap.h"

/* Expand and compare; "" as want means "must be refused" and then msg must
 * appear in the message. */
static void expands(const char *tmpl, int sca, const char *expo, const char *want,
		    const char *msg)
{
	struct err e = { 0 };
	char out[64];
	int rc = name_expand(out, sizeof(out), "-o", tmpl, sca, expo, &e);

	if (*want)
		ok(rc == 0 && !strcmp(out, want), "'%s' (SCA %d, '%s') -> '%s' (got '%s' %s)", tmpl,
		   sca, expo ? expo : "", want, rc ? "" : out, e.msg);
	else
		ok(rc < 0 && e.code == EXIT_INPUT && strstr(e.msg, msg) && strstr(e.msg, "-o: "),
		   "'%s' refused: %s", tmpl, e.msg);
}

static void checks(const char *tmpl, unsigned allow, unsigned need, const char *msg)
{
	struct err e = { 0 };
	int rc = name_check("--placed", tmpl, allow, need, &e);

	if (!msg)
		ok(rc == 0, "'%s' accepted (%s)", tmpl, e.msg);
	else
		ok(rc < 0 && e.code == EXIT_INPUT && strstr(e.msg, msg) &&
		   !strncmp(e.msg, "--placed: ", 10), "'%s' refused: %s", tmpl, e.msg);
}

int main(void)
{
	expands("plain.fits", 3, NULL, "plain.fits", NULL);
	expands("sca%d.fits", 3, NULL, "sca3.fits", NULL);
	expands("sca%02d.fits", 3, NULL, "sca03.fits", NULL);
	expands("sca%3d.fits", 3, NULL, "sca  3.fits", NULL);
	expands("sca%002d.fits", 12, NULL, "sca12.fits", NULL);
	expands("%s_%02d.fits", 18, "dither-1", "dither-1_18.fits", NULL);
	expands("100%%_%d", 5, NULL, "100%_5", NULL);
	expands("%%d%%s%%", 5, NULL, "%d%s%", NULL);
	expands("%d", 18, NULL, "18", NULL);
	/* refused: every other escape, a lone '%', widths beyond 16 */
	expands("%s%n%p", 1, "x", "", "'%n' is not a field");
	expands("%n", 1, NULL, "", "'%n' is not a field");
	expands("%p.fits", 1, NULL, "", "'%p' is not a field");
	expands("%x", 1, NULL, "", "'%x'");
	expands("%5s", 1, "x", "", "'%5s'");
	expands("%-3d", 1, NULL, "", "'%-3d'");
	expands("%ld", 1, NULL, "", "'%l'");
	expands("%.3d", 1, NULL, "", "'%.3d'");
	expands("a%", 1, NULL, "", "'%' is not a field");
	expands("%*d", 1, NULL, "", "'%*d'");
	expands("%17d", 1, NULL, "", "at most 16 wide");
	expands("%99999999999999999999d", 1, NULL, "", "at most 16 wide");
	expands("%d%d", 1, NULL, "", "only one");
	expands("%s%s", 1, "a", "", "only one");
	expands("%s.fits", 1, NULL, "", "needs --pointings");
	/* too long for the buffer, by one */
	{
		char big[80];

		memset(big, 'a', 63);
		big[63] = 0;
		expands(big, 1, NULL, big, NULL);
		big[63] = 'a';
		big[64] = 0;
		expands(big, 1, NULL, "", "longer than 63 bytes");
		memset(big, 'a', 62);
		strcpy(big + 62, "%d");
		expands(big, 12, NULL, "", "longer than 63 bytes");
	}
	/* what each option allows and needs */
	checks("out.csv", NAME_EXPOSURE, 0, NULL);
	checks("out_%s.csv", NAME_EXPOSURE, NAME_EXPOSURE, NULL);
	checks("out.csv", NAME_EXPOSURE, NAME_EXPOSURE, "needs a '%s'");
	checks("out_%d.csv", NAME_EXPOSURE, 0, "one file covers every SCA");
	checks("out_%s.csv", NAME_SCA | NAME_NEEDS_POINTINGS, 0, "needs --pointings");
	checks("psf_%s.fits", NAME_SCA, 0, "no exposure's name ('%s') here; only '%d'");
	checks("out_%n.csv", NAME_SCA, 0, "only '%d' (the SCA) and '%%' (a '%') may follow");
	checks("out_%n.csv", 0, 0, "only '%%' (a '%') may follow");
	checks("psf_%d.fits", NAME_SCA, NAME_SCA, NULL);
	checks("psf.fits", NAME_SCA, NAME_SCA, "needs a '%d'");
	ok(name_fields("a%02d_%s") == (NAME_SCA | NAME_EXPOSURE), "fields of 'a%%02d_%%s'");
	ok(name_fields("a%%d") == 0, "'a%%%%d' has no field");
	ok(name_fields("a%n%d") == 0, "a bad template has none");
	return done_testing();
}
