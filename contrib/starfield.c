/*
 * starfield - write a uniform field of stars as CSV, for benchmarks and load
 * tests: any number of rows, generated on the fly (nothing stored).
 *
 *   starfield [-n N] [-r RA] [-d DEC] [-w DEG] [-m MIN] [-M MAX] [-x] [-g] [-s SEED]
 *
 * Positions are uniform on the sky in a square WIDTH degrees wide about
 * (RA, DEC) (default: 0.9 deg, enough to cover all 18 SCAs of a boresight
 * pointing there), or with -x uniform in 1-based pixels of one SCA.
 * Magnitudes are AB, drawn from a power-law luminosity function
 * dN/dm ~ 10^(0.3 m) between MIN and MAX (default 20-27: faint stars).
 * -n 0 writes rows forever (for load tests that cut the stream).
 *
 * -g writes Sersic galaxies instead (columns type, n, re, phi, ratio), the
 * deep-field mix of tests/unit/sersic_model.c --field: n in 0.8..1.4 for
 * 60% (discs) and 1.5..4 for the rest, r_e log-normal about 3 pixels
 * (sigma 0.6 in ln, clipped to 0.3..60), axis ratio uniform in 0.2..1,
 * position angle uniform; use -m 20 -M 28 for its magnitudes.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static uint64_t state;

/* splitmix64: small, fast and good enough for placing stars. */
static double uniform(void)
{
	uint64_t z = (state += 0x9e3779b97f4a7c15ULL);

	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
	z ^= z >> 31;
	return (z >> 11) * 0x1.0p-53;
}

int main(int argc, char **argv)
{
	long long n = 100000;
	double ra = 0, dec = 0, width = 0.9, mmin = 20, mmax = 27;
	int pixels = 0, galaxies = 0, c;
	char buf[1 << 16];
	size_t len = 0;

	state = 1;
	while ((c = getopt(argc, argv, "n:r:d:w:m:M:xgs:h")) != -1) {
		switch (c) {
		case 'n': n = atoll(optarg); break;
		case 'r': ra = atof(optarg); break;
		case 'd': dec = atof(optarg); break;
		case 'w': width = atof(optarg); break;
		case 'm': mmin = atof(optarg); break;
		case 'M': mmax = atof(optarg); break;
		case 'x': pixels = 1; break;
		case 'g': galaxies = 1; break;
		case 's': state = strtoull(optarg, NULL, 10); break;
		default:
			fprintf(stderr, "usage: starfield [-n N] [-r RA] [-d DEC] [-w DEG] "
				"[-m MIN] [-M MAX] [-x] [-g] [-s SEED]\n");
			return c == 'h' ? 0 : 1;
		}
	}
	printf(pixels ? "id,x,y,mag%s\n" : "id,ra,dec,mag%s\n",
	       galaxies ? ",type,n,re,phi,ratio" : "");
	/* dN/dm ~ 10^(0.3 m): invert its cumulative distribution */
	double a = pow(10, 0.3 * mmin), b = pow(10, 0.3 * mmax);
	double sd0 = sin((dec - width / 2) * M_PI / 180), sd1 = sin((dec + width / 2) * M_PI / 180);
	for (long long i = 1; n == 0 || i <= n; i++) {
		double m = log10(a + (b - a) * uniform()) / 0.3, p, q;

		if (pixels) {
			p = 0.5 + 4088 * uniform();
			q = 0.5 + 4088 * uniform();
		} else {
			/* uniform in area: uniform in sin(dec) */
			q = asin(sd0 + (sd1 - sd0) * uniform()) * 180 / M_PI;
			p = ra + (uniform() - 0.5) * width / cos(dec * M_PI / 180);
			p = fmod(p + 360, 360);
		}
		len += snprintf(buf + len, sizeof(buf) - len, "%lld,%.7f,%.7f,%.3f", i, p, q, m);
		if (galaxies) {
			double u1 = uniform(), u2 = uniform();
			double gauss = sqrt(-2 * log(u1 + 1e-300)) * cos(2 * M_PI * u2);
			double sn = uniform() < 0.6 ? 0.8 + 0.6 * uniform() : 1.5 + 2.5 * uniform();
			double re = fmin(fmax(3.0 * exp(0.6 * gauss), 0.3), 60);
			double ratio = 0.2 + 0.8 * uniform();

			len += snprintf(buf + len, sizeof(buf) - len, ",sersic,%.3f,%.3f,%.1f,%.3f",
					sn, re, 360 * uniform(), ratio);
		}
		buf[len++] = '\n';
		if (len > sizeof(buf) - 128) {
			if (fwrite(buf, 1, len, stdout) != len)
				return 1;
			len = 0;
		}
	}
	return fwrite(buf, 1, len, stdout) != len;
}
