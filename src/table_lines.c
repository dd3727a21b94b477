/*
 * table_lines.c - the text tables' buffer, its lines and the CSV/whitespace
 * tokenizer, which table_header.c reads headers with and table_text.c rows:
 * the next complete line (a CSV row may span lines inside quotes), a line
 * given back, a line split into fields in place, and the check that refuses
 * control bytes and invalid UTF-8.  The buffer's layout and limits are
 * table_text.c's (see there); the state is struct text_reader
 * (table_text.h).
 */
#include <stdint.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif
#include <stdlib.h>
#include <string.h>

#include "err.h"
#include "input.h"
#include "table_text.h"

/* Bytes after the text buffer kept zero (table.h, TABLE_PAD). */
#define PAD TABLE_PAD

/* Whether buf[a, b) holds a '"' (b <= len). */
static int quote_in(struct text_reader *t, size_t a, size_t b)
{
	if (t->qscan && t->qfrom <= a) {
		if (t->qt != TEXT_NONE && t->qt >= a)
			return t->qt < b;
		if (t->qt == TEXT_NONE && b <= t->qscan)
			return 0;
	}
	{
		char *p = memchr(t->buf + a, '"', t->len - a);

		t->qt = p ? (size_t)(p - t->buf) : TEXT_NONE;
		t->qfrom = a;
		t->qscan = t->len;
	}
	return t->qt != TEXT_NONE && t->qt < b;
}

/*
 * Make the next complete line available: [*ls, *le) without its line end.
 * A CSV row may span lines inside quotes; quotes says whether to look for
 * them.  can_move says no cell points into the buffer yet, so it may be
 * compacted or grown.  Returns 1 for a line, 0 at the end of input, 2 when
 * the buffer is full and must be emptied first (only when !can_move),
 * -1 on error.
 */
int text_line(struct text_reader *t, char **ls, char **le, int quotes,
	      int can_move, struct err *e)
{
	for (;;) {
		size_t end = TEXT_NONE;
		int newlines = 1;

		if (t->nl == TEXT_NONE || t->nl < t->pos) {
			char *p = memchr(t->buf + t->pos, '\n', t->len - t->pos);

			t->nl = p ? (size_t)(p - t->buf) : TEXT_NONE;
		}
		if (t->nl != TEXT_NONE)
			end = t->nl;
		else if (t->eof)
			end = t->len;
		if (end != TEXT_NONE && quotes && quote_in(t, t->pos, end)) {
			/* A quoted cell may hold line ends: find the row's
			 * end outside quotes.  A quote opens a cell only at
			 * its start, as split_line() reads it. */
			int inq = 0, fstart = 1, ws = t->delim == ' ';
			size_t i;

			newlines = 1;
			for (i = t->pos; i < t->len; i++) {
				char c = t->buf[i];

				if (inq) {
					if (c == '"') {
						if (i + 1 < t->len && t->buf[i + 1] == '"')
							i++;
						else
							inq = 0;
					} else if (c == '\n') {
						newlines++;
					}
					continue;
				}
				if (c == '\n')
					break;
				if (c == '"' && fstart)
					inq = 1;
				else if (c == t->delim || (ws && c == '\t'))
					fstart = 1;
				else if (c != ' ')
					fstart = 0;
				if (c == '"')
					fstart = 0;
			}
			if (i < t->len) {
				end = i;
			} else if (t->eof) {
				if (inq)
					return err_set(e, EXIT_INPUT,
						       "%s:%ld: unterminated quoted field",
						       t->name, t->line + 1);
				end = t->len;
			} else {
				end = TEXT_NONE;
			}
			if (end != TEXT_NONE && end > t->nl)
				t->nl = TEXT_NONE;
		}
		if (end != TEXT_NONE) {
			if (end == t->len && t->pos == t->len)
				return 0;
			*ls = t->buf + t->pos;
			*le = t->buf + end;
			if (*le > *ls && (*le)[-1] == '\r')
				(*le)--;
			t->pos = end < t->len ? end + 1 : end;
			t->line += newlines;
			t->consumed = newlines;
			return 1;
		}
		/* Need more data. */
		if (t->len + 1 >= t->cap) {
			if (!can_move)
				return 2;
			if (t->pos > 0) {
				memmove(t->buf, t->buf + t->pos, t->len - t->pos);
				t->len -= t->pos;
				t->pos = 0;
				t->nl = TEXT_NONE;
				t->qscan = 0;
			} else {
				size_t cap = t->cap * 2;
				char *b;

				if (t->len >= TABLE_MAX_LINE)
					return err_set(e, EXIT_INPUT,
						       "%s:%ld: line longer than %u MiB",
						       t->name, t->line + 1,
						       TABLE_MAX_LINE >> 20);
				if (cap > TABLE_MAX_LINE + 2)
					cap = TABLE_MAX_LINE + 2;
				b = realloc(t->buf, cap + PAD);
				if (!b)
					return table_oom(e);
				memset(b + t->cap, 0, cap + PAD - t->cap);
				t->buf = b;
				t->cap = cap;
			}
			continue;
		}
		{
			ssize_t r = input_read(t->in, t->buf + t->len,
					       t->cap - 1 - t->len, e);

			if (r < 0)
				return -1;
			if (r == 0)
				t->eof = 1;
			t->len += (size_t)r;
		}
	}
}

