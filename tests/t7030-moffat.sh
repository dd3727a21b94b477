#!/bin/sh
# contrib/moffat, the example model that is not in the core, built with its
# own Makefile the way an outside author would: against the header in the
# tree, and against an installed wfiscene through pkg-config.  The star it
# draws carries the row's flux, sits where the row says, and turns with
# theta; bad parameters are refused with a message.
. "$(dirname "$0")/lib.sh"
require_python

# Only the sources, as an outside author has them (never a moffat.so that
# someone left behind by building in the tree).
for d in src-tree src-inst; do
	mkdir "$d" && cp "$TOP/contrib/moffat/Makefile" "$TOP/contrib/moffat/README" \
		"$TOP/contrib/moffat/moffat.c" "$d/" || exit 1
done

test_expect_success 'builds against the in-tree header with its Makefile' '
	make -s -C src-tree WFS_CFLAGS=-I"$TOP/include" &&
	test -f src-tree/moffat.so
'

test_expect_success 'exports wfs_model_entry and nothing else' '
	nm -D --defined-only src-tree/moffat.so | awk "{ print \$3 }" |
		grep -v "^_" >syms &&
	echo wfs_model_entry >want &&
	test_cmp want syms
'

# A mock host: the plugin's source compiled into a test program that lends
# it error() and nothing else, as wfiscene-model(7) suggests.  No wfiscene
# needed: this checks the model itself.
cat >mock.c <<'EOF'
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include "moffat.c"

static char msg[512];
static int fails;

static int mock_error(void *ctx, const char *fmt, ...)
{
	va_list ap;

	(void)ctx;
	va_start(ap, fmt);
	vsnprintf(msg, sizeof(msg), fmt, ap);
	va_end(ap);
	return -1;
}

#define CHECK(c, ...) do { if (!(c)) { fails++; printf("FAIL %d: ", __LINE__); \
	printf(__VA_ARGS__); printf("\n"); } } while (0)

#define N 96
static double img[N * N], part[N * N];

/* Render src into [x0, x0 + nx) x [y0, y0 + ny) of a buffer whose pixel
 * (0, 0) is detector pixel (ox, oy). */
static void draw(const struct wfs_model *m, void *st, const struct wfs_source *s,
		 double *buf, int ox, int oy, int x0, int y0, int nx, int ny)
{
	struct wfs_window w = { buf + (y0 - oy) * N + (x0 - ox), N, x0, y0, nx, ny };

	CHECK(m->render(st, NULL, NULL, s, &w) == 0, "render");
}

