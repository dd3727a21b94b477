/*
 * tap.h - a few macros for C unit tests that print TAP, run by prove.
 *
 *   ok(cond, "what holds");
 *   is_near(got, want, tol, "what");   |got - want| <= tol (absolute)
 *   is_rel(got, want, rtol, "what");   |got - want| <= rtol |want| (relative)
 *   skip_all("why");                   plan 0 and stop
 *   return done_testing();
 */
#ifndef WFS_TAP_H
#define WFS_TAP_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

static int tap_n, tap_failed;

#define ok(cond, ...) tap_ok(!!(cond), __FILE__, __LINE__, __VA_ARGS__)

static inline int tap_ok(int pass, const char *file, int line, const char *fmt, ...)
	__attribute__((format(printf, 4, 5)));
#include <stdarg.h>
static inline int tap_ok(int pass, const char *file, int line, const char *fmt, ...)
{
	va_list ap;

	printf("%s %d - ", pass ? "ok" : "not ok", ++tap_n);
	va_start(ap, fmt);
	vprintf(fmt, ap);
	va_end(ap);
	printf("\n");
	if (!pass) {
		printf("#   failed at %s:%d\n", file, line);
		tap_failed++;
	}
	fflush(stdout);
	return pass;
}

/* |got - want| <= tol, where tol is absolute; prints both on failure. */
#define is_near(got, want, tol, ...) do { \
	double g_ = (got), w_ = (want), t_ = (tol); \
	if (!ok(isfinite(g_) && fabs(g_ - w_) <= t_, __VA_ARGS__)) \
		printf("#   got %.10g, want %.10g, tolerance %.3g\n", g_, w_, t_); \
} while (0)

/* |got - want| <= rtol |want|: a relative tolerance (want 0 then asks for
 * exactly 0); prints both and the relative error on failure. */
#define is_rel(got, want, rtol, ...) do { \
	double g_ = (got), w_ = (want), t_ = (rtol); \
	if (!ok(isfinite(g_) && isfinite(w_) && fabs(g_ - w_) <= t_ * fabs(w_), __VA_ARGS__)) \
		printf("#   got %.10g, want %.10g, relative error %.3g, tolerance %.3g\n", \
		       g_, w_, w_ != 0 ? fabs(g_ - w_) / fabs(w_) : INFINITY, t_); \
} while (0)

#define diag(...) do { printf("# "); printf(__VA_ARGS__); printf("\n"); } while (0)

#define skip_all(why) do { printf("1..0 # SKIP %s\n", why); exit(0); } while (0)

static inline int done_testing(void)
{
	printf("1..%d\n", tap_n);
	return tap_failed ? 1 : 0;
}

#endif