/* Give back the line text_line() just returned. */
void text_unread(struct text_reader *t, char *ls)
{
	t->pos = (size_t)(ls - t->buf);
	t->line -= t->consumed;
	t->nl = TEXT_NONE;
}

#define BYTES(c) (0x0101010101010101ull * (uint64_t)(c))
#define LOW7 BYTES(0x7f)

/* High bit set in each byte of x that is zero: exact, no borrow across
 * bytes (Hacker's Delight 6-1). */
static inline uint64_t zero_bytes(uint64_t x)
{
	return ~(((x & LOW7) + LOW7) | x | LOW7);
}

/* High bit set in each byte of x that split_line() must look at: the
 * delimiter (a blank for whitespace tables, which then also means tab),
 * a quote, a control byte, DEL or a non-ASCII byte. */
static inline uint64_t special_bytes(uint64_t x, uint64_t delim8)
{
	uint64_t ctl = ~((x & LOW7) + BYTES(0x60)) & ~x & BYTES(0x80);

	return ctl | (x & BYTES(0x80)) | zero_bytes(x ^ delim8) |
		zero_bytes(x ^ BYTES('"')) | zero_bytes(x ^ BYTES(0x7f));
}

/* Length of the valid UTF-8 sequence at p, or 0. */
static int utf8_len(const unsigned char *p, const unsigned char *end)
{
	unsigned c = p[0];
	int n, i;
	unsigned min;
	uint32_t cp;

	if (c >= 0xc2 && c <= 0xdf)
		n = 2, cp = c & 0x1f, min = 0x80;
	else if (c >= 0xe0 && c <= 0xef)
		n = 3, cp = c & 0x0f, min = 0x800;
	else if (c >= 0xf0 && c <= 0xf4)
		n = 4, cp = c & 0x07, min = 0x10000;
	else
		return 0;
	if (end - p < n)
		return 0;
	for (i = 1; i < n; i++) {
		if ((p[i] & 0xc0) != 0x80)
			return 0;
		cp = (cp << 6) | (p[i] & 0x3f);
	}
	if (cp < min || cp > 0x10ffff || (cp >= 0xd800 && cp <= 0xdfff))
		return 0;
	return n;
}

static int bad_byte(struct text_reader *t, long line, const char *s, const char *p,
		    struct err *e)
{
	unsigned c = (unsigned char)*p;

	if (c == '\r')
		return err_set(e, EXIT_INPUT,
			       "%s:%ld: stray carriage return (lines must end in LF or CRLF)",
			       t->name, line);
	if (c >= 0x80)
		return err_set(e, EXIT_INPUT, "%s:%ld: invalid UTF-8 at byte %ld of the line",
			       t->name, line, (long)(p - s) + 1);
	return err_set(e, EXIT_INPUT, "%s:%ld: binary data: byte 0x%02x at byte %ld of the line",
		       t->name, line, c, (long)(p - s) + 1);
}