int main(void)
{
	struct wfs_host h = { .abi = WFS_ABI_VERSION, .size = sizeof(h), .error = mock_error };
	const struct wfs_model *m = wfs_model_entry(WFS_ABI_VERSION);
	double p[4] = { 3, 2.5, 0, 0 }, sum = 0;
	struct wfs_source s = { .x = 1047.3, .y = 2046.6, .flux = 1000, .param = p };
	struct wfs_box b;
	void *st;
	int i, k;

	CHECK(m && m->abi == WFS_ABI_VERSION && m->size == sizeof(*m), "descriptor");
	CHECK(!wfs_model_entry(WFS_ABI_VERSION + 1), "declines another ABI");
	CHECK(m->init(&h, &st) == 0, "init");

	/* flux, round and elliptical, narrow and wide */
	for (k = 0; k < 4; k++) {
		static const double par[4][4] = {
			{ 3, 2.5, 0, 0 }, { 4.765, 0.4, 0, 0 }, { 2.5, 4, 0.6, 33 }, { 8, 1, 0.3, -70 },
		};
		memcpy(p, par[k], sizeof(p));
		memset(img, 0, sizeof(img));
		CHECK(m->prepare(st, &s) == 0, "prepare %d: %s", k, msg);
		m->footprint(st, &s, &b);
		CHECK(b.x0 >= 1000 && b.x1 <= 1000 + N && b.y0 >= 2000 && b.y1 <= 2000 + N,
		      "box %d %d %d %d", b.x0, b.y0, b.x1, b.y1);
		draw(m, st, &s, img, 1000, 2000, 1000, 2000, N, N);
		for (sum = 0, i = 0; i < N * N; i++)
			sum += img[i];
		CHECK(fabs(sum / 1000 - 1) < 1e-4, "star %d: sum %.6f, want 1000", k, sum);
	}

	/* split into windows anywhere: the same pixels, bit for bit */
	p[0] = 3; p[1] = 2.5; p[2] = 0.2; p[3] = 10;
	memset(img, 0, sizeof(img));
	memset(part, 0, sizeof(part));
	m->prepare(st, &s);
	draw(m, st, &s, img, 1000, 2000, 1000, 2000, N, N);
	draw(m, st, &s, part, 1000, 2000, 1000, 2000, 47, 46);
	draw(m, st, &s, part, 1000, 2000, 1047, 2000, N - 47, 46);
	draw(m, st, &s, part, 1000, 2000, 1047, 2046, N - 47, N - 46);
	draw(m, st, &s, part, 1000, 2000, 1000, 2047, 47, N - 47);
	draw(m, st, &s, part, 1000, 2000, 1047, 2046, 0, 0);
	draw(m, st, &s, part, 1000, 2000, 1000, 2046, 47, 1);
	CHECK(!memcmp(img, part, sizeof(img)), "windows change pixels");

	/* only inside the window, and adding */
	for (i = 0; i < N * N; i++)
		part[i] = 7;
	draw(m, st, &s, part, 1000, 2000, 1040, 2040, 10, 10);
	for (i = 0; i < N * N; i++) {
		int x = 1000 + i % N, y = 2000 + i / N;
		int in = x >= 1040 && x < 1050 && y >= 2040 && y < 2050;

		CHECK(in ? part[i] == 7 + img[i] : part[i] == 7, "pixel %d %d", x, y);
	}

	/* far off the detector: no overflow in the box */
	s.x = 1e15;
	s.y = -1e15;
	m->prepare(st, &s);
	m->footprint(st, &s, &b);
	CHECK(b.x0 <= b.x1 && b.y0 <= b.y1, "far box");

	/* bad rows */
	{
		static const double bad[][4] = {
			{ 1, 2, 0, 0 }, { 0.5, 2, 0, 0 }, { NAN, 2, 0, 0 }, { 3, 0, 0, 0 },
			{ 3, -1, 0, 0 }, { 3, INFINITY, 0, 0 }, { 3, 2, 1, 0 }, { 3, 2, -0.1, 0 },
			{ 3, 2, 0, NAN }, { 1.02, 3, 0, 0 },
		};
		for (k = 0; k < (int)(sizeof(bad) / sizeof(bad[0])); k++) {
			memcpy(p, bad[k], sizeof(p));
			msg[0] = 0;
			s.x = s.y = 100;
			CHECK(m->prepare(st, &s) == -1 && msg[0], "bad row %d accepted", k);
		}
	}
	m->fini(st);
	printf("%s\n", fails ? "failed" : "ok");
	return fails != 0;
}
EOF

test_expect_success 'against a mock host: flux, windows, clipping, bad rows' '
	${CC:-cc} -std=c11 -Wall -Wextra -Werror -I"$TOP/include" -Isrc-tree \
		-o mock mock.c -lm &&
	./mock
'

# stars: three Moffat stars on SCA 1 (1-based catalog pixels) and the
# checks on the image: flux, centroid and orientation of each.
cat >stars.csv <<'EOF'
x,y,flux,type,beta,fwhm,ellip,theta
1000.3,1200.7,1000,moffat,3,2.5,,
2500,2500,500,moffat,4.765,1.2,0,0
3001.5,900.25,2000,moffat,2.5,4,0.5,30
EOF

cat >check.py <<'EOF'
import sys, math
import numpy as np
from astropy.io import fits
img = fits.getdata(sys.argv[1], 'WFI01').astype(np.float64)
stars = [(1000.3, 1200.7, 1000, None), (2500, 2500, 500, None),
         (3001.5, 900.25, 2000, 30.0)]
for x, y, flux, theta in stars:
    cx, cy = int(round(x)) - 1, int(round(y)) - 1
    h = 60
    cut = img[cy - h:cy + h + 1, cx - h:cx + h + 1]
    yy, xx = np.mgrid[cy - h:cy + h + 1, cx - h:cx + h + 1]
    tot = cut.sum()
    assert abs(tot / flux - 1) < 2e-3, ('flux', x, y, tot, flux)
    mx, my = (cut * xx).sum() / tot, (cut * yy).sum() / tot
    # catalog pixels are 1-based, numpy's 0-based
    assert abs(mx - (x - 1)) < 0.01 and abs(my - (y - 1)) < 0.01, ('centre', x, y, mx, my)
    if theta is not None:
        # second moments inside 3 FWHM: the major axis angle from +x to +y
        r2 = (xx - mx) ** 2 + (yy - my) ** 2
        w = cut * (r2 < 144)
        sxx = (w * (xx - mx) ** 2).sum(); syy = (w * (yy - my) ** 2).sum()
        sxy = (w * (xx - mx) * (yy - my)).sum()
        ang = 0.5 * math.degrees(math.atan2(2 * sxy, sxx - syy))
        assert abs(ang - theta) < 1, ('theta', ang, theta)
