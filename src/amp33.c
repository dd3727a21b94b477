/* amp33.c - the reference channel of amplifier 33; see amp33.h. */
#include "amp33.h"
#include "readnoise.h"
#include "rng_domains.h"


void amp33_rows(const struct ramp_pattern *p, const struct ramp_det *d,
		const struct ramp_key *k, const struct rnoise *rn, int fy0, int ny, uint16_t *out,
		double *scratch)
{
	struct ramp_key key = *k;
	struct ramp_det dw = *d;

	/* the channel's own numbers: the filter byte with DOM_FILTER_AMP33 */
	key.filter = (k->filter & 0x7f) | DOM_FILTER_AMP33;
	/* with the correlated noise, its white part per pixel and the
	 * channel's own (readnoise.h, channel 32) */
	if (rn)
		dw.read_noise = rn->par.white;
	for (int i = 0; i < ny; i++) {
		uint16_t *o = out + (size_t)i * AMP33_COLS;

		ramp_level1_row(p, &dw, &key, (uint32_t)(fy0 + i) * AMP33_COLS, AMP33_COLS, NULL, 0,
				o, (size_t)ny * AMP33_COLS, scratch);
		if (rn)
			rnoise_add_amp33_dn(rn, d->gain, fy0 + i, o, (size_t)ny * AMP33_COLS);
	}
}