static int grow_fields(struct text_reader *t, struct err *e)
{
	int cap = t->fields_cap ? 2 * t->fields_cap : 32;
	char **n = realloc(t->fields, (size_t)cap * sizeof(*n));

	if (!n)
		return table_oom(e);
	t->fields = n;
	t->fields_cap = cap;
	return 0;
}

static inline int push_field(struct text_reader *t, int *nf, char *f, struct err *e)
{
	if (*nf == t->fields_cap && grow_fields(t, e) < 0)
		return -1;
	t->fields[(*nf)++] = f;
	return 0;
}

#ifdef __SSE2__
/*
 * split_line()'s fast path.
 *
 * CSV rows of numbers, 16 bytes at a time: while a block holds only
 * printable ASCII and delimiters, each delimiter ends a field right
 * where it stands, with no byte looked at twice.  A block with
 * anything else in it (quote, tab, control, DEL, non-ASCII) goes to
 * the byte loop below from the block's start; fs and nf are then
 * what the byte loop would have at that point.  Blocks may read past
 * the line end into the next line's text (bits beyond end are
 * masked), never past the data in the buffer.
 */
static inline int split_blocks(struct text_reader *t, char **qp, char **fsp, char *end,
				int *nf, struct err *e)
{
	char *q = *qp, *fs = *fsp;
	const char *lim = t->buf + t->len;
	const __m128i dl = _mm_set1_epi8(t->delim), qt = _mm_set1_epi8('"');
	const __m128i del = _mm_set1_epi8(0x7f), sp = _mm_set1_epi8(0x20);

	while (q < end && lim - q >= 16) {
		__m128i x = _mm_loadu_si128((const __m128i *)q);
		unsigned d = (unsigned)_mm_movemask_epi8(_mm_cmpeq_epi8(x, dl));
		unsigned o = (unsigned)_mm_movemask_epi8(_mm_or_si128(
			_mm_or_si128(_mm_cmpeq_epi8(x, qt), _mm_cmpeq_epi8(x, del)),
			_mm_cmplt_epi8(x, sp)));
		ptrdiff_t left = end - q;

		if (left < 16) {
			d &= (1u << left) - 1;
			o &= (1u << left) - 1;
		}
		if (o)
			break;
		while (d) {
			char *fe = q + __builtin_ctz(d);
			char *next = fe + 1;

			d &= d - 1;
			while (fe > fs && fe[-1] == ' ')
				fe--;
			*fe = 0;
			if (push_field(t, nf, fs, e) < 0)
				return -1;
			while (next < end && *next == ' ')
				next++;
			fs = next;
		}
		q = left < 16 ? end : q + 16;
	}
	*qp = q;
	*fsp = fs;
	return 0;
}
#endif

/* A quoted cell of split_line() starting at *qp (its opening quote),
 * unquoted in place and pushed, *qp moved past it and the delimiter after
 * it.  Returns 0, 1 when it ends the line, or -1. */
static int split_quoted(struct text_reader *t, char **qp, char *s, char *end, long line,
			int *nf, struct err *e)
{
	int ws = t->delim == ' ';
	char *q = *qp, *fs = q, *w = q++;

	for (;;) {
		if (q >= end)
			return err_set(e, EXIT_INPUT, "%s:%ld: unterminated quoted field",
				       t->name, line);
		if (*q == '"') {
			if (q + 1 < end && q[1] == '"') {
				*w++ = '"';
				q += 2;
				continue;
			}
			q++;
			break;
		}
		if (*q == 0)
			return bad_byte(t, line, s, q, e);
		*w++ = *q++;
	}
	*w = 0;
	if (ws)
		while (q < end && (*q == ' ' || *q == '\t'))
			q++;
	else
		while (q < end && *q == ' ')
			q++;
	if (push_field(t, nf, fs, e) < 0)
		return -1;
	*qp = q;
	if (q == end)
		return 1;
	if (!ws) {
		if (*q != t->delim)
			return err_set(e, EXIT_INPUT, "%s:%ld: text after a closing quote",
				       t->name, line);
		q++;
		while (q < end && *q == ' ')
			q++;
	}
	*qp = q;
	return 0;
}

