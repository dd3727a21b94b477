/*
 * rng_domains.h - every purpose of the project's keyed random numbers, in
 * one list (rng.h: a generator's domain is rng_domain(purpose, filter,
 * SCA, group), purpose in bits 0-7, filter 8-15, SCA 16-23, group 24-31).
 *
 * A purpose serves one stream: two stages never share a value, so the
 * numbers of one never move when another changes.  A new purpose takes a
 * value not in this list.
 */
#ifndef WFS_RNG_DOMAINS_H
#define WFS_RNG_DOMAINS_H

enum rng_purpose {
	/* noise.c: the scene level's noise stages */
	DOM_SC_POISSON = 0x01,
	DOM_SC_READ = 0x02,
	DOM_SC_DARK_SHOT = 0x03,
	DOM_SC_DARK_FIELD = 0x04,
	DOM_SC_FLAT_FIELD = 0x05,
	DOM_SC_CR_HIT = 0x06,
	DOM_SC_CR_LOW = 0x07,
	DOM_SC_CR_HIGH = 0x08,
	DOM_SC_CR_LOW_N = 0x09,         /* per-centre counts and energies, for */
	DOM_SC_CR_HIGH_N = 0x0a,        /* lambda >= CR_PER_CENTRE */
	DOM_SC_CR_LOW_E = 0x0b,
	DOM_SC_CR_HIGH_E = 0x0c,
	/* ramp.c: levels 1 and 2 (group: the resultant, or the read) */
	DOM_RESET = 0x41,
	DOM_CR = 0x42,
	DOM_CR_DETAIL = 0x43,
	DOM_POIS = 0x44,
	DOM_SPLIT = 0x45,
	DOM_SPLIT_N = 0x46,
	DOM_READ = 0x47,
	DOM_GAP = 0x48,
	DOM_GLOW = 0x49,                /* persist.c's afterglow, read by read */
	DOM_REFREAD = 0x4a,
	/* readnoise.c: the correlated read noise */
	DOM_RN_PINK = 0x51,             /* group: the series, 0 shared, 1 + c own */
	DOM_RN_OFF = 0x52,              /* cell: read * 64 + c * 2 + parity */
	DOM_RN_SLOW = 0x53,             /* group: the knot; deviate: the pixel */
};

/* The filter byte of a domain: noise.c's dark field is that of any filter;
 * amp33.c's channel keeps ramp.c's purposes with this bit set on the
 * filter (the filters are below 16). */
#define DOM_ANY_FILTER 0xff
#define DOM_FILTER_AMP33 0x80

#endif