print('ok')
EOF

test_expect_success 'renders stars with the right flux, place and angle' '
	"$WFS" --filter F129 --sca 1 --plugin-path src-tree -o stars.fits stars.csv &&
	"$PY" check.py stars.fits
'

test_expect_success 'the same image on one thread and many, any tile size' '
	"$WFS" --filter F129 --sca 1 --plugin-path src-tree --threads 1 --tile 64 \
		-o one.fits stars.csv &&
	"$PY" -c "
import numpy as np
from astropy.io import fits
a = fits.getdata(\"one.fits\", \"WFI01\"); b = fits.getdata(\"stars.fits\", \"WFI01\")
assert np.array_equal(a, b), abs(a - b).max()
"'

bad() {
	printf 'x,y,flux,type,beta,fwhm,ellip\n100,100,10,moffat,%s,%s,%s\n' "$1" "$2" "$3" >bad.csv &&
	test_must_fail --status 1 "$WFS" --filter F129 --sca 1 --plugin-path src-tree \
		-o bad.fits bad.csv 2>err &&
	test_grep "bad.csv:2" err &&
	test_grep "$4" err &&
	! ls -A | grep -q "bad\.fits"
}

test_expect_success 'bad parameters are refused with the row and the reason' '
	bad 1 2 0 "beta must be above 1" &&
	bad 3 -1 0 "fwhm must be a positive" &&
	bad 3 2 1 "ellip must be at least 0 and below 1" &&
	bad 1.05 2 0 "beyond 512 pixels" &&
	bad "" 2 0 "model .moffat.: column .beta.: empty value" &&
	bad 3 "" 0 "column .fwhm.: empty value"
'

test_expect_success 'a missing required column is named' '
	printf "x,y,flux,type,fwhm\n100,100,10,moffat,2\n" >nobeta.csv &&
	test_must_fail "$WFS" --filter F129 --sca 1 --plugin-path src-tree \
		-o nobeta.fits nobeta.csv 2>err &&
	test_grep "beta" err &&
	! test -e nobeta.fits
'

# make install PREFIX=... (from a copy of the build: see wfs_install in
# lib.sh): the program, header, pkg-config file and plugin directory an
# outside author builds against.  The installed program finds the plugin
# installed beside its own with no help.
inst=$TRASH/inst
test_expect_success 'make install puts header, pkg-config file and man pages in place' '
	wfs_install "$inst" >install.log 2>&1 || { cat install.log; false; } &&
	test -f "$inst/include/wfiscene/model.h" &&
	test -f "$inst/lib/pkgconfig/wfiscene-model.pc" &&
	test -x "$inst/bin/wfiscene" &&
	test -d "$inst/lib/wfiscene" &&
	test -f "$inst/share/man/man7/wfiscene-model.7" &&
	PKG_CONFIG_PATH=$inst/lib/pkgconfig pkg-config --cflags wfiscene-model >cflags &&
	test_grep "$inst/include" cflags &&
	test_grep "fvisibility=hidden" cflags &&
	PKG_CONFIG_PATH=$inst/lib/pkgconfig pkg-config --variable=plugindir wfiscene-model >dir &&
	test "$(cat dir)" = "$inst/lib/wfiscene"
'

test_expect_success 'builds against the installed copy through pkg-config' '
	PKG_CONFIG_PATH=$inst/lib/pkgconfig make -C src-inst >build.log 2>&1 ||
		{ cat build.log; false; } &&
	test_grep "$inst/include" build.log &&
	PKG_CONFIG_PATH=$inst/lib/pkgconfig make -s -C src-inst install &&
	test -f "$inst/lib/wfiscene/moffat.so"
'

test_expect_success 'the installed wfiscene finds it in the plugin directory' '
	env -u WFISCENE_PLUGIN_PATH "$inst/bin/wfiscene" \
		--filter F129 --sca 1 -o inst.fits stars.csv &&
	"$PY" check.py inst.fits
'

test_done
