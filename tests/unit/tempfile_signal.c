/*
 * tempfile_signal.c - a fatal signal that lands while temporaries are being
 * created and removed, on any thread, leaves none of them behind.
 *
 * A child process runs two threads that create a temporary beside an
 * output, close it and discard it, over and over; the parent sends SIGINT
 * after a varying delay.  The child must exit 4 (EXIT_SIGNAL) and the
 * directory must then be empty.  Before the creation was made one step for
 * the handler, a signal between open(2) and the registration left the file.
 */
#include <dirent.h>
#include <limits.h>
#include <pthread.h>
#include <signal.h>
#include <stdlib.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "err.h"
#include "tempfile.h"
#include "tap.h"

static char out_path[PATH_MAX + 16];

static void *churn(void *arg)
{
	char tmp[PATH_MAX];

	(void)arg;
	for (;;) {
		struct err e = { 0 };
		int fd = tempfile_beside(out_path, tmp, sizeof(tmp), &e);

		if (fd < 0)
			_exit(3);
		close(fd);
		tempfile_discard(tmp);
	}
	return NULL;
}

/* Files left in dir (its entries other than . and ..). */
static int entries(const char *dir)
{
	DIR *d = opendir(dir);
	struct dirent *de;
	int n = 0;

	if (!d)
		return -1;
	while ((de = readdir(d)))
		if (strcmp(de->d_name, ".") && strcmp(de->d_name, ".."))
			n++;
	closedir(d);
	return n;
}

int main(void)
{
	const char *tmpdir = getenv("TMPDIR");
	char dir[PATH_MAX];
	int rounds = 400, bad_status = 0, left = 0, r;

	snprintf(dir, sizeof(dir), "%s/wfs-tempsig-XXXXXX", tmpdir && *tmpdir ? tmpdir : "/tmp");
	if (!mkdtemp(dir))
		skip_all("no temporary directory");
	snprintf(out_path, sizeof(out_path), "%s/out.fits", dir);
	for (r = 0; r < rounds; r++) {
		/* 0 to 2 ms in 97 steps, so the signal lands at every phase of
		 * the loop's create, close and remove */
		struct timespec delay = { 0, 20000L * ((r * 37) % 97) + 200000L };
		int status, ready[2];
		char c;
		pid_t pid;

		if (pipe(ready) || (pid = fork()) < 0)
			break;
		if (pid == 0) {
			pthread_t t;

			/* the signal must find the policy set: say so first;
			 * a child the signal does not end is ended by the
			 * alarm (a status other than 4) */
			tempfile_signals("tempfile_signal");
			alarm(20);
			if (!freopen("/dev/null", "w", stderr) || write(ready[1], "", 1) != 1)
				_exit(3);
			pthread_create(&t, NULL, churn, NULL);
			churn(NULL);
		}
		close(ready[1]);
		if (read(ready[0], &c, 1) != 1)
			c = 1;
		close(ready[0]);
		nanosleep(&delay, NULL);
		kill(pid, SIGINT);
		waitpid(pid, &status, 0);
		if (!WIFEXITED(status) || WEXITSTATUS(status) != EXIT_SIGNAL) {
			if (bad_status++ < 3)
				diag("round %d: status %#x", r, status);
		}
		if (entries(dir) != 0) {
			left++;
			/* clear the leftovers for the next round */
			DIR *d = opendir(dir);
			struct dirent *de;
			char p[PATH_MAX + 260];

			while (d && (de = readdir(d)))
				if (strcmp(de->d_name, ".") && strcmp(de->d_name, "..")) {
					snprintf(p, sizeof(p), "%s/%s", dir, de->d_name);
					unlink(p);
				}
			if (d)
				closedir(d);
		}
	}
	ok(r == rounds, "%d of %d rounds run (pipe and fork)", r, rounds);
	ok(bad_status == 0, "every interrupted child exits %d (%d of %d did not)", EXIT_SIGNAL,
	   bad_status, rounds);
	ok(left == 0, "no temporary left behind by a signal (%d of %d rounds left one)", left,
	   rounds);
	rmdir(dir);
	return done_testing();
}