/*
 * Split a CSV or whitespace line [s, end) in place into t->fields.  *end
 * may be overwritten (it is the line end or the spare byte).  Quoted cells
 * ("a, b", "say ""hi""") are unquoted in place.  Returns the field count
 * or -1.
 */
int split_line(struct text_reader *t, char *s, char *end, long line,
	       struct err *e)
{
	const unsigned char *cls = t->cls;
	int ws = t->delim == ' ';
	int nf = 0;
	char *q = s, *fs;
	uint64_t delim8 = BYTES((unsigned char)t->delim);

	while (q < end && (*q == ' ' || (ws && *q == '\t')))
		q++;
	fs = q;
#ifdef __SSE2__
	if (!ws && split_blocks(t, &q, &fs, end, &nf, e) < 0)
		return -1;
#endif
	while (q < end) {
		unsigned c = cls[(unsigned char)*q];

		if (c == C_PLAIN) {
			q++;
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
			/* Skip 8 ordinary bytes at a time; the next special one
			 * (delimiter, quote, control, non-ASCII) is handled by
			 * the byte loop. */
			while (end - q >= 8) {
				uint64_t x, m;

				memcpy(&x, q, 8);
				m = special_bytes(x, delim8);
				if (m) {
					q += __builtin_ctzll(m) >> 3;
					break;
				}
				q += 8;
			}
#endif
			continue;
		}
		if (c == C_DELIM) {
			char *fe = q;

			if (!ws)
				while (fe > fs && fe[-1] == ' ')
					fe--;
			*fe = 0;
			if (push_field(t, &nf, fs, e) < 0)
				return -1;
			q++;
			if (ws)
				while (q < end && (*q == ' ' || *q == '\t'))
					q++;
			else
				while (q < end && *q == ' ')
					q++;
			fs = q;
			if (ws && q == end)
				goto done;
			continue;
		}
		if (c == C_QUOTE) {
			int r;

			if (q != fs) {  /* a quote inside a bare cell is text */
				q++;
				continue;
			}
			r = split_quoted(t, &q, s, end, line, &nf, e);
			if (r < 0)
				return -1;
			if (r > 0)
				return nf;
			fs = q;
			continue;
		}
		if (c == C_HIGH) {
			int n = utf8_len((const unsigned char *)q,
					 (const unsigned char *)end);

			if (!n)
				return bad_byte(t, line, s, q, e);
			q += n;
			continue;
		}
		return bad_byte(t, line, s, q, e);
	}
	{
		char *fe = end;

		while (fe > fs && (fe[-1] == ' ' || (ws && fe[-1] == '\t')))
			fe--;
		*fe = 0;
		if (!(ws && fs == end) && push_field(t, &nf, fs, e) < 0)
			return -1;
	}
done:
	return nf;
}

void set_classes(struct text_reader *t, char delim)
{
	t->delim = delim;
	memset(t->cls, C_PLAIN, sizeof(t->cls));
	for (int c = 0; c < 32; c++)
		t->cls[c] = C_BAD;
	t->cls['\t'] = C_PLAIN;
	t->cls['\r'] = C_CR;
	t->cls[127] = C_BAD;
	for (int c = 128; c < 256; c++)
		t->cls[c] = C_HIGH;
	t->cls['"'] = C_QUOTE;
	if (delim == ' ') {
		t->cls[' '] = C_DELIM;
		t->cls['\t'] = C_DELIM;
	} else {
		t->cls[(unsigned char)delim] = C_DELIM;
	}
}

int check_text(struct text_reader *t, const char *s, const char *e, long line,
	       struct err *ep)
{
	for (const char *p = s; p < e; p++) {
		unsigned c = (unsigned char)*p;

		if ((c < 32 && c != '\t') || c == 127)
			return bad_byte(t, line, s, p, ep);
		if (c >= 0x80) {
			int n = utf8_len((const unsigned char *)p,
					 (const unsigned char *)e);

			if (!n)
				return bad_byte(t, line, s, p, ep);
			p += n - 1;
		}
	}
	return 0;
}
