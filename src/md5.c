/* md5.c - RFC 1321's MD5 of a buffer; see md5.h. */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "md5.h"

static uint32_t rol(uint32_t x, int c)
{
	return x << c | x >> (32 - c);
}

/* One 64-byte block into the state h. */
static void md5_block(uint32_t h[4], const uint32_t K[64], const unsigned char *p)
{
	/* the per-round shifts of RFC 1321 */
	static const int s[64] = {
		7, 12, 17, 22, 7, 12, 17, 22, 7, 12, 17, 22, 7, 12, 17, 22,
		5, 9, 14, 20, 5, 9, 14, 20, 5, 9, 14, 20, 5, 9, 14, 20,
		4, 11, 16, 23, 4, 11, 16, 23, 4, 11, 16, 23, 4, 11, 16, 23,
		6, 10, 15, 21, 6, 10, 15, 21, 6, 10, 15, 21, 6, 10, 15, 21,
	};
	uint32_t m[16], a = h[0], b = h[1], c = h[2], d = h[3];

	for (int i = 0; i < 16; i++)
		m[i] = (uint32_t)p[4 * i] | (uint32_t)p[4 * i + 1] << 8 |
		       (uint32_t)p[4 * i + 2] << 16 | (uint32_t)p[4 * i + 3] << 24;
	for (int i = 0; i < 64; i++) {
		uint32_t f;
		int g;

		if (i < 16) {
			f = (b & c) | (~b & d);
			g = i;
		} else if (i < 32) {
			f = (d & b) | (~d & c);
			g = (5 * i + 1) & 15;
		} else if (i < 48) {
			f = b ^ c ^ d;
			g = (3 * i + 5) & 15;
		} else {
			f = c ^ (b | ~d);
			g = (7 * i) & 15;
		}
		f += a + K[i] + m[g];
		a = d;
		d = c;
		c = b;
		b += rol(f, s[i]);
	}
	h[0] += a;
	h[1] += b;
	h[2] += c;
	h[3] += d;
}

void md5(const void *data, size_t n, unsigned char out[16])
{
	uint32_t h[4] = { 0x67452301, 0xefcdab89, 0x98badcfe, 0x10325476 };
	const unsigned char *p = data;
	unsigned char tail[128];
	size_t full = n / 64 * 64, rest = n - full, t;
	uint64_t bits = (uint64_t)n * 8;
	uint32_t K[64];

	/* K[i] = floor(2^32 |sin(i + 1)|) */
	for (int i = 0; i < 64; i++)
		K[i] = (uint32_t)(fabs(sin(i + 1.0)) * 4294967296.0);

	for (size_t i = 0; i < full; i += 64)
		md5_block(h, K, p + i);
	memcpy(tail, p + full, rest);
	tail[rest] = 0x80;
	t = rest + 1 <= 56 ? 64 : 128;
	memset(tail + rest + 1, 0, t - rest - 1);
	for (int i = 0; i < 8; i++)
		tail[t - 8 + i] = (unsigned char)(bits >> (8 * i));
	for (size_t i = 0; i < t; i += 64)
		md5_block(h, K, tail + i);
	for (int i = 0; i < 4; i++)
		for (int k = 0; k < 4; k++)
			out[4 * i + k] = (unsigned char)(h[i] >> (8 * k));
}
