/*
 * clock.h - the run's clock and its progress line (clock.c).
 *
 * Timings of the run loop (run.c), the workers (render.c) and the writer
 * (write.c) are taken here, so that none of them reaches into another for
 * the time of day.
 */
#ifndef WFS_CLOCK_H
#define WFS_CLOCK_H

struct engine;

double engine_clock(void);              /* monotonic seconds */
/* A progress line on stderr when it is a terminal, at most four times a
 * second unless force. */
void engine_progress(struct engine *g, const char *stage, int force);

#endif
